"""The plugin API: what a system and a model must provide.

Conventions used throughout:

- A *state* is ``x = (q_1..q_n, p_1..p_n)``: positions first, then momenta, so a batch of
  states has shape ``(N, 2n)``. Units are the system's own (the paper's toy systems are
  dimensionless).
- Arrays crossing the API are float64 numpy arrays. Backends convert at the boundary.
- A time grid ``t`` is 1-D, ``(T,)``, starting at the initial state's time. Data and
  evaluation grids are strictly increasing. (The reversibility metric flips the momenta
  and integrates forward again; no metric integrates backward in time.)

A third-party plugin subclasses :class:`System` or :class:`Model`, declares a config
dataclass (its defaults are the hyperparameters users get), and registers the class
under the entry-point group ``hnnbench.systems`` or ``hnnbench.models``.
"""

from __future__ import annotations

import dataclasses
import json
import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Optional

import numpy as np

from hnnbench._contracts import jsonio
from hnnbench._contracts.errors import ConfigError
from hnnbench._contracts.kinematics import Kinematics
from hnnbench._contracts.names import ORACLE, REFERENCES, STANDING_STILL
from hnnbench._contracts.outputs import checked
from hnnbench._contracts.space import SearchSpace

__all__ = [
    "CLEAN_INPUTS",
    "Dataset",
    "FitResult",
    "LATE_FRACTION",
    "ORACLE",
    "REFERENCES",
    "SELECTION_CRITERIA",
    "STANDING_STILL",
    "SELECTION_RULE",
    "SELECTION_Z",
    "Selection",
    "Model",
    "ModelConfig",
    "Progress",
    "STOPPED_BY_CALLER",
    "Split",
    "System",
    "SystemConfig",
    "TrainSettings",
    "Trajectories",
    "check_fraction",
    "check_int_at_least",
    "check_ordered",
    "check_positive",
]

#: Called by ``Model.fit`` as training goes: ``progress(step, {"train_loss": ...})``.
#: It may return ``True`` to ask the model to stop training there (a tuner's pruner,
#: docs/TUNING.md); a model that cannot stop early ignores it.
Progress = Callable[[int, Mapping[str, float]], Optional[bool]]
#: The start of ``Selection.stopped`` for a run stopped because its progress callback
#: returned ``True`` (the rest names the step).
STOPPED_BY_CALLER = "stopped by the progress callback"


def check_positive(owner: str, **values: float | int | None) -> None:
    """Raise a one-line :class:`ConfigError` for the first value that is not > 0.

    ``None`` values are skipped (they mean "use the default").
    """
    for key, value in values.items():
        if value is not None and not (value > 0 and math.isfinite(value)):
            raise ConfigError(
                f"{owner}.{key}={value} is invalid: expected a finite number > 0. "
                f"Fix it with {owner}.{key}=<positive value>."
            )


def check_int_at_least(owner: str, low: int, **values: Any) -> None:
    """Raise a one-line :class:`ConfigError` for the first value that is not an integer
    ``>= low`` (booleans are rejected)."""
    for key, value in values.items():
        ok = not isinstance(value, bool) and isinstance(value, (int, np.integer))
        if not ok or value < low:
            raise ConfigError(
                f"{owner}.{key}={value} is invalid: expected an integer >= {low}. "
                f"Fix it with {owner}.{key}=<integer >= {low}>."
            )


def check_fraction(owner: str, key: str, value: float, example: float) -> None:
    """Raise a one-line :class:`ConfigError` unless ``0 < value < 1``."""
    if not 0.0 < value < 1.0:
        raise ConfigError(
            f"{owner}.{key}={value} is invalid: expected a fraction strictly between 0 and "
            f"1, e.g. {owner}.{key}={example}."
        )


def check_ordered(owner: str, low_key: str, low: float, high_key: str, high: float) -> None:
    """Raise a one-line :class:`ConfigError` unless ``low <= high``."""
    if high < low:
        raise ConfigError(
            f"{owner}.{high_key}={high} is below {owner}.{low_key}={low}: expected "
            f"{low_key} <= {high_key}."
        )


# --------------------------------------------------------------------------- configs


@dataclass
class SystemConfig:
    """Base config of a system; subclass it (as a dataclass) to add data settings.

    The training fields are the task's training protocol (the paper fixes them per
    task); a model config may override each of them. Every other field describes how
    data and evaluation trajectories are made, and keys the dataset cache.
    """

    name: str = "???"
    #: Optimizer steps.
    steps: int = 2000
    #: Minibatch size; ``None`` trains on the full training set every step.
    batch_size: Optional[int] = None
    #: Adam learning rate.
    lr: float = 1e-3
    #: Adam (L2) weight decay.
    weight_decay: float = 0.0

    TRAINING_FIELDS: ClassVar[tuple[str, ...]] = ("steps", "batch_size", "lr", "weight_decay")

    def validate(self) -> None:
        """Raise :class:`ConfigError` on an invalid value. Extend in subclasses."""
        check_positive("system", steps=self.steps, batch_size=self.batch_size, lr=self.lr)
        if not (self.weight_decay >= 0 and math.isfinite(self.weight_decay)):
            raise ConfigError(
                f"system.weight_decay={self.weight_decay} is invalid: expected a finite "
                "number >= 0."
            )

    def data_fields(self) -> dict[str, Any]:
        """The fields that determine the generated data (the cache key)."""
        out = dataclasses.asdict(self)
        for key in (*self.TRAINING_FIELDS, "name"):
            out.pop(key, None)
        return out


@dataclass
class ModelConfig:
    """Base config of a model. ``None`` training fields take the system's protocol."""

    name: str = "???"
    steps: Optional[int] = None
    batch_size: Optional[int] = None
    lr: Optional[float] = None
    weight_decay: Optional[float] = None

    def validate(self) -> None:
        """Raise :class:`ConfigError` on an invalid value. Extend in subclasses."""
        check_positive("model", steps=self.steps, batch_size=self.batch_size, lr=self.lr)
        if self.weight_decay is not None and not (
            self.weight_decay >= 0 and math.isfinite(self.weight_decay)
        ):
            raise ConfigError(
                f"model.weight_decay={self.weight_decay} is invalid: expected a finite number >= 0."
            )


@dataclass(frozen=True)
class TrainSettings:
    """The training protocol of one job: the system's, with the model's overrides."""

    steps: int
    batch_size: Optional[int]
    lr: float
    weight_decay: float

    @classmethod
    def resolve(cls, system: SystemConfig, model: ModelConfig) -> TrainSettings:
        def pick(key: str) -> Any:
            value = getattr(model, key, None)
            return getattr(system, key) if value is None else value

        return cls(**{key: pick(key) for key in SystemConfig.TRAINING_FIELDS})


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Split:
    """One split (train or test) of a dataset.

    Attributes:
        x: ``(N, D)`` model inputs: states ``(N, 2n)``, or flattened observations
            (for pixel systems, two consecutive frames, ``D = 2 * H * W``).
        dxdt: ``(N, D)`` targets: the time derivative of ``x`` (clean, noise-free).
        traj: ``(N,)`` integer trajectory id of each point.
        t: ``(N,)`` time of each point within its trajectory.
        extras: further per-point arrays, each with leading dimension ``N`` (for pixel
            systems, ``"state"``: the true ``(N, 2n)`` state, used by the linear probe;
            for systems that add noise to their inputs, :data:`CLEAN_INPUTS`: the
            inputs before the noise, on which the test loss is taken).
    """

    x: np.ndarray
    dxdt: np.ndarray
    traj: np.ndarray
    t: np.ndarray
    extras: dict[str, np.ndarray] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.x.shape[0])


#: The criteria a system may select checkpoints on (:attr:`System.selection`).
SELECTION_CRITERIA = ("field", "rollout")

#: ``Split.extras`` key of the noise-free inputs ``(N, D)`` behind noisy ``x``: a system
#: that adds noise to its inputs stores them, and ``test_loss`` compares the model's
#: field at them with the (clean) targets, so the test loss has no noise floor
#: (docs/METRICS.md); the validation criterion that selects checkpoints and the
#: ``val_loss`` metric are taken there too. Training stays on the noisy inputs.
CLEAN_INPUTS = "x_clean"


@dataclass(frozen=True)
class Dataset:
    """A train/test split of points and targets, plus JSON-serialisable metadata.

    ``valid`` is the validation split. A system's ``dataset`` usually leaves it
    ``None`` and the job carves it from the training data before a model sees it
    (:func:`hnnbench._contracts.datasets.with_validation`, one rule for every system); a system
    whose seeds choose folds of one measured series gives its own (its ``meta``
    ``"validation"`` says by which rule). Models select their checkpoint on it, never on
    ``test``."""

    train: Split
    test: Split
    meta: dict[str, Any] = field(default_factory=dict)
    valid: Optional[Split] = None

    def save(self, path: Path) -> None:
        """Write to ``path`` (an ``.npz``), without pickle."""
        arrays: dict[str, np.ndarray] = {"__meta__": np.array(json.dumps(self.meta))}
        for split_name in ("train", "test", "valid"):
            split: Optional[Split] = getattr(self, split_name)
            if split is None:
                continue
            for key in ("x", "dxdt", "traj", "t"):
                arrays[f"{split_name}.{key}"] = getattr(split, key)
            for key, value in split.extras.items():
                arrays[f"{split_name}.extras.{key}"] = value
        _savez(path, arrays)

    @classmethod
    def load(cls, path: Path) -> Dataset:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {key: npz[key] for key in npz.files}
        meta = jsonio.loads(str(arrays.pop("__meta__")))

        def split(prefix: str) -> Split:
            extras = {
                key.split(".", 2)[2]: value
                for key, value in arrays.items()
                if key.startswith(f"{prefix}.extras.")
            }
            return Split(
                x=arrays[f"{prefix}.x"],
                dxdt=arrays[f"{prefix}.dxdt"],
                traj=arrays[f"{prefix}.traj"],
                t=arrays[f"{prefix}.t"],
                extras=extras,
            )

        valid = split("valid") if "valid.x" in arrays else None
        return cls(train=split("train"), test=split("test"), meta=meta, valid=valid)


@dataclass(frozen=True)
class Trajectories:
    """Ground-truth trajectories used by the rollout metrics.

    Attributes:
        t: ``(T,)`` time grid, ``t[0]`` is the time of the initial states.
        states: ``(M, T, 2n)`` true states along each trajectory.
        dt: the data's sampling interval (for plugins and plots; the rollout metrics
            integrate adaptively on ``t``).
        observations: for pixel systems, ``(M, T, D)`` model inputs along each
            trajectory (``None`` for state systems, whose inputs are the states).
        meta: JSON-serialisable description of the protocol (horizon, tolerances, ...).
    """

    t: np.ndarray
    states: np.ndarray
    dt: float
    observations: Optional[np.ndarray] = None
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def x0(self) -> np.ndarray:
        """``(M, 2n)`` initial states."""
        return self.states[:, 0]

    def save(self, path: Path) -> None:
        arrays = {
            "t": self.t,
            "states": self.states,
            "dt": np.array(self.dt),
            "__meta__": np.array(json.dumps(self.meta)),
        }
        if self.observations is not None:
            arrays["observations"] = self.observations
        _savez(path, arrays)

    @classmethod
    def load(cls, path: Path) -> Trajectories:
        with np.load(path, allow_pickle=False) as npz:
            return cls(
                t=npz["t"],
                states=npz["states"],
                dt=float(npz["dt"]),
                observations=npz["observations"] if "observations" in npz.files else None,
                meta=jsonio.loads(str(npz["__meta__"])),
            )


def _savez(path: Path, arrays: dict[str, np.ndarray]) -> None:
    savez: Any = np.savez  # numpy's stub reads **arrays as its allow_pickle keyword
    with open(path, "wb") as fh:
        savez(fh, **arrays)


# --------------------------------------------------------------------------- plugins


class System(ABC):
    """A physical system: its true energy and dynamics, its data and evaluation protocol.

    Class attributes a subclass sets:
        Config: its config dataclass (a :class:`SystemConfig` subclass).
        version: bump when data generation changes; every record stores it.
        description: one line for ``hnnbench list``.
        observation: ``"state"`` (models see ``(q, p)``) or ``"pixels"``.
        time_reversible: the true dynamics are time-reversal symmetric,
            ``R Φ_T R Φ_T x = x`` with ``R(q, p) = (q, -p)``; enables the
            reversibility metric (NaN elsewhere).
        conservative: the true dynamics conserve :meth:`energy`; enables the
            long-horizon energy-drift metric (NaN elsewhere). ``False`` for damped and
            measured systems.
        profiles: per-profile overrides of the config defaults, e.g.
            ``{"quick": {"steps": 200, "n_traj": 20}}``. The ``paper`` profile is the
            dataclass defaults; ``quick`` is the only other profile.
        order: position in listings and tables (lower first; ``None``: after the
            plugins that set one, by name).
        selection: the criterion the training loop selects checkpoints on
            (docs/METRICS.md, "Checkpoint selection"): ``"field"`` (the default), the
            model's field against the targets at the validation inputs, at the clean
            ones where the system adds noise (:data:`CLEAN_INPUTS`), in the system's
            coordinates; ``"rollout"``, for data with no clean inputs behind its noise
            (measured series): the position error of short rollouts from each window of
            ``selection_steps + 1`` consecutive validation states, which averages the
            measurement noise out. Pixel models select on their own objective.
        selection_steps: the intervals of one rollout window (``selection="rollout"``).
        reversal_in_distribution: whether the momentum-flipped states the
            reversibility test starts from are like the training data; ``False`` where
            every training trajectory turns one way (the n-body orbits), so the test
            probes states the models never saw (the report says so beside the metric).

    Optional methods and properties a subclass may override: :meth:`vector_field`
    (where the dynamics are known), :meth:`kinematics` (for second-order models),
    :attr:`lyapunov_time` (for chaotic systems), :attr:`angles` (positions that are
    angles), :attr:`wrapped_angles` (where the data wraps angles).
    """

    Config: ClassVar[type[SystemConfig]] = SystemConfig
    version: ClassVar[str] = "1"
    description: ClassVar[str] = ""
    observation: ClassVar[str] = "state"
    time_reversible: ClassVar[bool] = True
    conservative: ClassVar[bool] = True
    profiles: ClassVar[dict[str, dict[str, Any]]] = {}
    order: ClassVar[Optional[float]] = None
    selection: ClassVar[str] = "field"
    selection_steps: ClassVar[int] = 4
    reversal_in_distribution: ClassVar[bool] = True

    def __init__(self, cfg: SystemConfig) -> None:
        self.cfg = cfg

    @property
    def name(self) -> str:
        return self.cfg.name

    @property
    @abstractmethod
    def dof(self) -> int:
        """Degrees of freedom n; a state has 2n numbers."""

    @abstractmethod
    def energy(self, x: np.ndarray) -> np.ndarray:
        """True energy ``(N,)`` of states ``x`` of shape ``(N, 2n)``."""

    def vector_field(self, x: np.ndarray) -> Optional[np.ndarray]:
        """True ``dx/dt`` of shape ``(N, 2n)``, or ``None`` where unknown (measured data)."""
        return None

    @property
    def has_vector_field(self) -> bool:
        """Whether :meth:`vector_field` is implemented."""
        return type(self).vector_field is not System.vector_field

    @abstractmethod
    def dataset(self, seed: int) -> Dataset:
        """The train/test data for ``seed``. Must be deterministic given config and seed."""

    @abstractmethod
    def evaluation(self, seed: int) -> Trajectories:
        """Ground-truth evaluation trajectories for ``seed`` (deterministic)."""

    def kinematics(self) -> Optional[Kinematics]:
        """How positions move (:mod:`hnnbench._contracts.kinematics`): the map between canonical
        states ``(q, p)`` and velocity states ``(q, q̇)``. ``None`` (the default): not
        declared, and models that need it (second-order families) skip this system."""
        return None

    @property
    def lyapunov_time(self) -> Optional[float]:
        """The system's Lyapunov time (the inverse of its largest Lyapunov exponent),
        in its time units, for the configured regime; ``None`` where it is not chaotic
        or not known. Enables the ``vpt_lyapunov`` metric."""
        return None

    @property
    def angles(self) -> tuple[int, ...]:
        """Indices ``i < n`` of the positions ``q_i`` that are angles: the dynamics and
        the energy are 2π-periodic in each of them. Every neural network reads them
        through a periodic embedding (``model.angle_embedding``), and the state-error
        metrics compare them modulo 2π (docs/METRICS.md). ``()`` (the default): none.
        Independent of :attr:`wrapped_angles`, which says how the *data* gives them."""
        return ()

    @property
    def wrapped_angles(self) -> tuple[int, ...]:
        """Indices ``i < n`` of the positions ``q_i`` that the data gives as angles
        wrapped into ``[-π, π)``, so that consecutive samples of one trajectory jump by
        2π where the angle crosses ±π. Models that train on windows of consecutive
        states (:func:`hnnbench.neural._views.trajectory_windows`) make each window
        continuous again. ``()`` (the default): no coordinate is wrapped."""
        return ()

    def reverse(self, x: np.ndarray) -> np.ndarray:
        """The time-reversal map R: flip the momenta of ``(N, 2n)`` states."""
        out = np.array(x, dtype=np.float64, copy=True)
        out[..., self.dof :] *= -1.0
        return out


class Model(ABC):
    """A learner of dynamics.

    Class attributes a subclass sets:
        Config: its config dataclass (a :class:`ModelConfig` subclass).
        version, description, profiles: as for :class:`System`.
        backend: ``"torch"``, ``"jax"`` or ``"numpy"``.
        observations: the system observations it handles (``"state"``, ``"pixels"``).
        weights_file: the file name :meth:`save` writes in the job's directory, e.g.
            ``"weights.safetensors"``; ``None`` (the default): nothing to save.
        order: position in listings and tables, as for :class:`System`.
        ranked: ``False`` for a reference that is not a competitor (the oracle): its
            rows are shown but never ranked or highlighted as best.
        reference: the role of a trivial reference (:data:`REFERENCES`):
            ``"zero_field"`` (standing still, a model that predicts no motion: a leader
            must beat it to be marked best) or ``"true_field"`` (the oracle, the true
            dynamics: every metric's floor);
            ``None`` for a competitor. A reference is never ranked.
        search_space: what ``hnnbench tune`` may vary, ``{setting: distribution}``
            over fields of ``Config`` (:mod:`hnnbench._contracts.space`: ``LogUniform``,
            ``Uniform``, ``IntRange``, ``Categorical``); ``None`` (the default): the
            model is not tuned. Checked when the registry discovers the model.
        recipe: the model's paper's own training recipe, ``{setting: value}`` over
            fields of ``Config`` (the training fields included), which the defaults
            take under ``track=recipe`` (the smoke profile's overrides still apply on
            top); ``None`` (the default): no recipe, and the model's jobs on the recipe
            track are skipped. Checked when the registry discovers the model.
    """

    Config: ClassVar[type[ModelConfig]] = ModelConfig
    version: ClassVar[str] = "1"
    description: ClassVar[str] = ""
    backend: ClassVar[str] = "numpy"
    observations: ClassVar[tuple[str, ...]] = ("state",)
    profiles: ClassVar[dict[str, dict[str, Any]]] = {}
    weights_file: ClassVar[Optional[str]] = None
    order: ClassVar[Optional[float]] = None
    ranked: ClassVar[bool] = True
    reference: ClassVar[Optional[str]] = None
    search_space: ClassVar[Optional[SearchSpace]] = None
    recipe: ClassVar[Optional[dict[str, Any]]] = None

    def __init__(self, cfg: ModelConfig, system: System, device: str = "auto") -> None:
        self.cfg = cfg
        self.system = system
        self.requested_device = device
        #: Extra timings (seconds) a model wants recorded, e.g. ``{"compile_s": 1.2}``.
        self.timings: dict[str, float] = {}

    @property
    def name(self) -> str:
        return self.cfg.name

    @property
    def device(self) -> str:
        """The device actually used (``"cpu"``, ``"cuda:0"``, ...)."""
        return "cpu"

    @classmethod
    def requirements_missing(cls) -> Optional[str]:
        """Why this model cannot run in this environment at all, e.g. an install hint
        for a missing backend (``None``: it can). Checked by the registry without
        importing the backend; ``hnnbench list`` shows it and ``all`` leaves the model
        out."""
        return None

    @classmethod
    def unsupported_reason(cls, system: System) -> Optional[str]:
        """Why this model cannot run on ``system`` (``None`` if it can)."""
        if system.observation not in cls.observations:
            return (
                f"{system.observation} observations are not supported "
                f"(supports: {', '.join(cls.observations)})"
            )
        return None

    @abstractmethod
    def fit(self, data: Dataset, train: TrainSettings, seed: int, progress: Progress) -> FitResult:
        """Train on ``data.train``; report losses through ``progress``.

        Training that diverges (a non-finite loss) is reported in the result's
        ``diverged``, never raised: the job then records ``diverged`` with that reason.
        """

    def fit_seeds(
        self,
        data: Sequence[Dataset],
        train: TrainSettings,
        seeds: Sequence[int],
        progress: Progress,
    ) -> list[tuple[Model, FitResult]]:
        """Train one model per seed (seed ``seeds[k]`` on ``data[k]``, the system's
        dataset of that seed), in order: ``[(trained model, result)]``.

        A seed whose training diverges gets a result with ``diverged`` set; the others
        are unaffected. The default trains a fresh instance per seed, one after the
        other; a model that can train several seeds as one batch (the neural models)
        overrides it. Used when a job trains several seeds (``seeds_per_job``).
        """
        out: list[tuple[Model, FitResult]] = []
        for seed, seed_data in zip(seeds, data, strict=True):
            model = type(self)(self.cfg, self.system, self.requested_device)
            out.append((model, model.fit(seed_data, train, seed, progress)))
        return out

    @abstractmethod
    def time_derivative(self, x: np.ndarray) -> np.ndarray:
        """Predicted ``dx/dt`` ``(N, D)`` for inputs ``x`` ``(N, D)``."""

    @abstractmethod
    def rollout(
        self, x0: np.ndarray, t: np.ndarray, rtol: float = 1e-9, atol: float = 1e-9
    ) -> np.ndarray:
        """Integrate the learned dynamics from ``x0`` ``(M, D)`` over ``t`` ``(T,)``.

        Adaptive Dormand-Prince in float64, batched over initial states; ``t`` is
        increasing. Returns ``(M, T, D)``; raise
        :class:`hnnbench._contracts.errors.RolloutDiverged` if the solver gives up.
        """

    def loss(self, x: np.ndarray, dxdt: np.ndarray) -> float:
        """The loss reported as train/test loss: MSE of ``dx/dt`` (override for
        models whose objective is more than that, e.g. autoencoders)."""
        pred = checked(
            self,
            "time_derivative",
            self.time_derivative(x),
            np.shape(dxdt),
            "(N, D) like its targets",
        )
        return float(np.mean((pred - dxdt) ** 2))

    def energy(self, x: np.ndarray) -> Optional[np.ndarray]:
        """The learned conserved quantity ``(N,)`` if the model has one, else ``None``."""
        return None

    def encode(self, obs: np.ndarray) -> np.ndarray:
        """Map observations ``(N, D_obs)`` to the space :meth:`rollout` works in,
        ``(N, D_latent)`` (identity for state models)."""
        return obs

    def decode(self, z: np.ndarray) -> Optional[np.ndarray]:
        """Map latents ``(N, D_latent)`` back to observations ``(N, D_obs)``; ``None``
        for models without a decoder (state models)."""
        return None

    def save(self, path: Path) -> None:
        """Write the trained weights to exactly ``path`` (``<job dir>/<weights_file>``;
        write no other file and add no suffix), without pickle (safetensors, npz).
        Called after a successful fit when ``weights_file`` is set."""
        raise NotImplementedError(f"{type(self).__name__} does not implement save()")

    def load(self, path: Path) -> None:
        """Read weights written by :meth:`save` (the model is built with the same config
        and system)."""
        raise NotImplementedError(f"{type(self).__name__} does not implement load()")


#: The training log's columns (:attr:`FitResult.history`): the optimizer step, and the
#: losses on the training and validation sets at that step. (Named like the built-in
#: loss metrics, but a different thing: the log, not the evaluation.) Records written
#: before the validation split logged the test loss instead (``test_loss``).
HISTORY_STEP, HISTORY_TRAIN, HISTORY_VALID = "step", "train_loss", "val_loss"


#: The rule of :class:`Selection` (the record's ``selection.rule``): the last checkpoint is
#: scored unless an earlier one beats it on the validation criterion by more than
#: :data:`SELECTION_Z` paired standard errors (docs/METRICS.md, "Checkpoint selection").
SELECTION_RULE = (
    "the final checkpoint, unless an earlier one is lower on the criterion "
    "by more than 2 paired standard errors"
)
#: How many paired standard errors an earlier checkpoint must win by to be scored.
SELECTION_Z = 2.0
#: The share of training whose criterion change says whether a run converged: the
#: evaluation at or before ``(1 - LATE_FRACTION) * steps`` against the final one.
LATE_FRACTION = 0.2


@dataclass(frozen=True)
class Selection:
    """Which checkpoint of a training run is scored, and what the validation criterion
    says of it (docs/METRICS.md, "Checkpoint selection").

    The criterion is evaluated every ``interval`` steps on the validation split
    (``criterion`` names it: e.g. ``field_mse_clean``, the field's squared error at the
    clean inputs; ``rollout_q_mse_4``, the position error of 4-interval rollouts). The
    final checkpoint is scored unless the lowest earlier one beats it by more than
    :data:`SELECTION_Z` paired standard errors (the checkpoints share the validation
    points, so their difference is judged point by point).

    Attributes:
        step: the optimizer step of the scored weights.
        val_loss: the criterion's value there.
        evaluations: validation evaluations made (one per logging interval).
        first_step: the step of the first evaluation; ``step == first_step`` means the
            run did not improve after its first interval (:attr:`trained` is false).
        stopped: why training stopped before its last step (a non-finite loss after
            the selected checkpoint), else ``None``.
        criterion: the criterion's name (``None``: unnamed, e.g. a plugin's own loop).
        points: the validation points (or windows) the criterion averages.
        best_step, best_value: the lowest-criterion checkpoint.
        final_step, final_value: the last evaluated checkpoint.
        final_se: the paired standard error of ``final - best`` (NaN: undefined).
        late_step, late_value: the checkpoint at or before 80% of the steps.
        late_se: the paired standard error of ``late - final``.
    """

    step: int
    val_loss: float
    evaluations: int
    first_step: int
    stopped: Optional[str] = None
    criterion: Optional[str] = None
    points: int = 0
    best_step: Optional[int] = None
    best_value: float = math.nan
    final_step: Optional[int] = None
    final_value: float = math.nan
    final_se: float = math.nan
    late_step: Optional[int] = None
    late_value: float = math.nan
    late_se: float = math.nan

    @property
    def trained(self) -> bool:
        """Whether the selected weights come after the first evaluation."""
        return self.step > self.first_step

    @property
    def converged(self) -> Optional[bool]:
        """Whether the criterion stopped improving over the last :data:`LATE_FRACTION`
        of training: ``late - final`` is at most :data:`SELECTION_Z` paired standard
        errors (``None``: not measured, e.g. no late checkpoint or no standard error)."""
        if self.late_step is None or self.final_step is None or self.late_step >= self.final_step:
            return None
        change, se = self.late_value - self.final_value, self.late_se
        if not (math.isfinite(change) and math.isfinite(se)):
            return None
        return change <= SELECTION_Z * se

    def as_record(self) -> dict[str, Any]:
        """The record's ``selection`` field."""
        num = float  # non-finite values: the record writer encodes them
        out: dict[str, Any] = {
            "rule": SELECTION_RULE,
            "criterion": self.criterion,
            "step": self.step,
            "validation_loss": num(self.val_loss),
            "evaluations": self.evaluations,
            "first_step": self.first_step,
            "trained": self.trained,
            "stopped": self.stopped,
        }
        if self.best_step is not None:
            out.update(
                {
                    "points": self.points,
                    "best_step": self.best_step,
                    "best_value": num(self.best_value),
                    "final_step": self.final_step,
                    "final_value": num(self.final_value),
                    "final_se": num(self.final_se),
                    "late_step": self.late_step,
                    "late_value": num(self.late_value),
                    "late_se": num(self.late_se),
                    "converged": self.converged,
                }
            )
        return out


@dataclass
class FitResult:
    """What training returns.

    Attributes:
        history: columns of the training log (:data:`HISTORY_STEP`,
            :data:`HISTORY_TRAIN`, :data:`HISTORY_VALID`), all of the same length; a
            non-finite value in either loss column marks divergence, unless a
            checkpoint was selected before it (``selection``).
        steps: optimizer steps taken; 0 for a model without an iterative training
            loop (closed form, least squares), whose record then shows no training
            protocol.
        diverged: why training diverged (the job records ``diverged`` with this
            reason); ``None`` otherwise. The only way a fit reports divergence.
        selection: the checkpoint the model holds after ``fit`` (its weights are the
            selected ones), for a model that selects on validation; ``None`` for one
            that keeps its last iterate.
    """

    history: dict[str, list[float]] = field(default_factory=dict)
    steps: int = 0
    diverged: Optional[str] = None
    selection: Optional[Selection] = None
