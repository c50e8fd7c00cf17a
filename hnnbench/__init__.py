"""hnnbench: physics-informed models of dynamics vs plain networks, as a benchmark.

This module is hnnbench's public surface; every implementation module is private
(``hnnbench._name``) and may change without notice.

Running things (the ``hnnbench`` command's twins): :func:`run`, :func:`sweep`,
:func:`tune` (the tuned track), :func:`load`, :func:`leaderboard`; :func:`register` adds
a plugin to this process (a notebook's own model or system).

Writing plugins (docs/PLUGINS.md): :class:`System` and :class:`Model` with their config
dataclasses, the data containers, kinematics for second-order models, :class:`Metric`
declarations and the :class:`EvalContext` their ``compute`` reads, claim sets
(:class:`ClaimSet`), the dataset helpers (:func:`seed_stream`, :class:`TrajectorySplit`,
:func:`trajectory_dataset`), the reference integrator (:func:`solve_batch`), measured-data
lookup (:func:`locate`), the validation helpers, the errors and :func:`require_backend`
(a plugin module's guard for an optional dependency), and a model's search space
(:class:`LogUniform`, :class:`Uniform`, :class:`IntRange`, :class:`Categorical`). Neural
model families build on :mod:`hnnbench.neural`.

Importing hnnbench imports neither torch nor JAX (nor pandas).
"""

from hnnbench._claims import Claim, ClaimSet, Published
from hnnbench._contract import (
    CLEAN_INPUTS,
    ORACLE,
    REFERENCES,
    STANDING_STILL,
    Dataset,
    FitResult,
    Model,
    ModelConfig,
    Progress,
    Selection,
    Split,
    System,
    SystemConfig,
    TrainSettings,
    Trajectories,
    check_fraction,
    check_int_at_least,
    check_ordered,
    check_positive,
)
from hnnbench._data import URL_SCHEMES, DataArchive, locate
from hnnbench._datasets import (
    DATA_STREAM,
    EVAL_STREAM,
    SPLIT_STREAM,
    VALID_STREAM,
    TrajectoryIndices,
    TrajectorySplit,
    seed_stream,
    trajectory_dataset,
    with_validation,
)
from hnnbench._errors import (
    BackendMissingError,
    ConfigError,
    DataError,
    HnnbenchError,
    ModelOutputError,
    RolloutDiverged,
    UnknownNameError,
    UnsupportedPair,
    require_backend,
)
from hnnbench._integrate import VectorField, solve_batch
from hnnbench._kinematics import (
    Kinematics,
    LinearKinematics,
    MassMatrixKinematics,
    identity_kinematics,
)
from hnnbench._metric import (
    CheckRule,
    EvalContext,
    EvaluationConfig,
    Metric,
    per_point_squared_error,
    sem,
    summarize,
)
from hnnbench._registry import register
from hnnbench._space import Categorical, IntRange, LogUniform, SearchSpace, Uniform
from hnnbench._user_api import leaderboard, load, run, sweep, tune

__version__ = "0.4.0"

__all__ = [
    "BackendMissingError",
    "Categorical",
    "CheckRule",
    "CLEAN_INPUTS",
    "ORACLE",
    "REFERENCES",
    "STANDING_STILL",
    "Claim",
    "ClaimSet",
    "ConfigError",
    "DATA_STREAM",
    "DataArchive",
    "DataError",
    "Dataset",
    "EVAL_STREAM",
    "EvalContext",
    "EvaluationConfig",
    "FitResult",
    "Selection",
    "HnnbenchError",
    "IntRange",
    "Kinematics",
    "LinearKinematics",
    "LogUniform",
    "MassMatrixKinematics",
    "Metric",
    "Model",
    "ModelConfig",
    "ModelOutputError",
    "Progress",
    "Published",
    "RolloutDiverged",
    "SPLIT_STREAM",
    "SearchSpace",
    "VALID_STREAM",
    "Split",
    "System",
    "SystemConfig",
    "TrainSettings",
    "Trajectories",
    "TrajectoryIndices",
    "TrajectorySplit",
    "URL_SCHEMES",
    "Uniform",
    "UnknownNameError",
    "UnsupportedPair",
    "VectorField",
    "__version__",
    "check_fraction",
    "check_int_at_least",
    "check_ordered",
    "check_positive",
    "identity_kinematics",
    "leaderboard",
    "load",
    "locate",
    "per_point_squared_error",
    "register",
    "require_backend",
    "run",
    "seed_stream",
    "sem",
    "solve_batch",
    "summarize",
    "sweep",
    "trajectory_dataset",
    "tune",
    "with_validation",
]
