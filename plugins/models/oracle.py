"""The oracle: the system's true vector field, untrained. Its metrics are the floor."""

from __future__ import annotations

from typing import Optional

import numpy as np

from hnnbench import (
    ORACLE,
    Dataset,
    FitResult,
    Model,
    ModelConfig,
    Progress,
    System,
    TrainSettings,
    solve_batch,
)


class Oracle(Model):
    """True dynamics integrated with scipy's Dormand-Prince (RK45), no training."""

    Config = ModelConfig
    version = "1"
    backend = "numpy"
    order = 100
    ranked = False
    reference = ORACLE
    description = "True vector field (no training): the floor of every metric"

    @classmethod
    def unsupported_reason(cls, system: System) -> Optional[str]:
        reason = super().unsupported_reason(system)
        if reason is None and not system.has_vector_field:
            reason = "the system has no known vector field (measured data)"
        return reason

    def fit(self, data: Dataset, train: TrainSettings, seed: int, progress: Progress) -> FitResult:
        return FitResult(history={}, steps=0)

    def time_derivative(self, x: np.ndarray) -> np.ndarray:
        out = self.system.vector_field(x)
        assert out is not None
        return out

    def rollout(
        self, x0: np.ndarray, t: np.ndarray, rtol: float = 1e-9, atol: float = 1e-9
    ) -> np.ndarray:
        return solve_batch(self.time_derivative, x0, t, rtol=rtol, atol=atol, method="RK45")

    def energy(self, x: np.ndarray) -> np.ndarray:
        return self.system.energy(x)
