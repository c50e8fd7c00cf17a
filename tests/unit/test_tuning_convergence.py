"""How a tuned study converged (``hnnbench._results.report.convergence``): the best
criterion so far against the CPU spent, what the second half of the trials added, and
what equal compute would have given; summaries checked before use."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Optional

import pandas as pd
import pytest

from hnnbench._contracts.errors import DataError
from hnnbench._results.report import convergence
from hnnbench._results.report.convergence import (
    convergence_figure,
    convergence_frame,
    convergence_markdown,
    convergence_table,
    read_study_summaries,
    summary_problem,
)


def _summary(
    model: str, trials: list[tuple[str, Optional[float], float]], system: str = "spring"
) -> dict[str, Any]:
    """A study summary whose trial ``i`` is ``trials[i]``: (state, value, CPU s), of 100
    steps on 2 seeds each (a pruned trial stopped at step 10)."""
    return {
        "profile": "paper",
        "system": system,
        "model": model,
        "fold": None,
        "steps": 100,
        "seeds_per_trial": 2,
        "trial_seeds": [0, 1],
        "trials_budget": len(trials),
        "trials": [
            {
                "number": i,
                "state": state,
                "value": value,
                "cpu_s": cpu,
                "last_step": 10 if state == "pruned" else 100,
                "protocol": i == 0,
                "seed_values": None if value is None else [value, value],
            }
            for i, (state, value, cpu) in enumerate(trials)
        ],
    }


def test_the_best_so_far_follows_complete_trials_and_counts_every_trials_cpu():
    """A pruned trial's CPU is spent but its value never counts, even when it is lower."""
    frame = convergence_frame(
        [
            _summary(
                "a",
                [
                    ("complete", 4.0, 10),
                    ("pruned", 0.1, 5),
                    ("complete", 2.0, 20),
                    ("complete", 3.0, 10),
                ],
            )
        ]  # fmt: skip
    )
    assert list(frame["cpu_s"]) == [10, 15, 35, 45]
    assert list(frame["best"]) == [4.0, 4.0, 2.0, 2.0]
    # steps trained over both seeds: a pruned trial's to where it stopped; the cap 200 each
    assert list(frame["steps"]) == [200, 220, 420, 620]
    assert list(frame["cap"]) == [200, 400, 600, 800]
    table = convergence_table(frame)
    assert (table.loc[0, "steps_spent"], table.loc[0, "cap_used"]) == (620, 620 / 800)


def test_the_table_says_what_the_second_half_added_and_what_equal_cpu_gives():
    """Study a (cheap) sets its best in its first half; study b improves 4x in its second
    half, and at a's whole CPU (40 s) b had only its first trial's value."""
    a = _summary("a", [("complete", 1.0, 10), ("complete", 0.5, 10), ("pruned", None, 10),
                       ("pruned", None, 10)])  # fmt: skip
    b = _summary("b", [("complete", 8.0, 30), ("complete", 9.0, 30), ("complete", 2.0, 30),
                       ("pruned", None, 30)])  # fmt: skip
    table = convergence_table(convergence_frame([a, b])).set_index("model")
    assert table.loc["a", "best_trial"] == 1 and table.loc["a", "second_half_gain"] == 1
    assert table.loc["b", "best_trial"] == 2 and table.loc["b", "second_half_gain"] == 4
    assert table.loc["a", "equal_cpu_s"] == table.loc["b", "equal_cpu_s"] == 40
    assert table.loc["b", "best_at_equal_cpu"] == 8.0
    assert table.loc["a", "best_at_equal_cpu"] == 0.5
    text = convergence_markdown(table.reset_index())
    assert text.startswith("## Has the criterion flattened?\n")
    assert "1 of 2 studies had their best criterion by the end of the first" in text
    assert "spring/b (×4, trial 2) the second half still improved it" in text


def test_equal_cpu_before_a_studys_first_trial_ends_has_no_value(tmp_path: Path):
    cheap = _summary("cheap", [("complete", 1.0, 5), ("complete", 1.0, 5)])
    dear = _summary("dear", [("complete", 1.0, 100), ("complete", 0.5, 100)])
    frame = convergence_frame([cheap, dear])
    table = convergence_table(frame).set_index("model")
    assert math.isnan(table.loc["dear", "best_at_equal_cpu"])
    assert "| —" in convergence_markdown(table.reset_index())
    made = convergence_figure(frame, tmp_path / "c.png")
    assert made is not None and made.stat().st_size > 0


def test_fold_studies_are_compared_within_their_fold():
    one = _summary("a", [("complete", 1.0, 10)])
    two = _summary("b", [("complete", 1.0, 30)])
    three = {**_summary("b", [("complete", 1.0, 5)]), "fold": 1}
    one["fold"], two["fold"] = 0, 0
    table = convergence_table(convergence_frame([one, two, three]))
    assert sorted(zip(table["fold"], table["equal_cpu_s"], strict=True)) == [
        (0, 10),
        (0, 10),
        (1, 5),
    ]


@pytest.mark.parametrize(
    ("change", "said"),
    [
        (lambda s: s.update(trials="all"), "trials: 'all' is not list"),
        (lambda s: s["trials"][0].update(cpu_s=-1.0), "cpu_s -1.0 is not a finite number >= 0"),
        (
            lambda s: s["trials"][0].update(value="low"),
            "value: 'low' is not a number",
        ),
        (lambda s: s["trials"].append(dict(s["trials"][0])), "trial 0 is given twice"),
        (lambda s: s.update(fold=True), "fold: True is not int or NoneType"),
        (lambda s: s.update(fold=-1), "fold: -1 is not a fold number"),
        (lambda s: s.update(steps=0), "steps: 0 is not a count"),
        (lambda s: s.pop("seeds_per_trial"), "seeds_per_trial: missing (int expected)"),
        (lambda s: s["trials"][0].pop("last_step"), "last_step: missing (int or NoneType"),
        (lambda s: s.update(trial_seeds=[0, -1]), "trial_seeds: [0, -1] is not a list of seeds"),
        (
            lambda s: s["trials"][0].update(seed_values=[1.0]),
            "seed_values [1.0] are not a number per seed",
        ),
        (lambda s: s["trials"][0].update(last_step=101), "last_step 101 is not within 0-100"),
        (lambda s: s["trials"][0].update(last_step=1.5), "last_step: 1.5 is not int or NoneType"),
    ],
)
def test_a_summary_that_does_not_hold_together_is_refused_in_one_line(tmp_path, change, said):
    summary = _summary("hnn_jax", [("complete", 1.0, 10)])
    assert summary_problem(summary) is None
    change(summary)
    assert said in str(summary_problem(summary))
    folder = tmp_path / "tuning" / "spring"
    folder.mkdir(parents=True)
    name = "hnn_jax.json" if summary.get("fold") != -1 else "hnn_jax.fold-1.json"
    (folder / name).write_text(json.dumps(summary))
    with pytest.raises(DataError) as err:
        read_study_summaries(tmp_path / "tuning")
    assert said in str(err.value) and name in str(err.value)
    assert "\n" not in str(err.value)


def test_a_summary_filed_under_another_system_is_refused(tmp_path: Path):
    folder = tmp_path / "pendulum"
    folder.mkdir()
    (folder / "hnn_jax.json").write_text(json.dumps(_summary("hnn_jax", [("complete", 1.0, 1)])))
    with pytest.raises(DataError, match="it is a study of spring, filed under pendulum"):
        read_study_summaries(tmp_path)


def test_no_study_no_table():
    frame = convergence_frame([])
    assert frame.empty and convergence_table(frame).empty
    assert convergence_markdown(convergence_table(frame)) == ""
    assert isinstance(frame, pd.DataFrame)


def test_a_diverged_trial_is_read_as_the_codec_wrote_it_and_never_the_best():
    """A trial whose seed diverged scores the worst value, written as "inf"."""
    summary = _summary("a", [("complete", 2.0, 1), ("complete", 1.0, 1)])
    summary["trials"][1]["value"] = "inf"
    assert summary_problem(summary) is None
    assert list(convergence_frame([summary])["best"]) == [2.0, 2.0]


def test_simulated_and_measured_systems_and_a_skipped_study_share_one_table():
    """Folds beside no fold, and a study with no completed trial (a model the system
    skips: one failed trial in a fraction of a second): the skipped study sets no
    equal-CPU point and is named, not counted, in the sentence."""
    sim = _summary(
        "a",
        [("complete", 1.0, 10), ("complete", 0.5, 10), ("pruned", None, 10), ("pruned", None, 10)],
    )
    skipped = _summary("b", [("fail", None, 0.1)])
    measured = {**_summary("a", [("complete", 1.0, 5)], system="real"), "fold": 3}
    table = convergence_table(convergence_frame([sim, skipped, measured]))
    rows = table.set_index(["system", "model"])
    assert rows.loc[("spring", "a"), "equal_cpu_s"] == 40
    assert rows.loc[("spring", "a"), "best_at_equal_cpu"] == 0.5
    assert pd.isna(rows.loc[("spring", "b"), "best_trial"])
    assert rows.loc[("real", "a"), "fold"] == 3
    text = convergence_markdown(table)
    assert "2 of 2 studies had their best criterion" in text
    assert "No completed trial (or no finite criterion): spring/b." in text
    assert [line.split("|")[3].strip() for line in text.splitlines()[6:]] == ["—", "—", "3"]


def test_a_misnamed_or_repeated_summary_is_refused(tmp_path: Path):
    folder = tmp_path / "spring"
    folder.mkdir()
    summary = _summary("hnn_jax", [("complete", 1.0, 1)])
    (folder / "hnn_jax.old.json").write_text(json.dumps(summary))
    with pytest.raises(DataError, match="it is the study hnn_jax.json, filed as hnn_jax.old.json"):
        read_study_summaries(tmp_path)


def test_summaries_are_read_from_several_folders_each_study_once(tmp_path: Path):
    """One folder per study (scripts/maintainer/tune_sweep.sh's layout): read together,
    in the folders' order; the same study in two folders is refused, naming both."""
    for name, model in (("one", "hnn_jax"), ("two", "mlp_jax")):
        folder = tmp_path / name / "tuning" / "spring"
        folder.mkdir(parents=True)
        (folder / f"{model}.json").write_text(json.dumps(_summary(model, [("complete", 1.0, 1)])))
    folders = [tmp_path / "two" / "tuning", tmp_path / "one" / "tuning"]
    assert [s["model"] for s in read_study_summaries(folders)] == ["mlp_jax", "hnn_jax"]
    again = tmp_path / "three" / "tuning" / "spring"
    again.mkdir(parents=True)
    (again / "mlp_jax.json").write_text(json.dumps(_summary("mlp_jax", [("complete", 2.0, 1)])))
    with pytest.raises(DataError, match="the same study as .*two/tuning/spring/mlp_jax.json"):
        read_study_summaries([*folders, again.parent])


def test_trial_0_is_read_against_the_protocol_records_of_its_seeds():
    """Trial 0 re-runs the protocol's settings on the trial seeds: a study whose trial 0
    gave the protocol record's values is ×1 apart, one off by ×1.5 on a seed is ×1.5
    apart; a study whose seeds have no protocol record (a measured system's folds), or
    a tuned or variant record of the seed, pairs with nothing."""
    same = _summary("a", [("complete", 2.0, 10), ("complete", 1.0, 10)])
    off = _summary("b", [("complete", 3.0, 10)])
    folded = {**_summary("c", [("complete", 1.0, 10)]), "fold": 2, "trial_seeds": [10, 11]}
    runs = pd.DataFrame(
        [
            {"profile": "paper", "system": "spring", "model": m, "seed": seed, "track": track,
             "variant": variant, "criterion_value": value}
            for m, seed, track, variant, value in [
                ("a", 0, "protocol", "", 2.0), ("a", 1, "protocol", "", 2.0),
                ("a", 0, "tuned", "", 9.0), ("a", 1, "protocol", "lr=0.1", 9.0),
                ("b", 0, "protocol", "", 3.0), ("b", 1, "protocol", "", 2.0),
                ("c", 10, "tuned", "", 5.0),
            ]
        ]
    )  # fmt: skip
    summaries = [same, off, folded]
    reruns = convergence.protocol_reruns(convergence.trial0_frame(summaries), runs)
    got = reruns.set_index("model")
    assert got.loc["a", "protocol_seeds"] == 2 and got.loc["a", "protocol_apart"] == 1.0
    assert got.loc["b", "protocol_seeds"] == 2 and got.loc["b", "protocol_apart"] == 1.5
    assert got.loc["c", "protocol_seeds"] == 0 and math.isnan(got.loc["c", "protocol_apart"])
    table = convergence_table(convergence_frame(summaries), reruns)
    assert list(table["protocol_apart"].fillna(-1)) == [1.0, 1.5, -1]
    text = convergence_markdown(table)
    assert "1 of 2 studies agree within ×1.0001 on every seed; spring/b ×1.5 differ" in text
