"""The tutorial notebook runs end to end (tests/unit/test_tutorial.py checks it is the script's)."""

from __future__ import annotations

import os
import time

import pytest
from conftest import REPO

jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")
SOURCE = REPO / "docs" / "tutorial.py"


@pytest.mark.slow
def test_the_tutorial_runs(tmp_path, monkeypatch):
    monkeypatch.setenv("HNNBENCH_TUTORIAL_OUT", str(tmp_path / "tutorial"))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = jupytext.read(SOURCE)
    client = nbclient.NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    start = time.perf_counter()
    client.execute()
    seconds = time.perf_counter() - start
    print(f"tutorial executed in {seconds:.1f} s")  # the budget is 2 minutes (not gated)
    errors = [o for c in nb.cells for o in c.get("outputs", []) if o.output_type == "error"]
    assert not errors, errors
    last = nb.cells[-2].outputs[-1]["data"]["text/plain"]  # the final leaderboard
    assert "linear" in last and "hnn_jax" in last
    assert (
        tmp_path / "tutorial" / "sweep" / "spring" / "linear" / "seed1" / "result.json"
    ).exists()
    assert os.environ["HNNBENCH_TUTORIAL_OUT"] == str(tmp_path / "tutorial")
