"""The dissipative Hamiltonian neural network (Sosanya & Greydanus, 2022).

Two scalar networks, ``H(q, p)`` and ``D(q, p)``; the dynamics are
``ż = J ∇H + ∇D``: a conservative part (the symplectic gradient of ``H``) plus a
dissipative part (the gradient of ``D``), a Helmholtz decomposition of the field. The
learned energy is ``H``, the conserved part. With ``D ≡ 0`` it is the HNN.
"""

from __future__ import annotations

from hnnbench.neural import Family, NeuralModel

DHNN = Family(
    name="dhnn",
    title="Dissipative HNN: scalars H and D, dynamics J grad H + grad D",
    reference="Sosanya & Greydanus, Dissipative Hamiltonian Neural Networks: Learning "
              "Dissipative and Conservative Dynamics Separately, arXiv:2201.10085 (2022)",
    networks=lambda d: {"H": (d, 1), "D": (d, 1)},
    implementations={"torch": "hnnbench_plugins.models.dhnn.torch",
                     "jax": "hnnbench_plugins.models.dhnn.jax"},
    order=30,
    learned_energy=True,
)


class DHNNTorch(NeuralModel):
    """Dissipative HNN (PyTorch; closed-form input gradients)."""

    family = DHNN
    backend = "torch"
    version = "2"  # 2: angles embedded (model.angle_embedding)


class DHNNJax(NeuralModel):
    """Dissipative HNN (JAX; ``jax.grad``)."""

    family = DHNN
    backend = "jax"
    version = "2"  # 2: angles embedded (model.angle_embedding)
