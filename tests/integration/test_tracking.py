"""Runs you can watch: ``log_to=[mlflow,tensorboard]`` exports each finished job to a real
MLflow store (SQLite) and to TensorBoard event files, read back here with MLflow's client
and TensorBoard's EventAccumulator (hnnbench._running.tracking)."""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import pytest
from conftest import REPO, assert_one_line_error, hnnbench
from report_fixtures import write_run

from hnnbench._contracts.errors import ConfigError
from hnnbench._running import tracking


def test_log_to_names_trackers_with_a_did_you_mean():
    assert tracking.parse_log_to(None) == tracking.parse_log_to([]) == ()
    assert tracking.parse_log_to("mlflow,tensorboard") == ("mlflow", "tensorboard")
    assert tracking.parse_log_to(["tensorboard", "tensorboard"]) == ("tensorboard",)
    with pytest.raises(ConfigError, match="unknown tracker 'mlfow'. Did you mean 'mlflow'?"):
        tracking.parse_log_to(["mlfow"])
    with pytest.raises(ConfigError, match="mlflow_uri"):
        tracking.check("mlflow", "")


def test_a_missing_tracker_is_a_one_line_install_hint(monkeypatch):
    monkeypatch.setattr(tracking, "find_spec", lambda name: None)
    with pytest.raises(ConfigError) as info:
        tracking.check(["mlflow"], None)
    assert "pip install 'hnnbench[track]'" in str(info.value) and "\n" not in str(info.value)


def test_a_failing_exporter_warns_and_never_fails_the_job(tmp_path, monkeypatch, caplog):
    def broken(record, logdir):
        raise OSError("disk full")

    monkeypatch.setattr(tracking, "_to_tensorboard", broken)
    record = {"system": "spring", "model": "mlp_jax", "seed": 0, "status": "ok"}
    with caplog.at_level(logging.WARNING, logger="hnnbench"):
        warnings = tracking.export(record, tmp_path, ["tensorboard"])
    assert warnings == [
        "could not export spring/mlp_jax/seed0 to tensorboard: OSError: disk "
        "full; the record is unaffected"
    ]
    assert warnings[0] in caplog.text


def test_the_scalars_leave_out_what_is_not_finite():
    record = {
        "metrics": {
            "energy_mse": {"mean": 1e-3, "sem": 1e-4},
            "pixel_mse": {"mean": None, "sem": None},
            "rollout_mse": {"mean": float("inf"), "sem": None},
        },
        "timings": {"fit_s": 2.0},
        "history": {"step": [1, 2], "train_loss": [0.5, 0.4], "val_loss": [0.6, None]},
    }
    final, series = tracking.scalars(record)
    assert final == {"energy_mse": 1e-3, "energy_mse_sem": 1e-4, "timings/fit_s": 2.0}
    assert series == {"history/train_loss": [(1, 0.5), (2, 0.4)], "history/val_loss": [(1, 0.6)]}


def test_a_bad_log_to_is_refused_before_any_job(tmp_path):
    proc = hnnbench(
        "system=spring",
        "model=mlp_jax",
        "log_to=[tensorbord]",
        f"hydra.run.dir={tmp_path}",
        cwd=REPO,
    )
    assert_one_line_error(proc, "unknown tracker 'tensorbord'", "Did you mean 'tensorboard'?")
    assert not (tmp_path / "result.json").exists()


def _mlflow_runs(store: Path) -> tuple[Any, list[Any]]:
    """MLflow's client of the store ``store/mlflow.db`` and the runs it holds."""
    from mlflow.tracking import MlflowClient

    client = MlflowClient(tracking_uri=f"sqlite:///{store / 'mlflow.db'}")
    experiment = client.get_experiment_by_name("hnnbench")
    assert experiment is not None
    return client, client.search_runs([experiment.experiment_id])


def _events(job: Path) -> Any:
    """TensorBoard's reader of the job's event files."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(job / "tensorboard"))
    events.Reload()
    return events


@pytest.mark.slow
def test_a_sweep_exports_each_job_to_mlflow_and_tensorboard(tmp_path):
    """The real path: a sweep with log_to=[mlflow,tensorboard] writes its records, then
    each job's config, metrics and training history land in the sweep's MLflow store and
    in TensorBoard event files in the job's directory; the records are unchanged."""
    sweep = tmp_path / "sweep"
    proc = hnnbench(
        "-m",
        "system=spring",
        "model=mlp_jax",
        "profile=quick",
        "model.steps=40",
        "log_to=[mlflow,tensorboard]",
        f"hydra.sweep.dir={sweep}",
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "could not export" not in proc.stderr
    (path,) = sweep.rglob("result.json")  # <system>/<model>/seed0/model.steps=40/
    job = path.parent
    record = json.loads(path.read_text())
    assert record["status"] == "ok" and record["config"]["log_to"] == ["mlflow", "tensorboard"]
    client, runs = _mlflow_runs(sweep)
    events = _events(job)
    assert len(runs) == 1
    run = runs[0]
    assert run.info.run_name == "spring/mlp_jax/seed0" and run.info.status == "FINISHED"
    assert run.data.tags["hnnbench.status"] == "ok"
    assert run.data.tags["hnnbench.record"] == str((job / "result.json").resolve())
    assert run.data.params["model.steps"] == "40" and run.data.params["system.name"] == "spring"
    energy = record["metrics"]["energy_mse"]
    assert run.data.metrics["energy_mse"] == pytest.approx(energy["mean"], rel=1e-12)
    assert run.data.metrics["energy_mse_sem"] == pytest.approx(energy["sem"], rel=1e-12)
    history = client.get_metric_history(run.info.run_id, "history/train_loss")
    steps = record["history"]["step"]
    assert [m.step for m in history] == steps
    assert [m.value for m in history] == pytest.approx(record["history"]["train_loss"])
    # TensorBoard: the same history and metrics, and the config as text
    tags = events.Tags()
    assert {"history/train_loss", "history/val_loss", "metrics/energy_mse"} <= set(tags["scalars"])
    loss = events.Scalars("history/train_loss")
    assert [e.step for e in loss] == steps
    assert [e.value for e in loss] == pytest.approx(record["history"]["train_loss"], rel=1e-6)
    assert events.Scalars("metrics/energy_mse")[0].value == pytest.approx(energy["mean"], rel=1e-6)
    text = events.Tensors("config/text_summary")[0].tensor_proto.string_val[0].decode()
    assert '"steps": 40' in text
    # a resumed sweep keeps the record and sends nothing again
    proc = hnnbench(
        "-m",
        "system=spring",
        "model=mlp_jax",
        "profile=quick",
        "model.steps=40",
        "log_to=[mlflow,tensorboard]",
        f"hydra.sweep.dir={sweep}",
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert len(_mlflow_runs(sweep)[1]) == 1


@pytest.mark.slow
def test_export_of_a_record_to_a_given_store(tmp_path):
    """mlflow_uri decides the store; a failed job is a FAILED run with its error."""
    job = write_run(tmp_path / "s", "spring", "hnn_jax", 0, status="failed", rollout=False)
    record = json.loads((job / "result.json").read_text())
    store = tmp_path / "elsewhere"
    store.mkdir()
    assert tracking.export(record, job, ["mlflow"], f"sqlite:///{store / 'mlflow.db'}") == []
    _, runs = _mlflow_runs(store)
    assert [r.info.status for r in runs] == ["FAILED"]
    assert runs[0].data.tags["hnnbench.error"] == record["error"]
