"""Neural models for hnnbench: one core for every family and backend.

A model family is declared once (:class:`Family`) and implemented in one small module
per backend; its entry-point classes subclass :class:`NeuralModel`. The training loop
(:mod:`hnnbench.neural._loop`), seeded initial weights (:mod:`hnnbench.neural._init`),
float64 rollouts, pixel autoencoders and second-order coordinates
(:mod:`hnnbench.neural._views`) and weight files are shared. Backends
(:mod:`hnnbench.neural.torch`, :mod:`hnnbench.neural.jax`) are imported only when a
model is built. docs/MODELS.md ("Adding a family") shows a new family in a few lines.
"""

from hnnbench.neural._config import SHARED_SPACE, NeuralConfig
from hnnbench.neural._family import Family
from hnnbench.neural._model import NeuralModel

__all__ = ["SHARED_SPACE", "Family", "NeuralConfig", "NeuralModel"]
