"""A sweep says what its jobs took when published, and what that estimate rests on;
nothing when every job is kept from an earlier run."""

from __future__ import annotations

from hnnbench._sweeping import eta


def test_a_sweep_prints_its_estimate_and_progress(tmp_path):
    from conftest import hnnbench

    proc = hnnbench(
        "-m",
        "system=spring",
        "model=oracle",
        "profile=quick",
        "seed=0,1",
        f"hydra.sweep.dir={tmp_path / 'sweep'}",
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "hnnbench: the published runs of these jobs took" in proc.stderr, proc.stderr
    assert eta.ESTIMATE_BASIS in proc.stderr
    # Every job kept from that run: nothing will run, so no estimate.
    proc = hnnbench(
        "-m",
        "system=spring",
        "model=oracle",
        "profile=quick",
        "seed=0,1",
        f"hydra.sweep.dir={tmp_path / 'sweep'}",
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "published runs" not in proc.stderr and "2 kept from an earlier run" in proc.stderr, (
        proc.stderr
    )


def test_a_jobs_directory_whatever_its_track():
    assert eta.job_directory(["system=s", "model=m", "+seed=3", "track=tuned"]) == "s/m/seed3"
    assert eta.job_directory(["system=s", "model=m"]) == "s/m/seed0"  # the default seed
    assert eta.job_directory(["seed=1"]) is None
