"""A metric, declared once: what it computes and how every consumer treats it.

A :class:`Metric` holds everything about one metric: its name and definition, the
function that computes it from an evaluation, which direction is better, how tables
and figures display it, the tolerance of the regression gate, the systems it applies
to, and what a diverged rollout records for it. The evaluation, the leaderboard, the
report and ``hnnbench check`` all read these declarations; none names a metric.

Metrics are plugins of the entry-point group ``hnnbench.metrics``: each entry point
names a :class:`Metric` instance. hnnbench's own (:mod:`hnnbench.metrics`) are declared
there the same way, so a third-party package adds a metric to every leaderboard and
to ``hnnbench check`` with no change here (docs/PLUGINS.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    from hnnbench.api import System
    from hnnbench.evaluate import EvalContext

__all__ = ["CheckRule", "Metric", "always"]


def always(system: System) -> bool:
    """The default :attr:`Metric.applies`: every system."""
    return True


@dataclass(frozen=True)
class CheckRule:
    """Tolerance of ``hnnbench check`` for a metric (``--rules FILE`` overrides it).

    Attributes:
        factor: how much worse is tolerated, as a ratio compared in log space: a
            lower-is-better value fails above ``reference * factor``, a higher-is-better
            one below ``reference / factor``.
        floor: values below it count as it (a numerical noise floor, so that 1e-16 vs
            1e-14 from an exact model on two machines is no regression).
        gate: ``False``: differences are reported as information, never a failure.
    """

    factor: float = 10.0
    floor: float = 0.0
    gate: bool = True


@dataclass(frozen=True)
class Metric:
    """One metric (see the module docstring).

    Attributes:
        name: the record's key and the leaderboard's column (``<name>_mean``).
        description: one line: what it measures (``hnnbench list``, docs, page tooltips).
        compute: ``EvalContext -> values``: an array of per-trajectory (or per-point)
            values, summarised as their mean and standard error; a ``{"mean", "sem"}``
            dict; or ``None`` when it does not apply to this model (recorded as NaN).
            It may raise :class:`~hnnbench.errors.RolloutDiverged` (the metric then
            records :meth:`worst`).
        better: ``"lower"`` or ``"higher"``.
        scale: ``"log"`` (errors spanning decades) or ``"linear"``, for tables/figures.
        check: the regression gate's tolerance.
        applies: ``System -> bool``; elsewhere the metric is NaN ("not applicable").
        required: a non-finite value makes the job ``diverged``; ``False`` for metrics
            that probe failure modes on purpose (e.g. a long-horizon rollout).
        summary: shown in the end-of-sweep summary table.
        order: position in tables (lower first; then by name).
        reference: where its definition is documented.
        figures: the report's board figures that plot it: ``"heatmap"`` (a rank
            heatmap of models by system), ``"data_efficiency"`` (the metric against a
            swept training-set size).
    """

    name: str
    description: str
    compute: Callable[[EvalContext], Any]
    better: Literal["lower", "higher"] = "lower"
    scale: Literal["log", "linear"] = "log"
    check: CheckRule = field(default_factory=CheckRule)
    applies: Callable[[System], bool] = always
    required: bool = True
    summary: bool = True
    order: int = 1000
    reference: str = "docs/METRICS.md"
    figures: tuple[str, ...] = ()

    def worst(self) -> float:
        """The value recorded when the model failed (diverged): ``inf`` for errors,
        ``0`` where higher is better (a diverged model predicts nothing)."""
        return 0.0 if self.better == "higher" else math.inf
