"""A process forced to another CPU's dispatch names that one in its records (what a
dispatch forces: tests/unit/test_data_hashes.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from hnnbench._running.data_hashes import CpuDispatch


def test_a_process_forced_to_another_dispatch_names_that_one_in_its_records():
    """What ``environment()`` records is what the libraries chose, not what the CPU
    offers: forced to an SSE4.2 machine's choices, a process says so."""
    target = CpuDispatch("Nehalem", "")
    forcing = target.forcing(CpuDispatch.here())
    if isinstance(forcing, str):
        pytest.skip(forcing)  # no OpenBLAS, or numpy does not say its targets, here
    code = (
        "import json; from hnnbench._record.environment import environment; "
        "e = environment(); print(json.dumps([e['blas_kernel'], e['numpy_simd']]))"
    )
    child = subprocess.run(
        [sys.executable, "-P", "-c", code],
        env={**os.environ, **forcing},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert child.returncode == 0, child.stderr[-2000:]
    assert json.loads(child.stdout) == ["Nehalem", ""]
    assert CpuDispatch.of_record({"blas_kernel": "Nehalem", "numpy_simd": ""}) == target
