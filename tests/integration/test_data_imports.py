"""The measured-data module in a fresh interpreter: it imports no backend
(tests/unit/test_data.py has the rest)."""

from __future__ import annotations

import subprocess
import sys


def test_module_imports_no_backend():
    code = (
        "import sys, hnnbench._contracts.data_files; "
        "bad = [m for m in ('torch', 'jax') if m in sys.modules]; "
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
