"""The torch backend flushes subnormal floats while it trains and infers, as XLA does for
the JAX twin, and gives the caller's setting back."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytest.importorskip("torch")

CODE = """
import hnnbench
from hnnbench.neural.torch import _keeps_subnormals

before = _keeps_subnormals()
record = hnnbench.run("spring", "mlp_torch", profile="quick", out=OUT, save_model=False)
print(before, record["status"], _keeps_subnormals())
"""


def test_the_decorated_work_flushes_and_the_callers_setting_comes_back():
    import torch

    from hnnbench.neural.torch import _flushing_subnormals, _keeps_subnormals

    assert _keeps_subnormals()  # torch's default
    assert _flushing_subnormals(_keeps_subnormals)() is False  # flushed inside
    assert _keeps_subnormals()  # given back
    torch.set_flush_denormal(True)  # a caller that flushes keeps flushing
    try:
        assert _flushing_subnormals(_keeps_subnormals)() is False
        assert not _keeps_subnormals()
    finally:
        torch.set_flush_denormal(False)


def test_a_torch_job_in_this_process_leaves_subnormals_as_they_were(tmp_path):
    """A job run in-process (the API, a serial sweep) does not leave the process
    flushing subnormals: a test or notebook after it would see float arithmetic that
    breaks IEEE 754 (hypothesis refuses to run then). A fresh process, as the setting
    is the process's."""
    code = f"OUT = {str(tmp_path)!r}\n" + CODE
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split()[-3:] == ["True", "ok", "True"], proc.stdout[-2000:]
