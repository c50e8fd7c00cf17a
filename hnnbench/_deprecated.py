"""Import shims for the module names of hnnbench 0.2 (to be removed in 0.5).

hnnbench 0.3 made every implementation module private (``hnnbench._name``); the public
names are re-exported by :mod:`hnnbench` and :mod:`hnnbench.neural`. Importing an old
module name still works (through the 0.4 releases) and warns once, naming the new import.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable
from types import ModuleType
from typing import Any


def forward(old: str, new: str) -> Callable[[str], Any]:
    """Warn that ``old`` moved, and return a module ``__getattr__`` that reads ``new``."""
    warnings.warn(
        f"{old} is deprecated and will be removed in hnnbench 0.5: import the public "
        f"names from hnnbench (or hnnbench.neural); the implementation is now {new}, "
        "which is private", DeprecationWarning, stacklevel=3)
    module: ModuleType = importlib.import_module(new)

    def __getattr__(name: str) -> Any:
        return getattr(module, name)

    return __getattr__
