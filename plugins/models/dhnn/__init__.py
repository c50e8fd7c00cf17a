"""The dissipative Hamiltonian neural network (Sosanya & Greydanus, 2022).

Two scalar networks, ``H(q, p)`` and ``D(q, p)``; the dynamics are
``ż = J ∇H + ∇D``: a conservative part (the symplectic gradient of ``H``) plus a
dissipative part (the gradient of ``D``), a Helmholtz decomposition of the field. The
learned energy is ``H``, the conserved part. With ``D ≡ 0`` it is the HNN.

``model.dissipation_scale`` (``s``, default 1) weighs the dissipative part,
``ż = J ∇H + s ∇D``: the scale of ``∇D`` at initialisation and its learning speed
relative to ``H``'s. A knob of the family's search space (``hnnbench tune``).

The paper's recipe (the recipe track, ``track=recipe``), from the published code's
damped-spring experiment (github.com/DrewSosa/dissipative_hnns: train.py, models.py,
analyze_dampedspring.ipynb): two networks of 2 hidden layers of 256 tanh units, mean
squared error on derivatives, Adam at 1e-3 without weight decay, batches of 128, 5000
steps. Not taken: the residual connection of its second hidden layer, its batches as
consecutive unshuffled slices of the data, its time input (always 0), its final-iterate
model, and its other experiments' rates (5e-3 on the real pendulum).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from hnnbench import ConfigError, LogUniform
from hnnbench.neural import SHARED_SPACE, Family, NeuralConfig, NeuralModel

DHNN = Family(
    name="dhnn",
    title="Dissipative HNN: scalars H and D, dynamics J grad H + grad D",
    reference="Sosanya & Greydanus, Dissipative Hamiltonian Neural Networks: Learning "
    "Dissipative and Conservative Dynamics Separately, arXiv:2201.10085 (2022)",
    networks=lambda d: {"H": (d, 1), "D": (d, 1)},
    implementations={
        "torch": "hnnbench_plugins.models.dhnn.torch",
        "jax": "hnnbench_plugins.models.dhnn.jax",
    },
    order=30,
    learned_energy=True,
    search_space={**SHARED_SPACE, "dissipation_scale": LogUniform(0.1, 10.0)},
    recipe={
        "hidden": 256,
        "layers": 3,
        "activation": "tanh",
        "lr": 1e-3,
        "weight_decay": 0.0,
        "batch_size": 128,
        "steps": 5000,
    },
)


@dataclass
class DHNNConfig(NeuralConfig):
    """Attributes:
    dissipation_scale: ``s`` in ``ż = J ∇H + s ∇D`` (> 0; 1: the paper's model).
    """

    dissipation_scale: float = 1.0

    def validate(self) -> None:
        super().validate()
        if not (math.isfinite(self.dissipation_scale) and self.dissipation_scale > 0):
            raise ConfigError(
                f"model.dissipation_scale={self.dissipation_scale} is invalid: "
                "expected a finite number > 0, e.g. model.dissipation_scale=1."
            )


class _DHNN(NeuralModel):
    Config = DHNNConfig
    cfg: DHNNConfig

    def field_options(self) -> tuple[tuple[str, Any], ...]:
        return (("dissipation_scale", float(self.cfg.dissipation_scale)),)


class DHNNTorch(_DHNN):
    """Dissipative HNN (PyTorch; closed-form input gradients)."""

    family = DHNN
    backend = "torch"
    version = "2"  # 2: angles embedded (model.angle_embedding)


class DHNNJax(_DHNN):
    """Dissipative HNN (JAX; ``jax.grad``)."""

    family = DHNN
    backend = "jax"
    version = "2"  # 2: angles embedded (model.angle_embedding)
