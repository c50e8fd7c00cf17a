"""scripts/maintainer/publish_results.py --tuned: the tuned track published in parts (a
finished study is staged; a system is published once every family's study is in)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from publish_fixtures import publish_results, write_study


def tuned_jobs(root: Path) -> set[tuple[str, ...]]:
    return {
        p.parent.relative_to(root).parts for p in root.rglob("result.json") if "tuned" in p.parts
    }


def test_a_finished_study_is_staged_and_its_system_published_when_every_family_is_in(
    published_spring, tmp_path
):
    hnn, mlp = tmp_path / "hnn", tmp_path / "mlp"
    write_study(hnn, "spring", "hnn_jax")
    write_study(mlp, "spring", "mlp_jax", done=9)
    staged, waiting = publish_results.stage_tuned([hnn, mlp])
    assert staged == ["spring/hnn_jax"]
    assert waiting == ["spring/mlp_jax: study spring/mlp_jax has 9 of 16 trials; not staged"]
    here = published_spring / "staged" / "spring" / "hnn_jax"
    assert tuned_jobs(published_spring / "staged") == {
        ("spring", "hnn_jax", "tuned", "seed0"),
        ("spring", "hnn_jax", "tuned", "seed1"),
    }
    assert (here / "tuned" / "seed0" / "rollout.npz").is_file()
    assert json.loads((here / "hnn_jax.json").read_text())["selected"]
    # One family of two: nothing is published, and the page says what is staged.
    assert publish_results.publish_complete_systems() == []
    assert (
        tuned_jobs(published_spring / "records") == set()
        and not (published_spring / "tuning").exists()
    )
    assert publish_results.staged_lines() == [
        "- Tuned track, staged (not published until every family's study is in): "
        "`spring` has hnn (1 of 2 families)"
    ]
    # Staging the HNN again changes nothing; the MLP's study ends: spring is published.
    before = {p: p.read_bytes() for p in here.rglob("*") if p.is_file()}
    write_study(mlp, "spring", "mlp_jax")
    assert publish_results.stage_tuned([hnn, mlp])[0] == ["spring/hnn_jax", "spring/mlp_jax"]
    assert {p: p.read_bytes() for p in here.rglob("*") if p.is_file()} == before
    assert publish_results.publish_complete_systems() == ["spring"]
    assert {j[:2] for j in tuned_jobs(published_spring / "records")} == {
        ("spring", "hnn_jax"),
        ("spring", "mlp_jax"),
    }
    assert len(tuned_jobs(published_spring / "records")) == 4
    assert not (published_spring / "staged").exists()
    assert publish_results.staged_lines() == []
    assert sorted(p.name for p in (published_spring / "tuning" / "spring").iterdir()) == [
        "hnn_jax.json",
        "mlp_jax.json",
    ]
    # A family tuned again later (other settings) replaces its rows and its summary.
    shutil.rmtree(hnn)
    write_study(hnn, "spring", "hnn_jax", lr=0.005)
    assert publish_results.stage_tuned([hnn])[0] == ["spring/hnn_jax"]
    assert publish_results.publish_complete_systems() == ["spring"]
    tuned = published_spring / "records" / "spring" / "hnn_jax" / "tuned"
    assert sorted(p.relative_to(tuned).as_posix() for p in tuned.rglob("*.*")) == [
        "seed0/result.json",
        "seed0/rollout.npz",
        "seed1/result.json",
    ]
    record = json.loads((tuned / "seed0" / "result.json").read_text())
    assert record["tuning"]["selected"] == {"model.lr": 0.005}
    summary = json.loads((published_spring / "tuning" / "spring" / "hnn_jax.json").read_text())
    assert summary["selected"]["settings"] == {"model.lr": 0.005}


def test_a_pair_waits_until_its_studies_cover_the_protocols_seeds_and_their_finals_are_written(
    published_spring, tmp_path
):
    """A measured system's fold studies end one by one, and a study's final runs come
    after its summary: either way the pair waits, said in one line, and the others stage."""
    folds, hnn = tmp_path / "folds", tmp_path / "hnn"
    write_study(folds, "spring", "mlp_jax", seeds=(0,), fold=0)  # fold 1 (seed 1) to come
    write_study(hnn, "spring", "hnn_jax")
    staged, waiting = publish_results.stage_tuned([folds, hnn])
    assert staged == ["spring/hnn_jax"]
    assert waiting == [
        "spring/mlp_jax: its studies cover final seeds [0] of the protocol's [0, 1] (a "
        "measured system's fold studies end one by one); not staged"
    ]
    write_study(folds, "spring", "mlp_jax", seeds=(1,), fold=1)
    shutil.rmtree(folds / "final" / "spring" / "mlp_jax" / "seed1")  # still running
    staged, waiting = publish_results.stage_tuned([folds])
    assert staged == [] and waiting[0].startswith(
        "spring/mlp_jax: the final runs of seeds [1] are not written yet"
    )
    assert publish_results.publish_complete_systems() == []
    write_study(folds, "spring", "mlp_jax", seeds=(1,), fold=1)
    assert publish_results.stage_tuned([folds])[0] == ["spring/mlp_jax"]
    assert sorted(
        p.name for p in (published_spring / "staged" / "spring" / "mlp_jax").glob("*.json")
    ) == [
        "mlp_jax.fold0.json",
        "mlp_jax.fold1.json",
    ]
    assert publish_results.publish_complete_systems() == ["spring"]
    empty = tmp_path / "starting"
    empty.mkdir()
    assert publish_results.stage_tuned([empty]) == (
        [],
        [f"{empty}: no study summary yet (no tuning/ folder); not staged"],
    )


def test_fold_studies_run_side_by_side_in_folders_of_their_own_stage_together(
    published_spring, tmp_path
):
    """A folder takes one tuner at a time, so a measured system's fold studies run side by
    side each in an out= folder of its own; each study's final runs are read from its own
    folder, and a job found in two folders is refused."""
    f0, f1, hnn = tmp_path / "fold0", tmp_path / "fold1", tmp_path / "hnn"
    write_study(f0, "spring", "mlp_jax", seeds=(0,), fold=0)
    write_study(f1, "spring", "mlp_jax", seeds=(1,), fold=1)
    write_study(hnn, "spring", "hnn_jax")
    shutil.copytree(
        f1 / "final" / "spring" / "mlp_jax" / "seed1", f0 / "final" / "spring" / "mlp_jax" / "seed1"
    )
    with pytest.raises(
        SystemExit, match=r"the tuned run spring/mlp_jax seed 1 is in both .*fold0.* and .*fold1"
    ):
        publish_results.stage_tuned([f0, f1, hnn])
    assert not (published_spring / "staged").exists()
    shutil.rmtree(f0 / "final" / "spring" / "mlp_jax" / "seed1")
    assert publish_results.stage_tuned([f0, f1, hnn]) == (["spring/hnn_jax", "spring/mlp_jax"], [])
    assert {j[1:] for j in tuned_jobs(published_spring / "staged")} == {
        (m, "tuned", f"seed{k}") for m in ("mlp_jax", "hnn_jax") for k in (0, 1)
    }
    assert publish_results.publish_complete_systems() == ["spring"]


def test_a_tuned_pairs_figure_rollout_is_of_its_lowest_seed_no_trial_trained(
    published_spring, tmp_path
):
    """The figures draw what the rows read: of a tuned pair whose finals have rollouts on
    seeds 0 to 2, the one kept is seed 2's (seeds 0 and 1 are its trials' own)."""
    hnn, mlp = tmp_path / "hnn", tmp_path / "mlp"
    write_study(hnn, "spring", "hnn_jax", seeds=(0, 1, 2), rollouts=(0, 1, 2))
    write_study(mlp, "spring", "mlp_jax", seeds=(0, 1, 2), rollouts=(0, 1))  # none unseen
    publish_results.stage_tuned([hnn, mlp])
    kept = sorted(
        p.parent.relative_to(published_spring / "staged").parts
        for p in (published_spring / "staged").rglob("rollout.npz")
    )
    assert kept == [
        ("spring", "hnn_jax", "tuned", "seed2"),
        ("spring", "mlp_jax", "tuned", "seed0"),
    ]


def test_a_study_of_another_budget_than_its_systems_others_is_refused(published_spring, tmp_path):
    hnn, mlp = tmp_path / "hnn", tmp_path / "mlp"
    write_study(hnn, "spring", "hnn_jax")
    publish_results.stage_tuned([hnn])
    write_study(mlp, "spring", "mlp_jax", budget=24)
    with pytest.raises(SystemExit, match=r"unequal.*a system's studies share one budget"):
        publish_results.stage_tuned([mlp])
    assert {j[1] for j in tuned_jobs(published_spring / "staged")} == {"hnn_jax"}


def _bad_final(out: Path, seed: int, **tuning: Any) -> None:
    path = out / "final" / "spring" / "hnn_jax" / f"seed{seed}" / "result.json"
    record = json.loads(path.read_text())
    record["tuning"].update(tuning)
    record["config"]["model"]["lr"] = record["tuning"]["selected"]["model.lr"]
    path.write_text(json.dumps(record))


def _edit(path: Path, **fields: Any) -> None:
    path.write_text(json.dumps({**json.loads(path.read_text()), **fields}))


@pytest.mark.parametrize(
    "spoil, needle",
    [
        (lambda out, p: p.write_text("{"), "not valid JSON"),
        (lambda out, p: _edit(p, profile="quick"), "profile quick, not paper"),
        (lambda out, p: _edit(p, model="mlp_jax"), "a study of spring/mlp_jax, filed as"),
        (
            lambda out, p: _edit(
                p, trials=[{**t, "protocol": False} for t in json.loads(p.read_text())["trials"]]
            ),
            "its trial 0 is not the protocol's settings",
        ),
        (lambda out, p: _edit(p, steps="2000"), "steps: '2000' is not int"),
        (lambda out, p: _edit(p, protocol_value=1e-4), "is not its trial 0's value"),
        (lambda out, p: _edit(p, trials_budget=3), "more than its budget of 3"),
        (
            lambda out, p: _edit(
                p, selected={"number": 2, "value": 1e-3 / 3, "settings": {"model.lr": 0.003}}
            ),
            "is not the best completed trial",
        ),
        (
            lambda out, p: _edit(
                p, selected={"number": 5, "value": 1e-5, "settings": {"model.lr": 0.003}}
            ),
            "trial 5 is not a completed trial",
        ),
        (
            lambda out, p: _edit(
                p,
                trials=[
                    {**t, "settings": {"model.lr": 0.002}} if t["number"] == 0 else t
                    for t in json.loads(p.read_text())["trials"]
                ],
            ),
            "its trial 0 sets model.lr=0.002, the published protocol records",
        ),
        (
            lambda out, p: _edit(
                p,
                trials=[
                    {**t, "value": "n/a"} if t["number"] == 1 else t
                    for t in json.loads(p.read_text())["trials"]
                ],
            ),
            "trial 1: value 'n/a' is not a number",
        ),
        (
            lambda out, p: _bad_final(out, 1, selected={"model.lr": 0.004}),
            "its settings are not its study's selection",
        ),
        (lambda out, p: _bad_final(out, 1, study="spring/other"), "names no study"),
    ],
)
def test_a_study_that_does_not_hold_together_is_one_line_and_nothing_is_staged(
    published_spring, tmp_path, spoil, needle
):
    out = tmp_path / "hnn"
    summary = write_study(out, "spring", "hnn_jax")
    spoil(out, summary)
    with pytest.raises(SystemExit, match=needle):
        publish_results.main(["--tuned", str(out)])
    assert not (published_spring / "staged").exists() and not (published_spring / "tuning").exists()


def test_the_main_entry_stages_and_says_what_waits(published_spring, tmp_path, capsys):
    """``--tuned`` with nothing finished stages nothing, publishes nothing and says which
    study waits, in one line each."""
    out = tmp_path / "mlp"
    write_study(out, "spring", "mlp_jax", done=5)
    assert publish_results.main(["--tuned", str(out)]) == 0
    captured = capsys.readouterr()
    assert "spring/mlp_jax has 5 of 16 trials; not staged" in captured.err
    assert json.loads(captured.out) == {"staged": [], "published_tuned": []}
    assert not (published_spring / "staged").exists()


def test_tuned_rows_do_not_enter_through_the_sweep_door(published_spring, tmp_path, capsys):
    """Tuned records given as a sweep are refused, whole system or not: they enter with
    --tuned, checked against their studies' summaries."""
    hnn, mlp = tmp_path / "hnn", tmp_path / "mlp"
    write_study(hnn, "spring", "hnn_jax")
    write_study(mlp, "spring", "mlp_jax")
    assert publish_results.main([str(hnn / "final"), str(published_spring / "records")]) == 2
    assert "tuned rows enter with --tuned OUT" in capsys.readouterr().err
    both = [str(hnn / "final"), str(mlp / "final"), str(published_spring / "records")]
    assert publish_results.main(both) == 2
    assert tuned_jobs(published_spring / "records") == set()


def test_a_published_tuned_system_that_loses_a_family_is_refused(
    published_spring, tmp_path, capsys
):
    """Withdrawing one family's protocol rows from a tuned system would leave its tuned
    rows without that family's pair: refused, naming it."""
    hnn, mlp = tmp_path / "hnn", tmp_path / "mlp"
    write_study(hnn, "spring", "hnn_jax")
    write_study(mlp, "spring", "mlp_jax")
    publish_results.stage_tuned([hnn, mlp])
    assert publish_results.publish_complete_systems() == ["spring"]
    records = published_spring / "records" / "spring"
    shutil.rmtree(records / "mlp_jax" / "tuned")
    kept = [str(records / m) for m in ("hnn_jax", "mlp_jax", "oracle")]
    assert publish_results.main(kept) == 2
    assert "spring: tuned hnn; its protocol ran hnn, mlp" in capsys.readouterr().err


def test_protocol_records_that_disagree_on_a_setting_cannot_vouch_for_trial_0(
    published_spring, tmp_path
):
    """Trial 0 is checked against the published protocol records; where those records
    themselves hold two values of a setting, the check cannot be made: one line saying
    so, and nothing is staged."""
    path = published_spring / "records" / "spring" / "hnn_jax" / "seed1" / "result.json"
    record = json.loads(path.read_text())
    record["config"]["model"]["lr"] = 0.005
    path.write_text(json.dumps(record))
    out = tmp_path / "hnn"
    write_study(out, "spring", "hnn_jax")
    with pytest.raises(SystemExit, match="the published protocol records disagree on model.lr"):
        publish_results.main(["--tuned", str(out)])
    assert not (published_spring / "staged").exists()


def test_a_study_whose_trial_0_was_interrupted_and_replayed_is_staged(published_spring, tmp_path):
    """An interruption during trial 0 leaves it out of the summary (an interrupted trial
    is not counted) and the tuner runs its settings again as trial 1, flagged the
    protocol's: that study is staged; two trials flagged the protocol's are not."""
    out = tmp_path / "hnn"
    path = write_study(out, "spring", "hnn_jax")
    summary = json.loads(path.read_text())
    for trial in summary["trials"]:
        trial["number"] += 1
    summary["selected"]["number"] += 1
    path.write_text(json.dumps(summary))
    assert publish_results.stage_tuned([out])[0] == ["spring/hnn_jax"]
    summary["trials"][1]["protocol"] = True
    path.write_text(json.dumps(summary))
    with pytest.raises(SystemExit, match="its trial 0 is not the protocol's settings"):
        publish_results.stage_tuned([out])


def test_trial_0_is_read_against_the_protocol_configs_as_the_protocol_job_resolves_them():
    """A training field the model leaves None is the system's; a setting that is None on
    purpose matches None; 0 and 0.0 are one value; a setting the records do not hold
    cannot be checked, and a protocol trial that is not the study's first is none."""
    check = publish_results.protocol_settings_problem
    trial = {"number": 0, "protocol": True, "state": "complete", "value": 1.0}

    def summary(**settings: Any) -> dict[str, Any]:
        return {"protocol_trial": 0, "trials": [{**trial, "settings": settings}]}

    config = {"model": {"lr": None, "weight_decay": 0, "window": None}, "system": {"lr": 0.001}}
    assert check(summary(**{"model.lr": 0.001}), [config, config]) is None
    assert check(summary(**{"model.weight_decay": 0.0}), [config]) is None
    assert check(summary(**{"model.window": None}), [config]) is None  # None on purpose
    assert "do not state model.hidden" in (check(summary(**{"model.hidden": 64}), [config]) or "")
    other = {**config, "model": {**config["model"], "weight_decay": 0.0}}
    assert check(summary(**{"model.weight_decay": 0.0}), [config, other]) is None
    late = {"protocol_trial": 0, "trials": [{**trial, "number": 2, "settings": {}},
                                            {**trial, "number": 1, "protocol": False}]}  # fmt: skip
    assert check(late, [config]) == "its trial 0 is not the protocol's settings"
