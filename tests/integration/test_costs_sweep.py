"""The sweep's estimate and ETA in a real sweep, and the committed job costs against the
script that writes them (tests/unit/test_costs.py has the rest)."""

from __future__ import annotations

import json
import subprocess
import sys

from conftest import REPO

from hnnbench._sweeping import eta


def test_the_committed_job_costs_are_what_the_script_writes():
    script = REPO / "scripts" / "maintainer" / "job_costs.py"
    proc = subprocess.run(
        [sys.executable, str(script), "--check"], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    table = eta.load_costs()
    records = (
        json.loads(path.read_text("utf-8"))
        for path in (REPO / "results" / "records").rglob("result.json")
    )
    published = {(rec["system"], rec["model"]) for rec in records if not rec.get("variant")}
    assert published, "no published records"
    assert all(table[("paper", system, model)] > 0 for system, model in published)
    assert table[("quick", "spring", "oracle")] > 0
