"""Runs of one (system, model) that differ in other overrides (a hyperparameter sweep)
are separate rows of every table, never seeds of one row."""

from __future__ import annotations

import pandas as pd
import pytest
from report_fixtures import write_run

from hnnbench._record.loader import load
from hnnbench._results import check, report
from hnnbench._results.leaderboard import leaderboard, records_frame, summary_frame, variant_labels
from hnnbench._results.report.figures import slug
from hnnbench._results.report.published import ours_cell


def test_a_variant_is_the_overrides_that_differ_between_runs():
    assert variant_labels([]) == []
    assert variant_labels([None, ["seed=1"]]) == ["", ""]
    # identity and run settings never make a variant, even where they differ
    assert variant_labels(
        [
            [
                "system=spring",
                "model=hnn_torch",
                "seed=2",
                "profile=quick",
                "device=cpu",
                "threads=2",
                "save_model=false",
                "rerun=true",
                "hydra.launcher.n_jobs=2",
            ],
            ["system=pendulum", "model=mlp_torch", "seed=0", "profile=paper", "device=cuda"],
        ]
    ) == ["", ""]
    # an override every run shares is a sweep setting; absent counts as a value
    runs = [
        ["system.steps=50", "+model.hidden=100", "system.eval_t_end=80"],
        ["system.steps=50", "+model.hidden=200", "system.eval_t_end=80"],
        ["system.steps=50"],
    ]
    assert variant_labels(runs) == [
        "model.hidden=100 system.eval_t_end=80",
        "model.hidden=200 system.eval_t_end=80",
        "",
    ]
    # Hydra's append prefix does not make another variant
    assert variant_labels([["+model.hidden=100"], ["model.hidden=100"], ["model.hidden=5"]]) == [
        "model.hidden=100",
        "model.hidden=100",
        "model.hidden=5",
    ]


@pytest.fixture()
def hidden_sweep(tmp_path):
    """spring x hnn_torch at two hidden sizes, seeds 0 and 1, plus mlp_torch at the
    profile's own settings."""
    for seed in (0, 1):
        for hidden in (100, 200):
            metrics = {"train_loss": 0.03, "test_loss": 0.03, "energy_mse": hidden * 1e-6}
            write_run(
                tmp_path,
                "spring",
                "hnn_torch",
                seed,
                metrics=metrics,
                overrides=(f"model.hidden={hidden}",),
            )
        write_run(tmp_path, "spring", "mlp_torch", seed)
    return tmp_path


def test_leaderboard_has_a_row_per_variant(hidden_sweep):
    board = leaderboard(load(hidden_sweep).records)
    assert list(board.columns[:4]) == ["profile", "system", "model", "variant"]
    rows = {(r.model, r.variant): r for r in board.itertuples()}
    assert set(rows) == {
        ("mlp_torch", ""),
        ("hnn_torch", "model.hidden=100"),
        ("hnn_torch", "model.hidden=200"),
    }
    for key in rows:
        assert rows[key].n_seeds == 2 and rows[key].seeds == "0;1"
    assert rows[("hnn_torch", "model.hidden=100")].energy_mse_mean == pytest.approx(1e-4)
    assert rows[("hnn_torch", "model.hidden=200")].energy_mse_mean == pytest.approx(2e-4)
    summary = summary_frame(records_frame(load(hidden_sweep).records))
    assert "variant" in summary.columns and len(summary) == 6
    # leaderboard order (mlp before hnn), numeric variant order, then seeds
    assert [(r.model, r.variant, r.seed) for r in summary.itertuples()] == [
        ("mlp_torch", "", 0),
        ("mlp_torch", "", 1),
        ("hnn_torch", "model.hidden=100", 0),
        ("hnn_torch", "model.hidden=100", 1),
        ("hnn_torch", "model.hidden=200", 0),
        ("hnn_torch", "model.hidden=200", 1),
    ]


def test_numeric_variants_sort_by_value(tmp_path):
    for hidden in (1000, 200, 50):
        write_run(tmp_path, "spring", "hnn_torch", 0, overrides=(f"model.hidden={hidden}",))
    board = leaderboard(load(tmp_path).records)
    assert list(board["variant"]) == ["model.hidden=50", "model.hidden=200", "model.hidden=1000"]


def test_a_sweep_without_variants_keeps_the_plain_schema(tmp_path):
    for seed in (0, 1):
        write_run(tmp_path, "spring", "hnn_torch", seed)
    board = leaderboard(load(tmp_path).records)
    assert "variant" not in board.columns
    assert "variant" not in summary_frame(records_frame(load(tmp_path).records)).columns


def test_report_draws_each_variant_apart_and_claims_use_the_plain_runs(hidden_sweep):
    built = report.write_report(hidden_sweep)
    names = sorted(p.name for _, _, p in built.figures)
    assert "spring_energy.png" in names  # mlp_torch at the profile's settings
    assert "spring__model.hidden-100_energy.png" in names
    assert "spring__model.hidden-200_energy.png" in names
    assert any("[model.hidden=100]" in label for label, _, _ in built.figures)
    md = (hidden_sweep / "leaderboard.md").read_text()
    assert "model.hidden=100" in md and "model.hidden=200" in md
    lookup = report.board_lookup(built.board, "quick")
    assert lookup("spring", "hnn_torch", "energy_mse") is None  # no plain hnn_torch run
    assert lookup("spring", "mlp_torch", "energy_mse") is not None


def test_check_matches_rows_by_variant(hidden_sweep, tmp_path):
    reference = leaderboard(load(hidden_sweep).records)
    assert check.compare(reference, reference).ok
    worse = reference.copy()
    row = (worse["variant"] == "model.hidden=200").to_numpy()
    worse.loc[row, "energy_mse_mean"] *= 100
    result = check.compare(reference, worse)
    assert not result.ok
    assert [f.model for f in result.regressions] == ["hnn_torch [model.hidden=200]"]
    path = tmp_path / "ref.csv"
    reference.to_csv(path, index=False)
    assert check.compare(check.read_reference(path), reference).ok
    doubled = pd.concat([reference, reference.iloc[:1]])
    doubled.to_csv(path, index=False)
    with pytest.raises(check.CheckError, match="duplicate"):
        check.read_reference(path)


def test_paper_comparison_shows_only_the_plain_runs(hidden_sweep):
    board = leaderboard(load(hidden_sweep).records)
    assert ours_cell(board, "quick", "spring", "hnn_torch", "energy_mse") == "—"
    assert ours_cell(board, "quick", "spring", "mlp_torch", "energy_mse") != "—"


def test_long_variants_get_distinct_file_names():
    common = " ".join(f"system.option_number_{i}=1" for i in range(6))
    a = slug(f"{common} system.eval_t_end=40")
    b = slug(f"{common} system.eval_t_end=80")
    assert a != b and len(a) <= 91
    assert slug("model.hidden=100") == "model.hidden-100"
