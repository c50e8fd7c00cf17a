"""One plugin group's discovery through entry points: loading with broken-plugin
isolation, the checks a plugin must pass, listing order, in-process registration,
and a plugin's config defaults per profile and track (docs/PLUGINS.md).
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import io
import logging
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, Generic, Optional, TypeVar

from hnnbench._contracts.errors import ConfigError, HnnbenchError, UnknownNameError
from hnnbench._contracts.names import DEFAULT_TRACK, metric_name_problem, name_problem
from hnnbench._contracts.space import SearchSpace, space_problem

log = logging.getLogger("hnnbench")

__all__ = [
    "PROFILES",
    "PluginGroup",
    "PluginInfo",
    "default_config",
    "generation",
    "guarded",
    "refresh_all",
]


T = TypeVar("T")
#: Profiles that ship with hnnbench (conf/profile/*.yaml). ``paper`` is the default.
PROFILES = ("paper", "quick")
#: Every plugin group made, and how many times discovery was forgotten
#: (:func:`refresh_all`), for caches built from what discovery found.
_GROUPS_MADE: list[PluginGroup[Any]] = []
_REFRESHED = [0]


def refresh_all() -> None:
    """Forget what every plugin group discovered (after a plugin was installed or
    registered in this process)."""
    for plugins in _GROUPS_MADE:
        plugins.refresh()
    _REFRESHED[0] += 1


def generation() -> int:
    """How many times discovery was forgotten: a cache of something built from the
    discovered plugins (the ConfigStore's plugin configs) is stale once this changes."""
    return _REFRESHED[0]


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
        doc = (
            getattr(self.cls, "description", "")
            or getattr(self.cls, "title", "")
            or (self.cls.__doc__ or "")
        )
        return doc.strip().splitlines()[0] if doc.strip() else ""

    @property
    def backend(self) -> str:
        return str(getattr(self.cls, "backend", "-")) if self.kind == "model" and self.cls else "-"

    @property
    def family(self) -> str:
        """A neural model's family name (``hnn``), else ``-``."""
        family = getattr(self.cls, "family", None) if self.kind == "model" else None
        return str(getattr(family, "name", "-")) if family is not None else "-"

    @property
    def baseline(self) -> bool:
        """Whether the model's family declares itself the baseline
        (:attr:`hnnbench.neural.Family.baseline`)."""
        family = getattr(self.cls, "family", None) if self.kind == "model" else None
        return bool(getattr(family, "baseline", False))

    @property
    def search_space(self) -> Optional[SearchSpace]:
        """A usable model's declared search space (``hnnbench tune``), else ``None``."""
        if self.kind != "model" or self.cls is None:
            return None
        space = getattr(self.cls, "search_space", None)
        return space if space else None

    @property
    def recipe(self) -> Optional[dict[str, Any]]:
        """A usable model's declared paper recipe (``track=recipe``), else ``None``."""
        if self.kind != "model" or self.cls is None:
            return None
        recipe = getattr(self.cls, "recipe", None)
        return dict(recipe) if recipe else None


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

    def __post_init__(self) -> None:
        _GROUPS_MADE.append(self)

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
                            f"{ep.value}); uninstall one of the plugins"
                        )
                        other.cls = None
                    continue
                found[ep.name] = self._load(ep.name, ep.value, getattr(ep, "dist", None), ep.load)
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
            raise HnnbenchError(f"The {self.kind} '{name}' is installed but unusable: {info.error}")
        return info.cls

    def ordered(self, names: Iterable[str]) -> list[str]:
        """``names`` in listing order: the plugins' ``order`` (lower first; none: after
        those that have one), then by name; names not installed come last, by name."""
        plugins = self.discover()

        def key(name: str) -> tuple[int, float, str]:
            info = plugins.get(name)
            if info is None or info.cls is None:
                return (1, 0.0, name)
            return (0, _order_value(info.cls), name)

        return sorted(dict.fromkeys(names), key=key)

    def register(self, name: str, obj: Any) -> None:
        """See :func:`register`."""
        installed = {ep.name for ep in metadata.entry_points(group=self.group)}
        if name in installed:
            raise ConfigError(
                f"register: the {self.kind} name '{name}' is taken by an "
                "installed plugin; choose another name"
            )
        source = _InProcess(name, obj)
        info = self._load(name, source.value, None, source.load)
        if info.cls is None:
            raise ConfigError(f"register: {info.error}")
        self._registered[name] = obj
        refresh_all()

    # -- loading one ----------------------------------------------------------------
    def _load(self, name: str, target: str, dist: Any, load: Any) -> PluginInfo[T]:
        info: PluginInfo[T] = PluginInfo(
            kind=self.kind,
            name=name,
            target=target,
            distribution=dist.metadata["Name"] if dist is not None else None,
            dist_version=dist.version if dist is not None else None,
        )
        # A name becomes a directory, a file-name part and a table cell: one that is not
        # a plain name is refused before the plugin's code runs.
        info.error = name_problem(self.kind, name)
        if info.error is not None:
            info.error = f"{target}: {info.error}"
            return info
        obj, info.error = guarded(f"the {self.kind} '{name}' ({target})", "import failed", load)
        if info.error is not None:
            return info
        problem, error = guarded(
            f"the {self.kind} '{name}' ({target})",
            "check failed",
            lambda: self._problem(name, target, obj),
        )
        info.error = error or problem
        if info.error is None:
            info.cls = obj
        return info

    def _problem(self, name: str, target: str, obj: Any) -> Optional[str]:
        """Why ``obj`` cannot be this group's plugin ``name``, or ``None``."""
        base = self.base
        order_problem = _order_problem(obj)
        if self.instances:
            if not isinstance(obj, base):
                return f"{target} is not a {base.__module__}.{base.__name__}"
            if getattr(obj, "name", None) != name:
                return (
                    f"{target} is named '{getattr(obj, 'name', '?')}' but is "
                    f"registered as '{name}': use the same name"
                )
            if self.kind == "metric" and (problem := metric_name_problem(name)):
                return f"{target}: {problem}"
            return f"{target}: {order_problem}" if order_problem else None
        if not (isinstance(obj, type) and issubclass(obj, base)):
            return f"{target} is not a subclass of hnnbench.{base.__name__}"
        if order_problem:
            return f"{target}: {order_problem}"
        version = getattr(obj, "version", None)
        if not isinstance(version, str) or not version:
            return (
                f"{target}.version is {type(version).__name__} {version!r}: expected a "
                'non-empty str (e.g. version = "1"); a record stores it as text'
            )
        config_cls = getattr(obj, "Config", None)
        config_base = self.config_base
        if config_base is not None and not (
            isinstance(config_cls, type)
            and dataclasses.is_dataclass(config_cls)
            and issubclass(config_cls, config_base)
        ):
            return (
                f"{target}.Config must be a dataclass subclassing hnnbench.{config_base.__name__}"
            )
        profiles = getattr(obj, "profiles", {}) or {}
        if not isinstance(profiles, dict):
            return f"{target}.profiles must be a dict of profile name -> config overrides"
        unknown_profiles = sorted(set(profiles) - set(PROFILES))
        if unknown_profiles:
            return (
                f"{target}.profiles declares {unknown_profiles}, but hnnbench's "
                f"profiles are {', '.join(PROFILES)}; rename or remove them"
            )
        space = getattr(obj, "search_space", None)
        if space is not None and isinstance(config_cls, type):
            problem = space_problem(space, config_cls)
            if problem is not None:
                return f"{target}.{problem}"
        missing, error = guarded(
            f"the {self.kind} '{name}' ({target})",
            "requirements_missing() raised",
            getattr(obj, "requirements_missing", lambda: None),
        )
        if error is not None:
            return error
        if missing:
            return str(missing)
        if config_base is not None:
            tracks = [DEFAULT_TRACK, *(["recipe"] if getattr(obj, "recipe", None) else [])]
            for profile in PROFILES:
                for track in tracks:
                    what = f"its {profile} config" + (
                        " on the recipe track" if track == "recipe" else ""
                    )
                    _, error = guarded(
                        f"the {self.kind} '{name}' ({target})",
                        f"{what} cannot be built",
                        functools.partial(
                            default_config, self.kind, name, obj, profile, check=True, track=track
                        ),
                    )
                    if error is not None:
                        return (
                            f"{target}.recipe (track=recipe): {error}"
                            if track == "recipe" and "recipe" not in error
                            else error
                        )
        return None


def guarded(what: str, failure: str, call: Callable[[], Any]) -> tuple[Any, Optional[str]]:
    """``(call(), None)``, or ``(None, "<failure>: <Error>: <message>")`` when it raised
    anything but :class:`KeyboardInterrupt` (``sys.exit()`` included): a plugin's code
    runs here, and one broken plugin must not stop the others. Whatever the call prints
    to stdout goes to stderr, with ``what`` it came from (stdout is ``hnnbench list
    --json``'s)."""
    captured = io.StringIO()
    result: Any = None
    error: Optional[str] = None
    try:
        with contextlib.redirect_stdout(captured):
            result = call()
    except KeyboardInterrupt:
        raise
    except HnnbenchError as err:
        error = " ".join(str(err).split())
    except BaseException as err:  # noqa: BLE001 - SystemExit too: isolate the plugin
        text = " ".join(str(err).split()) if str(err).strip() else ""
        error = f"{failure}: {type(err).__name__}" + (f": {text}" if text else "")
    printed = captured.getvalue()
    if printed.strip():
        lines = printed.strip().splitlines()
        log.warning(
            "%s printed %d line(s) to stdout while loading (shown here, on stderr): %s",
            what,
            len(lines),
            " | ".join(lines[:5]) + (" | ..." if len(lines) > 5 else ""),
        )
    return result, error


def _order_problem(obj: Any) -> Optional[str]:
    """Why a plugin's ``order`` cannot place it in listings (a real number, or none)."""
    try:
        order = getattr(obj, "order", None)
    except Exception as err:  # noqa: BLE001 - a raising property
        return f"reading its order raised {type(err).__name__}"
    if order is None:
        return None
    if isinstance(order, bool) or not isinstance(order, (int, float)) or math.isnan(float(order)):
        return f"order must be a number (lower first), not {order!r}"
    return None


def _order_value(obj: Any) -> float:
    """A plugin's ``order`` for sorting: ``inf`` (last) when it has none or no usable one."""
    if obj is None or _order_problem(obj) is not None:
        return math.inf
    order = getattr(obj, "order", None)
    return math.inf if order is None else float(order)


def _sorted_by_order(found: dict[str, PluginInfo[Any]]) -> list[str]:
    def key(name: str) -> tuple[float, str]:
        return (_order_value(found[name].cls), name)

    return sorted(found, key=key)


def default_config(
    kind: str, name: str, cls: Any, profile: str, check: bool = False, track: str = DEFAULT_TRACK
) -> Any:
    """:func:`config_defaults` of the plugin class ``cls``; ``check``: also run the
    config's ``validate()`` (at discovery: a plugin whose own defaults are invalid is
    refused with the reason)."""
    fields = {f.name for f in dataclasses.fields(cls.Config)}
    overrides: dict[str, Any] = {}
    recipe = getattr(cls, "recipe", None) if track == "recipe" else None
    if isinstance(recipe, dict) and profile != "paper":
        # the smoke profile shortens training through the system's steps: a recipe's
        # own training length (a model field, which takes precedence) is left out
        recipe = {k: v for k, v in recipe.items() if k != "steps"}
    declared = [
        ("recipe", "recipe", recipe or {}),
        (
            f"profile '{profile}' overrides",
            "profiles",
            (getattr(cls, "profiles", {}) or {}).get(profile, {}),
        ),
    ]
    for what, attribute, values in declared:
        if not isinstance(values, dict):
            raise ConfigError(
                f"The {kind} '{name}' declares its {what} as "
                f"{type(values).__name__}: expected a dict of config field -> "
                f"value; fix {cls.__module__}.{cls.__name__}.{attribute}"
            )
        unknown = sorted(set(values) - fields)
        if unknown:
            raise ConfigError(
                f"The {kind} '{name}' declares {what} for unknown config fields {unknown}; "
                f"fix {cls.__module__}.{cls.__name__}.{attribute}"
            )
        overrides.update(values)
    config = cls.Config(**{**overrides, "name": name})
    if check:
        config.validate()
    return config
