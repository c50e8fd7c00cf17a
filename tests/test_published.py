"""The committed paper-profile leaderboard (results/) and the README that embeds it."""

from __future__ import annotations

import json
import math
import sys

import pandas as pd
import pytest
from conftest import REPO, hnnbench

from hnnbench.registry import available

RESULTS = REPO / "results"
sys.path.insert(0, str(REPO / "scripts"))
from publish_results import table_and_provenance  # noqa: E402


@pytest.fixture(scope="module")
def board() -> pd.DataFrame:
    return pd.read_csv(RESULTS / "leaderboard.csv")


def _block(text: str, name: str) -> str:
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    return text[text.index(begin) + len(begin):text.index(end)]


def test_every_registered_pair_has_three_seeds_of_the_paper_profile(board):
    pairs = set(zip(board["system"], board["model"], strict=True))
    assert pairs == {(s, m) for s in available("system") for m in available("model")}
    assert set(board["profile"]) == {"paper"}
    assert (board["n_seeds"] == 3).all()
    assert set(board["seeds"].astype(str)) == {"0;1;2"}


def test_readme_embeds_the_committed_table_provenance_and_an_existing_figure():
    table, prov = table_and_provenance((RESULTS / "leaderboard.md").read_text())
    block = _block((REPO / "README.md").read_text(), "leaderboard")
    assert table and table in block
    assert prov and prov in block
    assert "`hnnbench -m system=all model=all seed=0,1,2" in prov
    figure = block.split("](", 1)[1].split(")", 1)[0]
    assert (REPO / figure).is_file()
    assert prov in _block((RESULTS / "README.md").read_text(), "provenance")


def test_html_report_embeds_every_figure():
    page = (RESULTS / "leaderboard.html").read_text()
    figures = sorted((RESULTS / "figures").glob("*.png"))
    assert len(figures) >= 4 * 5  # 4 kinds for most of the 6 systems
    assert page.count("data:image/png;base64,") == len(figures)


@pytest.mark.slow
def test_rerunning_one_pair_lands_inside_the_committed_mean_pm_3_std(board, tmp_path):
    proc = hnnbench("system=spring", "model=hnn_torch", "seed=1",
                    f"hydra.run.dir={tmp_path}")
    assert proc.returncode == 0, proc.stderr[-2000:]
    record = json.loads((tmp_path / "result.json").read_text())
    row = board[(board["system"] == "spring") & (board["model"] == "hnn_torch")].iloc[0]
    for metric in ("train_loss", "test_loss", "energy_mse", "rollout_mse"):
        value = record["metrics"][metric]["mean"]
        mean, std = row[f"{metric}_mean"], row[f"{metric}_std"]
        assert math.isfinite(value)
        assert abs(value - mean) <= 3 * std + 1e-12, (metric, value, mean, std)
