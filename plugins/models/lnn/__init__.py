"""The Lagrangian neural network (Cranmer, Greydanus, Hoyer, Battaglia, Spergel, Ho 2020).

One network gives a scalar ``L(q, q̇)`` in velocity coordinates (the system's
:meth:`~hnnbench.System.kinematics` maps them to and from ``(q, p)``). The
accelerations follow from the Euler-Lagrange equations,

    q̈ = (∇_q̇ ∇_q̇ᵀ L)⁻¹ [∇_q L − (∇_q ∇_q̇ᵀ L) q̇],

solved per state (a linear system of the n×n velocity Hessian). The learned energy is
``E = q̇ · ∂L/∂q̇ − L``, which the exact Euler-Lagrange flow conserves.
"""

from __future__ import annotations

from hnnbench.neural import Family, NeuralModel

LNN = Family(
    name="lnn",
    title="Lagrangian NN: scalar L(q, q'), accelerations from Euler-Lagrange",
    reference="Cranmer, Greydanus, Hoyer, Battaglia, Spergel, Ho, Lagrangian Neural "
              "Networks, ICLR 2020 workshop (arXiv:2003.04630)",
    networks=lambda d: {"L": (d, 1)},
    implementations={"torch": "hnnbench_plugins.models.lnn.torch",
                     "jax": "hnnbench_plugins.models.lnn.jax"},
    coordinates="velocity",
    learned_energy=True,
)


class LNNTorch(NeuralModel):
    """Lagrangian NN (PyTorch; ``torch.func`` derivatives)."""

    family = LNN
    backend = "torch"
    version = "1"


class LNNJax(NeuralModel):
    """Lagrangian NN (JAX)."""

    family = LNN
    backend = "jax"
    version = "1"
