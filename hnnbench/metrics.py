"""Metric definitions: pure numpy, one function each.

Per-trajectory functions return one value per evaluation trajectory, shape ``(M,)``;
:func:`summarize` turns those into the mean and its standard error. docs/METRICS.md
gives the precise definitions and the evaluation protocol.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "energy_error_per_traj",
    "mse",
    "per_point_squared_error",
    "reversibility_per_traj",
    "rollout_error_per_traj",
    "sem",
    "summarize",
    "valid_prediction_time",
]


def mse(pred: np.ndarray, target: np.ndarray) -> float:
    """Mean squared error over all points and coordinates."""
    return float(np.mean((np.asarray(pred) - np.asarray(target)) ** 2))


def per_point_squared_error(pred: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``(N,)`` squared error of each point, averaged over its coordinates."""
    diff = np.asarray(pred, dtype=np.float64) - np.asarray(target, dtype=np.float64)
    return np.mean(diff.reshape(diff.shape[0], -1) ** 2, axis=1)


def energy_error_per_traj(energy_hat: np.ndarray, energy_true: np.ndarray) -> np.ndarray:
    """``(M,)`` time-mean of ``(E(x_hat(t)) - E(x(t)))^2`` for ``(M, T)`` energies."""
    return np.mean((np.asarray(energy_hat) - np.asarray(energy_true)) ** 2, axis=1)


def rollout_error_per_traj(x_hat: np.ndarray, x_true: np.ndarray) -> np.ndarray:
    """``(M,)`` mean over time and coordinates of ``(x_hat - x)^2`` for ``(M, T, D)``."""
    return np.mean((np.asarray(x_hat) - np.asarray(x_true)) ** 2, axis=(1, 2))


def reversibility_per_traj(x_back: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """``(M,)`` squared distance ``||x_back - x0||^2`` for ``(M, D)`` states."""
    return np.sum((np.asarray(x_back) - np.asarray(x0)) ** 2, axis=1)


def valid_prediction_time(
    x_hat: np.ndarray, x_true: np.ndarray, t: np.ndarray, threshold: float = 0.1
) -> np.ndarray:
    """``(M,)`` time until the relative error first exceeds ``threshold``.

    The relative error at time ``t_k`` is ``||x_hat - x|| / ||x||``. The valid prediction
    time is the last grid time before the first exceedance, measured from ``t[0]``; the
    whole horizon if it never exceeds. Non-finite errors count as exceedances.
    """
    t = np.asarray(t, dtype=np.float64)
    err = np.linalg.norm(x_hat - x_true, axis=-1)
    scale = np.maximum(np.linalg.norm(x_true, axis=-1), 1e-12)
    bad = ~(err / scale <= threshold)  # (M, T); NaN counts as bad
    out = np.empty(bad.shape[0])
    for i, row in enumerate(bad):
        hits = np.flatnonzero(row)
        if hits.size == 0:
            out[i] = t[-1] - t[0]
        else:
            out[i] = t[max(hits[0] - 1, 0)] - t[0] if hits[0] > 0 else 0.0
    return out


def sem(values: np.ndarray) -> float:
    """Standard error of the mean (``nan`` for fewer than two values)."""
    values = np.asarray(values, dtype=np.float64)
    if values.size < 2 or not np.all(np.isfinite(values)):
        return float("nan") if values.size < 2 else float("inf")
    return float(np.std(values, ddof=1) / np.sqrt(values.size))


def summarize(values: np.ndarray) -> dict[str, float]:
    """``{"mean": ..., "sem": ...}`` over evaluation trajectories (or points)."""
    values = np.asarray(values, dtype=np.float64)
    mean = float(np.mean(values)) if np.all(np.isfinite(values)) else float("inf")
    return {"mean": mean, "sem": sem(values)}
