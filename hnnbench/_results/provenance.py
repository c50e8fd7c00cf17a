"""What a record says about itself, verified rather than read.

- **Variants from the config** (:func:`config_variant`): a record's variant is the set of
  settings of its stored, resolved ``config`` that differ from the defaults of its
  (system, model, profile), composed now from the installed plugins
  (:func:`hnnbench._running.compose.compose`). Its ``overrides`` only say what its command line
  claimed: a setting that differs from the defaults but that no override sets is named
  (:attr:`Variant.undeclared`), and the record is a variant whatever its overrides say.
- **Plugin provenance** (:func:`plugin_problems`): the record's plugin versions and the
  packages that provided them (``plugins``, docs/PLUGINS.md "Versioning") against the
  installed ones; a missing (``null``) version is a mismatch, never a skip.
- **Reserved names** (:func:`reserved_key_problem`): a metric or timing key named like a
  column of the records frame or the leaderboard would replace that column.

Run-only settings (:data:`hnnbench._running.config.RUN_ONLY_KEYS`), the identity (seed,
profile, the system's and model's names), the track, and a tuned record's selected
settings (:func:`hnnbench._record.tracks.tuned_settings`) define no variant.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from functools import cache
from typing import Any, Literal, Optional

from hnnbench import _registry as registry
from hnnbench._contracts.errors import HnnbenchError
from hnnbench._contracts.names import (
    DEFAULT_TRACK,
    ID_COLUMNS,
    PROVENANCE_COLUMNS,
    RESERVED,
    STATUS_COLUMNS,
    TRACKS,
    metric_name_problem,
)
from hnnbench._record.codec import encode
from hnnbench._record.tracks import TRACK_KEYS, track_of, tuned_settings
from hnnbench._running.config import RUN_ONLY_KEYS

__all__ = [
    "Variant",
    "config_variant",
    "default_config",
    "plugin_problems",
    "reserved_key_problem",
    "value_text",
]

#: Top-level config keys that identify a job rather than configure it (its track too:
#: a row's identity, never a variant).
IDENTITY_KEYS = frozenset({"seed", "profile", *TRACK_KEYS})
#: Config paths that repeat the identity (the group choices).
IDENTITY_PATHS = frozenset({"system.name", "model.name"})
#: Override keys that choose a config group: they set no setting below it.
GROUP_KEYS = frozenset({"system", "model", "profile"})
#: A setting the record has and the installed plugin's defaults do not.
ABSENT = "<absent>"
#: Names a timing may not take: every other column of a records frame or leaderboard.
TAKEN = RESERVED | set(ID_COLUMNS) | set(STATUS_COLUMNS) | set(PROVENANCE_COLUMNS)


@cache
def _defaults_text(system: str, model: str, profile: str, track: str) -> str:
    from omegaconf import OmegaConf

    from hnnbench._running.compose import compose

    cfg = compose([f"system={system}", f"model={model}", f"profile={profile}", f"track={track}"])
    return json.dumps(encode(OmegaConf.to_container(cfg, resolve=True)), sort_keys=True)


def default_config(
    system: str, model: str, profile: str, track: str = DEFAULT_TRACK
) -> dict[str, Any]:
    """The resolved job config of (``system``, ``model``, ``profile``, ``track``) with
    nothing else set, as a record stores it (strict JSON values; on the recipe track the
    model's declared recipe is part of the defaults); composed once per process.

    Raises:
        HnnbenchError: a name that is not installed (the one-line message).
    """
    return dict(
        json.loads(
            _defaults_text(system, model, profile, track if track in TRACKS else DEFAULT_TRACK)
        )
    )


def value_text(value: Any) -> str:
    """A config value as an override writes it: ``200``, ``0.001``, ``true``, ``null``,
    ``[64,64]``, ``tanh``."""
    if isinstance(value, str):
        return value
    if isinstance(value, (list, dict)):
        return json.dumps(value, separators=(",", ":"), sort_keys=True)
    return json.dumps(value)


def _same(a: Any, b: Any) -> bool:
    """Equal values of equal JSON types (``200`` and ``200.0`` differ, ``1`` and
    ``true`` too)."""
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def _diff(
    record: dict[str, Any], default: dict[str, Any], prefix: str, out: dict[str, tuple[Any, Any]]
) -> None:
    """Settings of ``record`` whose value differs from ``default``: ``{path: (record's,
    default)}``. A setting the record lacks is not compared: a job run from the stored
    config (``--rerun``) takes the default for it."""
    for key in sorted(record):
        path = f"{prefix}{key}"
        if not prefix and (key in RUN_ONLY_KEYS or key in IDENTITY_KEYS):
            continue
        if path in IDENTITY_PATHS:
            continue
        mine = record[key]
        if key not in default:
            out[path] = (mine, ABSENT)
        elif isinstance(mine, dict) and isinstance(default[key], dict):
            _diff(mine, default[key], f"{path}.", out)
        elif not _same(mine, default[key]):
            out[path] = (mine, default[key])


def _declared(overrides: Any) -> set[str]:
    keys = set()
    for text in overrides or ():
        key = str(text).lstrip("+~").split("=", 1)[0].strip()
        if key and key not in GROUP_KEYS and not key.startswith("hydra"):
            keys.add(key)
    return keys


@dataclass(frozen=True)
class Variant:
    """A record's variant, from its config.

    Attributes:
        label: ``"model.hidden=64 system.steps=50"`` (sorted); ``""``: the profile's
            defaults (the main row).
        settings: ``{path: (record's value, default)}`` of every differing setting.
        undeclared: the differing settings that the record's overrides do not set.
        mismatch: the record's identity that its own config contradicts (``"model:
            record hnn_torch, config mlp_torch"``), or ``None``.
        problem: why the variant could not be derived (no config, a plugin that is not
            installed), or ``None``; ``label`` is then the overrides' claim.
        installed: ``False`` when ``problem`` is that a plugin is not installed.
    """

    label: str
    settings: dict[str, tuple[Any, Any]]
    undeclared: tuple[str, ...] = ()
    mismatch: Optional[str] = None
    problem: Optional[str] = None
    installed: bool = True

    def undeclared_text(self, profile: str) -> str:
        """One line: what differs from the defaults and that no override says so."""
        first = self.undeclared[0]
        mine, default = self.settings[first]
        more = len(self.undeclared) - 1
        return (
            f"config.{first} is {value_text(mine)} but the {profile} profile's default "
            f"is {value_text(default)}, and the record's overrides do not set it"
            + (f" (nor {more} other setting(s))" if more else "")
            + f": a variant ({self.label}), not the main row"
        )


def config_variant(record: dict[str, Any], fallback: str = "") -> Variant:
    """The variant of ``record`` from its stored config (see the module docstring);
    ``fallback`` (the overrides' label) where it cannot be derived."""
    config = record.get("config")
    system, model = record.get("system"), record.get("model")
    profile = record.get("profile") or "paper"
    if not (
        isinstance(config, dict)
        and isinstance(config.get("system"), dict)
        and isinstance(config.get("model"), dict)
    ):
        return Variant(
            fallback,
            {},
            problem="the record holds no resolved config "
            "(config.system, config.model): its variant cannot be verified",
        )
    identity = (
        ("system", system, config["system"].get("name")),
        ("model", model, config["model"].get("name")),
        ("profile", profile, (config.get("profile") or {}).get("name", profile)),
        ("seed", record.get("seed"), config.get("seed", record.get("seed"))),
    )
    wrong = [f"{key}: record {a}, config {b}" for key, a, b in identity if not _same(a, b)]
    try:
        default = default_config(str(system), str(model), str(profile), track_of(record))
    except HnnbenchError as err:
        installed = (
            _installed("system", str(system)) is not None
            and _installed("model", str(model)) is not None
        )
        return Variant(
            fallback,
            {},
            problem=f"its variant cannot be verified: {err}",
            installed=installed,
            mismatch="; ".join(wrong) or None,
        )
    settings: dict[str, tuple[Any, Any]] = {}
    _diff(config, default, "", settings)
    # A tuned record's selected settings and step budget define its track, not a variant.
    tuned = tuned_settings(record)
    settings = {path: pair for path, pair in settings.items() if path not in tuned}
    label = " ".join(f"{path}={value_text(mine)}" for path, (mine, _) in sorted(settings.items()))
    declared = _declared(record.get("overrides"))
    undeclared = tuple(
        p for p in sorted(settings) if not any(p == k or p.startswith(f"{k}.") for k in declared)
    )
    return Variant(label, settings, undeclared, mismatch="; ".join(wrong) or None)


def _installed(kind: Literal["system", "model"], name: str) -> Optional[dict[str, Any]]:
    info = registry.discover(kind).get(name)
    if info is None or not info.ok:
        return None
    return {
        "version": info.version,
        "distribution": info.distribution,
        "distribution_version": info.dist_version,
    }


KINDS: tuple[Literal["system", "model"], ...] = ("system", "model")


def plugin_problems(record: dict[str, Any]) -> list[tuple[str, str, str, bool]]:
    """``(field, record's value, installed value, gating)`` for each plugin version or
    package of ``record`` that differs from the installed one. A ``null`` (missing)
    value is a gating mismatch, never a skip; two different non-null versions of the
    package (``distribution_version``) are information only, since the plugin's own
    ``version`` says when its results change. Plugins that are not installed are not
    compared (nothing to compare with); records made before ``plugins`` was recorded
    are compared on ``system_version`` / ``model_version`` alone."""
    out = []
    plugins = record.get("plugins")
    for kind in KINDS:
        name = str(record.get(kind))
        have = _installed(kind, name)
        if have is None:
            continue
        key = f"{kind}_version"
        if record.get(key) is None or str(record.get(key)) != have["version"]:
            out.append((key, str(record.get(key)), have["version"], True))
        if not isinstance(plugins, dict):
            continue
        entry = plugins.get(kind)
        if not isinstance(entry, dict):
            out.append(
                (
                    f"plugins.{kind}",
                    "missing",
                    f"{have['distribution']} {have['distribution_version']}",
                    True,
                )
            )
            continue
        if entry.get("name") != name:
            out.append((f"plugins.{kind}.name", str(entry.get("name")), name, True))
        for field in ("version", "distribution", "distribution_version"):
            mine, theirs = entry.get(field), have[field]
            if mine is None or theirs is None or str(mine) != str(theirs):
                gate = field != "distribution_version" or mine is None or theirs is None
                out.append((f"plugins.{kind}.{field}", str(mine), str(theirs), gate))
    return out


def reserved_key_problem(record: dict[str, Any]) -> Optional[str]:
    """Why a metric or timing key of ``record`` would replace another column of the
    records frame (``"timings key 'seed' ..."``), or ``None``."""
    metrics = record.get("metrics") or {}
    timings = record.get("timings") or {}
    for name in metrics if isinstance(metrics, dict) else ():
        problem = metric_name_problem(str(name))
        if problem is not None:
            return f"metrics key '{name}': {problem}"
    for name in timings if isinstance(timings, dict) else ():
        name = str(name)
        if name in TAKEN or name in metrics or not re.fullmatch(r"[a-z][a-z0-9_]*_s", name):
            return (
                f"timings key '{name}' is not a timing name (lower-case, ending in '_s', "
                "and no table column): it would replace a column of the tables"
            )
    return None
