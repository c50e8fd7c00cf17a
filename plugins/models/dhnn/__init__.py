"""The dissipative Hamiltonian neural network (Sosanya & Greydanus, 2022).

Two scalar networks, ``H(q, p)`` and ``D(q, p)``; the dynamics are
``ż = J ∇H + ∇D``: a conservative part (the symplectic gradient of ``H``) plus a
dissipative part (the gradient of ``D``), a Helmholtz decomposition of the field. The
learned energy is ``H``, the conserved part. With ``D ≡ 0`` it is the HNN.

``model.dissipation_scale`` (``s``, default 1) weighs the dissipative part,
``ż = J ∇H + s ∇D``: the scale of ``∇D`` at initialisation and its learning speed
relative to ``H``'s. A knob of the family's search space (``hnnbench tune``).
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
    implementations={"torch": "hnnbench_plugins.models.dhnn.torch",
                     "jax": "hnnbench_plugins.models.dhnn.jax"},
    order=30,
    learned_energy=True,
    search_space={**SHARED_SPACE, "dissipation_scale": LogUniform(0.1, 10.0)},
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
            raise ConfigError(f"model.dissipation_scale={self.dissipation_scale} is invalid: "
                              "expected a finite number > 0, e.g. model.dissipation_scale=1.")


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
