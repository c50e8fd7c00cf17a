"""How models look in figures, from their records alone: colour by family (a model
without one: by name), line style by backend. Nothing here names a model."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hnnbench import _registry as registry

__all__ = ["color", "family_color", "line", "model_keys"]

PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
           "#17becf", "#bcbd22", "#7f7f7f")
#: Line styles by position of the backend among those shown: solid and wide first,
#: then dashed and thin on top, so twins that coincide both stay visible.
DASHES: tuple[Any, ...] = ("-", (0, (4, 2)), (0, (1, 1.5)), (0, (6, 2, 1, 2)))


def model_keys(models: Sequence[str], families: dict[str, str]) -> list[str]:
    """The colour key of each model: its family, else its name; keys in registry order
    (so a family keeps its colour across figures and sweeps)."""
    keys = [families.get(m) or m for m in models]
    ordered_models = registry.ordered("model", models)
    first: dict[str, int] = {}
    for m in ordered_models:
        first.setdefault(families.get(m) or m, len(first))
    return sorted(set(keys), key=lambda k: first[k])


def color(model: str, families: dict[str, str], models: Sequence[str]) -> str:
    """The colour of ``model``: the palette entry of its family (or name) among the
    colour keys of ``models``, in registry order."""
    keys = [families.get(m) or m for m in registry.available("model")]
    keys += [k for k in model_keys(models, families) if k not in keys]
    ordered = list(dict.fromkeys(keys))
    return PALETTE[ordered.index(families.get(model) or model) % len(PALETTE)]


def line(model: str, backend: str, families: dict[str, str], models: Sequence[str],
         backends: Sequence[str]) -> dict[str, Any]:
    """Matplotlib line properties of ``model`` (its ``backend`` from the record)."""
    rank = list(dict.fromkeys(backends)).index(backend) if backend in backends else 0
    style = {"color": color(model, families, models), "ls": DASHES[rank % len(DASHES)]}
    if rank == 0:
        return {**style, "lw": 2.4, "alpha": 0.85, "zorder": 2}
    return {**style, "lw": 1.3, "zorder": 3}


def family_color(family: str) -> str:
    """The colour of a family (a model without one: its name), as :func:`color` gives
    its models."""
    infos = registry.MODELS.discover()
    keys = [infos[m].family if infos[m].family != "-" else m
            for m in registry.available("model") if m in infos]
    keys = list(dict.fromkeys(keys))
    if family not in keys:
        keys.append(family)
    return PALETTE[keys.index(family) % len(PALETTE)]
