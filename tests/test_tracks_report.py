"""The tracks side by side: a report over protocol and recipe (or tuned) records says
each track's verdict per system and headline metric, and where it changes."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from report_fixtures import make_sweep, scale_metric

from hnnbench import _records as records
from hnnbench._report import write_report

PAIRS = (("spring", "mlp_torch"), ("spring", "hnn_torch"), ("pendulum", "mlp_torch"),
         ("pendulum", "hnn_torch"))
SEEDS = tuple(range(6))


def _as_track(root: Path, track: str) -> None:
    for path in root.rglob(records.RECORD_NAME):
        rec = records.read_record(path)
        assert rec is not None
        records.write_record(path.parent, {**rec, "track": track})


def test_the_report_sets_the_tracks_side_by_side_and_names_a_changed_verdict(tmp_path):
    protocol = make_sweep(tmp_path / "protocol", pairs=PAIRS, seeds=SEEDS)
    recipe = make_sweep(tmp_path / "recipe", pairs=PAIRS, seeds=SEEDS)
    _as_track(recipe, "recipe")
    # on the recipe track the MLP's spring energy error falls far below the HNN's
    scale_metric(recipe, "spring", "mlp_torch", "energy_mse", 1e-4)
    report = write_report([protocol, recipe], tmp_path / "out", figures=False)
    tracks = pd.read_csv(report.files["tracks"], keep_default_na=False)
    assert {"protocol", "recipe", "changes"} <= set(tracks.columns)
    cell = tracks[(tracks["system"] == "spring") & (tracks["metric"] == "energy_mse")].iloc[0]
    assert (cell["protocol"], cell["recipe"], cell["changes"]) == ("best: hnn", "best: mlp",
                                                                   True)
    same = tracks[(tracks["system"] == "pendulum") & (tracks["metric"] == "energy_mse")]
    assert same.iloc[0]["protocol"] == same.iloc[0]["recipe"] == "best: hnn"
    assert not same.iloc[0]["changes"]
    text = report.files["tracks_md"].read_text()
    assert "Where the verdict changes between tracks:" in text
    assert "- `spring`, `energy_mse`: protocol best: hnn; recipe best: mlp." in text
    assert "`pendulum`, `energy_mse`" not in text.split("changes between tracks:")[1]


def test_a_report_of_one_track_says_only_the_protocol_ran(tmp_path):
    report = write_report([make_sweep(tmp_path / "p", pairs=PAIRS, seeds=(0, 1))],
                          tmp_path / "out", figures=False)
    assert "tracks" not in report.files
    assert "Only the protocol track has published rows" in report.files["tracks_md"].read_text()


def test_a_report_of_the_recipe_track_alone_shows_its_verdicts(tmp_path):
    recipe = make_sweep(tmp_path / "recipe", pairs=PAIRS, seeds=SEEDS)
    _as_track(recipe, "recipe")
    report = write_report([recipe], tmp_path / "out", figures=False)
    tracks = pd.read_csv(report.files["tracks"], keep_default_na=False)
    assert "recipe" in tracks.columns and "protocol" not in tracks.columns
    assert not tracks["changes"].any()
    assert "Only the protocol track" not in report.files["tracks_md"].read_text()
