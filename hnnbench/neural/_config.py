"""The config every neural model shares: the 2019 paper's architecture and recipe."""

from __future__ import annotations

from dataclasses import dataclass
from types import MappingProxyType

from hnnbench._contracts.errors import ConfigError
from hnnbench._contracts.plugin import ModelConfig, check_int_at_least, check_positive
from hnnbench._contracts.space import Categorical, Distribution, IntRange, LogUniform
from hnnbench.neural._embedding import ANGLE_EMBEDDINGS

__all__ = ["ACTIVATIONS", "DTYPES", "LOSSES", "LR_SCHEDULES", "SHARED_SPACE", "NeuralConfig"]

ACTIVATIONS = ("tanh", "sigmoid", "softplus")
DTYPES = ("float32", "float64")
#: The training objectives of a family trained on derivatives (``NeuralConfig.loss``).
LOSSES = ("mse", "l1")
#: The learning-rate schedules of the training loop (``NeuralConfig.lr_schedule``;
#: :func:`hnnbench.neural._loop.lr_factors`).
LR_SCHEDULES = ("constant", "one_cycle")


@dataclass
class NeuralConfig(ModelConfig):
    """Every network of the model is an MLP of ``layers`` linear layers (``hidden``
    units each, no bias on the last), orthogonal weight init, trained with Adam.

    Attributes:
        hidden: hidden units per layer.
        layers: number of linear layers (the paper: 3, i.e. in -> 200 -> 200 -> out).
        activation: one of ``tanh``, ``sigmoid``, ``softplus``.
        dtype: training precision; rollouts always run in float64.
        log_every: record train/test loss every this many steps (0: about 200 points,
            at least 10 steps apart, so a 300-step smoke run does not spend a third of
            its time on test losses). It is also the length of one compiled training
            chunk of the JAX backend.
        rollout_max_steps: ODE solver step budget per rollout before it is declared
            diverged.
        angle_embedding: how every network reads the system's angles
            (:attr:`hnnbench.System.angles`): ``cos_sin``, ``wrap`` or ``none``
            (:mod:`hnnbench.neural._embedding`; docs/MODELS.md, "Periodic coordinates").
        loss: the training objective of a family trained on derivatives, over every
            component of the predicted time derivative: ``mse`` (mean squared error,
            every protocol's) or ``l1`` (mean absolute error, the LNN paper's recipe).
            Families trained on trajectory windows or pixels have their own objective
            and accept ``mse`` only. The validation loss that selects the checkpoint is
            the same objective on the validation split.
        lr_schedule: ``constant`` (every protocol's: ``lr`` at every step) or
            ``one_cycle`` (``lr`` is the peak; :func:`hnnbench.neural._loop.lr_factors`).
    """

    hidden: int = 200
    layers: int = 3
    activation: str = "tanh"
    dtype: str = "float32"
    log_every: int = 0
    rollout_max_steps: int = 50_000
    angle_embedding: str = "cos_sin"
    loss: str = "mse"
    lr_schedule: str = "constant"

    def validate(self) -> None:
        super().validate()
        check_positive("model", hidden=self.hidden, rollout_max_steps=self.rollout_max_steps)
        check_int_at_least("model", 2, layers=self.layers)
        if self.log_every < 0:
            raise ConfigError(f"model.log_every={self.log_every} is invalid: expected >= 0.")
        if self.activation not in ACTIVATIONS:
            raise ConfigError(
                f"model.activation='{self.activation}' is invalid: expected one of "
                f"{', '.join(ACTIVATIONS)}."
            )
        if self.angle_embedding not in ANGLE_EMBEDDINGS:
            raise ConfigError(
                f"model.angle_embedding='{self.angle_embedding}' is invalid: expected one "
                f"of {', '.join(ANGLE_EMBEDDINGS)}."
            )
        for key, value, allowed in (
            ("loss", self.loss, LOSSES),
            ("lr_schedule", self.lr_schedule, LR_SCHEDULES),
        ):
            if value not in allowed:
                raise ConfigError(
                    f"model.{key}='{value}' is invalid: expected one of {', '.join(allowed)}."
                )
        if self.dtype not in DTYPES:
            raise ConfigError(
                f"model.dtype='{self.dtype}' is invalid: expected one of {', '.join(DTYPES)}."
            )

    def log_interval(self, steps: int) -> int:
        """Steps between two loss records (one compiled chunk of the JAX backend)."""
        return self.log_every or max(10, steps // 200)


#: The search space over the settings every neural model has (``hnnbench tune``,
#: docs/TUNING.md): the learning rate around the protocols' 1e-3 (two decades), the
#: weight decay from none to the largest any protocol uses x 10, the width from a
#: quarter to twice the 2019 paper's 200 units, one to three hidden layers, and the
#: activation. A family declares ``{**SHARED_SPACE, <its own knobs>}`` (or leaves a
#: setting out that it cannot use), so that the settings all families share are searched
#: over the same ranges. Read-only.
SHARED_SPACE: MappingProxyType[str, Distribution] = MappingProxyType(
    {
        "lr": LogUniform(1e-4, 1e-2),
        "weight_decay": Categorical((0.0, 1e-5, 1e-4, 1e-3)),
        "hidden": Categorical((50, 100, 200, 400)),
        "layers": IntRange(2, 4),
        "activation": Categorical(ACTIVATIONS),
    }
)
