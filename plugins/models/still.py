"""Standing still: the zero field, ``x̂(t) = x₀``. A reference, never a competitor.

Every ranked leader must beat it on the rollout metrics to be marked best
(docs/STATISTICS.md, "The trivial references"): a model that predicts no motion scores
0 on an energy error of a conservative system and a sizeable rollout skill on data
that barely moves, so "best" without it can go to a model that does nothing. Its
metrics are computed by the same declarations as every model's; on pixel systems it
holds the first frame pair (its "latents" are the observations).
"""

from __future__ import annotations

from typing import Optional

import numpy as np

from hnnbench import (
    STANDING_STILL,
    Dataset,
    FitResult,
    Model,
    ModelConfig,
    Progress,
    TrainSettings,
)


class StandingStill(Model):
    """Predicts no motion: ``dx/dt = 0``, rollouts hold the initial state."""

    Config = ModelConfig
    version = "1"
    backend = "numpy"
    observations = ("state", "pixels")
    order = 99
    ranked = False
    reference = STANDING_STILL
    description = "Standing still, x(t) = x(0) (no training): the reference a leader must beat"

    def fit(self, data: Dataset, train: TrainSettings, seed: int, progress: Progress) -> FitResult:
        return FitResult(history={}, steps=0)

    def time_derivative(self, x: np.ndarray) -> np.ndarray:
        return np.zeros_like(np.asarray(x, dtype=np.float64))

    def rollout(
        self, x0: np.ndarray, t: np.ndarray, rtol: float = 1e-9, atol: float = 1e-9
    ) -> np.ndarray:
        x0 = np.atleast_2d(np.asarray(x0, dtype=np.float64))
        return np.repeat(x0[:, None, :], len(t), axis=1)

    def decode(self, z: np.ndarray) -> Optional[np.ndarray]:
        """Pixel systems: the held observations themselves."""
        return np.asarray(z) if self.system.observation == "pixels" else None
