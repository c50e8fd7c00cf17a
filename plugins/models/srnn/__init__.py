"""The symplectic recurrent neural network (Chen, Zhang, Arjovsky, Bottou, ICLR 2020).

A separable Hamiltonian ``H(q, p) = T(p) + V(q)`` from two scalar networks, trained
*through a leapfrog integrator*: from the first state of a window of consecutive
observed states of a training trajectory, ``substeps`` leapfrog steps per observed
interval (each interval's own measured time step) predict the next states, and the
loss is their mean squared error against the observations. No ``dx/dt`` target is
used. Checkpoints are selected on the system's validation criterion like every
family's (docs/METRICS.md, "Checkpoint selection"): the learned field ``(∂T/∂p,
−∂V/∂q)`` at the validation inputs, or, on measured data, short rollouts by the same
leapfrog map it trains through and rolls out with. Leapfrog
(Störmer-Verlet) is symplectic for separable ``H``:

    p ← p − (h/2) ∇V(q);   q ← q + h ∇T(p);   p ← p − (h/2) ∇V(q)

Rollouts (``model.integrator``): ``leapfrog`` (the default, and the SRNN the leaderboard
ranks) rolls out the model as it was trained, with its own leapfrog map at the training
step (the median observed interval over ``substeps``; each evaluation interval in equal
steps no longer than that, :func:`hnnbench.neural._backend.map_plan`). ``dopri5``
integrates the learned field ``ż = (∂T/∂p, −∂V/∂q)`` with the harness's adaptive
Dormand-Prince, as every other model is rolled out: a variant (``model.integrator=dopri5``,
a row of its own) that scores the learned Hamiltonian rather than the learned map. The
learned energy is ``T + V``. The original also optimised the initial states of noisy
trajectories; that is not done here.

The paper's recipe (the recipe track, ``track=recipe``), from the published code's
three-body script (github.com/zhengdao-chen/SRNN, src/script_3body_new and
src/run_experiments.py): two networks of 3 hidden layers of 512 tanh units, Adam at
3e-4 without weight decay, batches of 32 windows of 5 states, one leapfrog step per
observed interval. Not taken: its learning-rate decay on a plateau of the training-set
error (factor 0.7 after 15 epochs without improvement), its optimisation of the initial
states (from epoch 100), its length (1000 epochs) and its final-iterate model; the recipe
row trains for the system's protocol steps and keeps the best validation checkpoint like
every row.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from hnnbench import ConfigError, IntRange, check_int_at_least
from hnnbench.neural import SHARED_SPACE, Family, NeuralConfig, NeuralModel

SRNN = Family(
    name="srnn",
    title="Symplectic recurrent NN: H = T(p) + V(q) trained through leapfrog",
    reference="Chen, Zhang, Arjovsky, Bottou, Symplectic Recurrent Neural Networks, ICLR 2020",
    networks=lambda d: {"T": (d // 2, 1), "V": (d // 2, 1)},
    implementations={
        "torch": "hnnbench_plugins.models.srnn.torch",
        "jax": "hnnbench_plugins.models.srnn.jax",
    },
    order=60,
    data="windows",
    window=5,
    learned_energy=True,
    network_inputs={"T": "p", "V": "q"},
    # The window changes the training loss (the error over a longer horizon), not the
    # validation criterion, which is the system's (the same for every setting).
    search_space={**SHARED_SPACE, "window": IntRange(3, 8)},
    recipe={
        "hidden": 512,
        "layers": 4,
        "activation": "tanh",
        "lr": 3e-4,
        "weight_decay": 0.0,
        "batch_size": 32,
        "window": 5,
        "substeps": 1,
    },
)


#: ``model.integrator``: the trained leapfrog map, or the adaptive solver on the field.
INTEGRATORS = ("leapfrog", "dopri5")

#: The smoke profile: a narrow network (its second derivatives or leapfrog windows make
#: a step several times the HNN's), so quick jobs stay at seconds.
QUICK = {"quick": {**NeuralModel.profiles["quick"], "hidden": 32}}


@dataclass
class SRNNConfig(NeuralConfig):
    """Attributes:
    window: observed states per training window (the first is the start).
    substeps: leapfrog steps per observed interval.
    integrator: how rollouts are made: ``leapfrog`` (the trained map) or
        ``dopri5`` (the learned field, adaptive; the module docstring).
    """

    window: int = SRNN.window
    substeps: int = 1
    integrator: str = "leapfrog"

    def validate(self) -> None:
        super().validate()
        check_int_at_least("model", 2, window=self.window)
        check_int_at_least("model", 1, substeps=self.substeps)
        if self.integrator not in INTEGRATORS:
            raise ConfigError(
                f"model.integrator='{self.integrator}' is invalid: expected one of "
                f"{', '.join(INTEGRATORS)}."
            )


class _SRNN(NeuralModel):
    Config = SRNNConfig
    cfg: SRNNConfig

    def training_options(self) -> tuple[int, tuple[tuple[str, Any], ...]]:
        return self.cfg.window, (("substeps", int(self.cfg.substeps)),)

    def rolls_out_by_map(self) -> bool:
        return self.cfg.integrator == "leapfrog"

    def map_step(self) -> Optional[float]:
        """The leapfrog step of training (``data_step / substeps``) under
        ``integrator=leapfrog``; ``None`` (the adaptive solver) under ``dopri5``."""
        if not self.rolls_out_by_map():
            return None
        if self.data_step is None:
            raise RuntimeError(
                f"{self.name}: the leapfrog step is known after fit() or "
                "load() of a weights file that records it"
            )
        return self.data_step / int(self.cfg.substeps)


class SRNNTorch(_SRNN):
    """Symplectic recurrent NN (PyTorch)."""

    family = SRNN
    backend = "torch"
    version = "2"  # 2: rollouts by the trained leapfrog map; angles embedded
    profiles = QUICK


class SRNNJax(_SRNN):
    """Symplectic recurrent NN (JAX)."""

    family = SRNN
    backend = "jax"
    version = "2"  # 2: rollouts by the trained leapfrog map; angles embedded
    profiles = QUICK
