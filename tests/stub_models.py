"""A model that is registered but never run: a base for tests of what a third-party
model declares (its search space, its recipe) to the registry and ``hnnbench list``."""

from __future__ import annotations

import numpy as np

import hnnbench


class Unrun(hnnbench.Model):
    """A valid model class whose methods are never called."""

    def fit(self, data, train, seed, progress):  # pragma: no cover - not run
        raise NotImplementedError

    def time_derivative(self, x):  # pragma: no cover
        return x

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):  # pragma: no cover
        return np.zeros((len(x0), len(t), x0.shape[1]))
