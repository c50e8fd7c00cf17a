"""hnnbench's own metrics: pure-numpy definitions and their :class:`Metric`
declarations.

The first half holds one numpy function per definition: per-trajectory functions
return one value per evaluation trajectory, shape ``(M,)``, and :func:`summarize` turns
those into the mean and its standard error. The second half declares each built-in
metric (:class:`hnnbench.Metric`): how it is computed from an
:class:`~hnnbench.EvalContext`, where it applies, which way is better, and its
regression tolerance. They are registered through the entry-point group
``hnnbench.metrics`` in hnnbench's pyproject.toml, as a third party's would be.
docs/METRICS.md gives the precise definitions and the evaluation protocol.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from hnnbench import CheckRule, Metric, per_point_squared_error, sem, summarize

if TYPE_CHECKING:
    from hnnbench import EvalContext, System

__all__ = [
    "BUILTIN",
    "ENERGY_DRIFT_LONG",
    "ENERGY_MSE",
    "LONG_HORIZON_FACTOR",
    "PIXEL_MSE",
    "REVERSIBILITY_ERROR",
    "ROLLOUT_MSE",
    "ROLLOUT_SKILL",
    "TEST_LOSS",
    "TRAIN_LOSS",
    "VAL_LOSS",
    "VALID_PREDICTION_TIME",
    "VPT_CENSORED",
    "VPT_LYAPUNOV",
    "energy_drift_per_traj",
    "energy_error_per_traj",
    "mse",
    "per_point_squared_error",
    "reversibility_per_traj",
    "rollout_error_per_traj",
    "rollout_skill_per_traj",
    "sem",
    "state_difference",
    "summarize",
    "valid_prediction_time",
]


def mse(pred: np.ndarray, target: np.ndarray) -> float:
    """Mean squared error over all points and coordinates."""
    return float(np.mean((np.asarray(pred) - np.asarray(target)) ** 2))


def energy_error_per_traj(energy_hat: np.ndarray, energy_true: np.ndarray) -> np.ndarray:
    """``(M,)`` time-mean of ``(E(x_hat(t)) - E(x(t)))^2`` for ``(M, T)`` energies."""
    return np.mean((np.asarray(energy_hat) - np.asarray(energy_true)) ** 2, axis=1)


def state_difference(
    x_hat: np.ndarray, x_true: np.ndarray, angles: tuple[int, ...] = ()
) -> np.ndarray:
    """``x_hat - x_true`` (any shape ``(..., D)``), with the columns ``angles`` (the
    system's angle positions, :attr:`hnnbench.System.angles`) taken modulo 2π into
    ``[-π, π)``: an angle off by a whole turn is the same configuration, not an error
    of 2π."""
    diff = np.asarray(x_hat, dtype=np.float64) - np.asarray(x_true, dtype=np.float64)
    if angles:
        cols = list(angles)
        with np.errstate(invalid="ignore"):
            diff[..., cols] = diff[..., cols] - 2.0 * np.pi * np.floor(
                (diff[..., cols] + np.pi) / (2.0 * np.pi)
            )
    return diff


def rollout_error_per_traj(
    x_hat: np.ndarray, x_true: np.ndarray, angles: tuple[int, ...] = ()
) -> np.ndarray:
    """``(M,)`` mean over time and coordinates of ``(x_hat - x)^2`` for ``(M, T, D)``,
    angle differences modulo 2π (:func:`state_difference`)."""
    return np.mean(state_difference(x_hat, x_true, angles) ** 2, axis=(1, 2))


def rollout_skill_per_traj(
    x_hat: np.ndarray, x_true: np.ndarray, angles: tuple[int, ...] = ()
) -> np.ndarray:
    """``(M,)`` skill of a rollout over standing still: ``1 - e / e_static``, with ``e``
    the rollout's mean squared state error (:func:`rollout_error_per_traj`) and
    ``e_static`` that of holding each trajectory's initial state. 1: exact; 0: no better
    than not moving; negative: worse. A trajectory that does not move itself
    (``e_static == 0``) scores 1 if the rollout is exact there, else ``-inf``."""
    x_true = np.asarray(x_true, dtype=np.float64)
    err = rollout_error_per_traj(x_hat, x_true, angles)
    static = rollout_error_per_traj(np.broadcast_to(x_true[:, :1], x_true.shape), x_true, angles)
    with np.errstate(divide="ignore", invalid="ignore"):
        skill = 1.0 - err / static
    still = static == 0
    skill[still] = np.where(err[still] == 0, 1.0, -np.inf)
    skill[~np.isfinite(err)] = -np.inf
    return skill


def reversibility_per_traj(x_back: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """``(M,)`` squared distance ``||x_back - x0||^2`` for ``(M, D)`` states."""
    return np.sum((np.asarray(x_back) - np.asarray(x0)) ** 2, axis=1)


def valid_prediction_time(
    x_hat: np.ndarray,
    x_true: np.ndarray,
    t: np.ndarray,
    threshold: float = 0.1,
    angles: tuple[int, ...] = (),
) -> np.ndarray:
    """``(M,)`` time until the relative error first exceeds ``threshold``.

    The relative error at time ``t_k`` is ``||x_hat - x|| / ||x||``, with the columns
    ``angles`` compared modulo 2π (:func:`state_difference`) and taken in ``[-π, π)`` in
    the norm of ``x`` (an angle that has turned over several times does not inflate the
    scale). The valid prediction time is the last grid time before the first
    exceedance, measured from ``t[0]``; the whole horizon if it never exceeds (then it
    is censored: ``vpt_censored``). Non-finite errors count as exceedances.
    """
    t = np.asarray(t, dtype=np.float64)
    err = np.linalg.norm(state_difference(x_hat, x_true, angles), axis=-1)
    reference = state_difference(x_true, np.zeros_like(x_true), angles)
    scale = np.maximum(np.linalg.norm(reference, axis=-1), 1e-12)
    bad = ~(err / scale <= threshold)  # (M, T); NaN counts as bad
    out = np.empty(bad.shape[0])
    for i, row in enumerate(bad):
        hits = np.flatnonzero(row)
        if hits.size == 0:
            out[i] = t[-1] - t[0]
        else:
            out[i] = t[max(hits[0] - 1, 0)] - t[0] if hits[0] > 0 else 0.0
    return out


def energy_drift_per_traj(energy_end: np.ndarray, energy_start: np.ndarray) -> np.ndarray:
    """``(M,)`` relative drift ``|E_end - E_start| / |E_start|``."""
    start = np.asarray(energy_start, dtype=np.float64)
    return np.abs(np.asarray(energy_end) - start) / np.maximum(np.abs(start), 1e-300)


# --------------------------------------------------------------------------- declarations

#: The domain of every metric here: squared errors, relative drifts and times are >= 0.
NONNEGATIVE = (0.0, math.inf)

#: The long-horizon metric rolls out over this many evaluation horizons.
LONG_HORIZON_FACTOR = 10


def _loss(split: str, clean: bool = False) -> Any:
    def compute(ctx: EvalContext) -> Any:
        return ctx.loss_values(split, clean=clean)

    return compute


def _valid_loss(ctx: EvalContext) -> Any:
    """``None`` (undefined) for a dataset without a validation split (a model evaluated
    outside a job)."""
    return None if ctx.data.valid is None else ctx.loss_values("valid", clean=True)


def _energy_mse(ctx: EvalContext) -> np.ndarray:
    return energy_error_per_traj(ctx.energy_hat(), ctx.energy_true())


def _rollout_mse(ctx: EvalContext) -> np.ndarray:
    return rollout_error_per_traj(ctx.states_hat(), ctx.traj.states, ctx.system.angles)


def _rollout_skill(ctx: EvalContext) -> np.ndarray:
    return rollout_skill_per_traj(ctx.states_hat(), ctx.traj.states, ctx.system.angles)


def _vpt(ctx: EvalContext) -> np.ndarray:
    return valid_prediction_time(
        ctx.states_hat(), ctx.traj.states, ctx.traj.t, ctx.cfg.vpt_threshold, ctx.system.angles
    )


def _vpt_censored(ctx: EvalContext) -> Any:
    """The share of evaluation trajectories whose valid prediction time is the whole
    horizon (the rollout never left the threshold): there VPT is censored, a lower bound."""
    horizon = float(ctx.traj.t[-1] - ctx.traj.t[0])
    return {"mean": float(np.mean(_vpt(ctx) >= horizon)), "sem": math.nan}


def _vpt_lyapunov(ctx: EvalContext) -> np.ndarray:
    lyapunov = ctx.system.lyapunov_time
    assert lyapunov is not None
    return _vpt(ctx) / float(lyapunov)


def _reversibility(ctx: EvalContext) -> np.ndarray:
    """``R Φ_T R Φ_T z0`` against ``z0``: the main rollout's end state, reversed, rolled
    out over the same grid (so one compiled solve serves both), reversed again."""
    z0 = ctx.z0()
    end = ctx.rollout()[:, -1]
    again = ctx.roll(ctx.reverse(end), ctx.traj.t)
    return reversibility_per_traj(ctx.reverse(again[:, -1]), z0)


def _energy_drift_long(ctx: EvalContext) -> np.ndarray:
    t = ctx.traj.t
    long_t = t[0] + LONG_HORIZON_FACTOR * (t - t[0])  # same grid length: no new compile
    end = ctx.to_states(ctx.roll(ctx.z0(), long_t)[:, -1])
    with np.errstate(all="ignore"):
        e_end = ctx.system.energy(end)
    return energy_drift_per_traj(e_end, ctx.energy_true()[:, 0])


def _pixel_mse(ctx: EvalContext) -> Optional[np.ndarray]:
    return ctx.pixel_errors()


def _has_lyapunov_time(system: System) -> bool:
    return system.lyapunov_time is not None


def _time_reversible(system: System) -> bool:
    return bool(system.time_reversible)


def _conservative(system: System) -> bool:
    return bool(system.conservative)


def _pixels(system: System) -> bool:
    return system.observation == "pixels"


TRAIN_LOSS = Metric(
    "train_loss",
    "MSE of predicted vs target dx/dt on the training set, at the inputs "
    "the model trained on (noise included; pixels: the training objective). The zero "
    "field scores the mean squared target",
    _loss("train"),
    check=CheckRule(2, 1e-12),
    order=10,
    errors_fail_job=True,
    domain=NONNEGATIVE,
)
VAL_LOSS = Metric(
    "val_loss",
    "MSE of predicted vs target dx/dt on the validation set, carved from the "
    "training data, at the clean inputs where the system adds noise (pixels: the training "
    "objective); on every simulated state system the checkpoint selection criterion "
    "(selection.criterion) at the scored checkpoint. The zero field scores the mean "
    "squared target",
    _valid_loss,
    check=CheckRule(2, 1e-12),
    order=15,
    errors_fail_job=True,
    domain=NONNEGATIVE,
    selects=True,
)
TEST_LOSS = Metric(
    "test_loss",
    "MSE of predicted vs target dx/dt on the test set, at the clean inputs "
    "where the system adds noise to them (so the true field scores 0, not the noise "
    "floor; pixels: the training objective). The zero field scores the mean squared "
    "target",
    _loss("test", clean=True),
    check=CheckRule(2, 1e-12),
    order=20,
    figures=("data_efficiency",),
    log=True,
    headline=True,
    errors_fail_job=True,
    domain=NONNEGATIVE,
)
ENERGY_MSE = Metric(
    "energy_mse",
    "Mean squared error of the true energy along the model's rollout vs "
    "along the true trajectory. A model that does not move (the zero field) scores the "
    "true trajectory's own energy change: 0 on conservative systems, so it is marked "
    "best only among rollouts that beat standing still (rollout_skill > 0)",
    _energy_mse,
    check=CheckRule(10, 1e-10),
    order=30,
    figures=("heatmap", "data_efficiency"),
    log=True,
    headline=True,
    errors_fail_job=True,
    domain=NONNEGATIVE,
    best_requires=("rollout_skill", 0.0),
)
ROLLOUT_MSE = Metric(
    "rollout_mse",
    "Mean squared state error along the rollout (angles modulo 2 pi). The "
    "zero field scores the mean squared displacement of the true trajectory from its "
    "start",
    _rollout_mse,
    check=CheckRule(3, 1e-8),
    order=40,
    figures=("heatmap", "data_efficiency"),
    errors_fail_job=True,
    beat_reference=True,
    evidence="rollout",
    domain=NONNEGATIVE,
    headline=True,
)
ROLLOUT_SKILL = Metric(
    "rollout_skill",
    "Skill of the rollout over standing still: 1 - rollout error / the "
    "error of holding the initial state, per trajectory (angles modulo 2 pi). 1: exact; "
    "0: the zero field (no motion); negative: worse than not moving",
    _rollout_skill,
    better="higher",
    scale="linear",
    check=CheckRule(3, 0.0),
    order=45,
    errors_fail_job=True,
    beat_reference=True,
    evidence="rollout",
    domain=(-math.inf, 1.0),
)
REVERSIBILITY_ERROR = Metric(
    "reversibility_error",
    "Time-reversal test of the learned flow: mean |R Phi_T R Phi_T "
    "x0 - x0|^2 (R flips momenta; pixels: latent momenta). A diagnostic, never marked "
    "best: the zero field (no motion) scores exactly 0",
    _reversibility,
    check=CheckRule(10, 1e-10),
    applies=_time_reversible,
    order=50,
    ranked=False,
    errors_fail_job=True,
    domain=NONNEGATIVE,
)
VALID_PREDICTION_TIME = Metric(
    "valid_prediction_time",
    "Time until the rollout's relative state error first exceeds "
    "evaluation.vpt_threshold (angles modulo 2 pi, also in the state's norm); capped at "
    "the horizon (vpt_censored says how often). The zero field scores the time the true "
    "state takes to move threshold x its norm from its start",
    _vpt,
    better="higher",
    scale="linear",
    check=CheckRule(3, 0.0),
    order=60,
    errors_fail_job=True,
    beat_reference=True,
    evidence="rollout",
    domain=NONNEGATIVE,
    within_horizon=True,
)
VPT_CENSORED = Metric(
    "vpt_censored",
    "Share of evaluation trajectories whose valid prediction time reached "
    "the horizon (there it is a lower bound; the horizon caps valid_prediction_time). A "
    "diagnostic, never marked best",
    _vpt_censored,
    better="higher",
    scale="linear",
    # A share of a handful of trajectories moves in steps of 1/M: as a ratio, 0 against
    # one trajectory in 15 is infinitely apart. Shares below 0.25 count as 0.25, so the
    # check fails only when one run censors most trajectories and the other almost none.
    check=CheckRule(3, 0.25),
    order=65,
    ranked=False,
    domain=(0.0, 1.0),
)
VPT_LYAPUNOV = Metric(
    "vpt_lyapunov",
    "Valid prediction time in Lyapunov times (chaotic systems); as "
    "valid_prediction_time for a degenerate model",
    _vpt_lyapunov,
    better="higher",
    scale="linear",
    check=CheckRule(3, 0.0),
    applies=_has_lyapunov_time,
    order=70,
    errors_fail_job=True,
    beat_reference=True,
    evidence="rollout",
    domain=NONNEGATIVE,
)
ENERGY_DRIFT_LONG = Metric(
    "energy_drift_long",
    f"Relative true-energy drift at the end of a rollout "
    f"{LONG_HORIZON_FACTOR}x the evaluation horizon (conservative systems). The zero "
    "field scores 0, so it is marked best only among rollouts that beat standing still "
    "(rollout_skill > 0)",
    _energy_drift_long,
    check=CheckRule(10, 1e-10),
    applies=_conservative,
    required=False,
    order=80,
    domain=NONNEGATIVE,
    best_requires=("rollout_skill", 0.0),
)
PIXEL_MSE = Metric(
    "pixel_mse",
    "MSE of the decoded latent rollout against the true frames. A decoder "
    "of the mean frame scores the frames' variance",
    _pixel_mse,
    check=CheckRule(2, 1e-12),
    applies=_pixels,
    summary=False,
    order=90,
    errors_fail_job=True,
    domain=NONNEGATIVE,
)

#: hnnbench's own metrics, in table order (registered by entry points, not from here).
BUILTIN = (
    TRAIN_LOSS,
    VAL_LOSS,
    TEST_LOSS,
    ENERGY_MSE,
    ROLLOUT_MSE,
    ROLLOUT_SKILL,
    REVERSIBILITY_ERROR,
    VALID_PREDICTION_TIME,
    VPT_CENSORED,
    VPT_LYAPUNOV,
    ENERGY_DRIFT_LONG,
    PIXEL_MSE,
)
