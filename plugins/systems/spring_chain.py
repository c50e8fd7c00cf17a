"""A chain of N unit masses joined by unit springs between two fixed walls.

State layout (``dof = N``, a state has ``2N`` numbers): ``x = (q_1..q_N, p_1..p_N)``,
the displacements of the masses from their rest positions and their momenta (unit
masses: the velocities). With the walls at ``q_0 = q_{N+1} = 0``,

    H = Σ_i p_i² / 2 + Σ_{i=0..N} (q_{i+1} - q_i)² / 2,

    dq_i/dt = p_i,     dp_i/dt = q_{i-1} - 2 q_i + q_{i+1}.

The dynamics are linear, ``dx/dt = A x`` with ``A = [[0, I], [-K, 0]]`` and ``K`` the
tridiagonal matrix (2 on the diagonal, -1 beside it), so the motion is a sum of N
normal modes of angular frequencies ``ω_k = 2 sin(k π / (2 (N + 1)))``, ``k = 1..N``
(``A``'s eigenvalues are ``± i ω_k``). With N = 5 the periods run from 12.1 (k = 1) to
3.25 (k = 5) time units.

Data: ``n_traj`` trajectories of ``n_points`` samples over ``[0, t_end]`` (DOP853, rtol =
atol = ``data_rtol``). Each initial state is a direction uniform on the unit sphere of
the 2N-dimensional state space scaled to a radius ``|x| ~ U[radius_min, radius_max]``.
The dx/dt targets are the exact field at the clean states; Gaussian noise of std
``noise_std`` (default 0) is added to the inputs. The first ``1 - test_split`` of the
trajectories train, the LAST ``round(n_traj * test_split)`` test
(:meth:`SpringChainConfig.trajectory_split`). Evaluation: ``eval_n_traj`` fresh trajectories from
the same distribution (their own seed stream) over ``[0, eval_t_end]``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Optional

import numpy as np

from hnnbench import (
    DATA_STREAM,
    EVAL_STREAM,
    ConfigError,
    Dataset,
    Kinematics,
    System,
    SystemConfig,
    Trajectories,
    TrajectorySplit,
    check_fraction,
    check_int_at_least,
    check_ordered,
    check_positive,
    identity_kinematics,
    seed_stream,
    solve_batch,
    trajectory_dataset,
)

__all__ = [
    "SpringChain",
    "SpringChainConfig",
    "hamiltonian",
    "mode_frequencies",
    "stiffness_matrix",
    "vector_field",
]


# --------------------------------------------------------------------------- physics


def _split(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(..., 2N)`` states -> ``q``, ``p``, each ``(..., N)``."""
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[-1] // 2
    return x[..., :n], x[..., n:]


def _with_walls(q: np.ndarray) -> np.ndarray:
    """``(..., N)`` displacements -> ``(..., N + 2)`` with the fixed walls' zeros."""
    pad = [(0, 0)] * (q.ndim - 1) + [(1, 1)]
    return np.pad(q, pad)


def hamiltonian(x: np.ndarray) -> np.ndarray:
    """``H`` of states ``(..., 2N)``, shape ``(...)``."""
    q, p = _split(x)
    stretch = np.diff(_with_walls(q), axis=-1)  # (..., N + 1): q_{i+1} - q_i, i = 0..N
    return 0.5 * np.sum(p**2, axis=-1) + 0.5 * np.sum(stretch**2, axis=-1)


def vector_field(x: np.ndarray) -> np.ndarray:
    """``dx/dt = (p, q_{i-1} - 2 q_i + q_{i+1})`` of states ``(..., 2N)``, same shape."""
    q, p = _split(x)
    walls = _with_walls(q)
    force = walls[..., :-2] - 2.0 * q + walls[..., 2:]
    return np.concatenate([p, force], axis=-1)


def stiffness_matrix(n_masses: int) -> np.ndarray:
    """``K`` ``(N, N)``: ``H = pᵀp / 2 + qᵀ K q / 2`` (2 on the diagonal, -1 beside it)."""
    return 2.0 * np.eye(n_masses) - np.eye(n_masses, k=1) - np.eye(n_masses, k=-1)


def mode_frequencies(n_masses: int) -> np.ndarray:
    """Normal-mode angular frequencies ``ω_k = 2 sin(k π / (2 (N + 1)))``, ``(N,)``,
    ascending."""
    k = np.arange(1, n_masses + 1)
    return 2.0 * np.sin(k * np.pi / (2.0 * (n_masses + 1)))


# --------------------------------------------------------------------------- config


@dataclass
class SpringChainConfig(SystemConfig):
    """Data and evaluation protocol of the chain (dimensionless units)."""

    #: Number of moving masses N (the state has 2N numbers).
    n_masses: int = 5
    n_traj: int = 100
    t_end: float = 10.0
    n_points: int = 51
    #: Range of the initial states' Euclidean norm |(q, p)|.
    radius_min: float = 0.5
    radius_max: float = 1.5
    #: Gaussian noise added to the model inputs (targets stay clean).
    noise_std: float = 0.0
    #: Fraction of the trajectories (the last ones) held out as the test set.
    test_split: float = 0.2
    data_rtol: float = 1e-12
    eval_n_traj: int = 15
    eval_t_end: float = 50.0
    eval_n_points: int = 251
    eval_rtol: float = 1e-12
    steps: int = 3000
    batch_size: Optional[int] = 500
    lr: float = 1e-3
    weight_decay: float = 0.0

    def validate(self) -> None:
        super().validate()
        check_int_at_least("system", 1, n_masses=self.n_masses)
        check_positive(
            "system",
            t_end=self.t_end,
            radius_min=self.radius_min,
            data_rtol=self.data_rtol,
            eval_t_end=self.eval_t_end,
            eval_rtol=self.eval_rtol,
        )
        check_ordered("system", "radius_min", self.radius_min, "radius_max", self.radius_max)
        check_int_at_least(
            "system",
            2,
            n_traj=self.n_traj,
            n_points=self.n_points,
            eval_n_traj=self.eval_n_traj,
            eval_n_points=self.eval_n_points,
        )
        check_fraction("system", "test_split", self.test_split, 0.2)
        if not self.noise_std >= 0:
            raise ConfigError(
                f"system.noise_std={self.noise_std} is invalid: expected a number >= 0. "
                "Fix it with system.noise_std=0 or another non-negative value."
            )
        self.trajectory_split().check(self.n_traj)

    def trajectory_split(self) -> TrajectorySplit:
        """The LAST ``round(n_traj * test_split)`` trajectories test, the rest train."""
        return TrajectorySplit(self.test_split, test_from="last")


# --------------------------------------------------------------------------- system


class SpringChain(System):
    """N unit masses, nearest-neighbour unit springs, fixed walls at both ends."""

    order = 110

    Config: ClassVar[type[SystemConfig]] = SpringChainConfig
    cfg: SpringChainConfig
    version = "1"
    description = "Chain of N unit masses, unit springs, fixed walls (N = 5 by default: 10-D state)"
    time_reversible = True
    conservative = True
    profiles: ClassVar[dict[str, dict[str, Any]]] = {
        "quick": {
            "n_traj": 20,
            "steps": 300,
            "eval_n_traj": 5,
            "eval_t_end": 10.0,
            "eval_n_points": 51,
        }
    }

    @property
    def dof(self) -> int:
        return int(self.cfg.n_masses)

    def energy(self, x: np.ndarray) -> np.ndarray:
        return hamiltonian(x)

    def vector_field(self, x: np.ndarray) -> np.ndarray:
        return vector_field(x)

    def kinematics(self) -> Kinematics:
        """Unit masses: ``q̇ = p``."""
        return identity_kinematics()

    def initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``(n, 2N)`` states: uniform directions, norms U[radius_min, radius_max]."""
        direction = rng.standard_normal((n, 2 * self.dof))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        radius = rng.uniform(self.cfg.radius_min, self.cfg.radius_max, size=(n, 1))
        return direction * radius

    @property
    def data_dt(self) -> float:
        """Sampling interval of the training data."""
        return float(self.cfg.t_end) / (self.cfg.n_points - 1)

    def dataset(self, seed: int) -> Dataset:
        c = self.cfg
        rng = seed_stream(seed, DATA_STREAM)  # initial states, then the noise
        t = np.linspace(0.0, c.t_end, c.n_points)
        clean = solve_batch(
            self.vector_field,
            self.initial_states(rng, c.n_traj),
            t,
            rtol=c.data_rtol,
            atol=c.data_rtol,
        )  # (n_traj, T, 2N)
        dxdt = self.vector_field(clean)
        x = clean
        if c.noise_std > 0:
            x = clean + rng.normal(0.0, c.noise_std, size=clean.shape)
        split = c.trajectory_split()
        n_train, n_test = split.sizes(c.n_traj)
        return trajectory_dataset(
            x,
            dxdt,
            t,
            split,
            meta={
                "dt": self.data_dt,
                "n_masses": self.dof,
                "n_train_traj": n_train,
                "n_test_traj": n_test,
                "reference": "DOP853",
                "rtol": c.data_rtol,
            },
        )

    def evaluation(self, seed: int) -> Trajectories:
        c = self.cfg
        rng = seed_stream(seed, EVAL_STREAM)
        t = np.linspace(0.0, c.eval_t_end, c.eval_n_points)
        states = solve_batch(
            self.vector_field,
            self.initial_states(rng, c.eval_n_traj),
            t,
            rtol=c.eval_rtol,
            atol=c.eval_rtol,
        )
        return Trajectories(
            t=t,
            states=states,
            dt=self.data_dt,
            meta={
                "horizon": float(c.eval_t_end),
                "n_traj": int(c.eval_n_traj),
                "n_masses": self.dof,
                "reference": "DOP853",
                "rtol": c.eval_rtol,
            },
        )
