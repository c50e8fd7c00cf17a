"""The evaluation: every registered metric, computed the same way for every model.

:func:`evaluate` builds an :class:`EvalContext` for one trained model and asks each
registered :class:`~hnnbench._contracts.metric.Metric` (``hnnbench.metrics`` entry points) for
its value. The context computes what metrics share, once and only when asked: the
rollout from the evaluation trajectories' initial states, the map from a model's
latents to physical states (identity for state models; a linear probe fitted on the
training set for models with an encoder), energies along both. docs/METRICS.md is the
reference for what each number means.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from hnnbench._contracts.errors import JobTimeout, ModelOutputError, RolloutDiverged
from hnnbench._contracts.metric import EvalContext, EvaluationConfig, Metric, summarize
from hnnbench._contracts.plugin import Dataset, Model, System, Trajectories

log = logging.getLogger("hnnbench")

__all__ = ["Evaluation", "evaluate", "failed_metrics"]


@dataclass
class Evaluation:
    """Metrics (``{name: {"mean", "sem"}}``), divergence, arrays for figures, and the
    metrics whose computation raised (a plugin bug: recorded, not fatal)."""

    metrics: dict[str, dict[str, float]]
    diverged: Optional[str] = None
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)


def _nan() -> dict[str, float]:
    return {"mean": math.nan, "sem": math.nan}


def failed_metrics(
    system: System, metrics: Sequence[Metric], keep: Optional[dict[str, dict[str, float]]] = None
) -> dict[str, dict[str, float]]:
    """The record of a model that diverged: each applicable metric's worst value (NaN
    where it does not apply); values in ``keep`` (e.g. finite losses) stay."""
    out: dict[str, dict[str, float]] = {}
    for metric in metrics:
        if keep and metric.name in keep:
            out[metric.name] = keep[metric.name]
        elif metric.applies(system):
            out[metric.name] = {"mean": metric.worst(), "sem": math.nan}
        else:
            out[metric.name] = _nan()
    return out


#: ``progress(metric, index, total, seconds)``: a metric that applies starts
#: (``seconds`` None) or is done (:class:`hnnbench._running.progress.EvaluationProgress`).
MetricProgress = Callable[[str, int, int, Optional[float]], None]


def evaluate(
    system: System,
    model: Model,
    data: Dataset,
    traj: Trajectories,
    cfg: EvaluationConfig,
    metrics: Optional[Sequence[Metric]] = None,
    progress: Optional[MetricProgress] = None,
) -> Evaluation:
    """Compute every metric (default: all registered) of ``model`` on ``system``;
    ``progress`` is told as each metric that applies starts and is done."""
    if metrics is None:
        from hnnbench._registry.groups import metrics as registered

        metrics = registered()
    ctx = EvalContext(system, model, data, traj, cfg)
    result: dict[str, dict[str, float]] = {}
    errors: dict[str, str] = {}
    diverged: Optional[str] = None
    applies = {m.name: bool(m.applies(system)) for m in metrics}
    applying = [name for name, yes in applies.items() if yes]
    for metric in metrics:
        if not applies[metric.name]:
            result[metric.name] = _nan()
            continue
        index = applying.index(metric.name) + 1
        if progress is not None:
            progress(metric.name, index, len(applying), None)
        started = time.perf_counter()
        try:
            values = metric.compute(ctx)
        except RolloutDiverged as err:
            result[metric.name] = {"mean": metric.worst(), "sem": math.nan}
            if metric.decides_status:
                if diverged is None:
                    diverged = f"rollout diverged ({metric.name}): {err}"
            else:  # a diagnostic: its value says it failed, the reason goes beside it
                errors[metric.name] = f"rollout failed: {err}".splitlines()[0]
            continue
        except (KeyboardInterrupt, JobTimeout, ModelOutputError):
            raise  # a model that breaks its output contract fails the job, whatever asked
        except BaseException as err:  # noqa: BLE001 - a plugin's sys.exit() too
            # A metric whose declaration says so (hnnbench's own required metrics: what
            # every job is for; an exception there is usually the model's, e.g. out of
            # memory) fails the job with the traceback rather than leave a NaN that
            # reads "not applicable". Any other metric's error is recorded and the job
            # goes on: one broken metric plugin must not fail every job
            # (docs/PLUGINS.md).
            if metric.errors_fail_job:
                raise
            errors[metric.name] = f"{type(err).__name__}: {err}".splitlines()[0]
            log.warning("metric %s failed: %s", metric.name, errors[metric.name])
            result[metric.name] = _nan()
            continue
        finally:  # done, whichever way it went
            if progress is not None:
                progress(metric.name, index, len(applying), time.perf_counter() - started)
        if values is None:
            result[metric.name] = _nan()
        elif isinstance(values, dict):
            result[metric.name] = {
                "mean": float(values["mean"]),
                "sem": float(values.get("sem", math.nan)),
            }
        else:
            result[metric.name] = summarize(np.asarray(values, dtype=np.float64))
        mean = result[metric.name]["mean"]
        if metric.required and not math.isfinite(mean):
            # A metric that applies and computed a value: NaN there is no "not
            # applicable" (that is None), it is a model that produced NaN.
            result[metric.name]["mean"] = metric.worst() if math.isnan(mean) else mean
            if not metric.decides_status:
                errors[metric.name] = f"not finite ({mean})"
            elif diverged is None:
                diverged = f"{metric.name} is not finite ({mean})"
    return Evaluation(metrics=result, diverged=diverged, arrays=ctx.arrays, errors=errors)
