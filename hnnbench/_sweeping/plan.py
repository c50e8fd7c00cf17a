"""A command line checked before Hydra starts (:func:`plan`), or built from the
Python API's arguments (:func:`request`): a :class:`Plan` ready for
:func:`hnnbench._sweeping.execution.run_plan` (docs/ARCHITECTURE.md).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hnnbench._contracts.errors import ConfigError
from hnnbench._running.compose import check_hydra_node, compose, profile_of, track_of_overrides
from hnnbench._running.config import Job, fingerprint, hydra_error_line, prepare_job
from hnnbench._sweeping.overrides import (
    batch_seeds,
    flag_args,
    hydra_value,
    is_group,
    parse_flags,
    parse_override,
    trial_overrides,
)

__all__ = ["Plan", "plan", "request"]


@dataclass
class Plan:
    """A checked command line, ready for Hydra."""

    argv: list[str]
    multirun: bool
    n_jobs: int | None
    overrides: list[str] = field(default_factory=list)
    #: A swept group pinned to its first value in the command line Hydra composes its
    #: sweep-wide config with (``model=a`` for ``model=a,b``), because that config
    #: skips sweeps of groups: with the group empty, an override of one of its keys
    #: (``model.steps=5``) would not compose. The pinned text -> the sweep's text;
    #: :class:`Sweeper` hands Hydra's sweeper the sweep again.
    pinned: dict[str, str] = field(default_factory=dict)
    #: The jobs the plan composed and validated, by their config's fingerprint
    #: (:func:`~hnnbench._running.config.fingerprint`): a job of this command run in
    #: this process takes its own from here instead of validating its config again.
    validated: dict[str, Job] = field(default_factory=dict, repr=False)

    @property
    def hydra_argv(self) -> list[str]:
        """The command line given to Hydra (:attr:`argv`, swept groups pinned)."""
        back = {sweep: one for one, sweep in self.pinned.items()}
        return [back.get(arg, arg) for arg in self.argv]


def plan(argv: list[str]) -> Plan:
    """Check a Hydra command line and rewrite ``all``; raise :class:`ConfigError`.

    The flags are parsed by Hydra's own parser; every override is parsed, names are
    checked, and the config of the first job and of every other swept value is
    composed (Hydra's ``hydra`` node included) and validated, so that Hydra never gets
    a command line it would reject with a multi-line error.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf, open_dict

    ns = parse_flags(argv)
    flags = flag_args(ns)
    multirun = bool(ns.multirun)
    if ns.shell_completion:  # its arguments (install=bash) are not config overrides
        return Plan(
            argv=flags + list(ns.overrides),
            multirun=False,
            n_jobs=None,
            overrides=list(ns.overrides),
        )
    profile_of(list(ns.overrides))
    track_of_overrides(list(ns.overrides))
    parser = OverridesParser.create()
    entries = [parse_override(parser, text) for text in ns.overrides]
    if not (ns.help or ns.hydra_help or ns.info is not None):
        for kind in ("system", "model"):  # the shipped config names no plugin
            if not any(e.key == kind and not e.text.startswith("~") for e in entries):
                raise ConfigError(
                    f"no {kind} chosen: add {kind}=<name> to the command line (`hnnbench "
                    f"list` shows the {kind}s; {kind}=all for every one)"
                )
    if multirun:
        entries = batch_seeds(entries)
    rewritten = [e.text for e in entries]
    sweeps = {
        i: e for i, e in enumerate(entries) if e.sweep and (e.values is None or len(e.values) > 1)
    }
    if sweeps and not multirun:
        e = next(iter(sweeps.values()))
        vals = [str(v) for v in e.values or []]
        shown = f" ({', '.join(vals[:4])}{', ...' if len(vals) > 4 else ''})" if vals else ""
        if ns.cfg is not None or ns.info is not None:
            raise ConfigError(
                f"{e.key} has several values{shown}: --cfg and --info show one "
                "config, so give one value per key"
            )
        raise ConfigError(
            f"{e.key} has {len(vals) or 'several'} values{shown}: that is a sweep, so add -m, "
            f"e.g. hnnbench -m {' '.join(rewritten)}"
        )
    kwargs: dict[str, Any] = {}
    if ns.config_name is not None:
        kwargs["config_name"] = ns.config_name
    if ns.config_path is not None and not ns.config_path.startswith("pkg://"):
        kwargs["config_dir"] = ns.config_path
    extra: list[str] = []
    if ns.config_dir:  # Hydra puts it first on the search path, as these do
        if (Path(ns.config_dir) / f"{ns.config_name or 'config'}.yaml").is_file():
            kwargs.setdefault("config_dir", ns.config_dir)
            extra = ["hydra.searchpath=[pkg://hnnbench_conf]"]
        else:
            extra = [f"hydra.searchpath=[file://{ns.config_dir}]"]

    validated: dict[str, Job] = {}

    def validate(cfg: Any) -> None:
        """Validate a job's config; keep the job for this process's run of it."""
        job = prepare_job(cfg)
        key = fingerprint(cfg)
        if key is not None:
            validated[key] = job

    def job_config(overrides: list[str]) -> Any:
        """The job config (validated), then the hydra node it was composed with."""
        cfg = compose(overrides + extra, return_hydra_config=True, **kwargs)
        with open_dict(cfg):
            hydra_node = cfg.pop("hydra")
        validate(cfg)
        with open_dict(cfg):
            cfg["hydra"] = hydra_node
        check_hydra_node(cfg)
        with open_dict(cfg):
            del cfg["hydra"]
        return cfg

    # The first job, composed with everything (the hydra node and its directories too).
    base = job_config(trial_overrides(entries, {}))
    # Every other swept value, against the first value of the other keys: a group
    # (system, model, hydra/...) is composed again; a plain value is merged (fast).
    for i, e in sweeps.items():
        for value in (e.values or [])[1:]:
            if is_group(e.key) or e.prefix:
                job_config(trial_overrides(entries, {i: value}))
                continue
            cfg = copy.deepcopy(base)
            try:
                (ov,) = parser.parse_overrides([f"{e.key}={value}"])
                OmegaConf.update(cfg, e.key, ov.value(), merge=True)
            except ConfigError:
                raise
            except Exception as err:
                raise ConfigError(
                    f"Error merging override {e.key}={value}: {hydra_error_line(err)}"
                ) from None
            validate(cfg)
    n_jobs: int | None = 1
    counts: dict[str, int | None] = {}
    for e in entries:
        if not e.key.startswith("hydra"):
            counts[e.key] = None if e.values is None else max(len(e.values), 1)
    for count in counts.values():
        n_jobs = None if n_jobs is None or count is None else n_jobs * count
    pinned = {}
    for e in sweeps.values():
        if (
            e.key in ("system", "model", "profile")
            and not e.prefix
            and e.values
            and any(o.key.startswith(f"{e.key}.") for o in entries)
        ):
            pinned[f"{e.key}={e.values[0]}"] = e.text
    return Plan(
        argv=flags + rewritten,
        multirun=multirun,
        n_jobs=n_jobs,
        overrides=rewritten,
        pinned=pinned,
        validated=validated,
    )


def request(
    *,
    single: Mapping[str, Any],
    swept: Mapping[str, Sequence[Any]] = {},
    raw: Mapping[str, str] = {},
    multirun: bool,
) -> Plan:
    """The plan of a Python API call, with no command line built by the caller:
    ``single`` settings take one value each (quoted for Hydra by :func:`hydra_value`),
    ``swept`` settings a list of values (a sweep), ``raw`` settings are Hydra override
    values as written (e.g. ``"100,200"`` to sweep). Keys use dots (``model.steps``)
    or a Hydra group (``hydra/launcher``)."""
    overrides = [f"{key}={hydra_value(value)}" for key, value in single.items()]
    overrides += [
        f"{key}={','.join(hydra_value(v) for v in values)}" for key, values in swept.items()
    ]
    overrides += [f"{key}={value}" for key, value in raw.items()]
    return plan((["-m"] if multirun else []) + overrides)
