"""hnnbench: physics-informed models of dynamics vs plain networks, as a benchmark.

Running things (the ``hnnbench`` command's twins, :mod:`hnnbench.frontend`):
:func:`run`, :func:`sweep`, :func:`load`, :func:`leaderboard`; :func:`register` adds a
plugin to this process (a notebook's own model or system).

Writing plugins (docs/PLUGINS.md): :class:`System` and :class:`Model` with their config
dataclasses, the data containers, kinematics for second-order models, :class:`Metric`
declarations, the validation helpers and the errors. Neural model families build on
:mod:`hnnbench.neural`.

Importing hnnbench imports neither torch nor JAX (nor pandas).
"""

from hnnbench.api import (
    Dataset,
    FitResult,
    Model,
    ModelConfig,
    Progress,
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
from hnnbench.errors import (
    BackendMissingError,
    ConfigError,
    DataError,
    HnnbenchError,
    RolloutDiverged,
    UnknownNameError,
    UnsupportedPair,
)
from hnnbench.frontend import leaderboard, load, run, sweep
from hnnbench.kinematics import (
    Kinematics,
    LinearKinematics,
    MassMatrixKinematics,
    identity_kinematics,
)
from hnnbench.metric import CheckRule, Metric
from hnnbench.registry import register

__version__ = "0.2.0"

__all__ = [
    "BackendMissingError",
    "CheckRule",
    "ConfigError",
    "DataError",
    "Dataset",
    "FitResult",
    "HnnbenchError",
    "Kinematics",
    "LinearKinematics",
    "MassMatrixKinematics",
    "Metric",
    "Model",
    "ModelConfig",
    "Progress",
    "RolloutDiverged",
    "Split",
    "System",
    "SystemConfig",
    "TrainSettings",
    "Trajectories",
    "UnknownNameError",
    "UnsupportedPair",
    "__version__",
    "check_fraction",
    "check_int_at_least",
    "check_ordered",
    "check_positive",
    "identity_kinematics",
    "leaderboard",
    "load",
    "register",
    "run",
    "sweep",
]
