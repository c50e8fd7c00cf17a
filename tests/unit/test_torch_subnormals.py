"""The torch backend flushes subnormal floats on a CPU, as XLA does for the JAX twin."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytest.importorskip("torch")

CODE = """
import torch
from hnnbench.neural._config import NeuralConfig
from hnnbench.neural.torch import TorchBackend

tiny = torch.tensor([1e-39], dtype=torch.float32)  # subnormal in float32
before = float(tiny * 1.0)
TorchBackend(NeuralConfig(), "cpu")
after = float(tiny * 1.0)
print(before > 0.0, after == 0.0)
"""


def test_a_torch_backend_flushes_subnormals_in_its_process():
    """Before a backend exists, torch keeps a subnormal product; after, it is zero (in a
    fresh process: the setting is the process's)."""
    proc = subprocess.run(
        [sys.executable, "-c", CODE], capture_output=True, text=True, timeout=120, check=False
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split() == ["True", "True"], proc.stdout
