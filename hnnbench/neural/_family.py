"""A model family, declared once for every backend.

A family says what its networks are, which coordinates it works in, what training
data it needs and whether it learns an energy. The mathematics lives in one small
module per backend (its *implementation*), which provides, in that backend's ops:

- ``field(nets, z) -> ż``: the learned vector field of a batch ``z`` ``(N, d)`` in the
  family's coordinates (differentiable; also used, in float64, by the rollouts);
- ``energy(nets, z) -> (N,)``: the learned conserved quantity, if ``learned_energy``;
- ``window_loss(nets, windows, dts) -> scalar``: the training loss on trajectory
  windows, if ``data == "windows"``.

``nets`` maps each network name of :attr:`Family.networks` to a callable MLP of that
backend (``nets["H"](z)`` is ``(N, 1)``; the torch MLP also has ``input_gradient``).
Everything else (initial weights, the training loop, minibatches, float64 rollouts,
saving, pixel autoencoders, second-order coordinates) is shared: see
:class:`hnnbench.neural.NeuralModel`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any, Literal, Optional

from hnnbench._contracts.space import SearchSpace

__all__ = ["Family"]

#: ``d`` (the dimension of the coordinates the family works in, ``2n``) -> the
#: networks' ``{name: (d_in, d_out)}``, in initialisation order.
NetworkShapes = Callable[[int], dict[str, tuple[int, int]]]


@dataclass(frozen=True)
class Family:
    """Declaration of a model family (backend-neutral; imports no backend).

    Attributes:
        name: short name, e.g. ``"hnn"``; entry points are ``<name>_<backend>``.
        title: one line for ``hnnbench list``.
        reference: the paper it comes from.
        networks: ``d -> {name: (d_in, d_out)}``.
        implementations: backend -> module path of its implementation.
        coordinates: ``"canonical"``: works on ``(q, p)`` (or on pixel latents);
            ``"velocity"``: works on ``(q, q̇)`` through the system's
            :meth:`~hnnbench.System.kinematics` (second-order families).
        data: ``"derivatives"``: trains on ``(z, ż)`` pairs by mean squared error;
            ``"windows"``: trains on windows of consecutive observed states of each
            training trajectory (``window_loss``).
        window: states per window, first included (``data == "windows"``): the
            default training window (a model's ``window`` setting may change it).
            Checkpoints are selected on the system's validation criterion, as for
            every family (docs/METRICS.md, "Checkpoint selection").
        observations: the system observations it runs on (``"state"``, ``"pixels"``).
        learned_energy: whether the implementation defines ``energy``.
        network_inputs: which part of the working coordinates ``z = (q, v)`` each
            network reads: ``"z"`` (the default for a network not named here), ``"q"``
            (the positions) or ``"p"`` (the momenta or velocities). The angle embedding
            (:mod:`hnnbench.neural._embedding`) applies to the angles among a
            network's inputs.
        order: position of the family's models in listings and tables (each backend's
            model at ``order + 0.1 * k`` in :data:`BACKEND_ORDER`).
        baseline: the family every other is measured against: the aggregate across
            systems scores each run between this family's mean (0) and the floor (1)
            (docs/STATISTICS.md). One installed family declares it.
        search_space: what ``hnnbench tune`` may vary (``{setting: distribution}``
            over fields of the models' config; :data:`hnnbench.neural.SHARED_SPACE`
            holds the settings every network has); every backend's model declares it.
            ``None``: the family is not tuned.
        recipe: the family paper's own training recipe as settings of the models'
            config (``{setting: value}``; the training fields ``steps``,
            ``batch_size``, ``lr``, ``weight_decay`` included), applied under
            ``track=recipe`` (docs/TUNING.md, "Recipes"); every backend's model declares
            it. ``None``: no recipe (its models are skipped on the recipe track).
    """

    name: str
    title: str
    reference: str
    networks: NetworkShapes
    implementations: Mapping[str, str] = field(default_factory=dict)
    coordinates: Literal["canonical", "velocity"] = "canonical"
    data: Literal["derivatives", "windows"] = "derivatives"
    window: int = 0
    observations: tuple[str, ...] = ("state",)
    learned_energy: bool = False
    order: Optional[float] = None
    network_inputs: Mapping[str, Literal["z", "q", "p"]] = field(default_factory=dict)
    baseline: bool = False
    search_space: Optional[SearchSpace] = None
    recipe: Optional[Mapping[str, Any]] = None


#: Backends in listing order within a family.
BACKEND_ORDER = ("torch", "jax")


#: The implementation functions that take the model's options (:class:`Bound`).
OPTION_FUNCTIONS = ("field", "energy")


@dataclass(frozen=True)
class BoundFunction:
    """An implementation function with keyword options bound: ``f(*args)`` calls
    ``fn(*args, **options)``. Equal (and hashing equal) when ``fn`` and ``options`` are,
    so JAX's compiled functions, which take it as a static argument, are reused across
    models of the same settings."""

    fn: Callable[..., Any]
    options: tuple[tuple[str, Any], ...]

    def __call__(self, *args: Any) -> Any:
        return self.fn(*args, **dict(self.options))


@dataclass(frozen=True)
class Bound:
    """A family's implementation module with the model's options bound to its ``field``
    and ``energy`` (:data:`OPTION_FUNCTIONS`); ``window_loss`` and everything else as the
    module has them. Hashable (a static argument of JAX's compiled training chunk)."""

    module: ModuleType
    options: tuple[tuple[str, Any], ...]

    def __getattr__(self, name: str) -> Any:
        if name in ("module", "options") or name.startswith("__"):
            raise AttributeError(name)
        value = getattr(self.module, name)
        return BoundFunction(value, self.options) if name in OPTION_FUNCTIONS else value


def bind(module: ModuleType, options: tuple[tuple[str, Any], ...]) -> Any:
    """``module`` itself without options, else a :class:`Bound` view of it."""
    return Bound(module, tuple(options)) if options else module
