"""The second-order MLP: an MLP acceleration on the system's own kinematics (formerly
``node2``).

The model works in velocity coordinates ``(q, q̇)`` (the system's
:meth:`~hnnbench.System.kinematics` maps them to and from ``(q, p)``): the position's
rate is the velocity itself, exactly, and one unconstrained MLP ``g(q, q̇)`` gives the
acceleration, ``q̈ = g(q, q̇)``, with no symplectic or energy constraint. It is trained
like the baseline MLP, on ``(z, ż)`` pairs of the dataset's derivatives. No learned
energy.

What it is not: the second-order neural ODE of Gruver, Finzi, Stanton & Wilson (ICLR
2022), which this family was named after until hnnbench 0.4 (``node2``). Theirs learns
``M⁻¹(q)`` in ``(q, p)`` (so it is not given the system's kinematics), embeds angles as
``(cos, sin)`` and trains through RK4 on trajectory chunks. This family shares their
second-order structure (``q̇`` exact, a learned acceleration), which they found explains
most of the HNN's advantage, and nothing else; it is given the true kinematics, which
Gruver et al.'s model must learn.
"""

from __future__ import annotations

from hnnbench.neural import SHARED_SPACE, Family, NeuralModel

SO_MLP = Family(
    name="so_mlp",
    title="Second-order MLP: q'' = g(q, q'), q' exact from the system's kinematics",
    reference="the second-order structure of Gruver, Finzi, Stanton, Wilson, Deconstructing "
    "the Inductive Biases of Hamiltonian Neural Networks, ICLR 2022 (not their "
    "model)",
    networks=lambda d: {"g": (d, d // 2)},
    implementations={
        "torch": "hnnbench_plugins.models.so_mlp.torch",
        "jax": "hnnbench_plugins.models.so_mlp.jax",
    },
    order=50,
    coordinates="velocity",
    search_space=SHARED_SPACE,
)


class SOMLPTorch(NeuralModel):
    """Second-order MLP (PyTorch)."""

    family = SO_MLP
    backend = "torch"
    version = "1"


class SOMLPJax(NeuralModel):
    """Second-order MLP (JAX)."""

    family = SO_MLP
    backend = "jax"
    version = "1"
