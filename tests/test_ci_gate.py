"""The CI regression gate: the quick sweep over every system and model with two seeds,
checked against the committed reference (results/reference/quick.csv).

Regenerate the reference on purpose with:
    hnnbench -m system=all model=all profile=quick seed=0,1 hydra.sweep.dir=D
    hnnbench check D --reference results/reference/quick.csv --update
"""

from __future__ import annotations

import json

import pytest
from conftest import REPO, hnnbench

pytestmark = pytest.mark.slow


def test_quick_sweep_passes_the_committed_reference(tmp_path):
    reference = REPO / "results" / "reference" / "quick.csv"
    assert reference.exists(), "results/reference/quick.csv is missing"
    sweep = tmp_path / "sweep"
    proc = hnnbench("-m", "system=all", "model=all", "profile=quick", "seed=0,1",
                    f"hydra.sweep.dir={sweep}", cwd=tmp_path, timeout=3000)
    assert proc.returncode == 0, proc.stderr[-4000:]
    statuses = {}
    for path in sweep.rglob("result.json"):
        rec = json.loads(path.read_text())
        statuses[(rec["system"], rec["model"], rec["seed"])] = (rec["status"], rec["error"])
    assert not [k for k, (s, _) in statuses.items() if s in ("failed", "diverged")], statuses
    assert (sweep / "leaderboard.csv").exists() and (sweep / "leaderboard.html").exists()
    check = hnnbench("check", str(sweep), "--reference", str(reference))
    assert check.returncode == 0, check.stdout[-4000:] + check.stderr[-2000:]
