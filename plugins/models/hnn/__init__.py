"""The Hamiltonian neural network (Greydanus, Dzamba & Yosinski, NeurIPS 2019).

One network outputs a scalar ``H(q, p)``; the dynamics are its symplectic gradient
``ż = J ∇H = (∂H/∂p, -∂H/∂q)``, so the learned flow conserves the learned ``H``
exactly. The learned energy is ``H``. On pixel systems it is the latent dynamics of the
2019 autoencoder.
"""

from __future__ import annotations

from hnnbench.neural import SHARED_SPACE, Family, NeuralModel

HNN = Family(
    name="hnn",
    title="Hamiltonian NN: scalar H, dynamics (dH/dp, -dH/dq)",
    reference="Greydanus, Dzamba & Yosinski, Hamiltonian Neural Networks, NeurIPS 2019",
    networks=lambda d: {"H": (d, 1)},
    implementations={
        "torch": "hnnbench_plugins.models.hnn.torch",
        "jax": "hnnbench_plugins.models.hnn.jax",
    },
    order=20,
    search_space=SHARED_SPACE,
    observations=("state", "pixels"),
    learned_energy=True,
)


class HNNTorch(NeuralModel):
    """Hamiltonian NN (PyTorch; closed-form input gradient)."""

    family = HNN
    backend = "torch"
    version = "2"  # 2: angles embedded (model.angle_embedding)


class HNNJax(NeuralModel):
    """Hamiltonian NN (JAX; ``jax.grad``)."""

    family = HNN
    backend = "jax"
    version = "2"  # 2: angles embedded (model.angle_embedding)
