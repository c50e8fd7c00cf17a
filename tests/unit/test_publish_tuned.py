"""scripts/maintainer/publish_results.py --tuned: the tuned track published in parts (a
finished study is staged; a system is published once every family's study is in)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import pytest
from publish_fixtures import publish_results
from report_fixtures import write_run

TRIALS = 16


def write_study(
    out: Path,
    system: str,
    model: str,
    seeds: tuple[int, ...] = (0, 1),
    done: int = TRIALS,
    lr: float = 0.003,
    **change: Any,
) -> Path:
    """What ``hnnbench tune system=S model=M out=OUT`` leaves of a study of ``done`` of
    its 16 trials: its summary and, when it is finished, its final records (the
    selected ``model.lr`` on ``seeds``, seed 0 with a rollout). ``change`` overrides
    fields of the summary. Returns the summary's path."""
    study = f"{system}/{model}"
    selected = {"number": 3, "value": 1e-4, "settings": {"model.lr": lr}}
    trials = [
        {
            "number": n,
            "state": "complete" if n < 4 else "pruned",
            "value": 1e-3 / (n + 1),
            "settings": {"model.lr": 0.001 if n == 0 else lr},
            "protocol": n == 0,
        }
        for n in range(done)
    ]
    summary = {
        "system": system, "model": model, "study": study, "profile": "paper",
        "trials_budget": TRIALS, "steps": 2000, "criterion": "field_mse_clean",
        "seeds_per_trial": 2, "trial_seeds": [0, 1], "fold": None,
        "final_seeds": list(seeds), "protocol_trial": 0, "protocol_value": 1e-3,
        "selected": selected if done >= TRIALS else None, "trials": trials, **change,
    }  # fmt: skip
    path = out / "tuning" / system / f"{model}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(summary))
    if done < TRIALS:
        return path
    for seed in seeds:
        job = write_run(out / "final", system, model, seed, profile="paper", rollout=seed == 0)
        record = json.loads((job / "result.json").read_text())
        record["track"] = record["config"]["track"] = "tuned"
        record["config"]["model"]["lr"] = lr
        record["config"]["model"]["steps"] = 2000
        record["tuning"] = {
            "selected_on": "validation", "criterion": "field_mse_clean",
            "seeds_per_trial": 2, "trial_seeds": [0, 1], "protocol_trial": 0,
            "trials": TRIALS, "steps": 2000, "space": {}, "selected": {"model.lr": lr},
            "selected_trial": 3, "study": study, "cpu_s": 100.0,
        }  # fmt: skip
        (job / "result.json").write_text(json.dumps(record))
    return path


@pytest.fixture()
def spring(tree, tmp_path):
    """The tree with spring's protocol track published: the MLP, the HNN and the oracle
    (which has no tuned track) on seeds 0 and 1."""
    protocol = tmp_path / "protocol"
    for model in ("mlp_jax", "hnn_jax", "oracle"):
        for seed in (0, 1):
            write_run(protocol, "spring", model, seed, profile="paper", rollout=False)
    publish_results.copy_records([protocol])
    return tree / "results"


def tuned_jobs(root: Path) -> set[tuple[str, ...]]:
    return {
        p.parent.relative_to(root).parts for p in root.rglob("result.json") if "tuned" in p.parts
    }


def test_a_finished_study_is_staged_and_its_system_published_when_every_family_is_in(
    spring, tmp_path
):
    hnn, mlp = tmp_path / "hnn", tmp_path / "mlp"
    write_study(hnn, "spring", "hnn_jax")
    write_study(mlp, "spring", "mlp_jax", done=9)
    staged, waiting = publish_results.stage_tuned([hnn, mlp])
    assert staged == ["spring/hnn_jax"]
    assert waiting == ["spring/mlp_jax: study spring/mlp_jax has 9 of 16 trials; not staged"]
    assert tuned_jobs(spring / "staged") == {
        ("spring", "hnn_jax", "tuned", "seed0"),
        ("spring", "hnn_jax", "tuned", "seed1"),
    }
    assert (spring / "staged" / "spring" / "hnn_jax" / "tuned" / "seed0" / "rollout.npz").is_file()
    assert json.loads((spring / "tuning" / "spring" / "hnn_jax.json").read_text())["selected"]
    # One family of two: nothing is published, and the page says what is staged.
    assert publish_results.publish_complete_systems() == []
    assert tuned_jobs(spring / "records") == set()
    assert publish_results.staged_lines() == [
        "- Tuned track, staged (not published until every family's study is in): "
        "`spring` has hnn (1 of 2 families)"
    ]
    # The MLP's study ends (staging the HNN again changes nothing): spring is published.
    write_study(mlp, "spring", "mlp_jax")
    assert publish_results.stage_tuned([hnn, mlp])[0] == ["spring/hnn_jax", "spring/mlp_jax"]
    assert publish_results.publish_complete_systems() == ["spring"]
    assert {j[:2] for j in tuned_jobs(spring / "records")} == {
        ("spring", "hnn_jax"),
        ("spring", "mlp_jax"),
    }
    assert len(tuned_jobs(spring / "records")) == 4
    assert not (spring / "staged").exists()
    assert publish_results.staged_lines() == []
    assert sorted(p.name for p in (spring / "tuning" / "spring").iterdir()) == [
        "hnn_jax.json",
        "mlp_jax.json",
    ]
    # A family tuned again later (other settings, one seed fewer) replaces its rows.
    shutil.rmtree(hnn)
    write_study(hnn, "spring", "hnn_jax", seeds=(0,), lr=0.005)
    assert publish_results.stage_tuned([hnn])[0] == ["spring/hnn_jax"]
    assert publish_results.publish_complete_systems() == ["spring"]
    hnn_rows = [j for j in tuned_jobs(spring / "records") if j[1] == "hnn_jax"]
    assert hnn_rows == [("spring", "hnn_jax", "tuned", "seed0")]
    record = spring / "records" / "spring" / "hnn_jax" / "tuned" / "seed0" / "result.json"
    assert json.loads(record.read_text())["tuning"]["selected"] == {"model.lr": 0.005}


def _bad_final(out: Path, seed: int, **tuning: Any) -> None:
    path = out / "final" / "spring" / "hnn_jax" / f"seed{seed}" / "result.json"
    record = json.loads(path.read_text())
    record["tuning"].update(tuning)
    record["config"]["model"]["lr"] = record["tuning"]["selected"]["model.lr"]
    path.write_text(json.dumps(record))


@pytest.mark.parametrize(
    "spoil, needle",
    [
        (lambda out, p: p.write_text("{"), "not valid JSON"),
        (
            lambda out, p: p.write_text(
                json.dumps({**json.loads(p.read_text()), "profile": "quick"})
            ),
            "profile quick, not paper",
        ),
        (
            lambda out, p: p.write_text(
                json.dumps({**json.loads(p.read_text()), "model": "mlp_jax"})
            ),
            "a study of spring/mlp_jax, filed as spring/hnn_jax",
        ),
        (
            lambda out, p: p.write_text(
                json.dumps(
                    {
                        **json.loads(p.read_text()),
                        "trials": [
                            {**t, "protocol": False} for t in json.loads(p.read_text())["trials"]
                        ],
                    }
                )
            ),
            "its trial 0 is not the protocol's settings",
        ),
        (
            lambda out, p: p.write_text(json.dumps({**json.loads(p.read_text()), "steps": "2000"})),
            "steps: '2000' is not int",
        ),
        (
            lambda out, p: _bad_final(out, 1, selected={"model.lr": 0.004}),
            "its settings are not its study's selection",
        ),
        (lambda out, p: _bad_final(out, 1, study="spring/other"), "names no study"),
        (
            lambda out, p: shutil.rmtree(out / "final" / "spring" / "hnn_jax" / "seed1"),
            r"its final runs of seeds \[1\] are not in",
        ),
    ],
)
def test_a_study_that_does_not_hold_together_is_one_line_and_nothing_is_staged(
    spring, tmp_path, spoil, needle
):
    out = tmp_path / "hnn"
    summary = write_study(out, "spring", "hnn_jax")
    spoil(out, summary)
    with pytest.raises(SystemExit, match=needle):
        publish_results.main(["--tuned", str(out)])
    assert not (spring / "staged").exists() and not (spring / "tuning").exists()


def test_the_main_entry_stages_and_says_what_waits(spring, tmp_path, capsys):
    """``--tuned`` with nothing finished stages nothing, publishes nothing and says which
    study waits, in one line each; a folder that is not a tuner's is one line too."""
    out = tmp_path / "mlp"
    write_study(out, "spring", "mlp_jax", done=5)
    assert publish_results.main(["--tuned", str(out)]) == 0
    captured = capsys.readouterr()
    assert "spring/mlp_jax has 5 of 16 trials; not staged" in captured.err
    assert json.loads(captured.out) == {"staged": [], "published_tuned": []}
    with pytest.raises(SystemExit, match="holds no tuning/ folder"):
        publish_results.main(["--tuned", str(tmp_path)])
    assert not (spring / "staged").exists()


def test_a_tuned_system_short_of_a_family_is_not_published_as_a_sweep(spring, tmp_path, capsys):
    """The sweep door refuses what ``--tuned`` would keep staged: tuned rows of a system
    without every family its protocol ran."""
    out = tmp_path / "hnn"
    write_study(out, "spring", "hnn_jax")
    assert publish_results.main([str(out / "final"), str(spring / "records")]) == 2
    assert "spring: tuned hnn; its protocol ran hnn, mlp: a tuned system" in capsys.readouterr().err
    assert tuned_jobs(spring / "records") == set()
