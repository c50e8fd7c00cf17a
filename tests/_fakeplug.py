"""Misbehaving test models, installed as a real distribution (a ``.dist-info`` with entry
points) into a temporary directory that goes on ``PYTHONPATH`` / ``sys.path``.

- ``nan_model``: trains "fine" but predicts NaN everywhere (its rollout is NaN too).
- ``crash_model``: raises a RuntimeError during training.
- ``rollout_crash_model``: trains, then raises a RuntimeError in its rollout.
- ``needs_backend``: its module needs a backend that is not installed (import fails
  with hnnbench's one-line BackendMissingError, as the JAX models do without JAX).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DIST = "hnnbench_fakeplug"

MODULE = '''
import numpy as np

from hnnbench._contracts.plugin import FitResult, Model, ModelConfig


class NaNModel(Model):
    """Predicts NaN."""

    Config = ModelConfig
    backend = "numpy"

    def fit(self, data, train, seed, progress):
        progress(1, {"train_loss": 1.0})
        return FitResult(history={"step": [1], "train_loss": [1.0]}, steps=1)

    def time_derivative(self, x):
        return np.full(np.shape(x), np.nan)

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
        return np.full((len(x0), len(t), np.shape(x0)[1]), np.nan)


class CrashModel(NaNModel):
    """Raises during training."""

    def fit(self, data, train, seed, progress):
        raise RuntimeError("boom: the model crashed on purpose")


class RolloutCrashModel(NaNModel):
    """Trains, then raises in its rollout (e.g. out of memory)."""

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
        raise RuntimeError("boom: the rollout crashed on purpose")
'''

NO_BACKEND = """
from hnnbench._contracts.errors import require_backend

require_backend("hnnbench_no_such_backend_xyz", "jax")

from hnnbench_fakeplug import NaNModel as NeedsBackend  # noqa: E402
"""

ENTRY_POINTS = """[hnnbench.models]
nan_model = hnnbench_fakeplug:NaNModel
crash_model = hnnbench_fakeplug:CrashModel
rollout_crash_model = hnnbench_fakeplug:RolloutCrashModel
needs_backend = hnnbench_fakeplug.nobackend:NeedsBackend
"""


def install(site: Path) -> Path:
    """Write the package and its dist-info into ``site``; return ``site``."""
    pkg = site / DIST
    pkg.mkdir(parents=True, exist_ok=True)
    (pkg / "__init__.py").write_text(MODULE)
    (pkg / "nobackend.py").write_text(NO_BACKEND)
    info = site / f"{DIST}-0.1.dist-info"
    info.mkdir(exist_ok=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {DIST}\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(ENTRY_POINTS)
    return site


def env_for(site: Path) -> dict[str, str]:
    """Environment for a subprocess that sees the fake plugins."""
    path = os.pathsep.join(p for p in (str(site), os.environ.get("PYTHONPATH", "")) if p)
    return {"PYTHONPATH": path}


def activate(site: Path) -> None:
    """Make the fake plugins visible in this process (undo with :func:`deactivate`)."""
    from hnnbench import _registry as registry

    sys.path.insert(0, str(site))
    registry.refresh()


def deactivate(site: Path) -> None:
    from hydra.core.config_store import ConfigStore

    from hnnbench import _registry as registry

    store = ConfigStore.instance().repo.get("model", {})
    for name in ("nan_model", "crash_model", "needs_backend"):
        store.pop(f"{name}.yaml", None)

    while str(site) in sys.path:
        sys.path.remove(str(site))
    for name in list(sys.modules):
        if name == DIST or name.startswith(f"{DIST}."):
            del sys.modules[name]
    registry.refresh()
