"""Ideal pendulum, H = 3 (1 - cos q) + p^2 (the 2019 paper's units)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hnnbench_plugins.systems.toy import ToyConfig, ToySystem


@dataclass
class PendulumConfig(ToyConfig):
    """Paper settings: 50 trajectories x 45 points over [0, 3], radius U[1.3, 2.3]."""

    radius_min: float = 1.3
    radius_max: float = 2.3
    n_points: int = 45
    steps: int = 2000
    weight_decay: float = 1e-4


class Pendulum(ToySystem):
    """Ideal pendulum, H = 3 (1 - cos q) + p^2; the paper's task 2.

    The energy metric uses this true H (the original code used q^2 + p^2).
    """

    Config = PendulumConfig
    order = 20
    # 2: evaluation initial states drawn as the 2019 notebooks did (eval_init="box").
    # 3: the dataset keeps the clean inputs behind the noisy ones (the test loss's).
    version = "3"
    description = "Ideal pendulum, H = 3(1 - cos q) + p^2 (HNN paper, task 2)"
    profiles = {"quick": {"steps": 300, "eval_n_traj": 5}}

    def hamiltonian(self, q: np.ndarray, p: np.ndarray) -> np.ndarray:
        return 3.0 * (1.0 - np.cos(q)) + p**2

    def grad_h(self, q: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return 3.0 * np.sin(q), 2.0 * p

    @property
    def angles(self) -> tuple[int, ...]:
        """The pendulum's angle ``q``."""
        return (0,)
