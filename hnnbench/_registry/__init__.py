"""The registry: the installed plugins (systems, models, metrics, claim sets), found
through entry points, with broken-plugin isolation, did-you-mean lookups and listing
order. Above the contracts, beside ``hnnbench.neural``; it knows nothing of Hydra
(docs/ARCHITECTURE.md, "Layers").

Its API, re-exported here, is what the rest of hnnbench uses: ``from hnnbench import
_registry as registry``. :mod:`~hnnbench._registry.discovery` holds one group's
discovery, :mod:`~hnnbench._registry.groups` the four groups and their queries.
"""

from hnnbench._registry.discovery import (
    PROFILES,
    PluginGroup,
    PluginInfo,
    default_config,
    generation,
    guarded,
)
from hnnbench._registry.groups import (
    CLAIMS,
    GROUPS,
    METRICS,
    MODELS,
    SYSTEMS,
    Kind,
    all_claims,
    available,
    baseline_families,
    claim_sets,
    config_defaults,
    discover,
    family_models,
    get_class,
    group,
    metrics,
    ordered,
    refresh,
    register,
    validate_profile,
)

__all__ = [
    "CLAIMS",
    "GROUPS",
    "METRICS",
    "MODELS",
    "PROFILES",
    "SYSTEMS",
    "Kind",
    "PluginGroup",
    "PluginInfo",
    "all_claims",
    "available",
    "baseline_families",
    "claim_sets",
    "config_defaults",
    "default_config",
    "discover",
    "family_models",
    "generation",
    "get_class",
    "group",
    "guarded",
    "metrics",
    "ordered",
    "refresh",
    "register",
    "validate_profile",
]
