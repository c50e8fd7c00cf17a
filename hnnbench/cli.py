"""The ``hnnbench`` command.

``hnnbench list | report | check ...`` are subcommands; anything else is a Hydra
command line (``hnnbench -m system=all model=all seed=0,1,2``). Before Hydra starts,
the command line is checked here: names are validated (with a did-you-mean), ``all``
expands to every registered plugin, and each swept value is composed and validated,
so a bad input fails in one line before any job runs.
"""

from __future__ import annotations

import itertools
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from hnnbench import registry
from hnnbench.errors import ConfigError, HnnbenchError, UnknownNameError

USAGE = """\
usage: hnnbench [-m] [KEY=VALUE ...]        run one job, or a sweep with -m (Hydra)
       hnnbench list [--json]               registered systems and models
       hnnbench report DIR [--out OUT]      tables and figures from a sweep's records
       hnnbench check DIR --reference CSV   leaderboard regression gate

examples:
  hnnbench -m system=all model=all                  every model on every system (paper)
  hnnbench -m system=all model=all profile=quick    the smoke version
  hnnbench -m system=spring model=hnn_torch,mlp_torch seed=0,1,2
  hnnbench system=two_body model=hnn_jax            one run
  hnnbench --cfg job system=spring                  show the composed config

Hydra's own options: hnnbench --hydra-help. Docs: README.md, docs/.
"""

#: Hydra flags that take a value.
VALUE_FLAGS = {"--cfg", "-c", "--package", "-p", "--config-path", "-cp", "--config-name",
               "-cn", "--config-dir", "-cd", "--experimental-rerun"}
INFO_VALUES = {"all", "config", "defaults", "defaults-tree", "plugins", "searchpath"}

_single_run: list[dict] = []


def main(argv: Sequence[str] | None = None) -> None:
    """Console-script entry point; exits with the command's status."""
    sys.exit(run(list(sys.argv[1:] if argv is None else argv)))


def run(argv: list[str]) -> int:
    try:
        if argv and argv[0] == "list":
            return cmd_list(argv[1:])
        if argv and argv[0] in ("report", "check"):
            return _subcommand(argv[0], argv[1:])
        if argv and argv[0] in ("-h", "--help", "help"):
            print(USAGE)
            return 0
        return run_hydra(argv)
    except HnnbenchError as err:
        if os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        print(f"hnnbench: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("hnnbench: interrupted; finished jobs keep their records. Re-run the same "
              "command with hydra.sweep.dir=<dir> to resume.", file=sys.stderr)
        return 130


# --------------------------------------------------------------------------- list


def cmd_list(args: list[str]) -> int:
    import json

    from tabulate import tabulate

    if any(a not in ("--json",) for a in args):
        raise ConfigError(f"hnnbench list: unknown argument {args}; expected: [--json]")
    out = {}
    for kind in ("system", "model"):
        out[kind] = [
            {"name": i.name, "version": i.version, "backend": i.backend,
             "package": f"{i.distribution} {i.dist_version}" if i.distribution else "?",
             "status": "ok" if i.ok else "error", "description": i.description,
             "error": i.error}
            for i in registry.discover(kind).values()  # type: ignore[arg-type]
        ]
    if "--json" in args:
        print(json.dumps(out, indent=2))
        return 0
    for kind, title in (("system", "Systems"), ("model", "Models")):
        rows = [
            [r["name"], r["version"], r["backend"], r["package"],
             r["description"] if r["status"] == "ok" else f"ERROR: {r['error']}"]
            for r in out[kind]
        ]
        headers = ["name", "version", "backend", "package", "description"]
        if kind == "system":
            rows = [r[:2] + r[3:] for r in rows]
            headers = ["name", "version", "package", "description"]
        print(f"{title} (entry points: {registry.GROUPS[kind]})")
        print(tabulate(rows, headers=headers, tablefmt="simple"))
        print()
    print("Profiles: " + ", ".join(registry.PROFILES))
    return 0


def _subcommand(name: str, args: list[str]) -> int:
    import importlib

    try:
        module = importlib.import_module(f"hnnbench.{name}")
    except ModuleNotFoundError:
        raise HnnbenchError(f"'hnnbench {name}' is not available in this version") from None
    return int(module.main(args))


# --------------------------------------------------------------------------- hydra


@dataclass
class Plan:
    """A checked command line, ready for Hydra."""

    argv: list[str]
    multirun: bool
    n_jobs: int | None
    overrides: list[str] = field(default_factory=list)


def _split_args(argv: list[str]) -> tuple[list[str], list[str]]:
    """Separate Hydra flags (with their values) from overrides."""
    flags, overrides = [], []
    it = iter(range(len(argv)))
    for i in it:
        tok = argv[i]
        if tok in VALUE_FLAGS and i + 1 < len(argv):
            flags += [tok, argv[i + 1]]
            next(it, None)
        elif tok == "--info":
            flags.append(tok)
            if i + 1 < len(argv) and argv[i + 1] in INFO_VALUES:
                flags.append(argv[i + 1])
                next(it, None)
        elif tok.startswith("-"):
            flags.append(tok)
        else:
            overrides.append(tok)
    return flags, overrides


def _expand_names(kind: str, values: list[str]) -> list[str]:
    names = registry.available(kind)  # type: ignore[arg-type]
    out: list[str] = []
    for value in values:
        for name in names if value == "all" else [value]:
            if name not in registry.discover(kind):  # type: ignore[arg-type]
                raise UnknownNameError(kind, name, names)
            registry.get_class(kind, name)  # type: ignore[arg-type]  # unusable -> error
            if name not in out:
                out.append(name)
    return out


def plan(argv: list[str]) -> Plan:
    """Check a Hydra command line and rewrite ``all``; raise :class:`ConfigError`."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from hnnbench.config import compose, hydra_error_line, prepare_job, profile_of

    flags, overrides = _split_args(argv)
    multirun = "-m" in flags or "--multirun" in flags
    profile = profile_of(overrides)
    parser = OverridesParser.create()
    values: dict[str, list[str]] = {}
    rewritten: list[str] = []
    for text in overrides:
        try:
            (ov,) = parser.parse_overrides([text])
        except Exception as err:
            raise ConfigError(f"Cannot parse override '{text}': {hydra_error_line(err)}") from None
        key = ov.key_or_group
        if ov.is_sweep_override():
            try:
                vals = [str(v) for v in ov.sweep_string_iterator()]
            except Exception:  # glob/interval sweeps: Hydra expands them itself
                vals = []
        else:
            vals = [ov.get_value_element_as_str()] if ov.value() is not None else []
        if key in ("system", "model") and vals:
            vals = _expand_names(key, vals)
            text = f"{key}={','.join(vals)}"
        values[key] = vals
        rewritten.append(text)
    sweeping = {k: v for k, v in values.items() if len(v) > 1}
    if sweeping and not multirun:
        key, vals = next(iter(sweeping.items()))
        raise ConfigError(
            f"{key} has {len(vals)} values ({', '.join(vals[:4])}{', ...' if len(vals) > 4 else ''})"
            f": that is a sweep, so add -m, e.g. hnnbench -m {' '.join(rewritten)}"
        )
    # Compose and validate every swept value (each against the first of the others).
    base = {k: (v[0] if v else None) for k, v in values.items()}
    trials = [dict(base)]
    for key, vals in sweeping.items():
        for val in vals[1:]:
            trials.append({**base, key: val})
    verbatim = [t for t in rewritten if t.split("=", 1)[0].lstrip("+~") not in values
                or not values[t.split("=", 1)[0].lstrip("+~")]]
    for trial in trials:
        ovs = [f"{k}={v}" for k, v in trial.items() if v is not None] + verbatim
        ovs = [o for o in ovs if not o.startswith("hydra.") and not o.startswith("hydra/")]
        if not any(o.startswith("profile=") for o in ovs):
            ovs.append(f"profile={profile}")
        if "--cfg" in flags or "-c" in flags or "--info" in flags:
            break
        prepare_job(compose(ovs))
    n_jobs = 1
    for key, vals in values.items():
        if key.startswith("hydra"):
            continue
        n_jobs *= max(len(vals), 1)
    return Plan(argv=flags + rewritten, multirun=multirun, n_jobs=n_jobs, overrides=rewritten)


def _task(cfg) -> None:  # noqa: ANN001 - Hydra passes a DictConfig
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from hnnbench.run import run_job

    hc = HydraConfig.get()
    multirun = hc.mode == RunMode.MULTIRUN
    total = int(os.environ.get("HNNBENCH_N_JOBS", "0")) or None
    record = run_job(cfg, Path(hc.runtime.output_dir), hc.job.num if multirun else None, total)
    if not multirun:
        _single_run.append(record)


def run_hydra(argv: list[str]) -> int:
    import hydra

    from hnnbench.config import register_schema

    checked = plan(argv)
    register_schema()
    if checked.n_jobs:
        os.environ["HNNBENCH_N_JOBS"] = str(checked.n_jobs)
    if checked.multirun and checked.n_jobs:
        print(f"hnnbench: {checked.n_jobs} job(s)", file=sys.stderr)
    saved = sys.argv
    sys.argv = [saved[0] if saved else "hnnbench", *checked.argv]
    _single_run.clear()
    try:
        hydra.main(version_base="1.3", config_path="pkg://hnnbench_conf",
                   config_name="config")(_task)()
    finally:
        sys.argv = saved
    if _single_run:
        return _report_single(_single_run[-1])
    return 0


def _report_single(record: dict) -> int:
    from tabulate import tabulate

    status = record["status"]
    if status == "failed":
        print(f"hnnbench: error: {record.get('error')}", file=sys.stderr)
        return 1
    rows = [[k, v.get("mean"), v.get("sem")] for k, v in record.get("metrics", {}).items()]
    print(tabulate(rows, headers=["metric", "mean", "sem"], floatfmt=".4g"))
    print(f"status: {status}" + (f" ({record.get('error')})" if record.get("error") else ""))
    return 0 if status in ("ok", "skipped") else 1


def _product(lists: list[list[str]]) -> int:
    return len(list(itertools.product(*lists)))
