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
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from hnnbench import Categorical, ConfigError
from hnnbench.neural import SHARED_SPACE, Family, NeuralConfig, NeuralModel

#: The weight of the declared kinetic term ``|q̇|²`` added to the network's output
#: (the module docstring).
KINETIC_PRIOR = 0.5

LNN = Family(
    name="lnn",
    title="Lagrangian NN: scalar L(q, q'), accelerations from Euler-Lagrange",
    reference="Cranmer, Greydanus, Hoyer, Battaglia, Spergel, Ho, Lagrangian Neural "
              "Networks, ICLR 2020 workshop (arXiv:2003.04630)",
    networks=lambda d: {"L": (d, 1)},
    implementations={"torch": "hnnbench_plugins.models.lnn.torch",
                     "jax": "hnnbench_plugins.models.lnn.jax"},
    order=40,
    coordinates="velocity",
    learned_energy=True,
    # The shared space, but softplus only (LNNConfig), and the weight of the kinetic
    # term from none (the paper's plain network) to twice the default.
    search_space={**{k: v for k, v in SHARED_SPACE.items() if k != "activation"},
                  "kinetic_prior": Categorical((0.0, 0.25, 0.5, 1.0))},
)


#: The smoke profile: a narrow network (its second derivatives or leapfrog windows make
#: a step several times the HNN's), so quick jobs stay at seconds.
QUICK = {"quick": {**NeuralModel.profiles["quick"], "hidden": 32}}

@dataclass
class LNNConfig(NeuralConfig):
    """The shared architecture with the LNN paper's activation: softplus, whose second
    derivatives (the Euler-Lagrange equations need them) are smooth and nowhere
    flat. The paper's other choices (3 x 600 units, a searched initialisation, L1
    loss, one-cycle learning rate, ~10^8 samples) are not used: like every family,
    the LNN trains under each system's protocol (docs/MODELS.md)."""

    activation: str = "softplus"
    #: The weight of the declared kinetic term ``|q̇|²`` (the module docstring).
    kinetic_prior: float = KINETIC_PRIOR

    def validate(self) -> None:
        super().validate()
        if not (math.isfinite(self.kinetic_prior) and self.kinetic_prior >= 0):
            raise ConfigError(f"model.kinetic_prior={self.kinetic_prior} is invalid: "
                              "expected a finite number >= 0, e.g. model.kinetic_prior=0.5.")


class _LNN(NeuralModel):
    Config = LNNConfig
    cfg: LNNConfig

    def field_options(self) -> tuple[tuple[str, Any], ...]:
        return (("kinetic_prior", float(self.cfg.kinetic_prior)),)


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
