"""Importing the core in a fresh interpreter imports no backend
(tests/unit/test_registry.py has the registry itself)."""

from __future__ import annotations

import sys


def test_core_import_does_not_import_backends():
    import subprocess

    code = (
        "import sys, hnnbench, hnnbench._registry, hnnbench._running.config, "
        "hnnbench._running.job, hnnbench._running.evaluation, hnnbench._entry.command; "
        "print(sorted(m for m in ('torch', 'jax') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
