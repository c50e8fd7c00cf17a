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
from collections.abc import Iterable
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, Generic, Literal, Optional, TypeVar

from hnnbench._claims import Claim, ClaimSet
from hnnbench._contract import Model, ModelConfig, System, SystemConfig
from hnnbench._errors import ConfigError, HnnbenchError, UnknownNameError
from hnnbench._metric import Metric
from hnnbench._record_schema import metric_name_problem

Kind = Literal["system", "model", "metric", "claims"]
T = TypeVar("T")
#: Profiles that ship with hnnbench (conf/profile/*.yaml). ``paper`` is the default.
PROFILES = ("paper", "quick")

__all__ = [
    "CLAIMS",
    "GROUPS",
    "METRICS",
    "MODELS",
    "SYSTEMS",
    "PluginGroup",
    "all_claims",
    "claim_sets",
    "family_models",
    "PROFILES",
    "PluginInfo",
    "available",
    "config_defaults",
    "discover",
    "get_class",
    "group",
    "metrics",
    "ordered",
    "refresh",
    "register",
    "register_configs",
    "validate_profile",
]


@dataclass
class PluginInfo(Generic[T]):
    """One entry point and the outcome of loading it."""

    kind: str
    name: str
    target: str
    distribution: str | None
    dist_version: str | None
    #: The loaded class (systems, models) or instance (metrics, claim sets).
    cls: Optional[T] = None
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


@dataclass
class _InProcess:
    """What :meth:`PluginGroup._load` needs of an entry point, for a plugin registered
    in-process."""

    name: str
    obj: Any
    dist: None = None

    @property
    def value(self) -> str:
        return f"(registered in this process) {getattr(self.obj, '__qualname__', self.name)}"

    def load(self) -> Any:
        return self.obj


@dataclass
class PluginGroup(Generic[T]):
    """The plugins of one kind: an entry-point group, what its entry points must name
    (a subclass of ``base``, or an instance of it when ``instances``), discovery with
    broken-plugin isolation, lookup with did-you-mean, listing order and in-process
    registration. ``PluginGroup[type[System]]`` holds classes, ``PluginGroup[Metric]``
    instances; :meth:`get` returns that type."""

    kind: str
    group: str
    base: type
    instances: bool = False
    config_base: Optional[type] = None
    _registered: dict[str, Any] = field(default_factory=dict, repr=False)
    _found: Optional[dict[str, PluginInfo[T]]] = field(default=None, repr=False)

    # -- discovery ----------------------------------------------------------------
    def discover(self) -> dict[str, PluginInfo[T]]:
        """Every entry point of the group (and in-process registration), loaded, in
        listing order (cached; see :meth:`refresh`)."""
        if self._found is None:
            found: dict[str, PluginInfo[T]] = {}
            for ep in sorted(metadata.entry_points(group=self.group), key=lambda e: e.name):
                if ep.name in found:  # one name from two distributions: keep the first
                    other = found[ep.name]
                    if other.target != ep.value:
                        other.error = (
                            f"name '{ep.name}' is declared twice ({other.target} and "
                            f"{ep.value}); uninstall one of the plugins")
                        other.cls = None
                    continue
                found[ep.name] = self._load(ep.name, ep.value, getattr(ep, "dist", None),
                                            ep.load)
            for name, obj in self._registered.items():
                source = _InProcess(name, obj)
                found[name] = self._load(name, source.value, None, source.load)
            order = {name: i for i, name in enumerate(_sorted_by_order(found))}
            self._found = dict(sorted(found.items(), key=lambda item: order[item[0]]))
        return self._found

    def refresh(self) -> None:
        self._found = None

    def available(self) -> list[str]:
        """Names of the plugins that loaded, in listing order."""
        return [name for name, info in self.discover().items() if info.ok]

    def loaded(self) -> list[T]:
        """The plugins that loaded (classes or instances), in listing order."""
        return [info.cls for info in self.discover().values() if info.cls is not None]

    def get(self, name: str) -> T:
        """The plugin registered as ``name``.

        Raises:
            UnknownNameError: no such plugin (the message suggests the closest name).
            HnnbenchError: the plugin exists but failed to load.
        """
        info = self.discover().get(name)
        if info is None:
            raise UnknownNameError(self.kind, name, self.available())
        if info.cls is None:
            raise HnnbenchError(f"The {self.kind} '{name}' is installed but unusable: "
                                f"{info.error}")
        return info.cls

    def ordered(self, names: Iterable[str]) -> list[str]:
        """``names`` in listing order: the plugins' ``order`` (lower first; none: after
        those that have one), then by name; names not installed come last, by name."""
        plugins = self.discover()

        def key(name: str) -> tuple[int, float, str]:
            info = plugins.get(name)
            if info is None or info.cls is None:
                return (1, 0.0, name)
            order = getattr(info.cls, "order", None)
            return (0, float("inf") if order is None else float(order), name)

        return sorted(dict.fromkeys(names), key=key)

    def register(self, name: str, obj: Any) -> None:
        """See :func:`register`."""
        installed = {ep.name for ep in metadata.entry_points(group=self.group)}
        if name in installed:
            raise ConfigError(f"register: the {self.kind} name '{name}' is taken by an "
                              "installed plugin; choose another name")
        source = _InProcess(name, obj)
        info = self._load(name, source.value, None, source.load)
        if info.cls is None:
            raise ConfigError(f"register: {info.error}")
        self._registered[name] = obj
        refresh()

    # -- loading one ----------------------------------------------------------------
    def _load(self, name: str, target: str, dist: Any, load: Any) -> PluginInfo[T]:
        info: PluginInfo[T] = PluginInfo(
            kind=self.kind, name=name, target=target,
            distribution=dist.metadata["Name"] if dist is not None else None,
            dist_version=dist.version if dist is not None else None,
        )
        try:
            obj = load()
        except HnnbenchError as err:
            info.error = str(err)
            return info
        except Exception as err:  # a broken plugin must not break the others
            info.error = f"import failed: {type(err).__name__}: {err}".splitlines()[0]
            return info
        info.error = self._problem(name, target, obj)
        if info.error is None:
            info.cls = obj
        return info

    def _problem(self, name: str, target: str, obj: Any) -> Optional[str]:
        """Why ``obj`` cannot be this group's plugin ``name``, or ``None``."""
        base = self.base
        if self.instances:
            if not isinstance(obj, base):
                return f"{target} is not a {base.__module__}.{base.__name__}"
            if getattr(obj, "name", None) != name:
                return (f"{target} is named '{getattr(obj, 'name', '?')}' but is "
                        f"registered as '{name}': use the same name")
            if self.kind == "metric" and (problem := metric_name_problem(name)):
                return f"{target}: {problem}"
            return None
        if not (isinstance(obj, type) and issubclass(obj, base)):
            return f"{target} is not a subclass of hnnbench.{base.__name__}"
        config_cls = getattr(obj, "Config", None)
        config_base = self.config_base
        if config_base is not None and not (
                isinstance(config_cls, type) and dataclasses.is_dataclass(config_cls)
                and issubclass(config_cls, config_base)):
            return (f"{target}.Config must be a dataclass subclassing "
                    f"hnnbench.{config_base.__name__}")
        unknown_profiles = sorted(set(getattr(obj, "profiles", {}) or {}) - set(PROFILES))
        if unknown_profiles:
            return (f"{target}.profiles declares {unknown_profiles}, but hnnbench's "
                    f"profiles are {', '.join(PROFILES)}; rename or remove them")
        missing = getattr(obj, "requirements_missing", lambda: None)()
        return str(missing) if missing else None


def _sorted_by_order(found: dict[str, PluginInfo[Any]]) -> list[str]:
    def key(name: str) -> tuple[float, str]:
        order = getattr(found[name].cls, "order", None) if found[name].cls else None
        return (float("inf") if order is None else float(order), name)

    return sorted(found, key=key)


#: The four plugin groups.
SYSTEMS: PluginGroup[type[System]] = PluginGroup(
    "system", "hnnbench.systems", System, config_base=SystemConfig)
MODELS: PluginGroup[type[Model]] = PluginGroup(
    "model", "hnnbench.models", Model, config_base=ModelConfig)
METRICS: PluginGroup[Metric] = PluginGroup("metric", "hnnbench.metrics", Metric, instances=True)
CLAIMS: PluginGroup[ClaimSet] = PluginGroup("claims", "hnnbench.claims", ClaimSet,
                                            instances=True)
_GROUPS: dict[str, PluginGroup[Any]] = {g.kind: g for g in (SYSTEMS, MODELS, METRICS, CLAIMS)}
#: kind -> entry-point group name.
GROUPS: dict[str, str] = {kind: g.group for kind, g in _GROUPS.items()}


def group(kind: str) -> PluginGroup[Any]:
    """The plugin group of ``kind`` (``system``, ``model``, ``metric``, ``claims``)."""
    try:
        return _GROUPS[kind]
    except KeyError:
        raise ConfigError(f"unknown plugin kind '{kind}'; expected one of "
                          f"{', '.join(_GROUPS)}") from None


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
        raise ConfigError(f"register: unknown kind '{kind}'; expected one of "
                          f"{', '.join(_GROUPS)}")
    _GROUPS[kind].register(name, obj)


def discover(kind: Kind) -> dict[str, PluginInfo[Any]]:
    """Every entry point of ``kind``, loaded (cached; see :func:`refresh`)."""
    return group(kind).discover()


def refresh() -> None:
    """Forget discovered plugins (after installing one in a running process)."""
    for g in _GROUPS.values():
        g.refresh()
    _stored_profile.clear()


#: The profile whose plugin configs are in Hydra's ConfigStore (a cache, like discovery).
_stored_profile: dict[str, str] = {}


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


def config_defaults(kind: str, name: str, profile: str = "paper") -> Any:
    """The plugin's config dataclass instance for ``profile``: its defaults with the
    plugin's own profile overrides applied."""
    cls: Any = group(kind).get(name)
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
    stored = store.repo.get("system", {})
    if _stored_profile.get("profile") == profile and stored:  # already there (cached)
        return
    for plugins in (SYSTEMS, MODELS):
        for name in plugins.available():
            try:
                node = config_defaults(plugins.kind, name, profile)
            except HnnbenchError as err:
                info = plugins.discover()[name]
                info.error, info.cls = str(err), None
                continue
            store.store(group=plugins.kind, name=name, node=node, provider="hnnbench")
    _stored_profile["profile"] = profile


def family_models() -> dict[str, dict[str, str]]:
    """``{backend: {family: model}}`` of the installed models that declare a family."""
    out: dict[str, dict[str, str]] = {}
    for name, info in MODELS.discover().items():
        family = info.family
        if info.ok and family != "-":
            out.setdefault(info.backend, {})[family] = name
    return out


def claim_sets() -> list[ClaimSet]:
    """Every registered claim set (entry-point group ``hnnbench.claims``)."""
    return CLAIMS.loaded()


def all_claims() -> list[Claim]:
    """Every claim of every registered set."""
    return [claim for cs in claim_sets() for claim in cs.claims]
