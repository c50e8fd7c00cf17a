"""What a backend (torch, JAX) supplies to the neural models, and how it is loaded.

A backend provides only primitives; everything else is shared
(:mod:`hnnbench.neural._loop`, :class:`hnnbench.neural.NeuralModel`):

- a :class:`~hnnbench.neural._loop.Trainer` built from the shared numpy initial weights
  of ``S`` seeds, running compiled (JAX) or eager (torch) chunks of optimizer steps;
- the trained weights back as numpy arrays;
- an :class:`Inference`: the float64 field and learned energy, the batched adaptive
  Dormand-Prince solver, and, for pixel models, the autoencoder in training precision.

Backends are imported only when a model is built (``load_backend``), so listing,
composing, validating and reporting import neither torch nor JAX, and a job imports
only the backend it runs.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Sequence
from types import ModuleType
from typing import Optional, Protocol

import numpy as np

from hnnbench._contracts.errors import BackendMissingError, HnnbenchError
from hnnbench._contracts.plugin import TrainSettings
from hnnbench.neural._config import NeuralConfig
from hnnbench.neural._embedding import Layout
from hnnbench.neural._family import Family
from hnnbench.neural._loop import Trainer
from hnnbench.neural._views import Problem

__all__ = [
    "BACKENDS",
    "MIN_STEP_FRACTION",
    "Backend",
    "Inference",
    "Weights",
    "load_backend",
    "map_plan",
    "missing_backend",
    "rollout_min_step",
    "stall_text",
]

#: The stall rule of every neural rollout, in both backends (docs/METRICS.md,
#: "Diverged"): when the adaptive solver's next step size falls below this fraction of
#: the rollout's time span, the rollout has stalled (a learned field that turned stiff
#: or singular, e.g. an LNN's velocity Hessian passing through zero) and is recorded
#: ``diverged`` at once, instead of spending its whole step budget
#: (``model.rollout_max_steps``) on steps that cannot reach the horizon.
MIN_STEP_FRACTION = 1e-8


def rollout_min_step(t: np.ndarray) -> float:
    """The smallest step size a rollout over times ``t`` may take (the stall rule,
    :data:`MIN_STEP_FRACTION` of its span), in ``t``'s units."""
    t = np.asarray(t, dtype=np.float64)
    return MIN_STEP_FRACTION * float(abs(t[-1] - t[0])) if t.size else 0.0


def map_plan(t: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """How a rollout by a family's own discrete map (e.g. the SRNN's leapfrog) covers
    the grid ``t`` ``(T,)`` with steps no longer than ``step`` (> 0): each interval
    ``t[k] -> t[k+1]`` in ``m_k = ceil(|Δt_k| / step)`` equal steps of ``Δt_k / m_k``
    (negative when ``t`` decreases), so every grid time is landed on exactly.

    Returns:
        ``(m (T - 1,) int64, h (T - 1,) float64)``.
    """
    dt = np.diff(np.asarray(t, dtype=np.float64))
    m = np.maximum(1, np.ceil(np.abs(dt) / float(step) - 1e-9)).astype(np.int64)
    return m, dt / m


def stall_text(min_step: float) -> str:
    """How both backends name the stall rule in a diverged rollout's reason."""
    return f"the stall limit {min_step:.3g} ({MIN_STEP_FRACTION:g} of the rollout's span)"


#: Flat ``{"<net>.linears.<i>.weight": array, ...}`` of one seed (pixel models add
#: ``"autoencoder.encoder.<i>.weight"`` etc.), in the training dtype.
Weights = dict[str, np.ndarray]

#: backend name -> (module, class, the modules it needs, the pip extra providing them).
BACKENDS: dict[str, tuple[str, str, tuple[str, ...], str]] = {
    "torch": ("hnnbench.neural.torch", "TorchBackend", ("torch",), "torch"),
    "jax": ("hnnbench.neural.jax", "JaxBackend", ("jax", "equinox", "optax", "diffrax"), "jax"),
}


class Inference(Protocol):
    """A trained model's float64 computations (one seed)."""

    def field(self, z: np.ndarray) -> np.ndarray:
        """``(N, d) -> (N, d)``: the learned field, float64, per model time unit."""
        ...

    def energy(self, z: np.ndarray) -> np.ndarray:
        """``(N, d) -> (N,)``: the learned energy (families with ``learned_energy``)."""
        ...

    def rollout(
        self, z0: np.ndarray, t: np.ndarray, rtol: float, atol: float, max_steps: int
    ) -> np.ndarray:
        """Adaptive Dormand-Prince 5(4) in float64 from ``(M, d)`` over ``(T,)``
        (monotonic, may decrease), the batch integrated as one system; ``(M, T, d)``.
        Raises :class:`~hnnbench._contracts.errors.RolloutDiverged` when the solver gives up: more
        than ``max_steps`` steps, or a step size below :func:`rollout_min_step` (the
        stall rule, the same in every backend)."""
        ...

    def map_rollout(self, z0: np.ndarray, t: np.ndarray, step: float) -> np.ndarray:
        """The family's own discrete map (its implementation's ``step(nets, z, h)``)
        from ``(M, d)`` over ``(T,)`` in steps of at most ``step`` (:func:`map_plan`),
        float64; ``(M, T, d)``. Non-finite states are returned as they are."""
        ...

    def encode(self, x: np.ndarray) -> np.ndarray:
        """Pixel models: observations ``(N, D)`` -> latents ``(N, d)``."""
        ...

    def decode(self, z: np.ndarray) -> np.ndarray:
        """Pixel models: latents ``(N, d)`` -> observations ``(N, D)``."""
        ...

    def objective(self, x: np.ndarray, x_next: np.ndarray) -> float:
        """Pixel models: the training objective's mean over the pairs ``(x, x_next)``."""
        ...


class Backend(Protocol):
    """One backend, configured for a model (precision, device)."""

    #: ``"torch"`` or ``"jax"``.
    name: str
    #: The device actually used: ``"cpu"``, ``"cuda:0"``, ...
    device_name: str
    #: Seconds a model wants recorded, e.g. ``{"compile_s": ...}``; accumulated.
    timings: dict[str, float]

    def trainer(
        self,
        family: Family,
        impl: ModuleType,
        problem: Problem,
        initial: Sequence[Weights],
        settings: TrainSettings,
        layout: Layout,
    ) -> Trainer:
        """A trainer of ``len(initial)`` seeds, from their float64 initial weights;
        ``layout``: the family's networks on this system (what each reads, its angle
        embedding)."""
        ...

    def weights(self, trainer: Trainer) -> list[Weights]:
        """The current weights of each seed of ``trainer`` (training dtype)."""
        ...

    def inference(
        self, family: Family, impl: ModuleType, weights: Weights, layout: Layout
    ) -> Inference:
        """The float64 computations of one seed's trained weights."""
        ...


def missing_backend(name: str) -> Optional[str]:
    """Why backend ``name`` cannot be imported (an install hint), without importing it;
    ``None`` when its modules are installed."""
    if name not in BACKENDS:
        return f"unknown neural backend '{name}' (expected one of {', '.join(BACKENDS)})"
    _, _, needs, extra = BACKENDS[name]
    for module in needs:
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):  # a parent package missing, or a None entry
            found = False
        if not found:
            return (
                f"This model needs {module}, which is not installed. "
                f"Install it with: pip install 'hnnbench[{extra}]'"
            )
    return None


def load_backend(name: str, cfg: NeuralConfig, device: str) -> Backend:
    """Import backend ``name`` (``torch`` / ``jax``) and configure it; a missing
    install raises a one-line :class:`~hnnbench._contracts.errors.BackendMissingError`."""
    if name not in BACKENDS:
        raise HnnbenchError(
            f"Unknown neural backend '{name}': expected one of {', '.join(BACKENDS)}"
        )
    missing = missing_backend(name)
    if missing is not None:
        raise BackendMissingError(missing)
    module_name, class_name, _, _ = BACKENDS[name]
    module = importlib.import_module(module_name)
    backend: Backend = getattr(module, class_name)(cfg, device)
    return backend
