"""Listing, composing, validating and reporting import no backend; a job imports only
the backend it runs (benchmarks/startup.py times the same thing)."""

from __future__ import annotations

import subprocess
import sys

import pytest

NO_BACKEND = """
import sys
from hnnbench import _registry as registry
from hnnbench._entry import command as cli
from hnnbench._running.compose import compose
from hnnbench._running.config import prepare_job
cli.cmd_list([])
for model in registry.available("model"):
    prepare_job(compose(["system=spring", f"model={model}"]))
    registry.get_class("model", model).unsupported_reason  # touched, not built
print("IMPORTED", "torch" in sys.modules, "jax" in sys.modules)
"""

JOB = """
import sys, pathlib
from hnnbench._running.compose import compose
from hnnbench._running.job import run_job
overrides = ["system=spring", "model={model}", "profile=quick", "system.steps=10",
             "device=cpu", "save_model=false", "system.eval_n_points=10"]
record = run_job(compose(overrides), pathlib.Path(sys.argv[1]), overrides=overrides)[0].record
print("IMPORTED", record["status"], "torch" in sys.modules, "jax" in sys.modules)
"""


def _imported(code: str, *args: str) -> list[str]:
    out = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr[-3000:]
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("IMPORTED")][-1]
    return line.split()[1:]


def test_listing_and_composing_every_model_imports_no_backend():
    assert _imported(NO_BACKEND) == ["False", "False"]


def test_reporting_imports_no_backend(tmp_path):
    from report_fixtures import make_sweep

    sweep = make_sweep(tmp_path / "sweep")
    code = (
        "import sys\nfrom hnnbench._results.report import write_report\n"
        f"write_report({str(sweep)!r}, {str(tmp_path / 'out')!r})\n"
        "print('IMPORTED', 'torch' in sys.modules, 'jax' in sys.modules)\n"
    )
    assert _imported(code) == ["False", "False"]


@pytest.mark.parametrize(
    ("model", "expected"),
    [("mlp_torch", ["ok", "True", "False"]), ("mlp_jax", ["ok", "False", "True"])],
)
def test_a_job_imports_only_its_backend(model, expected, tmp_path):
    pytest.importorskip("torch" if "torch" in model else "jax")
    assert _imported(JOB.replace("{model}", model), str(tmp_path)) == expected
