"""hnnbench: physics-informed models of dynamics vs plain networks, as a benchmark.

The public API for plugin authors is re-exported here. Importing hnnbench imports
neither torch nor JAX.
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
    check_positive,
)
from hnnbench.errors import (
    BackendMissingError,
    ConfigError,
    DataError,
    HnnbenchError,
    RolloutDiverged,
    UnknownNameError,
)

__version__ = "0.1.0"

__all__ = [
    "BackendMissingError",
    "ConfigError",
    "DataError",
    "Dataset",
    "FitResult",
    "HnnbenchError",
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
    "__version__",
    "check_positive",
]
