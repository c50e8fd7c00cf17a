"""The tracks side by side: a report over protocol and recipe (or tuned) records says
each track's verdict per system and headline metric, and where it changes."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
from report_fixtures import make_sweep, scale_metric, write_run

from hnnbench import _record as records
from hnnbench._results.report import write_report
from hnnbench._results.report.figures import main_profile_figure

PAIRS = (
    ("spring", "mlp_torch"),
    ("spring", "hnn_torch"),
    ("pendulum", "mlp_torch"),
    ("pendulum", "hnn_torch"),
)
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
    assert (cell["protocol"], cell["recipe"], cell["changes"]) == ("best: hnn", "best: mlp", True)
    same = tracks[(tracks["system"] == "pendulum") & (tracks["metric"] == "energy_mse")]
    assert same.iloc[0]["protocol"] == same.iloc[0]["recipe"] == "best: hnn"
    assert not same.iloc[0]["changes"]
    text = report.files["tracks_md"].read_text()
    assert "Where the verdict changes between tracks:" in text
    assert "- `spring`, `energy_mse`: protocol best: hnn; recipe best: mlp." in text
    assert "`pendulum`, `energy_mse`" not in text.split("changes between tracks:")[1]


def test_a_report_of_one_track_says_only_the_protocol_ran(tmp_path):
    report = write_report(
        [make_sweep(tmp_path / "p", pairs=PAIRS, seeds=(0, 1))], tmp_path / "out", figures=False
    )
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


def _as_tuned(root: Path, lr: float) -> None:
    """Every record under ``root`` as the tuned track's, its tuning selecting
    ``model.lr=lr`` at a step budget of 20."""
    for path in root.rglob(records.RECORD_NAME):
        rec = records.read_record(path)
        assert rec is not None
        config = {
            **rec["config"],
            "track": "tuned",
            "model": {**rec["config"]["model"], "lr": lr, "steps": 20},
        }
        records.write_record(
            path.parent,
            {
                **rec,
                "track": "tuned",
                "config": config,
                "overrides": [*rec["overrides"], f"model.lr={lr}", "model.steps=20", "track=tuned"],
                "tuning": {
                    "selected_on": "validation",
                    "trials": 4,
                    "steps": 20,
                    "selected": {"model.lr": lr},
                    "cpu_s": 12.0,
                    "space": {},
                },
            },
        )


def test_a_report_draws_each_track_apart_and_speaks_of_the_protocol(tmp_path):
    """With a tuned track beside the protocol: the per-system figures of the tuned runs
    are their own (named by the track, not by the selected settings, which are no
    variant), the heatmaps and performance profiles of the main scope keep their names
    (the README embeds them) and the tuned track gets its own, and the per-system marks,
    the aggregate's left-out lines and the paper comparison's seed line speak of the
    protocol's rows only."""
    from hnnbench._results.report.verdicts import left_out_lines, marks_line

    pairs = PAIRS[:2]
    protocol = make_sweep(tmp_path / "protocol", pairs=pairs, seeds=SEEDS)
    alone = write_report([protocol], tmp_path / "alone")
    tuned = make_sweep(tmp_path / "tuned", pairs=pairs, seeds=(0, 1))  # 2 seeds: no verdict
    _as_tuned(tuned, 0.003)
    both = write_report([protocol, tuned], tmp_path / "both")
    names = {p.name for p in (tmp_path / "both" / "figures").glob("*.png")}
    assert {p.name for p in (tmp_path / "alone" / "figures").glob("*.png")} <= names
    assert "performance_profile.png" in names and "heatmap_energy_mse.png" in names
    assert "heatmap_energy_mse_quick_tuned.png" in names
    assert any(n.startswith("spring_tuned_") for n in names), sorted(names)
    assert not any("model.lr" in n or "/" in n for n in names), sorted(names)
    assert main_profile_figure(both.figures).name == "performance_profile.png"
    assert both.verdicts is not None and alone.verdicts is not None
    assert marks_line(both.verdicts.families) == marks_line(alone.verdicts.families)
    assert left_out_lines(both.verdicts.aggregate) == left_out_lines(alone.verdicts.aggregate)
    seed_line = both.files["paper"].read_text().splitlines()[2]
    assert seed_line == alone.files["paper"].read_text().splitlines()[2]
    assert "seed(s) per row" in seed_line


def test_a_report_of_another_track_alone_keeps_plain_names_and_compares_nothing(tmp_path):
    """A recipe-only report: its heatmaps keep the plain names (it is the only scope),
    no scope line, and the paper comparison says it reads the protocol track only."""
    recipe = make_sweep(tmp_path / "recipe", pairs=PAIRS, seeds=(0, 1, 2))
    _as_track(recipe, "recipe")
    report = write_report([recipe], tmp_path / "out")
    names = {p.name for p in (tmp_path / "out" / "figures").glob("*.png")}
    assert "heatmap_energy_mse.png" in names and not any("recipe" in n[:8] for n in names)
    assert any(n.startswith("spring_recipe_") for n in names), sorted(names)
    paper = report.files["paper"].read_text()
    assert "No protocol-track rows" in paper and "Profile ?" not in paper
    assert "Of the " not in report.files["aggregate_md"].read_text()


def test_the_aggregate_speaks_of_the_protocol_even_where_only_another_track_has_one(tmp_path):
    """The protocol track without its baseline (no MLP: nothing to normalise) beside a
    tuned track with one: the aggregate says there is none for the protocol (it does not
    show the tuned track's under the protocol's marks), names its scope, and draws the
    tuned track's performance profiles under the tuned track's name only."""
    protocol = make_sweep(tmp_path / "protocol", pairs=PAIRS[1::2], seeds=SEEDS)  # HNN only
    tuned = make_sweep(tmp_path / "tuned", pairs=PAIRS, seeds=SEEDS)
    _as_tuned(tuned, 0.003)
    report = write_report([protocol, tuned], tmp_path / "out")
    text = report.files["aggregate_md"].read_text()
    assert "No aggregate" in text and "Of the `quick` rows" in text, text
    assert main_profile_figure(report.figures) is None
    names = {p.name for p in (tmp_path / "out" / "figures").glob("*.png")}
    assert (
        "performance_profile_quick_tuned.png" in names and "performance_profile.png" not in names
    ), sorted(names)


def test_a_track_that_cannot_separate_its_leaders_changes_no_verdict(tmp_path):
    """Three recipe seeds cannot separate the HNN and the MLP ("too few seeds to
    separate"); the protocol's best, the HNN, is among them: no change of verdict, even
    where the MLP's mean moved ahead (said apart, as a difference of means)."""
    protocol = make_sweep(tmp_path / "protocol", pairs=PAIRS, seeds=SEEDS)
    recipe = make_sweep(tmp_path / "recipe", pairs=PAIRS, seeds=(0, 1, 2))
    _as_track(recipe, "recipe")
    scale_metric(recipe, "pendulum", "hnn_torch", "energy_mse", 1e4)  # now far behind
    report = write_report([protocol, recipe], tmp_path / "out", figures=False)
    tracks = pd.read_csv(report.files["tracks"], keep_default_na=False)
    rows = tracks[tracks["metric"] == "energy_mse"].set_index("system")
    assert rows.loc["spring", "protocol"] == "best: hnn"
    assert (
        rows.loc["spring", "recipe"].startswith("too few seeds to separate: ")
        and "hnn" in rows.loc["spring", "recipe"]
    )
    assert not rows.loc["spring", "changes"]
    # 3 seeds tie everyone: no separated change, but the best mean moved to the MLP
    assert rows.loc["pendulum", "recipe"] == "too few seeds to separate: mlp, hnn"
    assert not rows.loc["pendulum", "changes"] and rows.loc["pendulum", "mean_changes"]
    assert not rows.loc["spring", "mean_changes"]
    text = report.files["tracks_md"].read_text()
    assert "never separates its leaders" in text and "No verdict changes" in text
    assert (
        "- `pendulum`, `energy_mse`: protocol hnn (best); recipe mlp (too few seeds to "
        "separate)." in text.split("Where only the best mean moves")[1]
    )


def _with_study(root: Path, cpu_s: float, best: float, protocol: float) -> None:
    """The tuned records under ``root`` with the study fields ``hnnbench tune`` writes."""
    for path in root.rglob(records.RECORD_NAME):
        rec = records.read_record(path)
        assert rec is not None
        tuning = {
            **rec["tuning"],
            "criterion": "field_mse_clean",
            "seeds_per_trial": 2,
            "trial_seeds": [0, 1],
            "protocol_trial": 0,
            "protocol_value": protocol,
            "selected_value": best,
            "cpu_s": cpu_s,
            "cpu_s_per_trial": cpu_s / 4,
            "study": f"{rec['system']}/{rec['model']}",
        }
        records.write_record(path.parent, {**rec, "tuning": tuning})


def test_the_tracks_table_shows_the_tuning_gain_with_its_interval_negative_where_it_hurt(
    tmp_path,
):
    """Tuned against protocol on the seeds no trial trained (2 to 5 of 0 to 5), paired:
    the MLP's spring energy error 10x worse when tuned is a gain of x0.1 (negative on the
    log scale) with its interval, the HNN's pendulum one 10x better x10; the studies
    table shows each study's criterion, budget and CPU, and the cost figure is drawn."""
    from hnnbench._results.report.tuning import cost_figure, studies_frame

    protocol = make_sweep(tmp_path / "protocol", pairs=PAIRS, seeds=SEEDS)
    tuned = make_sweep(tmp_path / "tuned", pairs=PAIRS, seeds=SEEDS)
    _as_tuned(tuned, 0.003)
    _with_study(tuned, 40.0, 0.01, 0.02)
    scale_metric(tuned, "spring", "mlp_torch", "energy_mse", 10.0)
    scale_metric(tuned, "pendulum", "hnn_torch", "energy_mse", 0.1)
    report = write_report([protocol, tuned], tmp_path / "out", figures=False)
    gain = pd.read_csv(report.files["tuning_gain"])
    gain = gain[gain["seeds"] == "unseen"]  # the trial seeds' rows are kept apart
    energy = gain[gain["metric"] == "energy_mse"].set_index(["system", "family"])
    worse = energy.loc[("spring", "mlp")]
    assert worse["n"] == len(SEEDS) - 2 and worse["scale"] == "log"  # trial seeds 0, 1 out
    assert abs(worse["gain"] + 1.0) < 1e-9 and worse["low"] <= worse["gain"] <= worse["high"]
    assert worse["high"] < 0  # every paired seed worse: the interval is below 0
    assert abs(energy.loc[("pendulum", "hnn"), "gain"] - 1.0) < 1e-9
    assert abs(energy.loc[("spring", "hnn"), "gain"]) < 1e-9  # untouched: no gain
    text = report.files["tracks_md"].read_text()
    assert "## Tuning gain" in text and "×0.1 [×0.1, ×0.1] (4)" in text and "×10" in text
    assert "## The studies" in text and "4 x 20 x 2" in text and "field_mse_clean" in text
    tracks = pd.read_csv(report.files["tracks"], keep_default_na=False)
    assert {"protocol", "tuned", "protocol_effect", "tuned_effect", "still_mean"} <= set(
        tracks.columns
    )
    studies = studies_frame(report.records)
    assert len(studies) == 4 and set(studies["budget"]) == {"4 x 20 x 2"}
    made = cost_figure(studies, tmp_path / "cost.png")
    assert made is not None and made.stat().st_size > 0
    # four paired seeds cannot separate: the summary under the table says within noise
    assert "| spring | energy_mse | — | " in " ".join(text.split())
    # the figures: drawn with the report (what the HTML page shows) ...
    report = write_report([protocol, tuned], tmp_path / "out")
    names = {m.path.name for m in report.figures if m.label == "tuned track"}
    assert names == {"tuning_cost.png", "tuning_gain.png"}
    assert "figures/tuning_gain.png" in report.files["html"].read_text()
    # the tuned rows withdrawn, the same folder rebuilt: no table or figure of them is
    # left behind
    again = write_report([protocol], tmp_path / "out")
    for name in ("tracks.csv", "tuning_studies.csv", "tuning_gain.csv", "figures/tuning_gain.png",
                 "figures/tuning_cost.png"):  # fmt: skip
        assert not (tmp_path / "out" / name).exists(), name
    assert "## Tuning gain" not in again.files["tracks_md"].read_text()


def test_the_tracks_table_shows_the_standing_still_reference():
    """The standing-still reference's mean sits beside the tracks' verdicts."""
    from hnnbench._contracts.names import STANDING_STILL
    from hnnbench._results.families import Families
    from hnnbench._results.report.verdicts import tracks_frame

    board = pd.DataFrame(
        [
            {"profile": "paper", "system": "spring", "family": "hnn", "track": "protocol",
             "reference": None, "energy_mse_mean": 1e-3, "energy_mse_mark": "best",
             "energy_mse_effect": 1.0, "energy_mse_effect_low": 0.5,
             "energy_mse_effect_high": 1.5, "energy_mse_effect_vs": "mlp"},
            {"profile": "paper", "system": "spring", "family": "still", "track": "protocol",
             "reference": STANDING_STILL, "energy_mse_mean": 0.25, "energy_mse_mark": ""},
            {"profile": "paper", "system": "spring", "family": "hnn", "track": "tuned",
             "reference": None, "energy_mse_mean": 2e-3, "energy_mse_mark": "best"},
        ]
    )  # fmt: skip
    frame = tracks_frame(Families(board), ["energy_mse"])
    row = frame.iloc[0]
    assert row["still_mean"] == "0.25" or row["still_mean"].startswith("2.5")
    assert row["protocol_effect"] == "×10 [×3.2, ×32] vs mlp" and row["tuned_effect"] == ""


def test_a_track_without_references_of_its_own_is_read_against_the_protocols(tmp_path):
    """Standing still has no settings, so a track that changes only the models' settings
    scores it as the protocol does: the recipe track's cells are marked against the
    protocol's standing-still runs on the recipe's own seeds, which its family table
    shows too."""
    protocol = make_sweep(tmp_path / "protocol", pairs=PAIRS, seeds=SEEDS)
    for system in ("spring", "pendulum"):
        # seeds 0-5: standing still's rollout beats every family's on the spring; the
        # protocol also ran it on seeds 6 and 7, where it is far worse
        for seed in (*SEEDS, 6, 7):
            rollout = 1e-6 if system == "spring" and seed in SEEDS else 1e3
            metrics = {"test_loss": 6.0, "energy_mse": 0.0, "rollout_mse": rollout}
            write_run(protocol, system, "standing_still", seed, "ok", metrics, rollout=False)
    recipe = make_sweep(tmp_path / "recipe", pairs=PAIRS, seeds=SEEDS)
    _as_track(recipe, "recipe")
    report = write_report([protocol, recipe], tmp_path / "out", figures=False)
    tracks = pd.read_csv(report.files["tracks"], keep_default_na=False)
    rollout = tracks[tracks["metric"] == "rollout_mse"].set_index("system")
    # over seeds 0-7 the protocol's families beat standing still (mean 250) ...
    assert rollout.loc["spring", "protocol"].startswith(("best: ", "tied: "))
    # ... over the recipe's seeds 0-5 none does
    assert rollout.loc["spring", "recipe"] == "no family beats standing still"
    assert rollout.loc["pendulum", "recipe"].startswith(("best: ", "tied: "))
    families = pd.read_csv(report.files["families"], keep_default_na=False)
    still = families[families["family"] == "standing_still"].set_index(["system", "track"])
    assert sorted(still.index) == [
        ("pendulum", "protocol"),
        ("pendulum", "recipe"),
        ("spring", "protocol"),
        ("spring", "recipe"),
    ]
    assert still.loc[("spring", "protocol"), "n_seeds"] == 8
    assert still.loc[("spring", "recipe"), "n_seeds"] == len(SEEDS)
