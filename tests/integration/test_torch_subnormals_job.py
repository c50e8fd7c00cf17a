"""A torch job run in-process gives the process's subnormal setting back (the decorator
itself: tests/unit/test_torch_subnormals.py)."""

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
