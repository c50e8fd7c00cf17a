"""Composing a job's config through Hydra's compose API, as the command would, with
the checks that make a bad override one line (unknown settings with a
did-you-mean, Hydra groups and launchers that are not installed).
"""

from __future__ import annotations

import re
from dataclasses import fields
from typing import Any

from omegaconf import DictConfig, OmegaConf

from hnnbench import _registry as registry
from hnnbench._contracts.errors import ConfigError, UnknownNameError
from hnnbench._contracts.names import DEFAULT_TRACK, TRACKS
from hnnbench._running import configstore
from hnnbench._running.config import RunConfig, hydra_error_line, needs_running_hydra, not_a_setting

__all__ = [
    "HYDRA_PLUGIN_PACKAGES",
    "check_hydra_node",
    "compose",
    "profile_of",
    "track_of_overrides",
]


#: Hydra plugins that are installed separately, by config-group option.
HYDRA_PLUGIN_PACKAGES = {
    "hydra/launcher": {
        "joblib": "hydra-joblib-launcher",
        "submitit_local": "hydra-submitit-launcher",
        "submitit_slurm": "hydra-submitit-launcher",
        "ray": "hydra-ray-launcher",
        "ray_aws": "hydra-ray-launcher",
        "rq": "hydra-rq-launcher",
    },
    "hydra/sweeper": {
        "optuna": "hydra-optuna-sweeper",
        "ax": "hydra-ax-sweeper",
        "nevergrad": "hydra-nevergrad-sweeper",
    },
}


def _single_choice(overrides: list[str], key: str, default: str) -> str:
    """The value of ``key=...`` in ``overrides`` (the last one; ``default`` if none),
    refused when it sweeps several values (the plugin configs are stored per value)."""
    chosen = default
    for item in overrides:
        name, sep, value = item.partition("=")
        if sep and name.lstrip("+~") == key:
            chosen = value
    if "," in chosen or chosen.startswith(("glob(", "choice(", "range(")):
        raise ConfigError(f"{key}={chosen}: a sweep runs one {key}; start one sweep per {key}.")
    return chosen


def profile_of(overrides: list[str]) -> str:
    """The profile named by ``profile=...`` in ``overrides`` (default ``paper``)."""
    profile = _single_choice(overrides, "profile", "paper")
    registry.validate_profile(profile)
    return profile


def track_of_overrides(overrides: list[str]) -> str:
    """The track named by ``track=...`` in ``overrides`` (default ``protocol``): the
    recipe track's model defaults are each model's declared recipe."""
    track = _single_choice(overrides, "track", DEFAULT_TRACK)
    if track not in TRACKS:
        raise ConfigError(
            f"track={track} is invalid: expected one of {', '.join(TRACKS)} (docs/TUNING.md)."
        )
    return track


def compose(
    overrides: list[str] | None = None,
    return_hydra_config: bool = False,
    config_name: str = "config",
    config_dir: str | None = None,
) -> DictConfig:
    """Compose the job config for ``overrides`` as the CLI would (for tests, notebooks).

    ``hydra.*`` and ``hydra/<group>=<option>`` overrides are applied (and checked) too;
    the ``hydra`` node is returned only with ``return_hydra_config`` (see
    :func:`check_hydra_node`). ``config_dir`` composes a user's primary config from that directory
    instead of hnnbench's own (``--config-path``).

    Raises:
        ConfigError: a bad override (one line).
    """
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir, initialize_config_module
    from hydra.core.global_hydra import GlobalHydra

    overrides = list(overrides or [])
    _refuse_name_overrides(overrides)
    configstore.register(profile_of(overrides), track_of_overrides(overrides))
    GlobalHydra.instance().clear()
    context: Any
    if config_dir is None:
        context = initialize_config_module("hnnbench_conf", version_base="1.3")
    else:
        context = initialize_config_dir(str(config_dir), version_base="1.3")
    try:
        with context:
            _check_hydra_groups(overrides)
            return hydra_compose(
                config_name, overrides=overrides, return_hydra_config=return_hydra_config
            )
    except ConfigError:
        raise
    except Exception as err:
        raise (_unknown_setting(err, overrides) or ConfigError(hydra_error_line(err))) from None
    finally:
        GlobalHydra.instance().clear()


def _refuse_name_overrides(overrides: list[str]) -> None:
    """``system.name`` and ``model.name`` are set by the group choice: another name
    would run one plugin's class with another's settings under the wrong label."""
    for text in overrides:
        key, sep, value = text.lstrip("+~").partition("=")
        kind = key.split(".", 1)[0]
        if key in ("system.name", "model.name"):
            shown = value if sep and value else "<name>"
            raise ConfigError(
                f"{key} cannot be set: it follows the {kind} chosen; choose "
                f"the {kind} with {kind}={shown}"
            )


_NOT_IN = re.compile(r"Key '([^']+)' not in '([^']+)'")


def _unknown_setting(err: BaseException, overrides: list[str]) -> ConfigError | None:
    """Hydra's "Key 'x' not in 'SomeConfig'" for a plugin's config, as the one-line
    did-you-mean of :func:`not_a_setting` (``None`` for any other error)."""
    text = hydra_error_line(err)
    match = _NOT_IN.search(text)
    if match is None:
        return None
    key, config_name = match.groups()
    full = re.search(r"\(key: ([^)]+)\)", text)
    full_key = full.group(1) if full else key
    chosen: dict[str, str] = {}  # the groups chosen on the command line, tried first
    for item in overrides:
        name, sep, value = item.lstrip("+~").partition("=")
        if sep and name in ("system", "model"):
            chosen[name] = value
    for kind in ("system", "model"):
        plugins = registry.discover(kind)
        first = chosen.get(kind)
        candidates = [*([first] if first else []), *(n for n in plugins if n != first)]
        for name in candidates:
            info = plugins.get(name)
            config = getattr(info.cls, "Config", None) if info is not None else None
            if (
                info is not None
                and info.ok
                and config is not None
                and config.__name__ == config_name
            ):
                known = [f.name for f in fields(config)]
                return not_a_setting(f"{full_key} is not a setting of {kind} '{name}'", key, known)
    if config_name == RunConfig.__name__:
        return not_a_setting(
            f"{key} is not an hnnbench setting", key, [f.name for f in fields(RunConfig)]
        )
    return None


def check_hydra_node(cfg: DictConfig) -> None:
    """Resolve what Hydra needs before any job starts (the output directories) in a
    config composed with ``return_hydra_config=True``; raise a one-line ConfigError."""
    from omegaconf.errors import OmegaConfBaseException

    for key in ("hydra.run.dir", "hydra.sweep.dir", "hydra.sweep.subdir"):
        try:
            OmegaConf.select(cfg, key, throw_on_resolution_failure=True)
        except OmegaConfBaseException as err:
            if not needs_running_hydra(err):
                raise ConfigError(hydra_error_line(err)) from None


def _check_hydra_groups(overrides: list[str]) -> None:
    """``hydra/<group>=<option>``: an installed option of a Hydra group, with a
    did-you-mean and the package that provides a known but missing plugin."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parser = OverridesParser.create()
    groups_of, options_of = _hydra_group_lister(overrides, parser)
    for text in overrides:
        if not text.lstrip("+~").startswith("hydra/"):
            continue
        try:
            (ov,) = parser.parse_overrides([text])
        except Exception as err:
            raise ConfigError(f"Cannot parse override '{text}': {hydra_error_line(err)}") from None
        group = ov.key_or_group
        if ov.is_delete():
            continue
        groups = [f"hydra/{g}" for g in groups_of("hydra")]
        if group not in groups:
            raise UnknownNameError("Hydra config group", group, groups)
        options = options_of(group)
        values = (
            [str(v) for v in ov.sweep_string_iterator()]
            if ov.is_sweep_override()
            else [ov.get_value_element_as_str()]
        )
        kind = f"Hydra {group.split('/', 1)[1]}"
        for value in values:
            if value in options:
                continue
            package = HYDRA_PLUGIN_PACKAGES.get(group, {}).get(value)
            if package:
                raise ConfigError(
                    f"{kind} '{value}' is not installed: pip install {package} "
                    f"(installed: {', '.join(options)})"
                )
            raise UnknownNameError(kind, value, options)


def _hydra_group_lister(overrides: list[str], parser: Any) -> tuple[Any, Any]:
    """``(list_groups(parent), group_options(group))`` over Hydra's search path plus the
    entries of a ``hydra.searchpath=[...]`` override, so that a user's own option file
    (e.g. ``hydra/launcher/my_slurm.yaml`` in a directory on the search path) is known."""
    from hydra.core.global_hydra import GlobalHydra

    from hnnbench._running.hydra_private import group_lister

    loader = GlobalHydra.instance().config_loader()
    entries: list[str] = []
    for text in overrides:
        if text.lstrip("+~").split("=", 1)[0].strip() != "hydra.searchpath":
            continue
        try:
            (ov,) = parser.parse_overrides([text])
        except Exception as err:
            raise ConfigError(f"Cannot parse override '{text}': {hydra_error_line(err)}") from None
        value = ov.value()
        entries += [str(v) for v in (value if isinstance(value, list) else [value])]
    return group_lister(loader, entries)
