"""A newcomer's first hour (#51): what the command says about itself and about a run:
``hnnbench --version``, a single job's summary (only the metrics that apply, with their
direction), the evaluation's progress, and the sweep's estimate (tests/unit/test_costs.py)."""

from __future__ import annotations

import logging
import math
import re

from conftest import REPO, hnnbench

import hnnbench as hb
from hnnbench._entry.command import summary_rows, version_line
from hnnbench._running.progress import LOG_METRIC_S, EvaluationProgress


def test_version_is_hnnbenchs_not_hydras():
    proc = hnnbench("--version")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == version_line()
    assert re.fullmatch(
        rf"hnnbench {re.escape(hb.__version__)} \(Python [\d.]+, Hydra [\d.]+\)",
        proc.stdout.strip(),
    ), proc.stdout
    assert "--version" in hnnbench("--help").stdout


def test_a_single_jobs_summary_shows_the_metrics_that_apply():
    record = {
        "metrics": {
            "test_loss": {"mean": 0.5, "sem": 0.01},
            "reversibility_error": {"mean": None, "sem": None},
            "pixel_mse": {"mean": math.nan, "sem": math.nan},
            "valid_prediction_time": {"mean": 2.0, "sem": 0.1},
        }
    }
    assert summary_rows(record) == [
        ["test_loss \u2193", 0.5, 0.01],
        ["valid_prediction_time \u2191", 2.0, 0.1],
    ]


def test_a_single_run_on_measured_data_prints_no_nan_rows(tmp_path):
    """The measured pendulum is not time-reversible, has no pixels and no Lyapunov time:
    those metrics do not apply, and the table does not list them."""
    proc = hnnbench(
        "system=real_pendulum",
        "model=standing_still",
        "profile=quick",
        f"hydra.run.dir={tmp_path}",
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    table = proc.stdout.split("status:")[0]
    assert "test_loss \u2193" in table and "energy_mse \u2193" in table
    for absent in ("reversibility_error", "pixel_mse", "vpt_lyapunov", "nan  "):
        assert absent not in table, table


def test_the_evaluation_says_what_it_does(monkeypatch, caplog):
    """A log line when the evaluation starts and one per slow metric; a bar on a
    terminal; nothing when progress is off."""
    monkeypatch.setenv("HNNBENCH_PROGRESS", "log")
    with (
        caplog.at_level(logging.INFO, logger="hnnbench"),
        EvaluationProgress("spring/hnn_jax s0") as shown,
    ):
        shown.update("test_loss", 1, 2, None)
        shown.update("test_loss", 1, 2, 0.01)
        shown.update("energy_mse", 2, 2, None)
        shown.update("energy_mse", 2, 2, LOG_METRIC_S + 3.0)
    lines = [r.getMessage().strip() for r in caplog.records]
    assert lines == [
        "spring/hnn_jax s0 evaluation: 2 metrics",
        f"spring/hnn_jax s0 evaluation 2/2 energy_mse {LOG_METRIC_S + 3:.1f} s",
    ]
    monkeypatch.setenv("HNNBENCH_PROGRESS", "off")
    caplog.clear()
    with EvaluationProgress("x") as shown:
        shown.update("test_loss", 1, 1, 9.0)
    assert not caplog.records


def test_evaluate_reports_every_metric_that_applies(monkeypatch):
    """evaluate() tells its progress as each metric that applies starts and ends; one that
    does not apply is not computed and not shown."""
    import types

    from hnnbench._contracts.metric import EvaluationConfig, Metric
    from hnnbench._running import evaluation as _evaluate

    # the metrics here read nothing of the context: no system or model needed
    monkeypatch.setattr(_evaluate, "EvalContext", lambda *args: types.SimpleNamespace(arrays={}))

    def compute(ctx):
        return [1.0, 2.0]

    metrics = [
        Metric(name="alpha", description="a", compute=compute, better="lower"),
        Metric(
            name="beta",
            description="b",
            compute=compute,
            better="lower",
            applies=lambda system: False,
        ),
        Metric(name="gamma", description="c", compute=compute, better="higher"),
    ]
    seen = []
    result = _evaluate.evaluate(
        None,
        None,
        None,
        None,
        EvaluationConfig(),  # type: ignore
        metrics,
        progress=lambda *args: seen.append(args),
    )
    assert [(m, i, n, s is None) for m, i, n, s in seen] == [
        ("alpha", 1, 2, True),
        ("alpha", 1, 2, False),
        ("gamma", 2, 2, True),
        ("gamma", 2, 2, False),
    ]
    assert result.metrics["alpha"]["mean"] == 1.5 and math.isnan(result.metrics["beta"]["mean"])
