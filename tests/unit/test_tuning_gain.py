"""The tuning gain reads only the final seeds no trial trained
(``hnnbench._results.report.tuning.tuning_gain``), its ``criterion`` row included."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd

from hnnbench._results.families import Families
from hnnbench._results.leaderboard import records_frame
from hnnbench._results.report.tuning import (
    CRITERION_ROW,
    GAIN_SIDES,
    TRIAL,
    UNSEEN,
    _gain_plot,  # one figure's artists
    gain_figure,
    gain_markdown,
    gain_summary,
    studies_frame,
    tuning_gain,
)


def _rec(
    seed: int, track: str, criterion: float, loss: float = 1.0, trial_seeds: tuple[int, ...] = ()
) -> dict:
    rec: dict[str, Any] = {
        "system": "spring",
        "model": "hnn_jax",
        "family": "hnn",
        "backend": "jax",
        "seed": seed,
        "profile": "paper",
        "status": "ok",
        "ranked": True,
        "track": track,
        "metrics": {"test_loss": {"mean": loss, "sem": 0.0}},
        "selection": {"criterion": "field_mse_clean", "validation_loss": criterion},
    }
    if track == "tuned":
        rec["tuning"] = {"selected_on": "validation", "trial_seeds": list(trial_seeds)}
    return rec


def _gain(recs: list[dict]) -> pd.DataFrame:
    return tuning_gain(Families(pd.DataFrame({"family": ["hnn"]}), runs=records_frame(recs)))


def test_every_gain_row_reads_only_the_seeds_no_trial_trained():
    """Seeds 0 and 1 trained the trials and look 100x better tuned, on the criterion and
    on test loss (the selection's luck); on seeds 2-9 both are 2x better: every row says
    x2 on 8 seeds."""
    protocol = [_rec(s, "protocol", 1.0) for s in range(10)]
    tuned = [
        _rec(s, "tuned", 0.01 if s < 2 else 0.5, 0.01 if s < 2 else 0.5, trial_seeds=(0, 1))
        for s in range(10)
    ]
    every = _gain([*protocol, *tuned])
    gain = every[every["seeds"] == UNSEEN].set_index("metric")
    assert list(gain.index) == [CRITERION_ROW, "test_loss"]
    for metric in (CRITERION_ROW, "test_loss"):
        row = gain.loc[metric]
        assert row["n"] == 8 and row["scale"] == "log"
        assert math.isclose(row["gain"], math.log10(2)) and math.isclose(row["low"], row["high"])
    # the trial seeds' rows are kept apart, and the page says how much larger they are
    luck = every[every["seeds"] == TRIAL].set_index("metric")
    assert luck.loc[CRITERION_ROW, "n"] == 2 and math.isclose(luck.loc[CRITERION_ROW, "gain"], 2)
    text = gain_markdown(every, studies_frame([]))
    assert "×2 [×2, ×2] (8)" in text and "] (2)" not in text  # no trial-seed cell
    assert (
        "`criterion` 1 larger and 0 smaller of 1, `test_loss` 1 larger and 0 smaller of 1" in text
    )


def test_a_measured_systems_fold_studies_on_other_seeds_leave_every_final_seed_unseen():
    """Fold studies whose trials trained seeds 10-19 (the folds' data, other
    initialisations): all ten final seeds count. Fold studies that trained their own
    final seeds (no seed unseen) give no row at all."""
    protocol = [_rec(s, "protocol", 1.0) for s in range(10)]
    apart = [_rec(s, "tuned", 0.5, trial_seeds=(s % 5 + 10, s % 5 + 15)) for s in range(10)]
    assert set(_gain([*protocol, *apart])["n"]) == {10}
    for rec in apart:  # as the tuner writes them: one study per fold
        fold = (4 - rec["seed"]) % 5
        rec["tuning"].update(selected={"model.lr": 0.01}, fold=fold, study=f"s/hnn_jax/fold{fold}")
    text = gain_markdown(_gain([*protocol, *apart]), studies_frame(apart))
    assert "On `spring` (a measured system: one study per fold) the seeds of one fold" in text
    own = [_rec(s, "tuned", 0.5, trial_seeds=(s % 5, s % 5 + 5)) for s in range(10)]
    assert set(_gain([*protocol, *own])["seeds"]) == {TRIAL}
    # records that name no trial seeds are neither; the page names the family left out
    unknown = [_rec(s, "tuned", 0.5) for s in range(10)]
    for rec in unknown:
        del rec["tuning"]["trial_seeds"]
        rec["tuning"].update(selected={"model.lr": 0.01}, study="spring/hnn_jax")
    assert _gain([*protocol, *unknown]).empty
    text = gain_markdown(_gain([*protocol, *unknown]), studies_frame(unknown))
    assert "No tuning gain for spring/hnn: none of their final seeds is both known" in text


def test_no_tuned_row_reads_a_trial_seed_and_the_gain_still_shows_them_apart():
    """A tuned run on a trial seed is the selected trial again: the leaderboard's tuned
    row, the family view's runs (what marks and the aggregate read) leave it out
    (``in_sample``); the tuning gain still reads it, as its ``trial`` rows."""
    from hnnbench._results.families import families
    from hnnbench._results.leaderboard import in_sample, leaderboard_frame

    recs = [_rec(s, "protocol", 1.0) for s in range(10)]
    # seeds 0 and 1 look 500x better tuned: the selection's own seeds
    recs += [_rec(s, "tuned", 0.5, 0.001 if s < 2 else 0.5, trial_seeds=(0, 1)) for s in range(10)]
    frame = records_frame(recs)
    assert list(frame.loc[in_sample(frame), "seed"]) == [0, 1]
    board = leaderboard_frame(frame).set_index("track")
    assert board.loc["tuned", "seeds"] == "2;3;4;5;6;7;8;9"
    assert board.loc["tuned", "n_ok"] == 8 and board.loc["tuned", "test_loss_mean"] == 0.5
    assert board.loc["protocol", "n_ok"] == 10
    fams = families(frame)
    tuned_runs = fams.runs[fams.runs["track"] == "tuned"]
    assert sorted(tuned_runs["seed"]) == list(range(2, 10))
    assert sorted(fams.in_sample["seed"]) == [0, 1] and set(fams.in_sample["family"]) == {"hnn"}
    gain = tuning_gain(fams).set_index(["metric", "seeds"])
    assert gain.loc[("test_loss", UNSEEN), "n"] == 8
    assert gain.loc[("test_loss", TRIAL), "n"] == 2
    assert math.isclose(gain.loc[("test_loss", TRIAL), "gain"], 3.0)  # log10(1 / 0.001)
    # a trial seed's run that failed carries no value: its row still counts it
    recs[11] = {**recs[11], "status": "failed", "metrics": {}, "selection": None}
    board = leaderboard_frame(records_frame(recs)).set_index("track")
    assert board.loc["tuned", "n_failed"] == 1 and board.loc["tuned", "n_ok"] == 8


def _row(
    family: str,
    metric: str,
    gain: float,
    low: float,
    high: float,
    seeds: str = UNSEEN,
    n: int = 8,
    profile: str = "paper",
) -> dict[str, Any]:
    """A tuning gain row of factors ``gain`` in ``[low, high]`` on ``n`` paired seeds (as
    :func:`tuning_gain` writes them, log10)."""
    return {"profile": profile, "system": "spring", "family": family, "metric": metric,
            "seeds": seeds, "n": n, "gain": math.log10(gain), "low": math.log10(low),
            "high": math.log10(high), "coverage": 1 - 2 * 0.5**n, "scale": "log"}  # fmt: skip


def test_the_summary_sorts_each_family_by_its_gains_interval_and_draws_them(tmp_path: Path):
    """A family goes under `helped` where its interval lies above x1 (x1.04 written with
    three digits, not as x1), `hurt` below, `within noise` across it or on fewer seeds
    than can separate, largest gain first; the trial seeds' rows (their luck) and
    metrics outside the headline are not read. The figure draws one interval per family
    and panel, the log-scale metrics only, an infinite end as an arrow at the axis."""
    rows = [
        _row("a", CRITERION_ROW, 4.0, 2.0, 8.0),
        _row("b", CRITERION_ROW, 1.04, 1.01, 1.08),
        _row("c", CRITERION_ROW, 0.5, 0.3, 0.8),
        _row("d", CRITERION_ROW, 1.3, 0.8, 2.0),
        _row("e", CRITERION_ROW, 9.0, 0.9, 20.0),
        _row("f", CRITERION_ROW, 30.0, 20.0, 40.0, n=4),  # all four better: too few seeds
        _row("c", CRITERION_ROW, 50.0, 40.0, 60.0, seeds=TRIAL),  # the selection's own seeds
        _row("a", "test_loss", 0.9, 0.5, 1.5),
        {**_row("b", "test_loss", 2.0, 1.5, 3.0), "high": math.inf},  # a diverged protocol
        _row("a", "train_loss", 0.2, 0.1, 0.3),  # not a headline metric
    ]
    gain = pd.DataFrame(rows)
    summary = gain_summary(gain).set_index("metric")
    assert list(summary.index) == [CRITERION_ROW, "test_loss"]
    assert list(summary.columns) == ["profile", "system", *GAIN_SIDES]
    helped, noise, hurt = (summary.loc[CRITERION_ROW, side] for side in GAIN_SIDES)
    assert (helped, noise, hurt) == ("a ×4, b ×1.04", "f ×30, e ×9, d ×1.3", "c ×0.5")
    assert summary.loc["test_loss", "helped"] == "b ×2"
    assert summary.loc["test_loss", "within noise"] == "a ×0.9"
    text = " ".join(gain_markdown(gain, studies_frame([])).split())
    assert "| spring | criterion | a ×4, b ×1.04 |" in text and "fewer than 6 paired seeds" in text
    fig = _gain_plot(gain)
    assert fig is not None
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in panels] == ["criterion (paper)", "test_loss (paper)"]
    assert [len(ax.containers) for ax in panels] == [6, 2]  # trial seeds' row not drawn
    from matplotlib.collections import PathCollection

    arrows = [[c for c in ax.collections if isinstance(c, PathCollection)] for ax in panels]
    assert [len(a) for a in arrows] == [0, 1]  # the infinite end's arrow, at the axis
    assert arrows[1][0].get_offsets()[0][0] == panels[1].get_xlim()[1]
    made = gain_figure(gain, tmp_path / "gain.png")
    assert made is not None and made.stat().st_size > 0
    # nothing left to draw: no figure, and an earlier one is removed
    linear = gain.assign(scale="linear")
    assert not gain_summary(linear).empty and gain_figure(linear, made) is None
    assert not made.exists()
    assert gain_summary(gain.iloc[:0]).empty


def test_a_second_profile_keeps_its_own_rows_and_panels():
    """Two profiles: the summary names each row's profile, the figure a row of panels
    per profile."""
    gain = pd.DataFrame(
        [_row("a", CRITERION_ROW, 4.0, 2.0, 8.0), _row("a", CRITERION_ROW, 0.5, 0.3, 0.8,
                                                          profile="quick")]
    )  # fmt: skip
    summary = gain_summary(gain)
    assert list(summary["profile"]) == ["paper", "quick"]
    assert list(summary["helped"]) == ["a ×4", "—"] and list(summary["hurt"]) == ["—", "a ×0.5"]
    assert "| quick | spring | criterion |" in " ".join(
        gain_markdown(gain, studies_frame([])).split()
    )
    fig = _gain_plot(gain)
    assert fig is not None
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert titles == ["criterion (paper)", "criterion (quick)"]
