"""The second-order neural ODE ("NODE + second-order structure", Gruver et al. 2022).

The model works in velocity coordinates ``(q, q̇)`` (the system's
:meth:`~hnnbench.System.kinematics` maps them to and from ``(q, p)``): the position's
rate is the velocity itself, exactly, and one unconstrained MLP ``g(q, q̇)`` gives the
acceleration, ``q̈ = g(q, q̇)``, with no symplectic or energy constraint. Gruver et al.
found that this second-order structure, not symplecticity, explains most of the HNN's
advantage. No learned energy.
"""

from __future__ import annotations

from hnnbench.neural import SHARED_SPACE, Family, NeuralModel

NODE2 = Family(
    name="node2",
    title="Second-order neural ODE: q'' = g(q, q'), q' exact",
    reference="Gruver, Finzi, Stanton, Wilson, Deconstructing the Inductive Biases of "
              "Hamiltonian Neural Networks, ICLR 2022",
    networks=lambda d: {"g": (d, d // 2)},
    implementations={"torch": "hnnbench_plugins.models.node2.torch",
                     "jax": "hnnbench_plugins.models.node2.jax"},
    order=50,
    search_space=SHARED_SPACE,
    coordinates="velocity",
)


class NODE2Torch(NeuralModel):
    """Second-order neural ODE (PyTorch)."""

    family = NODE2
    backend = "torch"
    version = "1"


class NODE2Jax(NeuralModel):
    """Second-order neural ODE (JAX)."""

    family = NODE2
    backend = "jax"
    version = "1"
