"""Measured double pendulum of Schmidt & Lipson (2009).

Data file: ``real_double_pend_h_1.txt`` from the supplement of M. Schmidt and H. Lipson,
"Distilling free-form natural laws from experimental data", Science 324:81 (2009).
Header ``% o1 o2 w1 w2``, then 1520 rows of 10 columns (CRLF line endings)::

    trial, t [s], θ1, θ2 [rad], ω1, ω2 [rad/s], ω1, ω2 (repeated), α1, α2 [rad/s²]

in two trials (0: 819 rows, t = 0-8.86 s; 1: 701 rows, t = 23.19-31.63 s), sampled at
dt = 0.01 s with dropped frames (85 gaps of 0.02-0.19 s). θ1 and θ2 are each rod's
angle from the downward vertical (not the angle between the rods: fitting the
equations of motion both ways leaves relative residuals of 25-27% with absolute angles
and 86-87% with relative ones), unwrapped: in trial 1 both rods rotate many turns. The file is
found by :func:`hnnbench.locate` (``data_path``, ``$HNNBENCH_DATA_DIR``, the cache,
``url``, then the data set's public archive, as the measured pendulum's) and checked
against its SHA-256 (docs/DATA.md).

Protocol:

- State ``x = (q, p) = (θ1, θ2, ω1, ω2)``: the "momenta" are the measured angular
  velocities, not canonical momenta (:meth:`kinematics` is the identity). With
  ``wrap_angles`` (default) the angles of the data points are wrapped into ``[-π, π)``.
- Targets: ``dx/dt = (ω1, ω2, α1, α2)``, the file's own angular velocities and measured
  accelerations (every row is a point: no differencing, so gaps cost nothing).
- Split: by the folds of the measured pendulum (:mod:`hnnbench_plugins.systems.
  real_pendulum`): ``folds`` blocks of rows in time order, the seed's fold tests on one
  (seed 0: the last, as before), the later half of the block before it validates, rows
  within ``fold_gap_s`` of an edge on the training or validation side are dropped.
- Evaluation: the test segment is cut into ``eval_chunks`` contiguous chunks of equal
  length that cross no gap and no trial boundary; each is one trajectory (its first
  measured state the initial state, its measured states the reference). With
  ``wrap_angles``, each chunk's angles are shifted by whole turns so that its first
  state lies in ``[-π, π)``; the chunk stays continuous.
- Energy: the energy of an ideal double pendulum (point masses on massless rods) whose
  parameters ``m2/m1``, ``l2/l1``, ``g/l1`` (and two linear damping rates) are fitted by
  least squares to the measured accelerations of the whole series
  (:func:`fit_energy_model`), in units of ``m1 l1²`` (1/s²). It is the metric's model of
  the device (no model sees it), so it is one for every fold. The true vector field is
  unknown (no :meth:`vector_field`: the oracle is skipped).
- ``time_reversible = False``, ``conservative = False``: the device is damped (the
  fitted energy decays by about 3% per second).

``python -m hnnbench_plugins.systems.real_double_pendulum`` prints the figures of
docs/SYSTEMS_REAL_DOUBLE_PENDULUM.md (data checks, fitted parameters, residuals).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

import numpy as np
from scipy.optimize import least_squares

from hnnbench import (
    ConfigError,
    DataError,
    Dataset,
    Kinematics,
    Split,
    SystemConfig,
    Trajectories,
    identity_kinematics,
)
from hnnbench_plugins.systems.double_pendulum import wrap_angle
from hnnbench_plugins.systems.real_pendulum import MeasuredTableSystem, RealPendulumConfig

__all__ = [
    "COLUMNS",
    "FILENAME",
    "SHA256",
    "EnergyModel",
    "RealDoublePendulum",
    "RealDoublePendulumConfig",
    "derivative_consistency",
    "fit_energy_model",
    "predicted_accelerations",
    "wrap_angle",
]

#: The file's name in the Schmidt & Lipson data set.
FILENAME = "real_double_pend_h_1.txt"
#: SHA-256 of the published file (from the data set's SHA256SUMS).
SHA256 = "9ea97ad3b1c6b83b2762f1c84760bfd55638809436a8ece0c2dfffb96ddaec37"
#: Columns of a data row (the file repeats ω1, ω2).
COLUMNS = (
    "trial",
    "t",
    "theta1",
    "theta2",
    "omega1",
    "omega2",
    "omega1_copy",
    "omega2_copy",
    "alpha1",
    "alpha2",
)
#: Column indices of the angles, angular velocities and angular accelerations.
THETA, OMEGA, ALPHA = slice(2, 4), slice(4, 6), slice(8, 10)
#: Starting point of the energy-model fit: m2/m1, l2/l1, g/l1 [1/s²], damping rates [1/s].
FIT_START = (1.0, 1.0, 50.0, 0.0, 0.0)


@dataclass
class RealDoublePendulumConfig(RealPendulumConfig):
    """Settings: 2000 full-batch steps, weight decay 1e-5, five folds (seed 0 tests on the
    last fifth of the rows).

    The location fields (``data_path``, ``url``, ``archive_url``, ``archive_sha256``,
    ``download_timeout_s``) and the other checks are the measured pendulum's.
    """

    #: A sampling interval above this many median intervals is a gap (chunks avoid it).
    max_gap_factor: float = 1.5
    #: Number of contiguous chunks of the test segment used as evaluation trajectories.
    eval_chunks: int = 10
    #: Wrap the data points' angles into [-π, π) (and start each chunk there).
    wrap_angles: bool = True
    steps: int = 2000
    batch_size: Optional[int] = None
    weight_decay: float = 1e-5

    def data_fields(self) -> dict[str, Any]:
        """The dataset cache key: this file's hash instead of where it was found."""
        out = super().data_fields()
        out["sha256"] = SHA256
        return out

    def validate(self) -> None:
        super().validate()
        if not isinstance(self.wrap_angles, bool):
            raise ConfigError(
                f"system.wrap_angles={self.wrap_angles} is invalid: expected true or false."
            )


# --------------------------------------------------------------------------- energy model


@dataclass(frozen=True)
class EnergyModel:
    """An ideal double pendulum fitted to measured accelerations.

    Attributes:
        mass_ratio: ``m2 / m1``.
        length_ratio: ``l2 / l1``.
        g_over_l1: ``g / l1`` in 1/s².
        damping: ``(k1, k2)`` in 1/s: generalised forces ``Q1 = -k1 ω1 + k2 (ω2 - ω1)``,
            ``Q2 = -k2 (ω2 - ω1)``, per ``(m1 + m2) l1²``.
        residual_rms: ``(2,)`` RMS of predicted minus measured ``(α1, α2)`` over the fit's
            points, rad/s².
        relative_residual: ``residual_rms`` over the RMS of the measured ``(α1, α2)``.
        n_points: rows used by the fit.
    """

    mass_ratio: float
    length_ratio: float
    g_over_l1: float
    damping: tuple[float, float]
    residual_rms: tuple[float, float]
    relative_residual: tuple[float, float]
    n_points: int

    @property
    def coefficients(self) -> tuple[float, float, float, float, float]:
        """``(a, b, c, d, e)`` of ``E / (m1 l1²) = a ω1²/2 + b ω2²/2 + c ω1 ω2 cos(θ1 - θ2)
        + d (1 - cos θ1) + e (1 - cos θ2)``."""
        mu, lam, g = self.mass_ratio, self.length_ratio, self.g_over_l1
        return 1.0 + mu, mu * lam**2, mu * lam, (1.0 + mu) * g, mu * lam * g

    def energy(self, x: np.ndarray) -> np.ndarray:
        """Energy ``(...)`` of states ``(..., 4)`` = ``(θ1, θ2, ω1, ω2)``, in units of
        ``m1 l1²`` (1/s²), zero at the downward rest state."""
        x = np.asarray(x, dtype=np.float64)
        th1, th2, w1, w2 = x[..., 0], x[..., 1], x[..., 2], x[..., 3]
        a, b, c, d, e = self.coefficients
        kinetic = 0.5 * a * w1**2 + 0.5 * b * w2**2 + c * w1 * w2 * np.cos(th1 - th2)
        return kinetic + d * (1.0 - np.cos(th1)) + e * (1.0 - np.cos(th2))


def predicted_accelerations(params: np.ndarray, theta: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Angular accelerations ``(N, 2)`` of the damped ideal double pendulum.

    Args:
        params: ``(m2/m1, l2/l1, g/l1, k1, k2)`` (see :class:`EnergyModel`).
        theta, omega: ``(N, 2)`` absolute rod angles and angular velocities.

    Solves ``M(θ) α = r`` with, per ``(m1 + m2) l1²`` (``β = m2 / (m1 + m2)``,
    ``λ = l2 / l1``, ``Δ = θ1 - θ2``): ``M = [[1, β λ cos Δ], [β λ cos Δ, β λ²]]``,
    ``r1 = -β λ ω2² sin Δ - (g/l1) sin θ1 + Q1``,
    ``r2 = β λ ω1² sin Δ - β λ (g/l1) sin θ2 + Q2``.
    """
    mu, lam, g, k1, k2 = (float(v) for v in params)
    beta = mu / (1.0 + mu)
    delta = theta[:, 0] - theta[:, 1]
    w1, w2 = omega[:, 0], omega[:, 1]
    q1 = -k1 * w1 + k2 * (w2 - w1)
    q2 = -k2 * (w2 - w1)
    r1 = -beta * lam * w2**2 * np.sin(delta) - g * np.sin(theta[:, 0]) + q1
    r2 = beta * lam * w1**2 * np.sin(delta) - beta * lam * g * np.sin(theta[:, 1]) + q2
    m12 = beta * lam * np.cos(delta)
    m22 = beta * lam**2
    det = m22 - m12**2
    return np.stack([(m22 * r1 - m12 * r2) / det, (r2 - m12 * r1) / det], axis=-1)


def fit_energy_model(table: np.ndarray) -> EnergyModel:
    """Fit :func:`predicted_accelerations` to the measured ``(α1, α2)`` of ``table`` rows.

    Levenberg-Marquardt (scipy ``least_squares``, deterministic) from :data:`FIT_START`
    on the residuals divided by the RMS of each measured acceleration column (so both
    rods weigh alike). Raises DataError if it fails or gives an unphysical pendulum.
    """
    theta, omega, alpha = table[:, THETA], table[:, OMEGA], table[:, ALPHA]
    scale = np.sqrt(np.mean(alpha**2, axis=0))

    def residuals(params: np.ndarray) -> np.ndarray:
        return ((predicted_accelerations(params, theta, omega) - alpha) / scale).ravel()

    result = least_squares(residuals, np.array(FIT_START), method="lm")
    mu, lam, g = result.x[:3]
    if not (result.success and mu > 0 and lam > 0 and g > 0):
        raise DataError(
            f"The energy model of {FILENAME} did not fit (m2/m1={mu:.3g}, l2/l1={lam:.3g}, "
            f"g/l1={g:.3g}): the file is not the original; use the original file."
        )
    rms = np.sqrt(np.mean((predicted_accelerations(result.x, theta, omega) - alpha) ** 2, 0))
    return EnergyModel(
        mass_ratio=float(mu),
        length_ratio=float(lam),
        g_over_l1=float(g),
        damping=(float(result.x[3]), float(result.x[4])),
        residual_rms=(float(rms[0]), float(rms[1])),
        relative_residual=(float(rms[0] / scale[0]), float(rms[1] / scale[1])),
        n_points=int(len(table)),
    )


# --------------------------------------------------------------------------- data checks


def derivative_consistency(table: np.ndarray, max_gap_factor: float = 1.5) -> dict[str, Any]:
    """How the file's derivative columns relate to its angles, per trial.

    Returns ``omega_copy_equal`` (the repeated ω columns equal the first ones at every
    row) and, per trial, the relative RMS differences (RMS of the difference over the
    RMS of the column, for each rod) between ω and central differences of θ, and between
    α and central differences of ω, over rows whose two neighbours are gap-free samples.
    """
    out: dict[str, Any] = {"omega_copy_equal": bool(np.array_equal(table[:, OMEGA], table[:, 6:8]))}
    for trial in np.unique(table[:, 0]):
        rows = table[table[:, 0] == trial]
        t = rows[:, 1]
        steps = np.diff(t)
        ok = steps <= max_gap_factor * np.median(steps)
        mid = ok[1:] & ok[:-1]  # rows 1..n-2 with gap-free neighbours
        span = (t[2:] - t[:-2])[:, None]

        def rel(derived: np.ndarray, column: np.ndarray, mid: np.ndarray = mid) -> list[float]:
            diff = (derived - column)[mid]
            return [float(v) for v in np.sqrt(np.mean(diff**2, 0) / np.mean(column[mid] ** 2, 0))]

        theta, omega, alpha = rows[:, THETA], rows[:, OMEGA], rows[:, ALPHA]
        out[f"trial_{int(trial)}"] = {
            "rows": int(len(rows)),
            "gaps": int((~ok).sum()),
            "omega_vs_central_diff_theta": rel((theta[2:] - theta[:-2]) / span, omega[1:-1]),
            "alpha_vs_central_diff_omega": rel((omega[2:] - omega[:-2]) / span, alpha[1:-1]),
        }
    return out


# --------------------------------------------------------------------------- system


class RealDoublePendulum(MeasuredTableSystem):
    """Measured double pendulum (Schmidt & Lipson 2009), state (θ1, θ2, ω1, ω2)."""

    Config = RealDoublePendulumConfig
    data_file, data_sha256, data_columns = FILENAME, SHA256, COLUMNS
    #: The parser's messages list the repeated ω columns by their names in the file.
    data_column_labels = "trial, t, theta1, theta2, omega1, omega2, omega1, omega2, alpha1, alpha2"
    data_expected_rows = "about 1500"
    order = 100
    cfg: RealDoublePendulumConfig
    version = "2"  # 2: seeds choose folds of the series; energy model fitted to all rows
    description = "Measured double pendulum, Schmidt & Lipson 2009, state (theta1, theta2, w1, w2)"

    def __init__(self, cfg: SystemConfig) -> None:
        super().__init__(cfg)
        self._energy_model: Optional[EnergyModel] = None

    @property
    def dof(self) -> int:
        return 2

    def kinematics(self) -> Kinematics:
        """The state's "momenta" are the measured angular velocities: ``q̇ = p``."""
        return identity_kinematics()

    @property
    def angles(self) -> tuple[int, ...]:
        """Both rods' angles."""
        return (0, 1)

    @property
    def wrapped_angles(self) -> tuple[int, ...]:
        """Both rods' angles, when ``wrap_angles`` is set."""
        return (0, 1) if self.cfg.wrap_angles else ()

    def energy(self, x: np.ndarray) -> np.ndarray:
        """The fitted ideal double pendulum's energy (:meth:`energy_model`), 1/s²."""
        return self.energy_model().energy(x)

    def energy_model(self) -> EnergyModel:
        """The energy model fitted to the training segment (once per instance)."""
        if self._energy_model is None:
            s = self._structure()
            self._energy_model = fit_energy_model(s["table"])
        return self._energy_model

    # ------------------------------------------------------------------ data

    def _states(self, table: np.ndarray) -> np.ndarray:
        """``(N, 4)`` states ``(θ1, θ2, ω1, ω2)`` of table rows, angles wrapped if set."""
        states = np.concatenate([table[:, THETA], table[:, OMEGA]], axis=1)
        if self.cfg.wrap_angles:
            states[:, :2] = wrap_angle(states[:, :2])
        return states

    def dataset(self, seed: int) -> Dataset:
        """The measured states and derivatives of ``seed``'s fold (train, validation and
        test segments)."""
        s = self._structure()
        table = s["table"]
        seg = self._segments(s, seed)
        x = self._states(table)
        dxdt = np.concatenate([table[:, OMEGA], table[:, ALPHA]], axis=1)

        def split(code: int) -> Split:
            rows = np.flatnonzero(seg["role"] == code)
            return Split(
                x=x[rows].copy(),
                dxdt=dxdt[rows].copy(),
                traj=table[rows, 0].astype(np.int64),
                t=table[rows, 1].copy(),
            )

        train, valid, test = split(0), split(1), split(2)
        return Dataset(
            train=train,
            test=test,
            valid=valid,
            meta={
                "data_file": str(s["path"]),
                "sha256": SHA256,
                "n_rows": s["n_rows"],
                "dt": s["dt"],
                "state": "(q, p) = (theta1, theta2, omega1, omega2), measured angular "
                "velocities (not canonical momenta)",
                "targets": "(omega1, omega2, alpha1, alpha2) from the file",
                "wrap_angles": self.cfg.wrap_angles,
                "fold": seg["fold"],
                "folds": self.cfg.folds,
                "validation": seg["rule"],
                "test_rows": list(seg["test"]),
                "valid_rows": list(seg["valid"]),
                "n_train": len(train),
                "n_valid": len(valid),
                "n_test": len(test),
                "n_gaps": int(s["gap"].sum()),
                "n_dropped_at_edges": int((seg["role"] == -1).sum()),
            },
        )

    def evaluation(self, seed: int) -> Trajectories:
        """``eval_chunks`` gap-free chunks of ``seed``'s measured test segment."""
        s = self._structure()
        starts, length, grid = self._chunks(s, seed)
        table = s["table"]
        states = np.stack(
            [
                np.concatenate([table[b : b + length, THETA], table[b : b + length, OMEGA]], 1)
                for b in starts
            ]
        )  # (n_chunks, length, 4), unwrapped
        if self.cfg.wrap_angles:
            first = states[:, :1, :2]
            states[:, :, :2] -= first - wrap_angle(first)  # whole turns per chunk and rod
        meta = {**grid["meta"], "wrap_angles": self.cfg.wrap_angles}
        return Trajectories(t=grid["t"], states=states, dt=s["dt"], meta=meta)


def _main() -> None:
    """Print the data checks and the energy model of docs/SYSTEMS_REAL_DOUBLE_PENDULUM.md."""
    import json

    cfg = RealDoublePendulumConfig(name="real_double_pendulum")
    system = RealDoublePendulum(cfg)
    s = system._structure()
    table = s["table"]
    start, stop = system._segments(s, 0)["test"]
    model = system.energy_model()
    test = table[start:stop]
    test_rms = np.sqrt(
        np.mean(
            (
                predicted_accelerations(
                    np.array(
                        [model.mass_ratio, model.length_ratio, model.g_over_l1, *model.damping]
                    ),
                    test[:, THETA],
                    test[:, OMEGA],
                )
                - test[:, ALPHA]
            )
            ** 2,
            0,
        )
        / np.mean(test[:, ALPHA] ** 2, 0)
    )
    energy, ranges = {}, {}
    for trial in np.unique(table[:, 0]):
        rows = table[table[:, 0] == trial]
        e = model.energy(np.concatenate([rows[:, THETA], rows[:, OMEGA]], 1))
        slope = np.polyfit(rows[:, 1] - rows[0, 1], np.log(e), 1)[0]
        ranges[f"trial_{int(trial)}"] = {
            "theta1": [float(rows[:, 2].min()), float(rows[:, 2].max())],
            "theta2": [float(rows[:, 3].min()), float(rows[:, 3].max())],
            "max_abs_omega": [float(v) for v in np.abs(rows[:, OMEGA]).max(0)],
            "t": [float(rows[0, 1]), float(rows[-1, 1])],
        }
        energy[f"trial_{int(trial)}"] = {
            "mean": float(e.mean()),
            "min": float(e.min()),
            "max": float(e.max()),
            "first_20_mean": float(e[:20].mean()),
            "last_20_mean": float(e[-20:].mean()),
            "log_slope_per_s": float(slope),
        }
    traj = system.evaluation(0)
    report = {
        "structure": {
            "rows": s["n_rows"],
            "dt": s["dt"],
            "gaps": int(s["gap"].sum()),
            "test_rows": [start, stop],
            "split_time": float(table[start, 1]),
        },
        "ranges": ranges,
        "derivatives": derivative_consistency(table, cfg.max_gap_factor),
        "energy_model": {
            **model.__dict__,
            "coefficients": model.coefficients,
            "test_relative_residual": list(test_rms),
        },
        "energy_along_trials": energy,
        "evaluation": {
            k: traj.meta[k]
            for k in (
                "n_traj",
                "chunk_points",
                "horizon",
                "chunk_start_times",
                "unused_test_rows",
                "max_grid_deviation",
            )
        },
        "evaluation_states_beyond_pi": float(np.mean(np.abs(traj.states[..., :2]) > np.pi)),
        "stand_still": stand_still_scores(system),
    }
    print(json.dumps(report, indent=1, default=float))


def stand_still_scores(system: RealDoublePendulum, seed: int = 0) -> dict[str, float]:
    """The rollout and energy MSE of a "model" that predicts no motion, ``x̂(t) = x(0)``,
    on the evaluation chunks: the floor a learned rollout must beat to show that it
    predicts anything (the chunks are short)."""
    from hnnbench_plugins.metrics import energy_error_per_traj, rollout_error_per_traj

    states = system.evaluation(seed).states  # (M, T, 4)
    still = np.repeat(states[:, :1], states.shape[1], axis=1)
    energy = system.energy(states.reshape(-1, 4)).reshape(states.shape[:2])
    energy_still = system.energy(still.reshape(-1, 4)).reshape(states.shape[:2])
    return {
        "rollout_mse": float(rollout_error_per_traj(still, states).mean()),
        "energy_mse": float(energy_error_per_traj(energy_still, energy).mean()),
    }


if __name__ == "__main__":
    _main()
