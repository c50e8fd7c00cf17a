"""How models look in figures: one colour per family, a shade and a line style per twin
(the family's models on other backends), the same in every figure and every report.

Colours come from the registry, never from the rows a report holds: a family's colour
is fixed by its position among the installed families in listing order (the ranked
families take the colour-blind-safe palette of Okabe & Ito, the references, such as the
oracle, greys), and a twin's shade and dashes by its position among its family's models.
A family no installed plugin declares (records of a plugin not installed here) takes a
colour from a hash of its name, so it too keeps it. Nothing here names a model."""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from hnnbench import _registry as registry

__all__ = [
    "PALETTE",
    "REFERENCE_COLORS",
    "color",
    "family_color",
    "line",
    "log_axes",
    "model_color",
    "model_keys",
    "panel_grid",
    "save_panels",
    "twin_rank",
]

#: Colours of the ranked families, in listing order: Okabe & Ito's colour-blind-safe set
#: (blue, vermillion, bluish green, reddish purple, orange, sky blue; their black and
#: yellow left out: black is the references', yellow too faint for lines), then Paul
#: Tol's muted colours for more families.
PALETTE = (
    "#0072B2",
    "#D55E00",
    "#009E73",
    "#CC79A7",
    "#E69F00",
    "#56B4E9",
    "#882255",
    "#44AA99",
    "#999933",
    "#332288",
    "#DDCC77",
    "#AA4499",
)
#: Colours of the references (``ranked = False``: standing still, the oracle), in
#: listing order.
REFERENCE_COLORS = ("#7f7f7f", "#b3b3b3", "#4d4d4d", "#d0d0d0")
#: Line styles by a model's position among its family's models (:func:`twin_rank`):
#: solid and wide first, then dashed and thin on top, so twins that coincide both stay
#: visible.
DASHES: tuple[Any, ...] = ("-", (0, (4, 2)), (0, (1, 1.5)), (0, (6, 2, 1, 2)))
#: How much darker each further twin is drawn (mixed with black), by twin rank.
SHADES = (0.0, 0.38, 0.18, 0.52)


def _key(name: str, family: str | None) -> str:
    return family if family and family != "-" else name


def _layout() -> tuple[dict[str, str], dict[str, list[str]]]:
    """``({family: colour}, {family: [its models in listing order]})`` of every
    installed model (broken ones included: a colour never moves because a plugin failed
    to load; discovery itself is cached, so this is cheap)."""
    infos = registry.MODELS.discover()
    twins: dict[str, list[str]] = {}
    reference: dict[str, bool] = {}
    for name in registry.ordered("model", infos):
        info = infos[name]
        key = _key(name, info.family)
        twins.setdefault(key, []).append(name)
        ranked = bool(getattr(info.cls, "ranked", True)) if info.cls is not None else True
        reference[key] = reference.get(key, False) or not ranked
    colors: dict[str, str] = {}
    n_ranked = n_reference = 0
    for key in twins:
        if reference[key]:
            colors[key] = REFERENCE_COLORS[n_reference % len(REFERENCE_COLORS)]
            n_reference += 1
        else:
            colors[key] = PALETTE[n_ranked % len(PALETTE)]
            n_ranked += 1
    return colors, twins


def family_color(family: str) -> str:
    """The colour of a family (a model without one: its name)."""
    colors, _ = _layout()
    if family in colors:
        return colors[family]
    digest = int(hashlib.sha256(family.encode()).hexdigest()[:8], 16)
    return PALETTE[digest % len(PALETTE)]


def twin_rank(model: str, family: str | None = None) -> int:
    """``model``'s position among its family's installed models (0: the first in
    listing order, or a model the registry does not know)."""
    _, twins = _layout()
    models = twins.get(_key(model, family), [])
    return models.index(model) if model in models else 0


def _darker(color: str, amount: float) -> str:
    """``color`` (``#rrggbb``) mixed with black by ``amount`` (0: unchanged)."""
    if amount <= 0:
        return color
    rgb = [int(color[i : i + 2], 16) for i in (1, 3, 5)]
    return "#" + "".join(f"{round(c * (1.0 - amount)):02x}" for c in rgb)


def model_keys(models: Sequence[str], families: dict[str, str]) -> list[str]:
    """The colour key of each model (its family, else its name), once each, in listing
    order."""
    return list(dict.fromkeys(_key(m, families.get(m)) for m in registry.ordered("model", models)))


def color(model: str, families: dict[str, str], models: Sequence[str] = ()) -> str:
    """The colour of ``model``: its family's, in the shade of its twin rank. (``models``,
    the others drawn beside it, no longer matter: kept for callers.)"""
    family = families.get(model)
    rank = twin_rank(model, family)
    return _darker(family_color(_key(model, family)), SHADES[rank % len(SHADES)])


def model_color(model: str) -> str:
    """The colour of ``model`` by the family its installed plugin declares (:func:`color`),
    for a figure whose rows name models only (a study summary); a model not installed
    here: its name's."""
    _, twins = _layout()
    family = next((key for key, names in twins.items() if model in names), None)
    return color(model, {model: family} if family else {})


def log_axes(ax: Any) -> None:
    """Both axes of ``ax`` on log scales, labelled with plain numbers (``200``, ``0.001``)
    at the decades and at 2 and 5 between them, so that the labels of an axis spanning
    about one decade do not run into one another."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    ax.set_xscale("log")
    ax.set_yscale("log")
    for axis, (low, high) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        narrow = 0 < low < high and math.log10(high / low) < 2
        axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0) if narrow else (1.0,)))
        axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        axis.set_minor_locator(LogLocator(base=10, subs=tuple(range(2, 10))))
        axis.set_minor_formatter(NullFormatter())


def line(
    model: str,
    backend: str,
    families: dict[str, str],
    models: Sequence[str] = (),
    backends: Sequence[str] = (),
) -> dict[str, Any]:
    """Matplotlib line properties of ``model``: its colour (:func:`color`) and, by its
    twin rank, its dashes and width (``backend``, ``models`` and ``backends`` no longer
    matter: the registry decides)."""
    rank = twin_rank(model, families.get(model))
    style = {"color": color(model, families), "ls": DASHES[rank % len(DASHES)]}
    if rank == 0:
        return {**style, "lw": 2.4, "alpha": 0.85, "zorder": 2}
    return {**style, "lw": 1.3, "zorder": 3}


def panel_grid(n: int) -> tuple[Figure, list[Any]]:
    """A figure of ``n`` panels of 4.2 x 3.4 inches, at most 3 per row: the figure and
    its axes, row by row (the cells after the ``n``-th are hidden by
    :func:`save_panels`)."""
    cols = min(n, 3)
    fig = Figure(figsize=(4.2 * cols, 3.4 * math.ceil(n / cols)))
    axes = fig.subplots(math.ceil(n / cols), cols, squeeze=False)
    return fig, list(axes.flat)


def save_panels(fig: Figure, axes: Sequence[Any], n: int, path: Path) -> Path:
    """Hide the axes after the ``n``-th, lay the figure out and write it to ``path``
    (its folder made), at 110 dpi."""
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    return path
