"""Models that each fail in one way; all derive from hnnbench's oracle."""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np

from hnnbench import ModelConfig
from hnnbench_plugins.models.oracle import Oracle


class RequirementsRaise(Oracle):
    """requirements_missing() raises instead of returning a hint."""

    @classmethod
    def requirements_missing(cls):
        raise RuntimeError("cannot tell what is missing")


class OrderNotANumber(Oracle):
    """order is not a number."""

    order = "first"  # type: ignore[assignment]


@dataclass
class RaisingConfig(ModelConfig):
    def __post_init__(self) -> None:
        raise SystemExit("config refuses")


class ConfigRaises(Oracle):
    """Its Config's __post_init__ calls sys.exit()."""

    Config = RaisingConfig


class ExitsInFit(Oracle):
    """fit calls sys.exit()."""

    def fit(self, data, train, seed, progress):
        sys.exit(3)


class HangsInFit(Oracle):
    """fit never returns (CPU-bound, swallowing ordinary exceptions)."""

    def fit(self, data, train, seed, progress):
        x = np.ones((50, 50))
        while True:
            try:
                x = np.tanh(x @ x)
                time.sleep(0.01)
            except Exception:  # noqa: BLE001 - a careless plugin: the limit still holds
                pass
