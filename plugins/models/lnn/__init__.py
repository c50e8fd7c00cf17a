"""The Lagrangian neural network (Cranmer, Greydanus, Hoyer, Battaglia, Spergel, Ho 2020).

One network gives a scalar ``L(q, q̇)`` in velocity coordinates (the system's
:meth:`~hnnbench.System.kinematics` maps them to and from ``(q, p)``). The
accelerations follow from the Euler-Lagrange equations,

    q̈ = (∇_q̇ ∇_q̇ᵀ L)⁻¹ [∇_q L − (∇_q ∇_q̇ᵀ L) q̇],

solved per state (a linear system of the n×n velocity Hessian). The learned energy is
``E = q̇ · ∂L/∂q̇ − L``, which the exact Euler-Lagrange flow conserves.
"""

from __future__ import annotations

from dataclasses import dataclass

from hnnbench.neural import Family, NeuralConfig, NeuralModel

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


class LNNTorch(NeuralModel):
    """Lagrangian NN (PyTorch; ``torch.func`` derivatives)."""

    Config = LNNConfig
    family = LNN
    backend = "torch"
    version = "1"
    profiles = QUICK


class LNNJax(NeuralModel):
    """Lagrangian NN (JAX)."""

    Config = LNNConfig
    family = LNN
    backend = "jax"
    version = "1"
    profiles = QUICK
