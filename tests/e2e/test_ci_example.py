"""docs/examples/plugin-ci.yml, the CI gate docs/CI.md gives a plugin repository: its
``run:`` steps, as they are, in bash, in order, against the example plugin
tests/plugin_pkg (the hosting service's own steps, ``uses:``, are what this test stands
in for: the checkouts are copies, and pip installs into a temporary target without the
network). The models are cut to one family beside the plugin's to spare the test
budget: the HNN (spring x mlp_jax's quick energy_drift_long does not reproduce the
committed quick reference on the machine this test was written on: 108 against 8)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from conftest import REPO

pytestmark = pytest.mark.slow

WORKFLOW = REPO / "docs" / "examples" / "plugin-ci.yml"
#: What the test leaves out of its copy of hnnbench (the checkout step's).
_NOT_COPIED = shutil.ignore_patterns(
    ".git",
    ".venv",
    "runs",
    "records",
    "figures",
    "*.html",
    "*_cache",
    "__pycache__",
    "build",
    "dist",
    "*.egg-info",
    "tests",
    "benchmarks",
    "docs",
)


def _steps() -> tuple[dict[str, str], list[dict]]:
    workflow = yaml.safe_load(WORKFLOW.read_text())
    (job,) = workflow["jobs"].values()
    return {k: str(v) for k, v in job["env"].items()}, job["steps"]


def test_the_example_workflow_gates_a_plugin_end_to_end(tmp_path):
    env, steps = _steps()
    plugin = shutil.copytree(REPO / "tests" / "plugin_pkg", tmp_path / "plugin")  # checkout
    shutil.copytree(REPO, plugin / env["HNNBENCH_SRC"], ignore=_NOT_COPIED)  # checkout
    site = tmp_path / "site"
    summary = tmp_path / "summary.md"
    env.update(
        MODELS="linear_lstsq,hnn_jax",
        PIP_FLAGS=f"--quiet --no-deps --no-build-isolation --no-index --target {site}",
        GITHUB_STEP_SUMMARY=str(summary),
        PATH=os.pathsep.join(
            [str(site / "bin"), str(Path(sys.executable).parent), os.environ["PATH"]]
        ),
        PYTHONPATH=str(site),
    )
    ran = []
    for step in steps:
        if "run" not in step:
            assert "uses" in step, step
            continue
        proc = subprocess.run(
            ["bash", "-e", "-o", "pipefail", "-c", step["run"]],
            cwd=plugin,
            env={**os.environ, **env},
            capture_output=True,
            text=True,
            timeout=3000,
        )
        assert proc.returncode == 0, f"{step['name']}: {proc.stdout[-3000:]}{proc.stderr[-3000:]}"
        ran.append((step["name"], proc.stdout))
    assert [name for name, _ in ran] == [
        "Install hnnbench and the plugin",
        "Quick sweep",
        "Gate on the published quick reference",
        "Job summary",
    ]
    listed = ran[0][1]
    assert "quartic" in listed and "linear_lstsq" in listed
    # both went into the target (this process's editable hnnbench may still be the one
    # imported: the same source)
    assert list(site.glob("hnnbench-*.dist-info")) and (site / "bin" / "hnnbench").is_file()
    assert list(site.glob("hnnbench_toy_plugin-*.dist-info"))
    gate = ran[2][1]
    assert "hnnbench check: OK, no regressions" in gate
    assert "compared 1 pair(s)" in gate  # spring x hnn_jax, gated on the reference
    assert "spring energy_mse: linear_lstsq ranks " in gate  # among the reference's families
    assert (
        "quartic: the reference has no rows for system quartic; linear_lstsq ranked against "
        "the families run beside it: hnn_jax"
    ) in gate
    assert "too few seeds to separate (1 seed;" in gate
    report = plugin / "reports" / "hnnbench-check.xml"
    import xmlschema

    xmlschema.XMLSchema(str(REPO / "tests" / "schemas" / "junit.xsd")).validate(str(report))
    assert summary.read_text().startswith("### \u2705 hnnbench check: OK, no regressions")
    records = [json.loads(p.read_text()) for p in (plugin / "sweep").rglob("result.json")]
    assert sorted((r["system"], r["model"], r["status"]) for r in records) == [
        ("quartic", "hnn_jax", "ok"),
        ("quartic", "linear_lstsq", "ok"),
        ("spring", "hnn_jax", "ok"),
        ("spring", "linear_lstsq", "ok"),
    ]
