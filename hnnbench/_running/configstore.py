"""Hydra's ConfigStore: the job schema, hnnbench's sweeper, and every working plugin's
config as an option of the ``system`` / ``model`` group with the defaults of one profile
and track (docs/ARCHITECTURE.md, "Design decisions"). The registry finds the plugins;
this is where Hydra learns about them.
"""

from __future__ import annotations

import functools

from hnnbench import _registry as registry
from hnnbench._contracts.names import DEFAULT_TRACK
from hnnbench._running.config import RunConfig, SweeperConfig

__all__ = ["register"]

#: What the ConfigStore holds: the (profile, track) of its plugin configs, with the
#: registry's generation they were built from (a cache, like discovery).
_stored: dict[str, tuple[str, str, int]] = {}


def register(profile: str = "paper", track: str = DEFAULT_TRACK) -> None:
    """Store the job schema, hnnbench's sweeper, and every working plugin's config as an
    option of the ``system`` / ``model`` Hydra config group, with the defaults of
    ``profile`` on ``track`` (a model's declared recipe on the recipe track:
    :func:`hnnbench._registry.config_defaults`). Done once per (profile, track) until the
    registry forgets its plugins. A plugin whose config cannot be built (whatever it
    raises) is marked broken, with the reason, and left out."""
    from hydra.core.config_store import ConfigStore

    registry.validate_profile(profile)
    store = ConfigStore.instance()
    store.store(name="hnnbench_schema", node=RunConfig, provider="hnnbench")
    store.store(group="hydra/sweeper", name="hnnbench", node=SweeperConfig, provider="hnnbench")
    key = (profile, track, registry.generation())
    if _stored.get("key") == key and store.repo.get("system", {}):  # already there
        return
    for plugins in (registry.SYSTEMS, registry.MODELS):
        for name in plugins.available():
            info = plugins.discover()[name]
            node, error = registry.guarded(
                f"the {plugins.kind} '{name}' ({info.target})",
                f"its {profile} config cannot be built",
                functools.partial(registry.config_defaults, plugins.kind, name, profile, track),
            )
            if error is not None:
                info.error, info.cls = error, None
                continue
            store.store(group=plugins.kind, name=name, node=node, provider="hnnbench")
    _stored["key"] = key
