"""A first quick sweep (seed 0, two systems, two models) makes no separation claim in any
of its outputs: no best or tied mark, no "beats", no bold cell, no star in a figure's
data; its aggregate says "too few seeds to separate" (docs/STATISTICS.md)."""

from __future__ import annotations

import re

import pandas as pd
import pytest
from conftest import hnnbench

pytestmark = pytest.mark.slow


def test_a_one_seed_sweep_claims_nothing(tmp_path):
    sweep = tmp_path / "sweep"
    proc = hnnbench(
        "-m",
        "system=spring,pendulum",
        "model=mlp_jax,hnn_jax",
        "profile=quick",
        "seed=0",
        f"hydra.sweep.dir={sweep}",
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    families = pd.read_csv(sweep / "families.csv")
    marks = families[[c for c in families.columns if c.endswith("_mark")]]
    assert set(marks.astype(object).fillna("").to_numpy().ravel()) <= {"", "too_few_seeds"}
    assert (marks == "too_few_seeds").to_numpy().any()
    for name in ("leaderboard.md", "aggregate.md", "tracks.md", "leaderboard.html"):
        text = (sweep / name).read_text()
        assert " beats " not in text, name
        assert not re.search(r"\| \*[^|*]+\*", text), name  # no bold or italic cell
        assert 'class="best"' not in text and 'class="tied"' not in text, name
        assert "best:" not in text, name
    assert "too few seeds to separate" in (sweep / "aggregate.md").read_text()
    assert "too few seeds" not in proc.stdout.lower() or "best" not in proc.stdout.lower()
