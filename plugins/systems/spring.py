"""Ideal mass-spring, H = q^2 + p^2 (the 2019 paper's units: k = 2, m = 1/2)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hnnbench_plugins.systems.toy import ToyConfig, ToySystem


@dataclass
class SpringConfig(ToyConfig):
    """Paper settings: 50 trajectories x 30 points over [0, 3], radius U[0.1, 1.0]."""

    radius_min: float = 0.1
    radius_max: float = 1.0
    n_points: int = 30
    steps: int = 2000
    weight_decay: float = 1e-4


class Spring(ToySystem):
    """Ideal mass-spring, H = q^2 + p^2; the paper's task 1."""

    Config = SpringConfig
    order = 10
    # 2: evaluation initial states drawn as the 2019 notebooks did (eval_init="box").
    # 3: the dataset keeps the clean inputs behind the noisy ones (the test loss's).
    version = "3"
    description = "Ideal mass-spring, H = q^2 + p^2 (HNN paper, task 1)"
    profiles = {"quick": {"steps": 300, "eval_n_traj": 5}}

    def hamiltonian(self, q: np.ndarray, p: np.ndarray) -> np.ndarray:
        return q**2 + p**2

    def grad_h(self, q: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return 2.0 * q, 2.0 * p
