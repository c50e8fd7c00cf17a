"""hnnbench: physics-informed models of dynamics vs plain networks, as a benchmark.

This module is hnnbench's public surface; the implementation is private, one underscore
package per layer (``hnnbench._contracts``, ``hnnbench._running``, ...;
docs/ARCHITECTURE.md), and may change without notice.

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

from importlib import metadata as _metadata

from hnnbench._contracts.claims import Claim, ClaimSet, Published
from hnnbench._contracts.data_files import URL_SCHEMES, DataArchive, locate
from hnnbench._contracts.datasets import (
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
from hnnbench._contracts.errors import (
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
from hnnbench._contracts.integrate import VectorField, solve_batch
from hnnbench._contracts.kinematics import (
    Kinematics,
    LinearKinematics,
    MassMatrixKinematics,
    identity_kinematics,
)
from hnnbench._contracts.metric import (
    CheckRule,
    EvalContext,
    EvaluationConfig,
    Metric,
    per_point_squared_error,
    sem,
    summarize,
)
from hnnbench._contracts.names import ORACLE, REFERENCES, STANDING_STILL
from hnnbench._contracts.plugin import (
    CLEAN_INPUTS,
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
from hnnbench._contracts.space import Categorical, IntRange, LogUniform, SearchSpace, Uniform
from hnnbench._entry.api import leaderboard, load, run, sweep, tune
from hnnbench._registry import register

#: The installed distribution's version (pyproject.toml is its one source).
__version__ = _metadata.version("hnnbench")

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
