"""The Lagrangian neural network (Cranmer, Greydanus, Hoyer, Battaglia, Spergel, Ho 2020).

One network gives a scalar ``L(q, q̇)`` in velocity coordinates (the system's
:meth:`~hnnbench.System.kinematics` maps them to and from ``(q, p)``). The
accelerations follow from the Euler-Lagrange equations,

    q̈ = (∇_q̇ ∇_q̇ᵀ L)⁻¹ [∇_q L − (∇_q ∇_q̇ᵀ L) q̇],

solved per state (a linear system of the n×n velocity Hessian). The learned energy is
``E = q̇ · ∂L/∂q̇ − L``, which the exact Euler-Lagrange flow conserves.

Declared structure: the learned Lagrangian is the network plus a fixed kinetic term,
``L(q, q̇) = net(q, q̇) + KINETIC_PRIOR · |q̇|²`` (:data:`KINETIC_PRIOR` = 1/2, in the
system's units). The network starts from the shared seeded initialisation like every
family's; the added term makes the velocity Hessian ``∂²L/∂q̇²`` start at the identity
plus the network's (small) Hessian, so the first accelerations are of the data's size
instead of ~50x too large (a near-singular Hessian at initialisation stalled the spring
and pendulum LNN at lr 1e-3: the issue "Every family at its honest best"). The network
learns the difference to the true Lagrangian, whose kinetic term the prior only
approximates (the 2019 spring's true one is ``q̇²/4``). It is the LNN's alone: the other
families invert no Hessian of their network. Its weight is ``model.kinetic_prior``
(default :data:`KINETIC_PRIOR`; 0: the plain network, as in the paper), a knob of the
family's search space (``hnnbench tune``).

The paper's recipe (the recipe track, ``track=recipe``: :data:`RECIPE`), from its
published double-pendulum notebook (github.com/MilesCranmer/lagrangian_nns,
notebooks/DoublePendulum.ipynb; ``lnn.py``'s ``custom_init``): 3 hidden layers of 600
softplus units, the plain network (no kinetic term), the paper's initialisation
(``model.init=paper``: :func:`paper_init_arrays`), the mean absolute error, a one-cycle
learning rate peaking at 1e-3 (the notebook's ``args.lr``; its one-cycle cell was last
run at 1e-5 with 1e-3 commented out), minibatches of 512, no weight decay (the
notebook's L2 term, 5.7e-7 or 1e-6 of the squared weights over a summed loss, is below
1e-11 of the mean loss's scale). Not taken: its training length (300 epochs of 2000
minibatches, 600 000 steps: the recipe row trains for the system's protocol steps, and
``model.steps=600000`` gives the notebook's) and its data (fresh random states of the
analytic field every epoch: hnnbench's rows train on the system's dataset).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from hnnbench import Categorical, ConfigError
from hnnbench.neural import SHARED_SPACE, Family, NeuralConfig, NeuralModel

#: The weight of the declared kinetic term ``|q̇|²`` added to the network's output
#: (the module docstring).
KINETIC_PRIOR = 0.5
#: ``model.init``: ``shared`` (the seeded orthogonal initialisation every family shares)
#: or ``paper`` (:func:`paper_init_arrays`).
INITS = ("shared", "paper")
#: The numpy stream of the paper's initialisation: ``default_rng([seed, PAPER_STREAM])``
#: (apart from the shared initialisation's streams).
PAPER_STREAM = 40
#: The paper's per-layer scale of a weight's standard deviation ``scale / sqrt(n)``
#: (``n``: the larger of the weight's dimensions): the first layer's, each middle
#: layer's per layer index ``i`` (``scale = MIDDLE * i``), the last layer's per ``n``
#: (``scale = n``).
FIRST_SCALE, MIDDLE_SCALE = 2.2, 0.58

#: The LNN paper's recipe (the module docstring), applied under ``track=recipe``.
RECIPE = {
    "hidden": 600,
    "layers": 4,
    "activation": "softplus",
    "kinetic_prior": 0.0,
    "init": "paper",
    "loss": "l1",
    "lr_schedule": "one_cycle",
    "lr": 1e-3,
    "batch_size": 512,
    "weight_decay": 0.0,
}

LNN = Family(
    name="lnn",
    title="Lagrangian NN: scalar L(q, q'), accelerations from Euler-Lagrange",
    reference="Cranmer, Greydanus, Hoyer, Battaglia, Spergel, Ho, Lagrangian Neural "
    "Networks, ICLR 2020 workshop (arXiv:2003.04630)",
    networks=lambda d: {"L": (d, 1)},
    implementations={
        "torch": "hnnbench_plugins.models.lnn.torch",
        "jax": "hnnbench_plugins.models.lnn.jax",
    },
    order=40,
    coordinates="velocity",
    learned_energy=True,
    # The shared space, but softplus only (LNNConfig), and the weight of the kinetic
    # term from none (the paper's plain network) to twice the default.
    search_space={
        **{k: v for k, v in SHARED_SPACE.items() if k != "activation"},
        "kinetic_prior": Categorical((0.0, 0.25, 0.5, 1.0)),
    },
    recipe=RECIPE,
)


def paper_init_arrays(seed: int, shapes: dict[str, tuple[int, ...]]) -> dict[str, np.ndarray]:
    """The LNN paper's initialisation of one MLP, float64, for its ``{name: shape}``
    (``linears.<i>.weight`` ``(out, in)`` and ``linears.<i>.bias``, in layer order): zero
    biases; layer ``i`` of ``m`` weights drawn normal with standard deviation
    ``scale_i / sqrt(n_i)``, ``n_i`` the larger of its dimensions, ``scale_0 =``
    :data:`FIRST_SCALE`, ``scale_i = MIDDLE_SCALE · i`` in between, and ``scale_{m-1} =
    n_{m-1}`` for the last (a standard deviation of ``sqrt(n)``: the paper's choice)."""
    rng = np.random.default_rng([seed, PAPER_STREAM])
    weights = [name for name in shapes if name.endswith("weight")]
    arrays: dict[str, np.ndarray] = {}
    for name, shape in shapes.items():
        if not name.endswith("weight"):
            arrays[name] = np.zeros(shape)
            continue
        i, n = weights.index(name), max(shape)
        scale = FIRST_SCALE if i == 0 else n if i == len(weights) - 1 else MIDDLE_SCALE * i
        arrays[name] = rng.standard_normal(shape) * scale / np.sqrt(n)
    return arrays


#: The smoke profile: a narrow network (its second derivatives or leapfrog windows make
#: a step several times the HNN's), so quick jobs stay at seconds.
QUICK = {"quick": {**NeuralModel.profiles["quick"], "hidden": 32}}


@dataclass
class LNNConfig(NeuralConfig):
    """The shared architecture with the LNN paper's activation: softplus, whose second
    derivatives (the Euler-Lagrange equations need them) are smooth and nowhere
    flat. The paper's other choices (3 x 600 units, its initialisation, L1 loss,
    one-cycle learning rate, batches of 512: :data:`RECIPE`) are the defaults on the
    recipe track only: on the protocol track the LNN trains under each system's
    protocol like every family (docs/MODELS.md, docs/TUNING.md)."""

    activation: str = "softplus"
    #: The weight of the declared kinetic term ``|q̇|²`` (the module docstring).
    kinetic_prior: float = KINETIC_PRIOR
    #: The initial weights (:data:`INITS`): ``shared`` or ``paper``.
    init: str = "shared"

    def validate(self) -> None:
        super().validate()
        if self.init not in INITS:
            raise ConfigError(
                f"model.init='{self.init}' is invalid: expected one of {', '.join(INITS)}."
            )
        if not (math.isfinite(self.kinetic_prior) and self.kinetic_prior >= 0):
            raise ConfigError(
                f"model.kinetic_prior={self.kinetic_prior} is invalid: "
                "expected a finite number >= 0, e.g. model.kinetic_prior=0.5."
            )


class _LNN(NeuralModel):
    Config = LNNConfig
    cfg: LNNConfig

    def field_options(self) -> tuple[tuple[str, Any], ...]:
        return (("kinetic_prior", float(self.cfg.kinetic_prior)),)

    def initial_weights(self, seed: int, d_obs: Optional[int] = None) -> dict[str, np.ndarray]:
        shared = super().initial_weights(seed, d_obs)
        if self.cfg.init == "shared":
            return shared
        prefix = "L."
        mine = {k[len(prefix) :]: v.shape for k, v in shared.items() if k.startswith(prefix)}
        return {**shared, **{prefix + k: v for k, v in paper_init_arrays(seed, mine).items()}}


class LNNTorch(_LNN):
    """Lagrangian NN (PyTorch; closed-form input Hessians:
    :func:`hnnbench.neural.torch.input_hessian`)."""

    family = LNN
    backend = "torch"
    version = "3"  # 3: angles embedded (model.angle_embedding)
    profiles = QUICK


class LNNJax(_LNN):
    """Lagrangian NN (JAX)."""

    family = LNN
    backend = "jax"
    version = "3"  # 3: angles embedded (model.angle_embedding)
    profiles = QUICK
