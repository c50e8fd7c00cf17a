"""The baseline: an MLP that outputs the time derivative directly (the 2019 paper's).

``ż = f(z)``: one network ``f`` of ``d`` inputs and ``d`` outputs, no structure. On
pixel systems it is the latent dynamics of the 2019 autoencoder.
"""

from __future__ import annotations

from hnnbench.neural import SHARED_SPACE, Family, NeuralModel

MLP = Family(
    name="mlp",
    title="Baseline MLP predicting dx/dt directly (paper architecture)",
    reference="Greydanus, Dzamba & Yosinski, Hamiltonian Neural Networks, NeurIPS 2019",
    networks=lambda d: {"f": (d, d)},
    implementations={
        "torch": "hnnbench_plugins.models.mlp.torch",
        "jax": "hnnbench_plugins.models.mlp.jax",
    },
    order=10,
    search_space=SHARED_SPACE,
    observations=("state", "pixels"),
    baseline=True,
)


class MLPTorch(NeuralModel):
    """Baseline MLP predicting dx/dt directly (PyTorch)."""

    family = MLP
    backend = "torch"
    version = "2"  # 2: angles embedded (model.angle_embedding)


class MLPJax(NeuralModel):
    """Baseline MLP predicting dx/dt directly (JAX: equinox + optax + diffrax)."""

    family = MLP
    backend = "jax"
    version = "2"  # 2: angles embedded (model.angle_embedding)
