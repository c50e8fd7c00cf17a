"""One-degree-of-freedom Hamiltonian toy systems with the 2019 paper's data protocol.

Data: ``n_traj`` trajectories over ``[0, t_end]`` sampled at ``n_points`` times. Each
initial state points in a random direction (a uniform draw in the square [-1, 1]^2,
normalised, as the original did) scaled to a radius drawn uniformly from
``[radius_min, radius_max]``. Gaussian noise of std ``noise_std`` is added to q and p;
the dx/dt targets are the true vector field at the clean states. The first
``1 - test_split`` of the trajectories train, the rest test (the training count is the
rounded one, ``round(n_traj * (1 - test_split))``: :meth:`ToyConfig.trajectory_split`).

Evaluation: ``eval_n_traj`` fresh noise-free trajectories over ``[0, eval_t_end]`` with
``eval_n_points`` points, integrated with DOP853 at ``eval_rtol``. Their initial states
come from ``eval_init``:

- ``"box"`` (default): the draw of the 2019 analysis notebooks (spring and pendulum
  alike): each of q and p independently, magnitude uniform in
  ``[eval_box_min, eval_box_max]`` (0.2 and 1.0 there) with a random sign. For the
  spring this reaches radius sqrt(2), beyond the training radius 1; for the pendulum it
  lies mostly inside the training annulus' hole (radius < 1.3).
- ``"train"``: the training distribution above (what version 1 of both systems did).

docs/METRICS.md gives measured figures for both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hnnbench import (
    CLEAN_INPUTS,
    DATA_STREAM,
    EVAL_STREAM,
    ConfigError,
    Dataset,
    Kinematics,
    LinearKinematics,
    System,
    SystemConfig,
    Trajectories,
    TrajectorySplit,
    check_fraction,
    check_int_at_least,
    check_ordered,
    check_positive,
    seed_stream,
    solve_batch,
    trajectory_dataset,
)

#: Initial-state distributions of the evaluation trajectories (``ToyConfig.eval_init``).
EVAL_INITS = ("train", "box")


@dataclass
class ToyConfig(SystemConfig):
    """Data and evaluation protocol of a 1-DOF toy system (times in the system's units)."""

    n_traj: int = 50
    t_end: float = 3.0
    n_points: int = 30
    radius_min: float = 0.1
    radius_max: float = 1.0
    noise_std: float = 0.1
    test_split: float = 0.5
    data_rtol: float = 1e-10
    eval_n_traj: int = 15
    eval_t_end: float = 20.0
    eval_n_points: int = 100
    eval_rtol: float = 1e-12
    eval_init: str = "box"
    eval_box_min: float = 0.2
    eval_box_max: float = 1.0

    def validate(self) -> None:
        super().validate()
        check_positive(
            "system",
            t_end=self.t_end,
            radius_min=self.radius_min,
            data_rtol=self.data_rtol,
            eval_t_end=self.eval_t_end,
            eval_rtol=self.eval_rtol,
        )
        check_int_at_least(
            "system",
            2,
            n_traj=self.n_traj,
            n_points=self.n_points,
            eval_n_traj=self.eval_n_traj,
            eval_n_points=self.eval_n_points,
        )
        check_fraction("system", "test_split", self.test_split, 0.5)
        check_ordered("system", "radius_min", self.radius_min, "radius_max", self.radius_max)
        if self.eval_init not in EVAL_INITS:
            raise ConfigError(
                f"system.eval_init='{self.eval_init}' is invalid: expected one of "
                f"{', '.join(EVAL_INITS)} (see docs/METRICS.md)."
            )
        if self.eval_box_min < 0:
            raise ConfigError(f"system.eval_box_min={self.eval_box_min} is invalid: expected >= 0.")
        check_ordered(
            "system", "eval_box_min", self.eval_box_min, "eval_box_max", self.eval_box_max
        )
        if self.noise_std < 0:
            raise ConfigError(f"system.noise_std={self.noise_std} is invalid: expected >= 0.")
        self.trajectory_split().check(self.n_traj)

    def trajectory_split(self) -> TrajectorySplit:
        """The last ``test_split`` of the trajectories test; the training count is the
        rounded one, ``round(n_traj * (1 - test_split))`` (as since version 1)."""
        return TrajectorySplit(self.test_split, test_from="last", rounding="train")


class ToySystem(System):
    """Base of the 1-DOF systems: subclasses define ``hamiltonian`` and its gradient."""

    Config = ToyConfig
    cfg: ToyConfig
    time_reversible = True

    @property
    def dof(self) -> int:
        return 1

    #: ``dq/dt`` per unit momentum: H = V(q) + p^2 in the paper's units gives 2.
    velocity_per_momentum: float = 2.0

    def grad_h(self, q: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(dH/dq, dH/dp)``."""
        raise NotImplementedError

    def kinematics(self) -> Kinematics:
        """``q̇ = 2 p`` (``H = V(q) + p^2``)."""
        return LinearKinematics(self.velocity_per_momentum)

    def hamiltonian(self, q: np.ndarray, p: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def energy(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        return self.hamiltonian(x[..., 0], x[..., 1])

    def vector_field(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        dh_dq, dh_dp = self.grad_h(x[..., 0], x[..., 1])
        return np.stack([dh_dp, -dh_dq], axis=-1)

    def initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``(n, 2)`` initial states at radii in ``[radius_min, radius_max]``."""
        direction = rng.random((n, 2)) * 2.0 - 1.0
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        radius = rng.uniform(self.cfg.radius_min, self.cfg.radius_max, size=(n, 1))
        return direction * radius

    def box_initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``(n, 2)`` states whose q and p each have a magnitude uniform in
        ``[eval_box_min, eval_box_max]`` and a random sign (the 2019 evaluation draw)."""
        low, high = self.cfg.eval_box_min, self.cfg.eval_box_max
        magnitude = rng.uniform(low, high, size=(n, 2))
        sign = np.where(rng.random((n, 2)) < 0.5, -1.0, 1.0)
        return sign * magnitude

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
        )  # (n_traj, T, 2)
        dxdt = self.vector_field(clean)
        noisy = clean + rng.normal(0.0, c.noise_std, size=clean.shape)
        split = c.trajectory_split()
        n_train, n_test = split.sizes(c.n_traj)
        return trajectory_dataset(
            noisy,
            dxdt,
            t,
            split,
            extras={CLEAN_INPUTS: clean} if c.noise_std > 0 else None,
            meta={"dt": float(t[1] - t[0]), "n_train_traj": n_train, "n_test_traj": n_test},
        )

    def evaluation(self, seed: int) -> Trajectories:
        c = self.cfg
        rng = seed_stream(seed, EVAL_STREAM)
        t = np.linspace(0.0, c.eval_t_end, c.eval_n_points)
        draw = self.box_initial_states if c.eval_init == "box" else self.initial_states
        states = solve_batch(
            self.vector_field,
            draw(rng, c.eval_n_traj),
            t,
            rtol=c.eval_rtol,
            atol=c.eval_rtol,
        )
        return Trajectories(
            t=t,
            states=states,
            dt=c.t_end / (c.n_points - 1),
            meta={
                "horizon": c.eval_t_end,
                "n_traj": c.eval_n_traj,
                "reference": "DOP853",
                "rtol": c.eval_rtol,
                "initial_states": c.eval_init,
            },
        )
