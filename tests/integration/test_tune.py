"""The tuned track (docs/TUNING.md): search spaces declared by the plugins and checked at
registration, the tracks in records, leaderboards and the gate, the progress callback
that stops training (the pruner's lever), and ``hnnbench tune`` end to end: the same
budget for every model, selection on validation only, final records of the tuned track,
and resuming."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import REPO
from report_fixtures import tuned_rows_problems

import hnnbench
from hnnbench import _registry as registry
from hnnbench._contracts.errors import ConfigError, UnknownNameError
from hnnbench._contracts.names import DEFAULT_TRACK
from hnnbench._contracts.plugin import STOPPED_BY_CALLER, TrainSettings
from hnnbench._contracts.space import (
    Categorical,
    IntRange,
    LogUniform,
    Uniform,
    describe,
    space_json,
    space_problem,
)
from hnnbench._record.fields import json_schema
from hnnbench._record.tracks import track_of, track_problem, tuned_settings
from hnnbench._results.check.compare import compare
from hnnbench._results.check.records import budget_findings
from hnnbench._results.leaderboard import leaderboard, records_frame
from hnnbench._running.compose import compose
from hnnbench._running.config import prepare_job
from hnnbench.neural import SHARED_SPACE, NeuralConfig
from hnnbench.neural._loop import train
from tests.conftest import assert_one_line_error
from tests.conftest import hnnbench as hnnbench_cli

# --------------------------------------------------------------------------- spaces


@dataclass
class _Cfg(NeuralConfig):
    window: int = 5

    def validate(self) -> None:
        super().validate()
        if self.window < 2:
            raise ConfigError(f"model.window={self.window} is invalid: expected >= 2.")


@pytest.mark.parametrize(
    "space, needle",
    [
        ({"nope": LogUniform(1e-4, 1e-2)}, "'nope', which is not a setting of _Cfg"),
        ({"steps": IntRange(10, 100)}, "the step budget"),
        ({"lr": (1e-4, 1e-2)}, "expected LogUniform, Uniform, IntRange or Categorical"),
        ({"lr": LogUniform(0.0, 1e-2)}, "needs 0 < low < high"),
        ({"lr": Uniform(1.0, 1.0)}, "needs finite low < high"),
        ({"layers": IntRange(2.0, 4)}, "needs integers low < high"),  # type: ignore[arg-type]
        ({"activation": Categorical(())}, "non-empty tuple"),
        ({"activation": Categorical(("tanh", "tanh"))}, "repeats a choice"),
        ({"activation": Categorical(("tanh", "relu"))}, "'relu' is refused by _Cfg"),
        ({"window": IntRange(1, 8)}, "the value 1 is refused by _Cfg"),
        ({}, "is empty"),
        ([("lr", LogUniform(1e-4, 1e-2))], "must be a mapping"),
    ],
)
def test_a_bad_search_space_is_refused_with_the_reason(space, needle):
    problem = space_problem(space, _Cfg)
    assert problem is not None and needle in problem, problem


def test_the_shared_space_is_valid_and_described_in_one_line():
    assert space_problem(SHARED_SPACE, NeuralConfig) is None
    text = describe(SHARED_SPACE)
    assert "lr: log-uniform [0.0001, 0.01]" in text and "\n" not in text
    assert space_json({"window": IntRange(3, 8, changes_training_loss=True)}) == {
        "window": {"kind": "int", "low": 3, "high": 8, "changes_training_loss": True}
    }


def test_every_built_in_neural_family_declares_a_valid_space_over_its_config():
    families = {}
    for name, info in registry.discover("model").items():
        family = getattr(info.cls, "family", None)
        if info.ok and family is not None:
            assert info.search_space, f"{name} declares no search space"
            assert space_problem(info.search_space, info.cls.Config) is None
            families.setdefault(family.name, []).append(dict(info.search_space))
    assert len(families) >= 6
    for spaces in families.values():  # a family's backends declare one space
        assert all(s == spaces[0] for s in spaces)
    # the settings every family has are searched over the same ranges
    for spaces in families.values():
        for key in ("lr", "weight_decay", "hidden", "layers"):
            assert spaces[0][key] == SHARED_SPACE[key]


def test_a_third_party_model_declares_a_space_and_list_shows_it(tmp_path):
    from stub_models import Unrun

    class Spaced(Unrun):
        search_space = {"lr": hnnbench.LogUniform(1e-3, 1e-1)}

    class BadSpace(Spaced):
        search_space = {"hidden": hnnbench.IntRange(1, 10)}  # not a ModelConfig field

    try:
        hnnbench.register("model", "spaced_model", Spaced)
        assert registry.discover("model")["spaced_model"].search_space == Spaced.search_space
        with pytest.raises(ConfigError, match="search_space names 'hidden'"):
            hnnbench.register("model", "badspace_model", BadSpace)
        import contextlib
        import io

        from hnnbench._entry.command import cmd_list

        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            cmd_list(["--json"])
        listed = {m["name"]: m for m in json.loads(out.getvalue())["model"]}
        assert listed["spaced_model"]["search_space"] == {
            "lr": {"kind": "log_uniform", "low": 1e-3, "high": 1e-1}
        }
        assert listed["hnn_jax"]["search_space"]["hidden"]["kind"] == "categorical"
        assert listed["oracle"]["search_space"] is None
    finally:
        registry.MODELS._registered.pop("spaced_model", None)
        registry.refresh()


def test_hnnbench_list_shows_the_spaces():
    proc = hnnbench_cli("list")
    assert proc.returncode == 0, proc.stderr
    assert "Search spaces (hnnbench tune" in proc.stdout
    assert "window: int [3, 8]" in proc.stdout
    assert "kinetic_prior" in proc.stdout and "dissipation_scale" in proc.stdout


# --------------------------------------------------------------------------- knobs


def _fields(model: str, **settings) -> np.ndarray:
    """The field of ``model`` on the spring with the seed-0 initial weights."""
    overrides = [f"model.{k}={v}" for k, v in settings.items()]
    job = prepare_job(
        compose(
            [
                "system=spring",
                f"model={model}",
                "model.hidden=16",
                "model.dtype=float64",
                *overrides,
            ]
        )
    )
    system = job.system_cls(job.system_cfg)
    m = job.model_cls(job.model_cfg, system, "cpu")
    m.set_weights(m.initial_weights(0))
    x = np.random.default_rng(0).normal(size=(7, 2))
    return m.time_derivative(x)


@pytest.mark.parametrize("backend", ["torch", "jax"])
def test_the_dhnn_dissipation_scale_weighs_its_dissipative_part(backend):
    f0, f1, f3 = (_fields(f"dhnn_{backend}", dissipation_scale=s) for s in (1e-9, 1.0, 3.0))
    np.testing.assert_allclose(f3 - f0, 3.0 * (f1 - f0), rtol=1e-6, atol=1e-12)
    assert not np.allclose(f1, f0)


@pytest.mark.parametrize("backend", ["torch", "jax"])
def test_the_lnn_kinetic_prior_reaches_its_field(backend):
    default, same, other = (
        _fields(f"lnn_{backend}", **kw)
        for kw in ({}, {"kinetic_prior": 0.5}, {"kinetic_prior": 1.0})
    )
    np.testing.assert_array_equal(default, same)
    assert not np.allclose(default, other)


def test_the_knobs_agree_between_backends():
    for model, setting in (("lnn", {"kinetic_prior": 0.25}), ("dhnn", {"dissipation_scale": 0.3})):
        np.testing.assert_allclose(
            _fields(f"{model}_torch", **setting),
            _fields(f"{model}_jax", **setting),
            rtol=1e-9,
            atol=1e-12,
        )


@pytest.mark.parametrize("setting", ["model.kinetic_prior=-1", "model.dissipation_scale=0"])
def test_a_bad_knob_is_one_line(setting):
    model = "lnn_jax" if "kinetic" in setting else "dhnn_jax"
    with pytest.raises(ConfigError, match=setting.replace(".", r"\.")):
        prepare_job(compose(["system=spring", f"model={model}", setting]))


# --------------------------------------------------------------------------- stopping


class _Trainer:
    def __init__(self) -> None:
        self.chunks = 0

    def run_chunk(self, indices, length, lrs=None):
        self.chunks += 1
        return np.ones((1, length)), np.array([1.0 / self.chunks])

    def keep(self, seeds):
        pass


def test_a_loss_changing_knob_turns_the_pruner_off_and_the_srnn_window_does_not():
    """The pruner compares the training loop's validation loss across trials: a knob
    declared ``changes_training_loss`` turns it off; the SRNN's window changes only the
    training windows (its validation windows keep the family's length), so its study
    is pruned like every other family's."""
    from hnnbench._tuning.request import TuneRequest
    from hnnbench._tuning.tuner import Tuner

    tuner = Tuner(TuneRequest(system="spring", models=["srnn_jax"], trials=2))
    flagged = {"window": IntRange(3, 8, changes_training_loss=True)}
    assert tuner._pruner_name(flagged) == "none (window changes the training loss)"
    srnn = registry.discover("model")["srnn_jax"].search_space
    assert not any(d.changes_training_loss for d in srnn.values())
    assert tuner._pruner_name(srnn).startswith("successive_halving")


def test_a_progress_callback_that_returns_true_stops_training_with_the_reason():
    trainer = _Trainer()
    settings = TrainSettings(steps=100, batch_size=None, lr=1e-3, weight_decay=0.0)
    calls = []

    def progress(step, losses):
        calls.append(step)
        return step >= 30

    (fit,) = train(trainer, 10, settings, [0], 10, progress)
    assert trainer.chunks == 3 and fit.steps == 30 and calls == [10, 20, 30]
    assert fit.diverged is None and fit.selection is not None
    assert fit.selection.step == 30
    assert fit.selection.stopped.startswith(STOPPED_BY_CALLER)
    # None (any other answer) goes on to the end
    (fit,) = train(_Trainer(), 10, settings, [0], 10, lambda step, losses: None)
    assert fit.steps == 100 and fit.selection.stopped is None


# --------------------------------------------------------------------------- records


def _record(
    model: str,
    seed: int,
    track: str | None = None,
    value: float = 1.0,
    selected: dict | None = None,
    trials: int = 4,
    cpu: float = 10.0,
    system: str = "spring",
) -> dict:
    rec = {
        "system": system,
        "model": model,
        "seed": seed,
        "profile": "quick",
        "status": "ok",
        "backend": "jax",
        "family": model.split("_")[0],
        "ranked": True,
        "metrics": {"test_loss": {"mean": value, "sem": 0.0}},
        "timings": {"total_s": 1.0},
        "overrides": [f"model={model}", f"seed={seed}"],
        "config": {"model": {"name": model}, "system": {"name": system}},
    }
    if track is not None:
        rec["track"] = track
        rec["config"]["track"] = track
    if track == "tuned":
        selected = selected or {"model.lr": 0.003}
        rec["tuning"] = {
            "selected_on": "validation",
            "trials": trials,
            "steps": 50,
            "selected": selected,
            "cpu_s": cpu,
            "space": {},
        }
        rec["overrides"] += [f"{k}={v}" for k, v in selected.items()] + [
            "model.steps=50",
            "track=tuned",
        ]
        for key, v in {**selected, "model.steps": 50}.items():
            rec["config"]["model"][key.split(".", 1)[1]] = v
    return rec


def test_the_record_schema_declares_track_and_tuning():
    props = json_schema()["properties"]
    assert props["track"]["enum"] == ["protocol", "tuned", "recipe"]
    assert props["tuning"]["properties"]["selected_on"]["enum"] == ["validation"]
    assert "track" not in json_schema()["required"]  # absent: protocol
    assert track_of({}) == DEFAULT_TRACK == "protocol"
    assert track_of({"track": "tuned"}) == "tuned"


def test_a_tuned_records_selected_settings_and_budget_are_its_track_not_a_variant():
    rec = _record("hnn_jax", 0, "tuned", selected={"model.lr": 0.003, "model.hidden": 64})
    assert tuned_settings(rec) == {"model.lr", "model.hidden", "model.steps"}
    assert tuned_settings(_record("hnn_jax", 0)) == frozenset()
    frame = records_frame([_record("hnn_jax", 0), rec])
    assert list(frame["variant"]) == ["", ""]
    assert list(frame["track"]) == ["protocol", "tuned"]
    assert frame["tuning_cpu_s"].iloc[1] == 10.0


@pytest.mark.parametrize(
    "change, needle",
    [
        (lambda r: r.pop("tuning"), "must say how it was tuned"),
        (lambda r: r["tuning"].update(selected_on="test"), "selects on validation only"),
        (lambda r: r["tuning"].pop("trials"), "tuning.trials"),
        (lambda r: r["tuning"].update(selected={}), "tuning.selected: missing"),
        (lambda r: r["config"]["model"].update(lr=0.1), "model.lr=0.003, but the record's config"),
        (lambda r: r.update(track="protocol"), "the record says protocol, its config tuned"),
    ],
)
def test_a_tuned_record_that_does_not_hold_together_is_a_problem(change, needle):
    rec = _record("hnn_jax", 0, "tuned")
    assert track_problem(rec) is None
    change(rec)
    problem = track_problem(rec)
    assert problem is not None and needle in problem, problem


def test_tracks_are_separate_rows_never_ranked_together():
    from hnnbench._results.families import families
    from hnnbench._results.leaderboard import records_frame

    recs = [_record("hnn_jax", s, None, 1.0) for s in (0, 1)]
    recs += [_record("mlp_jax", s, None, 2.0) for s in (0, 1)]
    recs += [_record("hnn_jax", s, "tuned", 0.5) for s in (0, 1)]
    recs += [_record("mlp_jax", s, "tuned", 0.1) for s in (0, 1)]
    board = leaderboard(recs)
    assert list(zip(board["track"], board["model"], strict=True)) == [  # registry order
        ("protocol", "mlp_jax"),
        ("protocol", "hnn_jax"),
        ("tuned", "mlp_jax"),
        ("tuned", "hnn_jax"),
    ]
    assert list(board["n_seeds"]) == [2, 2, 2, 2]
    assert "variant" not in board  # the tuned settings are no variant
    assert board["tuning_cpu_s"].isna().tolist() == [True, True, False, False]
    fams = families(records_frame(recs), board).board
    assert set(fams["track"]) == {"protocol", "tuned"} and len(fams) == 4
    # each track ranked on its own: its leader is the best of its own rows (with too few
    # seeds to separate: 2), never the other track's
    for track, leader in (("protocol", "hnn"), ("tuned", "mlp")):
        rows = fams[fams["track"] == track].set_index("family")
        assert rows["test_loss_mean"].idxmin() == leader
        assert rows.loc[leader, "test_loss_mark"] == "too_few_seeds"
    # a protocol-only board keeps the plain schema (no track column)
    assert "track" not in leaderboard(recs[:4]) and "tuning_cpu_s" not in leaderboard(recs[:4])


def test_a_pairs_tuning_cpu_is_the_sum_of_its_studies_one_per_fold():
    """A measured system's tuned row holds one study per fold, each stated in its
    records: the row's ``tuning_cpu_s`` sums the studies (each counted once), as the
    studies table and the cost figure do; records naming no study count as one."""
    from hnnbench._results.leaderboard import tuning_cpu

    recs = [_record("hnn_jax", s, "tuned") for s in range(4)]
    for seed, rec in enumerate(recs):
        rec["tuning"].update(study=f"real_pendulum/hnn_jax/fold{seed % 2}", cpu_s=10.0 + seed % 2)
    board = leaderboard(recs)
    assert board["tuning_cpu_s"].tolist() == [21.0]
    assert tuning_cpu(records_frame(recs)) == 21.0
    recs[0]["tuning"]["cpu_s"] = None  # fold 0's other record still states it
    assert tuning_cpu(records_frame(recs)) == 21.0
    recs[2]["tuning"]["cpu_s"] = None  # no record of fold 0 states it: unknown, not less
    assert math.isnan(tuning_cpu(records_frame(recs)))
    for rec in recs:
        rec["tuning"].update(cpu_s=11.0)
        del rec["tuning"]["study"]
    assert tuning_cpu(records_frame(recs)) == 11.0


def test_the_tracks_table_says_what_each_familys_tuning_cost():
    from hnnbench._results.families import families
    from hnnbench._results.leaderboard import records_frame
    from hnnbench._results.report.verdicts import tracks_frame, tracks_markdown, tuning_costs

    recs = [_record("hnn_jax", s, None, 1.0) for s in (0, 1)]
    recs += [_record("hnn_jax", s, "tuned", 0.5, cpu=1234.4) for s in (0, 1)]
    recs += [_record("mlp_jax", s, "tuned", 0.1, cpu=87.6) for s in (0, 1)]
    recs += [_record("hnn_jax", s, "tuned", 0.5, cpu=5.0, system="pendulum") for s in (0, 1)]
    # the protocol's standing-still reference stands in the tuned track too; it is not tuned
    still = [_record("standing_still", s, None, 6.0) for s in (0, 1)]
    for rec in still:
        rec.update(backend="numpy", family="standing_still", ranked=False, reference="zero_field")
    fams = families(records_frame(recs + still), leaderboard(recs + still))
    assert len(fams.board[fams.board["family"] == "standing_still"]) == 2  # protocol, tuned
    costs = tuning_costs(fams)
    assert costs.to_dict("records") == [
        {"profile": "quick", "system": "spring", "mlp": "88", "hnn": "1,234"},
        {"profile": "quick", "system": "pendulum", "mlp": "—", "hnn": "5"},
    ]
    text = tracks_markdown(tracks_frame(fams), costs)
    assert "| quick     | spring   | 88    | 1,234 |" in text
    assert "the CPU seconds of its studies" in text
    # no tuned row: no cost table, and the plain text is unchanged
    protocol = recs[:2] + [_record("mlp_jax", s, "recipe", 0.1) for s in (0, 1)]
    fams = families(records_frame(protocol), leaderboard(protocol))
    assert tuning_costs(fams).empty
    assert tracks_markdown(tracks_frame(fams), tuning_costs(fams)) == tracks_markdown(
        tracks_frame(fams)
    )
    assert "CPU seconds" not in tracks_markdown(tracks_frame(fams))


def test_the_gate_never_compares_a_tuned_row_with_a_protocol_one():
    ref = leaderboard([_record("hnn_jax", 0, None, 1.0)])
    cur = leaderboard([_record("hnn_jax", 0, "tuned", 100.0)])
    result = compare(ref, cur)
    assert [f.check for f in result.regressions] == ["missing"]
    assert [(f.check, f.model) for f in result.info] == [("new", "hnn_jax (tuned track)")]


def test_the_gate_flags_unequal_tuning_budgets_on_a_system():
    recs = [_record("hnn_jax", 0, "tuned", trials=4), _record("mlp_jax", 0, "tuned", trials=3)]
    (finding,) = budget_findings(recs)
    assert finding.check == "budget" and "unequal tuning budgets" in finding.current
    assert budget_findings(recs[:1] + [_record("mlp_jax", 0, "tuned", trials=4)]) == []


def test_a_track_that_is_not_one_is_refused_in_one_line():
    with pytest.raises(ConfigError, match="track=fancy is invalid"):
        prepare_job(compose(["system=spring", "model=hnn_jax", "track=fancy"]))
    with pytest.raises(UnknownNameError):
        prepare_job(compose(["system=spring", "model=hnn_jax", "evaluation.metrics=[nope]"]))


# --------------------------------------------------------------------------- the tuner


def test_bad_tune_arguments_are_one_line_errors():
    for args, needle in (
        (["system=spring", "model=hnn_jax"], "trials= is required"),
        (["system=spring", "model=hnn_jax", "trials=0"], "trials=0 is invalid"),
        (
            ["system=spring", "model=hnn_jax", "trials=2", "model.lr=1"],
            "model settings are what the tuner searches",
        ),
        (["system=spring", "model=hnn_jax", "trials=2", "bogus=1"], "unknown argument 'bogus'"),
        (["system=spring", "model=oracle", "trials=2"], "declares no search space"),
        (["system=spring,pendulum", "model=hnn_jax", "trials=2"], "one system per tuning"),
    ):
        assert_one_line_error(hnnbench_cli("tune", *args), needle)


optuna = pytest.importorskip("optuna")


def _trial_records(root: Path, model: str) -> list[dict]:
    return [
        json.loads(p.read_text())
        for p in sorted((root / "trials" / "spring" / model).glob("trial*/seed*/result.json"))
    ]


@pytest.mark.slow
def test_tune_gives_every_model_the_same_budget_and_selects_on_validation(tmp_path):
    out = tmp_path / "tuned"
    board = hnnbench.tune(
        "spring",
        ["mlp_jax", "hnn_jax"],
        trials=3,
        seeds=(0, 1, 2),
        profile="quick",
        out=out,
        steps=40,
        pin_cpu=False,
    )
    # the rows read seed 2 alone: seeds 0 and 1 are the trials' (the selected trial again)
    assert set(board["track"]) == {"tuned"} and list(board["n_ok"]) == [1, 1]
    assert list(board["seeds"]) == ["2", "2"]
    assert (board["tuning_cpu_s"] > 0).all()
    for model in ("mlp_jax", "hnn_jax"):
        trials = _trial_records(out, model)
        assert len(trials) == 6  # 3 trials of 2 seeds, each trial one batched job
        for trial in trials:  # a trial computes the selecting metric alone, never a test one
            assert set(trial["metrics"]) == {"val_loss"}
            assert trial["track"] == "tuned" and trial["tuning"]["selected_on"] == "validation"
            assert trial["seed_batch"] == [0, 1] and trial["tuning"]["trial_seeds"] == [0, 1]
            assert trial["selection"]["criterion"] == "field_mse_clean"
        summary = json.loads((out / "tuning" / "spring" / f"{model}.json").read_text())
        assert (summary["criterion"], summary["seeds_per_trial"]) == ("field_mse_clean", 2)
        for t in summary["trials"]:  # a trial's score: the mean of its seeds' criteria
            seeds = [r for r in trials if r["tuning"]["trial"] == t["number"]]
            mean = sum(r["selection"]["validation_loss"] for r in seeds) / 2
            assert t["state"] == "complete" and math.isclose(t["value"], mean, rel_tol=1e-12)
        assert summary["trials"][0]["protocol"] and summary["protocol_value"] is not None
        complete = [t for t in summary["trials"] if t["state"] == "complete"]
        best = min(complete, key=lambda t: (t["value"], t["number"]))
        assert summary["selected"]["number"] == best["number"]
        assert best["value"] <= summary["protocol_value"]  # never worse than trial 0
        finals = [
            json.loads(p.read_text())
            for p in sorted((out / "final" / "spring" / model).glob("seed*/result.json"))
        ]
        assert [f["seed"] for f in finals] == [0, 1, 2]
        for final in finals:
            tuning = final["tuning"]
            assert final["track"] == "tuned" and track_problem(final) is None
            assert (tuning["trials"], tuning["steps"], tuning["selected_on"]) == (
                3,
                40,
                "validation",
            )
            assert tuning["selected"] == best["settings"] and final["steps"] <= 40
            assert "test_loss" in final["metrics"]
            assert math.isclose(
                tuning["cpu_s"], sum(t["cpu_s"] for t in summary["trials"]), abs_tol=1e-3
            )  # rounded to ms
            assert (tuning["criterion"], tuning["seeds_per_trial"]) == ("field_mse_clean", 2)
            assert (tuning["protocol_trial"], tuning["trial_seeds"]) == (0, [0, 1])
            assert tuning["cpu_s_per_trial"] > 0
        # the selected trial ran seeds 0 and 1 with the same settings (as one batch): the
        # same criterion as the final runs of those seeds, up to float32 batching
        final_mean = sum(f["selection"]["validation_loss"] for f in finals[:2]) / 2
        assert math.isclose(final_mean, best["value"], rel_tol=1e-4)

    # the rule the published tuned rows are held to (tests/integration/test_published.py)
    # holds for a real tuner's records
    finals_all = [json.loads(p.read_text()) for p in sorted((out / "final").rglob("result.json"))]
    ran = [
        {"system": "spring", "model": m, "family": m.split("_")[0], "status": "ok"}
        for m in ("mlp_jax", "hnn_jax")
    ]
    assert tuned_rows_problems(finals_all, ran, least_seeds=2) == []

    # resuming runs nothing new; another step budget on the same studies is refused
    again = hnnbench.tune(
        "spring",
        ["mlp_jax", "hnn_jax"],
        trials=3,
        seeds=(0, 1, 2),
        profile="quick",
        out=out,
        steps=40,
        pin_cpu=False,
    )
    assert len(_trial_records(out, "mlp_jax")) == 6
    assert list(again["test_loss_mean"]) == list(board["test_loss_mean"])
    with pytest.raises(ConfigError, match="made with other settings .*steps: 40 -> 41"):
        hnnbench.tune(
            "spring",
            ["mlp_jax"],
            trials=3,
            seeds=(0,),
            profile="quick",
            out=out,
            steps=41,
            pin_cpu=False,
        )

    # hnnbench check reads the tuned track like a sweep: tracks kept, budgets equal
    ref = tmp_path / "ref.csv"
    assert (
        hnnbench_cli("check", str(out / "final"), "--reference", str(ref), "--update").returncode
        == 0
    )
    proc = hnnbench_cli("check", str(out / "final"), "--reference", str(ref))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "tuned" in ref.read_text().splitlines()[1]

    # the cost estimate and the tracks table read the same directory
    scripts = REPO / "scripts" / "analysis"
    costs = subprocess.run(
        [
            sys.executable,
            str(scripts / "tuning_costs.py"),
            str(out),
            "--trials",
            "5",
            "--steps",
            "100",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert costs.returncode == 0, costs.stderr
    assert "| spring | hnn_jax | 6 |" in costs.stdout and "spring: about" in costs.stdout
    table = subprocess.run(
        [sys.executable, str(scripts / "tracks_table.py"), str(out / "final")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert table.returncode == 0, table.stderr
    assert "| spring | mlp | " in table.stdout and "the same on every track" in table.stdout

    # the report reads the studies' summaries: how each study's best criterion converged
    page = tmp_path / "page"
    proc = hnnbench_cli(
        "report", str(out / "final"), "--out", str(page), "--tuning", str(out / "tuning")
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    convergence = pd.read_csv(page / "tuning_convergence.csv")
    assert sorted(convergence["model"]) == ["hnn_jax", "mlp_jax"]
    assert (convergence["trials"] == 3).all() and (convergence["cpu_s"] > 0).all()
    assert (page / "figures" / "tuning_convergence.png").exists()
    assert "## Has the criterion flattened?" in (page / "tracks.md").read_text()
    proc = hnnbench_cli("report", str(out / "final"), "--out", str(page), "--tuning", str(out))
    assert proc.returncode != 0 and "holds no study summary" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.slow
def test_an_interrupted_trial_runs_its_settings_again(tmp_path):
    from hnnbench._tuning import tuner as tuning
    from hnnbench._tuning.request import TuneRequest

    out = tmp_path / "tuned"
    request = TuneRequest(
        system="spring",
        models=["mlp_jax"],
        trials=2,
        seeds=[0],
        profile="quick",
        out=out,
        steps=20,
        pruner="none",
        seeds_per_trial=1,
        overrides=["pin_cpu=false"],
    )
    tuner = tuning.Tuner(request)
    space = registry.discover("model")["mlp_jax"].search_space
    study = tuner._open("mlp_jax", space, 20)
    # a trial left running by a killed process (no record written)
    # a trial left running by a killed process (no record written): the protocol's
    left = study.ask({n: tuning._distribution(d) for n, d in space.items()})
    assert left.user_attrs.get("protocol")
    studies = tuning.run_tuning(request)
    trials = studies[0].trials
    assert len(trials) == 2 and all(t["state"] == "complete" for t in trials)
    assert trials[0]["number"] == 1  # the replay, with the interrupted trial's settings
    assert trials[0]["protocol"] and trials[0]["settings"] == tuner.protocol_settings(
        "mlp_jax", space
    )
    assert trials[1]["settings"] != trials[0]["settings"]  # a draw of the sampler


@pytest.mark.slow
def test_a_studys_final_seeds_split_across_two_folders_are_the_one_process_runs(tmp_path):
    """docs/TUNING.md, "A study's final seeds in two processes": a copy of a finished
    study's tuning/ and trials/ is the same study, so its final seeds trained in the copy
    are those a single process trains; copied back, they are read back, not redone, and
    the summary then names every final seed."""
    import shutil

    def tune(out: Path, seeds: tuple[int, ...]) -> None:
        hnnbench.tune(
            "spring",
            ["mlp_jax"],
            trials=2,
            seeds=seeds,
            profile="quick",
            out=out,
            steps=40,
            pin_cpu=False,
        )

    def finals(out: Path) -> dict[int, dict]:
        paths = (out / "final" / "spring" / "mlp_jax").glob("seed*/result.json")
        return {int(p.parent.name[4:]): json.loads(p.read_text()) for p in paths}

    one, first, second = tmp_path / "one", tmp_path / "first", tmp_path / "second"
    tune(one, (0, 1, 2, 3))
    tune(first, (0, 1))
    second.mkdir()
    for part in ("tuning", "trials"):
        shutil.copytree(first / part, second / part)
    tune(second, (2, 3))
    assert len(_trial_records(second, "mlp_jax")) == 4  # the copy's trials: read, not rerun
    for seed in (2, 3):
        shutil.copytree(
            second / "final" / "spring" / "mlp_jax" / f"seed{seed}",
            first / "final" / "spring" / "mlp_jax" / f"seed{seed}",
        )
    copied = {s: r["created_at"] for s, r in finals(first).items()}
    tune(first, (0, 1, 2, 3))
    merged, reference = finals(first), finals(one)
    assert {s: r["created_at"] for s, r in merged.items()} == copied  # nothing redone
    assert sorted(merged) == sorted(reference) == [0, 1, 2, 3]
    measured = ("cpu_s", "cpu_s_per_trial")  # the CPU each run of the trials took
    assert len({json.dumps(r["tuning"], sort_keys=True) for r in merged.values()}) == 1
    for seed, record in merged.items():
        assert {k: v for k, v in record["tuning"].items() if k not in measured} == {
            k: v for k, v in reference[seed]["tuning"].items() if k not in measured
        }
        for name in ("test_loss", "val_loss"):
            assert math.isclose(
                record["metrics"][name]["mean"],
                reference[seed]["metrics"][name]["mean"],
                rel_tol=1e-6,
            ), (seed, name)
    summary = json.loads((first / "tuning" / "spring" / "mlp_jax.json").read_text())
    assert summary["final_seeds"] == [0, 1, 2, 3]


@pytest.mark.slow
def test_the_protocol_trial_is_trial_0_and_never_pruned(tmp_path):
    """A study's trial 0 runs the protocol's settings (the model's config under the
    profile, its training fields as the protocol resolves them) and is never pruned, even
    by a pruner that prunes everything; the trials after it are pruned on the criterion
    the observer reports (the mean over the trial's seeds)."""
    from hnnbench._tuning import tuner as tuning
    from hnnbench._tuning.request import TuneRequest

    class _Always(optuna.pruners.BasePruner):
        def prune(self, study, trial) -> bool:
            return True

    request = TuneRequest(
        system="spring",
        models=["mlp_jax"],
        trials=2,
        seeds=[0],
        profile="quick",
        out=tmp_path / "tuned",
        steps=30,
        overrides=["pin_cpu=false"],
    )
    tuner = tuning.Tuner(request)
    space = registry.discover("model")["mlp_jax"].search_space
    (group,) = tuner.groups("mlp_jax")
    assert group.trial_seeds == (0, 1) and group.fold is None
    study = tuner._open("mlp_jax", space, 30, group)
    study.pruner = _Always()
    for k in (1, 2):
        tuner._run_trial(study, "mlp_jax", space, 30, k, group)
    first, second = study.trials[:2]
    assert first.user_attrs["protocol"] and first.state == optuna.trial.TrialState.COMPLETE
    protocol = tuner.protocol_settings("mlp_jax", space)
    assert first.user_attrs["settings"] == protocol
    job = compose(["system=spring", "model=mlp_jax", "profile=quick"])
    settings = TrainSettings.resolve(prepare_job(job).system_cfg, prepare_job(job).model_cfg)
    assert protocol["model.lr"] == settings.lr and protocol["model.hidden"] == job.model.hidden
    assert second.state == optuna.trial.TrialState.PRUNED
    records_of = tuner._trial_records("mlp_jax", first.number, group)
    assert [r["seed"] for r in records_of] == [0, 1]
    assert first.value == tuning.trial_score(records_of, tuner.objective)[0]
    assert first.intermediate_values  # reported to the pruner, never pruned


def test_a_measured_system_gets_one_study_per_fold_whose_trials_never_see_its_test_block(
    monkeypatch,
):
    """On a measured system each fold of the final seeds has its own study, whose trials
    train seeds of that fold only and none of the final seeds (seeds s + 10 and s + 15:
    the fold's data, other initialisations): the selection for a final seed never read
    its test block, and no final run repeats a trial (docs/TUNING.md); a simulated
    system has one study on seeds 0 and 1."""
    from hnnbench._tuning import tuner as tuning
    from hnnbench._tuning.request import DEFAULT_SEEDS, TuneRequest

    request = TuneRequest(system="real_pendulum", models=["hnn_jax"], trials=2, profile="quick")
    assert list(request.seeds) == list(range(10)) == list(DEFAULT_SEEDS)
    groups = tuning.Tuner(request).groups("hnn_jax")
    assert [g.fold for g in groups] == [4, 3, 2, 1, 0]
    for g in groups:
        assert g.trial_seeds == tuple(s + 10 for s in g.final_seeds)
        assert all((4 - s) % 5 == g.fold for s in (*g.trial_seeds, *g.final_seeds))
    assert sorted(s for g in groups for s in g.final_seeds) == list(range(10))
    late = TuneRequest(
        system="real_pendulum", models=["hnn_jax"], trials=2, seeds=[0, 1], trial_seed=1
    )
    assert [g.trial_seeds for g in tuning.Tuner(late).groups("hnn_jax")] == [(5, 10), (6, 11)]
    simulated = TuneRequest(system="spring", models=["hnn_jax"], trials=2, seeds_per_trial=3)
    (one,) = tuning.Tuner(simulated).groups("hnn_jax")
    assert one.trial_seeds == (0, 1, 2) and one.final_seeds == tuple(range(10))
    # a fold rule that gives a fold no seed outside the final ones: one line, not a hang
    stuck = tuning.Tuner(request)
    monkeypatch.setattr(
        stuck._prepared("hnn_jax").system_cls, "fold", lambda self, seed: min(int(seed), 4)
    )
    with pytest.raises(ConfigError, match="fold 0 has 0 seed"):
        stuck.groups("hnn_jax")


def test_the_sweep_scripts_fold_processes_hold_the_same_studies_as_one_process(tmp_path):
    """scripts/maintainer/tune_sweep.sh runs a measured system's fold studies as processes
    of their own (one out= folder each): each process holds exactly one study, the one a
    single process over all ten seeds would hold for that fold (its name, fold, trial
    seeds and final seeds), in a folder named after that fold; a simulated system is one
    process over every seed."""
    from hnnbench._tuning import tuner as tuning
    from hnnbench._tuning.request import TuneRequest

    script = Path(__file__).resolve().parents[2] / "scripts" / "maintainer" / "tune_sweep.sh"
    env = {**os.environ, "DRY_RUN": "1", "JOBS": "1"}
    run = subprocess.run(
        ["bash", str(script), "real_pendulum,spring", str(tmp_path)],
        env=env, capture_output=True, text=True, check=True, timeout=60,
        start_new_session=True,
    )  # fmt: skip
    assert not any(tmp_path.iterdir())  # a dry run makes nothing
    lines = [dict(a.split("=", 1) for a in line.split()[2:]) for line in run.stdout.splitlines()]
    whole = TuneRequest(system="real_pendulum", models=["hnn_jax"], trials=2)
    by_fold = {g.fold: g for g in tuning.Tuner(whole).groups("hnn_jax")}
    folds = [a for a in lines if a["system"] == "real_pendulum" and a["model"] == "hnn_jax"]
    assert len(folds) == 5
    for args in folds:
        seeds = [int(s) for s in args["seeds"].split(",")]
        part = TuneRequest(system="real_pendulum", models=["hnn_jax"], trials=2, seeds=seeds)
        (group,) = tuning.Tuner(part).groups("hnn_jax")
        assert group == by_fold[group.fold]
        assert args["out"] == f"{tmp_path}/real_pendulum_fold{group.fold}/hnn_jax"
    assert sorted(s for a in folds for s in map(int, a["seeds"].split(","))) == list(range(10))
    spring = [a for a in lines if a["system"] == "spring"]
    assert len(spring) == 6 and {a["seeds"] for a in spring} == {"0,1,2,3,4,5,6,7,8,9"}
    assert len(lines) == 6 * 5 + 6
    # fewer final seeds than folds: a fold with none has no process, and the script ends 0
    few = subprocess.run(
        ["bash", str(script), "real_pendulum", str(tmp_path)],
        env={**env, "SEEDS": "3"}, capture_output=True, text=True, timeout=60,
        start_new_session=True,
    )  # fmt: skip
    assert few.returncode == 0, few.stderr
    assert sorted({line.split()[5] for line in few.stdout.splitlines()}) == [
        "seeds=0",
        "seeds=1",
        "seeds=2",
    ]


def test_a_trials_score_is_the_mean_of_its_seeds_criteria_and_worst_if_one_fails():
    from hnnbench._tuning import tuner as tuning

    objective = tuning.objective_metric()

    def rec(value: float, status: str = "ok") -> dict:
        return {
            "status": status,
            "selection": {"criterion": "rollout_q_mse_4", "validation_loss": value},
        }

    assert tuning.trial_score([rec(1.0), rec(3.0)], objective) == (2.0, "rollout_q_mse_4")
    assert tuning.trial_score([rec(1.0), rec(3.0, "diverged")], objective)[0] == objective.worst()
    no_selection = {"status": "ok", "metrics": {"val_loss": {"mean": 0.5}}}
    assert tuning.trial_score([no_selection], objective) == (0.5, "val_loss")


def _study_record(model: str, seed: int, study: str, lr: float) -> dict:
    """A final record of ``study`` as the tuner writes its ``tuning`` block."""
    rec = _record(model, seed, "tuned", selected={"model.lr": lr}, system="real_pendulum")
    rec["selection"] = {"criterion": "rollout_q_mse_4", "validation_loss": 1.0}
    rec["tuning"].update(
        criterion="rollout_q_mse_4", seeds_per_trial=2, protocol_trial=0, study=study
    )
    return rec


def test_the_published_tuned_rows_rule_reads_studies_per_fold_and_skipped_families():
    """``report_fixtures.tuned_rows_problems``: a measured system's fold studies may
    select different settings, one study may not; a family the protocol skipped there
    needs no tuned row, one it ran does."""
    ran = [
        {"system": "real_pendulum", "model": m, "family": m.split("_")[0], "status": s}
        for m, s in (("hnn_jax", "ok"), ("mlp_jax", "ok"), ("lnn_jax", "skipped"))
    ]
    tuned = [
        _study_record(m, seed, f"{m}-fold{seed % 2}", 0.001 * (1 + seed % 2))
        for m in ("hnn_jax", "mlp_jax")
        for seed in range(4)
    ]
    assert tuned_rows_problems(tuned, ran, least_seeds=4) == []
    one_study = [_study_record("hnn_jax", s, "hnn", 0.001 * (1 + s % 2)) for s in range(4)]
    found = tuned_rows_problems(one_study + tuned[4:], ran, least_seeds=4)
    assert found == ["real_pendulum/hnn: study hnn selected 2 configurations"], found
    found = tuned_rows_problems(tuned[:4], ran, least_seeds=4)
    assert found == ["real_pendulum: tuned ['hnn'], protocol ['hnn', 'mlp']"], found
    tuned[0]["tuning"]["seeds_per_trial"] = 1
    tuned[1]["tuning"]["criterion"] = "field_mse"
    found = tuned_rows_problems(tuned, ran, least_seeds=5)
    assert any("1 seed(s) per trial" in f for f in found), found
    assert any("tuned on field_mse, selected on another" in f for f in found), found
    assert any("tuned seeds [0, 1, 2, 3]" in f for f in found), found


def test_unequal_seeds_per_trial_are_unequal_budgets():
    base = _record("hnn_jax", 0, "tuned")
    other = _record("mlp_jax", 0, "tuned")
    other["tuning"] = {**other["tuning"], "seeds_per_trial": 2}
    found = budget_findings([base, other])
    assert len(found) == 1 and "x 2 seed(s): mlp_jax" in found[0].current
