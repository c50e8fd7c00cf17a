"""The evaluation pipeline: one implementation of every metric for every model.

:func:`evaluate` rolls the model out from the evaluation trajectories' initial states,
maps its rollouts to physical states (identity for state models; a linear probe for
models with an encoder), and computes the metrics of :mod:`hnnbench.metrics`.
docs/METRICS.md is the reference for what each number means.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

from hnnbench import metrics as M
from hnnbench.api import Dataset, Model, System, Trajectories
from hnnbench.config import EvaluationConfig
from hnnbench.errors import RolloutDiverged
from hnnbench.integrate import rk4

__all__ = [
    "HIGHER_IS_BETTER",
    "ROLLOUT_METRICS",
    "Evaluation",
    "LinearProbe",
    "evaluate",
    "loss_metrics",
    "worst",
]

#: Metrics that come from rollouts; ``inf`` when the rollout diverges.
ROLLOUT_METRICS = (
    "energy_mse",
    "rollout_mse",
    "reversibility_error",
    "time_reversal_error",
    "valid_prediction_time",
    "pixel_mse",
)


#: Metrics where higher is better; a diverged run gets 0 for them instead of inf.
HIGHER_IS_BETTER = ("valid_prediction_time",)


def worst(metric: str) -> dict[str, float]:
    """The value recorded for ``metric`` when the run diverged: ``inf`` for errors,
    ``0`` for metrics where higher is better (a diverged model predicts nothing)."""
    return {"mean": 0.0 if metric in HIGHER_IS_BETTER else float("inf"), "sem": float("nan")}


@dataclass
class LinearProbe:
    """Affine least-squares map from model latents ``(N, k)`` to states ``(N, 2n)``."""

    weight: np.ndarray
    bias: np.ndarray

    @classmethod
    def fit(cls, latents: np.ndarray, states: np.ndarray) -> LinearProbe:
        design = np.concatenate([latents, np.ones((latents.shape[0], 1))], axis=1)
        coef, *_ = np.linalg.lstsq(design, states, rcond=None)
        return cls(weight=coef[:-1], bias=coef[-1])

    def __call__(self, latents: np.ndarray) -> np.ndarray:
        return latents @ self.weight + self.bias


@dataclass
class Evaluation:
    """Metrics (``{name: {"mean", "sem"}}``), divergence, and arrays for figures."""

    metrics: dict[str, dict[str, float]]
    diverged: Optional[str] = None
    arrays: dict[str, np.ndarray] = field(default_factory=dict)


def loss_metrics(system: System, model: Model, data: Dataset) -> dict[str, dict[str, float]]:
    """train_loss / test_loss with their standard error over points.

    State systems: the MSE of predicted vs target dx/dt. Observation (pixel) systems:
    the model's full training objective (``Model.loss``), as the paper reports it.
    """
    out = {}
    for split_name in ("train", "test"):
        split = getattr(data, split_name)
        if system.observation == "state":
            per_point = M.per_point_squared_error(model.time_derivative(split.x), split.dxdt)
            out[f"{split_name}_loss"] = M.summarize(per_point)
        else:
            value = float(model.loss(split.x, split.dxdt))
            out[f"{split_name}_loss"] = {"mean": value, "sem": float("nan")}
    return out


def _energies(system: System, states: np.ndarray) -> np.ndarray:
    """``(M, T)`` true energy along ``(M, T, 2n)`` states."""
    m, t, d = states.shape
    with np.errstate(all="ignore"):
        return system.energy(states.reshape(m * t, d)).reshape(m, t)


def evaluate(
    system: System, model: Model, data: Dataset, traj: Trajectories, ev: EvaluationConfig
) -> Evaluation:
    """Compute every metric of ``model`` on ``system``'s evaluation ``traj``."""
    result: dict[str, Any] = dict(loss_metrics(system, model, data))
    arrays: dict[str, np.ndarray] = {"t": traj.t, "states_true": traj.states}
    pixels = traj.observations is not None

    if pixels:
        assert traj.observations is not None
        z0 = model.encode(traj.observations[:, 0])
        probe = LinearProbe.fit(model.encode(data.train.x), data.train.extras["state"])
    else:
        z0 = traj.x0
        probe = None

    diverged: Optional[str] = None
    try:
        z_hat = model.rollout(z0, traj.t, rtol=ev.rtol, atol=ev.atol)
        if not np.all(np.isfinite(z_hat)):
            raise RolloutDiverged("rollout produced non-finite states")
    except RolloutDiverged as err:
        diverged = f"rollout diverged: {err}"
        for key in ROLLOUT_METRICS:
            result[key] = worst(key)
        if not system.time_reversible:
            result["time_reversal_error"] = {"mean": float("nan"), "sem": float("nan")}
        return Evaluation(metrics=result, diverged=diverged, arrays=arrays)

    m, t_len, _ = z_hat.shape
    states_hat = probe(z_hat.reshape(m * t_len, -1)).reshape(m, t_len, -1) if probe else z_hat
    e_true, e_hat = _energies(system, traj.states), _energies(system, states_hat)
    result["energy_mse"] = M.summarize(M.energy_error_per_traj(e_hat, e_true))
    result["rollout_mse"] = M.summarize(M.rollout_error_per_traj(states_hat, traj.states))
    result["valid_prediction_time"] = M.summarize(
        M.valid_prediction_time(states_hat, traj.states, traj.t, ev.vpt_threshold)
    )
    arrays.update(states_hat=states_hat, energy_true=e_true, energy_hat=e_hat)
    learned = model.energy(z_hat.reshape(m * t_len, -1))
    if learned is not None:
        arrays["learned_energy"] = np.asarray(learned).reshape(m, t_len)
    if pixels:
        assert traj.observations is not None
        decoded = model.decode(z_hat.reshape(m * t_len, -1))
        if decoded is not None:
            obs = traj.observations.reshape(m * t_len, -1)
            per_traj = np.mean(((decoded - obs) ** 2).reshape(m, -1), axis=1)
            result["pixel_mse"] = M.summarize(per_traj)

    # Reversibility: fixed-step RK4 forward over the horizon at the data's dt, then back.
    horizon = float(traj.t[-1] - traj.t[0])
    n_steps = max(1, int(round(horizon / traj.dt)))
    dt = horizon / n_steps
    forward = rk4(model.time_derivative, z0, dt, n_steps)
    back = rk4(model.time_derivative, forward, -dt, n_steps)
    result["reversibility_error"] = M.summarize(M.reversibility_per_traj(back, z0))

    # Time reversal R o Phi_T o R o Phi_T, where the system is reversible (state space).
    if system.time_reversible and not pixels:
        # Only the end state is used, but the grid is the evaluation grid: adaptive solvers
        # choose their steps independently of the output times, and a JAX model then
        # compiles one rollout for both uses instead of two.
        t_grid = traj.t
        try:
            end = model.rollout(z0, t_grid, rtol=ev.rtol, atol=ev.atol)[:, -1]
            again = model.rollout(system.reverse(end), t_grid, rtol=ev.rtol, atol=ev.atol)
            returned = system.reverse(again[:, -1])
            result["time_reversal_error"] = M.summarize(M.reversibility_per_traj(returned, z0))
        except RolloutDiverged as err:
            diverged = f"time-reversal rollout diverged: {err}"
            result["time_reversal_error"] = worst("time_reversal_error")
    else:
        result["time_reversal_error"] = {"mean": float("nan"), "sem": float("nan")}

    for key in ROLLOUT_METRICS:
        value = result.get(key, {}).get("mean")
        if value is not None and np.isinf(value) and diverged is None:
            diverged = f"{key} is not finite"
    return Evaluation(metrics=result, diverged=diverged, arrays=arrays)
