"""Plugin discovery through entry points, and their Hydra config registration.

Systems are entry points of the group ``hnnbench.systems``, models of
``hnnbench.models`` (each names a class) and metrics of ``hnnbench.metrics`` (each names
a :class:`~hnnbench._metric.Metric` instance); built-ins are declared in hnnbench's own
pyproject.toml exactly like third-party plugins. A plugin whose import fails is kept
with its error (``hnnbench list`` shows it) and left out of everything else.

Order: listings, ``all`` and tables follow :func:`ordered`: a plugin's ``order``
attribute (lower first; built-ins set it), then its name.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cache
from importlib import metadata
from typing import Any, Literal

from hnnbench._claims import Claim, ClaimSet
from hnnbench._contract import Model, ModelConfig, System, SystemConfig
from hnnbench._errors import ConfigError, HnnbenchError, UnknownNameError
from hnnbench._metric import Metric
from hnnbench._record_schema import metric_name_problem

Kind = Literal["system", "model", "metric", "claims"]
GROUPS: dict[str, str] = {"system": "hnnbench.systems", "model": "hnnbench.models",
                          "metric": "hnnbench.metrics", "claims": "hnnbench.claims"}
BASES: dict[str, type] = {"system": System, "model": Model}
CONFIG_BASES: dict[str, type] = {"system": SystemConfig, "model": ModelConfig}
#: Kinds whose entry points name an instance, not a class.
INSTANCE_KINDS: dict[str, type] = {"metric": Metric, "claims": ClaimSet}
#: Profiles that ship with hnnbench (conf/profile/*.yaml). ``paper`` is the default.
PROFILES = ("paper", "quick")

__all__ = [
    "GROUPS",
    "all_claims",
    "claim_sets",
    "family_models",
    "PROFILES",
    "PluginInfo",
    "available",
    "config_defaults",
    "discover",
    "get_class",
    "metrics",
    "ordered",
    "refresh",
    "register",
    "register_configs",
    "validate_profile",
]


@dataclass
class PluginInfo:
    """One entry point and the outcome of loading it."""

    kind: str
    name: str
    target: str
    distribution: str | None
    dist_version: str | None
    #: The loaded class (systems, models) or instance (metrics, claim sets).
    cls: Any = None
    error: str | None = None

    @property
    def ok(self) -> bool:
        return self.cls is not None

    @property
    def version(self) -> str:
        return str(getattr(self.cls, "version", "?")) if self.cls else "?"

    @property
    def description(self) -> str:
        if self.cls is None:
            return ""
        doc = getattr(self.cls, "description", "") or getattr(self.cls, "title", "") or (
            self.cls.__doc__ or "")
        return doc.strip().splitlines()[0] if doc.strip() else ""

    @property
    def backend(self) -> str:
        return str(getattr(self.cls, "backend", "-")) if self.kind == "model" and self.cls else "-"

    @property
    def family(self) -> str:
        """A neural model's family name (``hnn``), else ``-``."""
        family = getattr(self.cls, "family", None) if self.kind == "model" else None
        return str(getattr(family, "name", "-")) if family is not None else "-"


def _load(kind: str, ep: metadata.EntryPoint) -> PluginInfo:
    dist = getattr(ep, "dist", None)
    info = PluginInfo(
        kind=kind, name=ep.name, target=ep.value,
        distribution=dist.metadata["Name"] if dist is not None else None,
        dist_version=dist.version if dist is not None else None,
    )
    try:
        cls = ep.load()
    except HnnbenchError as err:
        info.error = str(err)
        return info
    except Exception as err:  # a broken plugin must not break the others
        info.error = f"import failed: {type(err).__name__}: {err}".splitlines()[0]
        return info
    if kind in INSTANCE_KINDS:
        expected = INSTANCE_KINDS[kind]
        if not isinstance(cls, expected):
            info.error = f"{ep.value} is not a {expected.__module__}.{expected.__name__}"
        elif getattr(cls, "name", None) != ep.name:
            info.error = (f"{ep.value} is named '{getattr(cls, 'name', '?')}' but is "
                          f"registered as '{ep.name}': use the same name")
        elif kind == "metric" and (problem := metric_name_problem(ep.name)):
            info.error = f"{ep.value}: {problem}"
        else:
            info.cls = cls
        return info
    base = BASES[kind]
    if not (isinstance(cls, type) and issubclass(cls, base)):
        info.error = f"{ep.value} is not a subclass of hnnbench._contract.{base.__name__}"
        return info
    config_cls = getattr(cls, "Config", None)
    if not (isinstance(config_cls, type) and dataclasses.is_dataclass(config_cls)
            and issubclass(config_cls, CONFIG_BASES[kind])):
        info.error = (
            f"{ep.value}.Config must be a dataclass subclassing "
            f"hnnbench._contract.{CONFIG_BASES[kind].__name__}"
        )
        return info
    unknown_profiles = sorted(set(getattr(cls, "profiles", {}) or {}) - set(PROFILES))
    if unknown_profiles:
        info.error = (f"{ep.value}.profiles declares {unknown_profiles}, but hnnbench's "
                      f"profiles are {', '.join(PROFILES)}; rename or remove them")
        return info
    missing = getattr(cls, "requirements_missing", lambda: None)()
    if missing:
        info.error = str(missing)
        return info
    info.cls = cls
    return info


def ordered(kind: Kind, names: Any) -> list[str]:
    """``names`` in listing order: the plugins' ``order`` (lower first; none: after
    those that have one), then by name; names not installed come last, by name."""
    plugins = _discover(kind)

    def key(name: str) -> tuple[int, float, str]:
        info = plugins.get(name)
        if info is None or info.cls is None:
            return (1, 0.0, name)
        order = getattr(info.cls, "order", None)
        return (0, float("inf") if order is None else float(order), name)

    return sorted(dict.fromkeys(names), key=key)


@cache
def _discover(kind: str) -> dict[str, PluginInfo]:
    found: dict[str, PluginInfo] = {}
    for ep in sorted(metadata.entry_points(group=GROUPS[kind]), key=lambda e: e.name):
        if ep.name in found:  # same name from two distributions: keep the first, say so
            other = found[ep.name]
            if other.target != ep.value:
                other.error = (
                    f"name '{ep.name}' is declared twice ({other.target} and {ep.value}); "
                    "uninstall one of the plugins"
                )
                other.cls = None
            continue
        found[ep.name] = _load(kind, ep)
    for name, obj in _REGISTERED[kind].items():
        found[name] = _load(kind, _InProcess(name, obj))  # type: ignore[arg-type]
    order = {name: i for i, name in enumerate(_sorted_by_order(found))}
    return dict(sorted(found.items(), key=lambda item: order[item[0]]))


def _sorted_by_order(found: dict[str, PluginInfo]) -> list[str]:
    def key(name: str) -> tuple[float, str]:
        order = getattr(found[name].cls, "order", None) if found[name].cls else None
        return (float("inf") if order is None else float(order), name)

    return sorted(found, key=key)


@dataclass
class _InProcess:
    """What :func:`_load` needs of an entry point, for a plugin registered in-process."""

    name: str
    obj: Any
    dist: None = None

    @property
    def value(self) -> str:
        return f"(registered in this process) {getattr(self.obj, '__qualname__', self.name)}"

    def load(self) -> Any:
        return self.obj


#: Plugins registered in this process (:func:`register`), by kind.
_REGISTERED: dict[str, dict[str, Any]] = {kind: {} for kind in GROUPS}


def register(kind: Kind, name: str, obj: Any) -> None:
    """Add a plugin to this process without packaging it: a :class:`System` or
    :class:`Model` subclass, a :class:`~hnnbench._metric.Metric` or a
    :class:`~hnnbench._claims.ClaimSet`. It then takes part in ``all``, sweeps and
    reports exactly like an installed one, in this process: with the basic launcher
    (other launchers start processes that only know installed plugins). For notebooks
    and tests; a package declares entry points instead (docs/PLUGINS.md).

    Raises:
        ConfigError: ``name`` is taken by an installed plugin, or ``obj`` is not a
            plugin of ``kind`` (the message says why).
    """
    if kind not in GROUPS:
        raise ConfigError(f"register: unknown kind '{kind}'; expected one of "
                          f"{', '.join(GROUPS)}")
    installed = {ep.name for ep in metadata.entry_points(group=GROUPS[kind])}
    if name in installed:
        raise ConfigError(f"register: the {kind} name '{name}' is taken by an installed "
                          "plugin; choose another name")

    info = _load(kind, _InProcess(name, obj))  # type: ignore[arg-type]
    if info.cls is None:
        raise ConfigError(f"register: {info.error}")
    _REGISTERED[kind][name] = obj
    refresh()


def discover(kind: Kind) -> dict[str, PluginInfo]:
    """Every entry point of ``kind``, loaded (cached; see :func:`refresh`)."""
    return _discover(kind)


def refresh() -> None:
    """Forget discovered plugins (after installing one in a running process)."""
    _discover.cache_clear()


def available(kind: Kind) -> list[str]:
    """Names of the plugins of ``kind`` that loaded, in listing order."""
    return [name for name, info in discover(kind).items() if info.ok]


def metrics() -> list[Metric]:
    """Every registered metric that loaded, in table order."""
    return [info.cls for info in discover("metric").values() if info.cls is not None]


def get_class(kind: Kind, name: str) -> type[Any]:
    """The plugin class registered as ``name``.

    Raises:
        UnknownNameError: no such plugin (the message suggests the closest name).
        HnnbenchError: the plugin exists but failed to load.
    """
    plugins = discover(kind)
    info = plugins.get(name)
    if info is None:
        raise UnknownNameError(kind, name, available(kind))
    if info.cls is None:
        raise HnnbenchError(f"The {kind} '{name}' is installed but unusable: {info.error}")
    return info.cls


def validate_profile(name: str) -> None:
    if name not in PROFILES:
        raise UnknownNameError("profile", name, PROFILES)


def config_defaults(kind: Kind, name: str, profile: str = "paper") -> Any:
    """The plugin's config dataclass instance for ``profile``: its defaults with the
    plugin's own profile overrides applied."""
    cls = get_class(kind, name)
    overrides = dict(getattr(cls, "profiles", {}).get(profile, {}))
    fields = {f.name for f in dataclasses.fields(cls.Config)}
    unknown = sorted(set(overrides) - fields)
    if unknown:
        raise ConfigError(
            f"The {kind} '{name}' declares profile '{profile}' overrides for unknown config "
            f"fields {unknown}; fix {cls.__module__}.{cls.__name__}.profiles"
        )
    return cls.Config(**{**overrides, "name": name})


def register_configs(profile: str = "paper") -> None:
    """Store every working plugin's config as an option of the ``system`` / ``model``
    Hydra config group, with the defaults of ``profile``."""
    from hydra.core.config_store import ConfigStore

    validate_profile(profile)
    store = ConfigStore.instance()
    for kind in ("system", "model"):
        for name in available(kind):
            try:
                node = config_defaults(kind, name, profile)
            except HnnbenchError as err:
                info = discover(kind)[name]
                info.error, info.cls = str(err), None
                continue
            store.store(group=kind, name=name, node=node, provider="hnnbench")


def family_models() -> dict[str, dict[str, str]]:
    """``{backend: {family: model}}`` of the installed models that declare a family."""
    out: dict[str, dict[str, str]] = {}
    for name, info in discover("model").items():
        family = info.family
        if info.ok and family != "-":
            out.setdefault(info.backend, {})[family] = name
    return out


def claim_sets() -> list[ClaimSet]:
    """Every registered claim set (entry-point group ``hnnbench.claims``)."""
    return [info.cls for info in discover("claims").values() if info.cls is not None]


def all_claims() -> list[Claim]:
    """Every claim of every registered set."""
    return [claim for cs in claim_sets() for claim in cs.claims]
