"""A third-party plugin as an outside author would write it: one system, one model.

- ``quartic``: the anharmonic oscillator H = q^4 / 4 + p^2 / 2, reusing nothing from
  hnnbench but the public API. Its data and its evaluation trajectories come from their
  own seed streams (``seed_stream(seed, DATA_STREAM)``, ``seed_stream(seed,
  EVAL_STREAM)``), as docs/PLUGINS.md asks.
- ``linear_lstsq``: dx/dt = A x + b fitted by least squares (no training loop).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hnnbench import (
    DATA_STREAM,
    EVAL_STREAM,
    Dataset,
    FitResult,
    Model,
    ModelConfig,
    Split,
    System,
    SystemConfig,
    Trajectories,
    seed_stream,
    solve_batch,
)


@dataclass
class QuarticConfig(SystemConfig):
    n_traj: int = 20
    n_points: int = 20
    t_end: float = 4.0
    eval_n_traj: int = 4
    eval_t_end: float = 8.0
    steps: int = 1


class Quartic(System):
    """Anharmonic oscillator H = q^4/4 + p^2/2."""

    Config = QuarticConfig
    version = "3"  # 3: the data and the evaluation from their own seed streams
    description = "Anharmonic oscillator H = q^4/4 + p^2/2 (test plugin)"
    profiles = {"quick": {"n_traj": 10}}

    @property
    def dof(self) -> int:
        return 1

    def energy(self, x):
        return x[..., 0] ** 4 / 4 + x[..., 1] ** 2 / 2

    def vector_field(self, x):
        return np.stack([x[..., 1], -(x[..., 0] ** 3)], axis=-1)

    def _trajectories(self, rng, n, t_end, n_points):
        x0 = rng.uniform(-1.0, 1.0, size=(n, 2))
        t = np.linspace(0.0, t_end, n_points)
        return t, solve_batch(self.vector_field, x0, t, rtol=1e-10, atol=1e-10)

    def dataset(self, seed: int) -> Dataset:
        c = self.cfg
        t, xs = self._trajectories(seed_stream(seed, DATA_STREAM), c.n_traj, c.t_end, c.n_points)
        half = c.n_traj // 2

        def split(sl):
            x = xs[sl].reshape(-1, 2)
            n = xs[sl].shape[0]
            return Split(
                x=x,
                dxdt=self.vector_field(x),
                traj=np.repeat(np.arange(n), c.n_points),
                t=np.tile(t, n),
            )

        return Dataset(
            train=split(slice(0, half)),
            test=split(slice(half, None)),
            meta={"dt": float(t[1] - t[0])},
        )

    def evaluation(self, seed: int) -> Trajectories:
        c = self.cfg
        # fresh trajectories over twice a training trajectory's span (docs/PLUGINS.md)
        t, xs = self._trajectories(seed_stream(seed, EVAL_STREAM), c.eval_n_traj, c.eval_t_end, 50)
        return Trajectories(t=t, states=xs, dt=c.t_end / (c.n_points - 1))


@dataclass
class LinearConfig(ModelConfig):
    ridge: float = 1e-8


class LinearLeastSquares(Model):
    """dx/dt = A x + b by ridge-regularised least squares."""

    Config = LinearConfig
    version = "0.3"
    backend = "numpy"
    description = "Linear dx/dt = A x + b by least squares (test plugin)"

    def fit(self, data, train, seed, progress):
        x = np.concatenate([data.train.x, np.ones((len(data.train), 1))], axis=1)
        gram = x.T @ x + self.cfg.ridge * np.eye(x.shape[1])
        self.coef = np.linalg.solve(gram, x.T @ data.train.dxdt)
        progress(1, {"train_loss": float(np.mean((x @ self.coef - data.train.dxdt) ** 2))})
        return FitResult(history={}, steps=1)

    def time_derivative(self, x):
        return x @ self.coef[:-1] + self.coef[-1]

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
        return solve_batch(self.time_derivative, x0, t, rtol=rtol, atol=atol, method="RK45")
