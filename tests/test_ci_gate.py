"""The CI regression gate: a quick sweep of every system with the JAX twin of every
neural family and the oracle, seed 0, checked with ``hnnbench check`` against the
committed reference (results/reference/quick.csv).

The reference file is the gate's scope: the test sweeps exactly its systems and models,
so regenerating it with another scope changes the gate. The torch twins are not swept
here (they take longer and are held to their JAX twins by tests/test_backend_parity.py).

Regenerate the reference on purpose, after a change that moves quick-profile metrics:
    make ci-reference
"""

from __future__ import annotations

import json

import pandas as pd
import pytest
from conftest import REPO, hnnbench

pytestmark = pytest.mark.slow

REFERENCE = REPO / "results" / "reference" / "quick.csv"


def test_quick_sweep_passes_the_committed_reference(tmp_path):
    assert REFERENCE.exists(), "results/reference/quick.csv is missing: make ci-reference"
    ref = pd.read_csv(REFERENCE)
    assert set(ref["profile"]) == {"quick"} and set(ref["seeds"].astype(str)) == {"0"}
    systems = ",".join(dict.fromkeys(ref["system"]))
    models = ",".join(dict.fromkeys(ref["model"]))
    sweep = tmp_path / "sweep"
    proc = hnnbench("-m", f"system={systems}", f"model={models}", "profile=quick", "seed=0",
                    "hydra/launcher=joblib", "hydra.launcher.n_jobs=2",
                    f"hydra.sweep.dir={sweep}", cwd=tmp_path, timeout=3000)
    assert proc.returncode == 0, proc.stderr[-4000:]
    statuses = {}
    for path in sweep.rglob("result.json"):
        rec = json.loads(path.read_text())
        statuses[(rec["system"], rec["model"], rec["seed"])] = (rec["status"], rec["error"])
    assert len(statuses) == len(ref), sorted(statuses)
    assert not [k for k, (s, _) in statuses.items() if s == "failed"], statuses
    assert (sweep / "leaderboard.csv").exists() and (sweep / "leaderboard.html").exists()
    check = hnnbench("check", str(sweep), "--reference", str(REFERENCE))
    assert check.returncode == 0, check.stdout[-4000:] + check.stderr[-2000:]
