"""The sweep's estimate and ETA (hnnbench._sweeping.eta) and the job-cost table it reads."""

from __future__ import annotations

import io
import json
import time
from pathlib import Path

from conftest import REPO

from hnnbench._sweeping import eta


def test_the_job_costs_are_the_protocol_tracks_own(tmp_path, monkeypatch):
    """A tuned or recipe record, or a variant, trains other settings: its time is no
    protocol job's."""
    monkeypatch.syspath_prepend(str(REPO / "scripts" / "maintainer"))
    import job_costs

    def write(track, seed, total, *extra):
        rec = {
            "system": "spring",
            "model": "hnn_jax",
            "seed": seed,
            "profile": "paper",
            "timings": {"total_s": total},
            **({"track": track} if track else {}),
            "overrides": ["system=spring", "model=hnn_jax", f"seed={seed}", *extra],
        }
        path = tmp_path / (track or "protocol") / f"seed{seed}{''.join(extra)}" / "result.json"
        path.parent.mkdir(parents=True)
        path.write_text(json.dumps(rec))

    write(None, 0, 10.0)
    write("protocol", 1, 12.0)
    write("tuned", 0, 500.0)
    write("recipe", 0, 900.0)
    write(None, 2, 700.0, "model.hidden=400")
    (row,) = job_costs.rows(tmp_path, tmp_path / "no_quick.csv")
    assert (row["system"], row["model"], row["seconds"], row["n_runs"]) == (
        "spring",
        "hnn_jax",
        "11",
        2,
    )


def test_a_broken_cost_file_gives_no_estimate(tmp_path):
    bad = tmp_path / "costs.csv"
    bad.write_text("profile,system\nx,y\n")
    assert eta.load_costs(bad) == {}
    assert eta.load_costs(tmp_path / "missing.csv") == {}


def test_job_key_and_durations():
    assert eta.job_key(["system=spring", "model=hnn_jax", "seed=1"], "paper") == (
        "paper",
        "spring",
        "hnn_jax",
    )
    assert eta.job_key(["profile=quick", "system=a", "model=b"], "paper") == ("quick", "a", "b")
    assert eta.job_key(["seed=1"], "paper") is None
    # the published costs are the protocol's: a recipe job's is not known
    assert eta.job_key(["system=a", "model=b", "track=recipe"], "paper") is None
    assert eta.job_key(["system=a", "model=b", "track=protocol"], "paper") == ("paper", "a", "b")
    assert [eta.duration_text(s) for s in (3, 600, 3 * 3600 + 300)] == [
        "3 s",
        "10 min",
        "3 h 05 min",
    ]
    assert eta.duration_text(80 * 60) == "80 min"


def test_estimate_line_counts_what_is_known():
    table = {("paper", "s", "a"): 3600.0, ("paper", "s", "b"): 1800.0}
    keys = [("paper", "s", "a"), ("paper", "s", "b"), ("paper", "s", "c"), None]
    line = eta.estimate_line(keys, table, workers=2)
    assert line is not None
    assert "took 1 h 30 min of job time (about 45 min on 2 workers)" in line
    assert "2 job(s) have no published run" in line
    assert line.endswith(f"({eta.ESTIMATE_BASIS})")  # what it rests on, said with it
    assert "published runs" in eta.ESTIMATE_BASIS and "CPU" in eta.ESTIMATE_BASIS
    assert eta.estimate_line([("paper", "s", "c")], table, workers=2) is None


def _record(directory: Path, job: str) -> None:
    path = directory / job / "x" / "result.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("{}")


def test_progress_counts_new_records_and_scales_the_eta(tmp_path):
    """Kept records are not counted; the ETA scales the published cost of the jobs
    left by this sweep's pace so far."""
    table = {("paper", "s", "a"): 10.0, ("paper", "s", "b"): 30.0}
    _record(tmp_path, "s/a/seed0")  # kept from an earlier run
    out = io.StringIO()
    progress = eta.SweepProgress(
        tmp_path, default_profile="paper", costs=table, every_s=0.05, out=out
    )
    jobs = [["system=s", f"model={m}", f"seed={k}"] for m in ("a", "b") for k in (0, 1)]
    progress.add(jobs)
    assert progress.started
    _record(tmp_path, "s/a/seed1")
    deadline = time.monotonic() + 10
    while "1/3 jobs done" not in out.getvalue() and time.monotonic() < deadline:
        time.sleep(0.05)
    progress.stop()
    line = out.getvalue().strip().splitlines()[-1]
    assert line.startswith("hnnbench: 1/3 jobs done in "), line
    # One job of cost 10 done; two of cost 30 left: the ETA is 6x the elapsed time.
    assert "for the 2 left" in line
    assert progress.line().startswith("1/3 jobs done")


def test_progress_counts_the_jobs_of_another_track(tmp_path):
    """A recipe sweep's jobs are counted like any other (they have no published cost,
    so the ETA is the mean time per finished job)."""
    table = {("paper", "s", "a"): 10.0}
    out = io.StringIO()
    progress = eta.SweepProgress(
        tmp_path, default_profile="paper", costs=table, every_s=0.05, out=out
    )
    progress.add([["system=s", "model=a", "track=recipe", f"seed={k}"] for k in (0, 1)])
    _record(tmp_path, "s/a/seed0")
    deadline = time.monotonic() + 10
    while "1/2 jobs done" not in out.getvalue() and time.monotonic() < deadline:
        time.sleep(0.05)
    progress.stop()
    assert progress.line().startswith("1/2 jobs done"), out.getvalue()
    assert "for the 1 left" in progress.line()


def test_progress_calls_on_new_when_records_arrive_and_survives_its_errors(tmp_path):
    """``on_new`` (the sweeper's leaderboard rewrite) runs once new records are there,
    not before, at most once per ``on_new_every_s``; an exception in it is printed once
    and the watching goes on."""
    calls: list[float] = []

    def on_new() -> None:
        calls.append(time.monotonic())
        raise OSError("disk full")

    out = io.StringIO()
    progress = eta.SweepProgress(
        tmp_path,
        default_profile="paper",
        costs={},
        every_s=0.02,
        out=out,
        on_new=on_new,
        on_new_every_s=0.0,
    )
    progress.add([["system=s", "model=a", "seed=0"], ["system=s", "model=a", "seed=1"]])
    time.sleep(0.2)
    assert calls == []  # no record yet
    _record(tmp_path, "s/a/seed0")
    deadline = time.monotonic() + 10
    while len(calls) < 1 and time.monotonic() < deadline:
        time.sleep(0.02)
    _record(tmp_path, "s/a/seed1")
    while len(calls) < 2 and time.monotonic() < deadline:
        time.sleep(0.02)
    time.sleep(0.2)
    progress.stop()
    assert len(calls) == 2, calls  # once per arrival, not once per poll
    assert out.getvalue().count("could not update the sweep's report: disk full") == 1
    assert "2/2 jobs done" in out.getvalue()
