"""The four plugin groups (systems, models, metrics, claim sets) and the registry's
queries over them (docs/ARCHITECTURE.md, "Layers").
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Literal

from hnnbench._contracts.claims import Claim, ClaimSet
from hnnbench._contracts.errors import ConfigError, UnknownNameError
from hnnbench._contracts.metric import Metric
from hnnbench._contracts.names import DEFAULT_TRACK
from hnnbench._contracts.plugin import Model, ModelConfig, System, SystemConfig
from hnnbench._registry.discovery import (
    PROFILES,
    PluginGroup,
    PluginInfo,
    default_config,
    refresh_all,
)

__all__ = [
    "CLAIMS",
    "GROUPS",
    "Kind",
    "METRICS",
    "MODELS",
    "SYSTEMS",
    "all_claims",
    "available",
    "baseline_families",
    "claim_sets",
    "config_defaults",
    "discover",
    "family_models",
    "get_class",
    "group",
    "metrics",
    "ordered",
    "refresh",
    "register",
    "validate_profile",
]


Kind = Literal["system", "model", "metric", "claims"]
#: The four plugin groups.
SYSTEMS: PluginGroup[type[System]] = PluginGroup(
    "system", "hnnbench.systems", System, config_base=SystemConfig
)
MODELS: PluginGroup[type[Model]] = PluginGroup(
    "model", "hnnbench.models", Model, config_base=ModelConfig
)
METRICS: PluginGroup[Metric] = PluginGroup("metric", "hnnbench.metrics", Metric, instances=True)
CLAIMS: PluginGroup[ClaimSet] = PluginGroup("claims", "hnnbench.claims", ClaimSet, instances=True)
_GROUPS: dict[str, PluginGroup[Any]] = {g.kind: g for g in (SYSTEMS, MODELS, METRICS, CLAIMS)}
#: kind -> entry-point group name.
GROUPS: dict[str, str] = {kind: g.group for kind, g in _GROUPS.items()}


def group(kind: str) -> PluginGroup[Any]:
    """The plugin group of ``kind`` (``system``, ``model``, ``metric``, ``claims``)."""
    try:
        return _GROUPS[kind]
    except KeyError:
        raise ConfigError(
            f"unknown plugin kind '{kind}'; expected one of {', '.join(_GROUPS)}"
        ) from None


def register(kind: Kind, name: str, obj: Any) -> None:
    """Add a plugin to this process without packaging it: a :class:`System` or
    :class:`Model` subclass, a :class:`~hnnbench.Metric` or a
    :class:`~hnnbench.ClaimSet`. It then takes part in ``all``, sweeps and reports
    exactly like an installed one, in this process: with the basic launcher (other
    launchers start processes that only know installed plugins). For notebooks and
    tests; a package declares entry points instead (docs/PLUGINS.md).

    Raises:
        ConfigError: ``name`` is taken by an installed plugin, or ``obj`` is not a
            plugin of ``kind`` (the message says why).
    """
    if kind not in _GROUPS:
        raise ConfigError(f"register: unknown kind '{kind}'; expected one of {', '.join(_GROUPS)}")
    _GROUPS[kind].register(name, obj)


def discover(kind: Kind) -> dict[str, PluginInfo[Any]]:
    """Every entry point of ``kind``, loaded (cached; see :func:`refresh`)."""
    return group(kind).discover()


def refresh() -> None:
    """Forget discovered plugins (after installing one in a running process)."""
    refresh_all()


def available(kind: Kind) -> list[str]:
    """Names of the plugins of ``kind`` that loaded, in listing order."""
    return group(kind).available()


def ordered(kind: Kind, names: Iterable[str]) -> list[str]:
    """``names`` in listing order (:meth:`PluginGroup.ordered`)."""
    return group(kind).ordered(names)


def metrics() -> list[Metric]:
    """Every registered metric that loaded, in table order."""
    return METRICS.loaded()


def get_class(kind: Kind, name: str) -> Any:
    """The plugin of ``kind`` registered as ``name`` (typed: use ``SYSTEMS.get`` /
    ``MODELS.get``); raises as :meth:`PluginGroup.get`."""
    return group(kind).get(name)


def validate_profile(name: str) -> None:
    if name not in PROFILES:
        raise UnknownNameError("profile", name, PROFILES)


def config_defaults(
    kind: str, name: str, profile: str = "paper", track: str = DEFAULT_TRACK
) -> Any:
    """The plugin's config dataclass instance for ``profile`` and ``track``: its
    defaults, with a model's declared :attr:`~hnnbench.Model.recipe` on the recipe
    track, and the plugin's own profile overrides on top."""
    return default_config(kind, name, group(kind).get(name), profile, track=track)


def family_models() -> dict[str, dict[str, str]]:
    """``{backend: {family: model}}`` of the installed models that declare a family."""
    out: dict[str, dict[str, str]] = {}
    for name, info in MODELS.discover().items():
        family = info.family
        if info.ok and family != "-":
            out.setdefault(info.backend, {})[family] = name
    return out


def baseline_families() -> list[str]:
    """The families of the installed models that declare themselves the baseline
    (:attr:`hnnbench.neural.Family.baseline`: the family the aggregate across systems
    normalises against), in listing order."""
    models = MODELS.discover()
    return list(
        dict.fromkeys(
            models[name].family
            for name in MODELS.ordered(models)
            if models[name].ok and models[name].baseline and models[name].family != "-"
        )
    )


def claim_sets() -> list[ClaimSet]:
    """Every registered claim set (entry-point group ``hnnbench.claims``)."""
    return CLAIMS.loaded()


def all_claims() -> list[Claim]:
    """Every claim of every registered set."""
    return [claim for cs in claim_sets() for claim in cs.claims]
