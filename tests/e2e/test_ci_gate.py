"""The CI regression gate: a quick sweep, seed 0, checked with ``hnnbench check``
against the committed reference (results/reference/quick.csv): every system with the
JAX twin of every neural family and the oracle, and the torch twins on the spring.

The reference file is the gate's scope: the test sweeps exactly its pairs (one Hydra
sweep per set of systems that share a set of models), so regenerating it with another
scope changes the gate. Regenerate it on purpose, after a change that moves
quick-profile metrics:
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
    models_of: dict[str, list[str]] = {}
    for system, model in zip(ref["system"], ref["model"], strict=True):
        models_of.setdefault(system, []).append(model)
    groups: dict[tuple[str, ...], list[str]] = {}  # model set -> its systems
    for system, models in models_of.items():
        groups.setdefault(tuple(models), []).append(system)
    sweep = tmp_path / "sweep"
    for i, (models, systems) in enumerate(groups.items()):
        proc = hnnbench(
            "-m",
            f"system={','.join(systems)}",
            f"model={','.join(models)}",
            "profile=quick",
            "seed=0",
            "hydra/launcher=joblib",
            "hydra.launcher.n_jobs=2",
            f"hydra.sweep.dir={sweep / str(i)}",
            cwd=tmp_path,
            timeout=3000,
        )
        assert proc.returncode == 0, proc.stderr[-4000:]
    statuses = {}
    for path in sweep.rglob("result.json"):
        rec = json.loads(path.read_text())
        statuses[(rec["system"], rec["model"], rec["seed"])] = (rec["status"], rec["error"])
    assert len(statuses) == len(ref), sorted(statuses)
    assert not [k for k, (s, _) in statuses.items() if s == "failed"], statuses
    assert (sweep / "0" / "leaderboard.csv").exists()
    assert (sweep / "0" / "leaderboard.html").exists()
    check = hnnbench("check", *map(str, sorted(sweep.iterdir())), "--reference", str(REFERENCE))
    assert check.returncode == 0, check.stdout[-4000:] + check.stderr[-2000:]
