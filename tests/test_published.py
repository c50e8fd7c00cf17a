"""The committed paper-profile leaderboard (results/), built from the committed records
(results/records), and the README that embeds it."""

from __future__ import annotations

import json
import math
import sys

import numpy as np
import pandas as pd
import pytest
from conftest import REPO, hnnbench

from hnnbench import _records as records
from hnnbench._registry import available
from hnnbench._table import leaderboard

RESULTS = REPO / "results"
RECORDS = RESULTS / "records"
sys.path.insert(0, str(REPO / "scripts"))
from publish_results import table_and_provenance  # noqa: E402


@pytest.fixture(scope="module")
def board() -> pd.DataFrame:
    return pd.read_csv(RESULTS / "leaderboard.csv")


@pytest.fixture(scope="module")
def committed() -> list[dict]:
    loaded = records.load(RECORDS, strict=True)  # every record checked against the schema
    assert not loaded.problems, loaded.problems
    return loaded.records


def _block(text: str, name: str) -> str:
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    return text[text.index(begin) + len(begin):text.index(end)]


def test_every_committed_record_is_valid_paper_profile(committed):
    assert committed
    for rec in committed:
        assert rec["profile"] == "paper" and rec["status"] in records.STATUSES


def test_the_leaderboard_is_the_one_of_the_committed_records(board, committed):
    rebuilt = leaderboard(committed)
    key = ["system", "model"]
    assert rebuilt[key].values.tolist() == board[key].values.tolist()
    for column in [c for c in board.columns if c.endswith("_mean") and not c.endswith("s_mean")]:
        np.testing.assert_allclose(rebuilt[column].to_numpy(float), board[column].to_numpy(float),
                                   rtol=1e-12, equal_nan=True, err_msg=column)


def test_every_published_system_has_every_model_with_three_seeds(board):
    """Every installed model, or the missing ones named in results/README.md as not run."""
    systems = set(board["system"])
    have = {(s, m) for s, m in zip(board["system"], board["model"], strict=True)}
    assert have <= {(s, m) for s in systems for m in available("model")}
    listing = (REPO / "results" / "README.md").read_text()
    for system in systems:
        missing = [m for m in available("model") if (system, m) not in have]
        if missing:
            line = next((ln for ln in listing.splitlines()
                         if ln.startswith(f"- Partly published: `{system}` lacks ")), "")
            assert all(m in line for m in missing), (system, missing, line)
    assert set(board["profile"]) == {"paper"}
    assert (board["n_seeds"] == 3).all()
    assert set(board["seeds"].astype(str)) == {"0;1;2"}
    assert systems <= set(available("system"))


def test_readme_embeds_the_committed_table_provenance_and_an_existing_figure():
    table, prov = table_and_provenance((RESULTS / "leaderboard.md").read_text())
    block = _block((REPO / "README.md").read_text(), "leaderboard")
    assert table and table in block
    assert prov and prov in block
    assert "`hnnbench -m system=" in prov
    figure = block.split("](", 1)[1].split(")", 1)[0]
    assert (REPO / figure).is_file()
    assert prov in _block((RESULTS / "README.md").read_text(), "provenance")


def test_html_report_embeds_every_figure():
    page = (RESULTS / "leaderboard.html").read_text()
    figures = sorted((RESULTS / "figures").glob("*.png"))
    assert len(figures) >= 4
    assert page.count("data:image/png;base64,") == len(figures)


@pytest.mark.slow
def test_rerunning_one_pair_lands_inside_the_committed_mean_pm_3_std(board, tmp_path):
    row = board[(board["system"] == "spring") & (board["model"] == "hnn_torch")]
    if row.empty:
        pytest.skip("spring is not published yet")
    proc = hnnbench("system=spring", "model=hnn_torch", "seed=1",
                    f"hydra.run.dir={tmp_path}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    record = json.loads((tmp_path / "result.json").read_text())
    row = row.iloc[0]
    for metric in ("train_loss", "test_loss", "energy_mse", "rollout_mse"):
        value = record["metrics"][metric]["mean"]
        mean, std = row[f"{metric}_mean"], row[f"{metric}_std"]
        assert math.isfinite(value)
        assert abs(value - mean) <= 3 * std + 1e-12, (metric, value, mean, std)
