"""Killing a sweep loses nothing: finished records survive intact, and re-running the
same command into the same directory finishes the rest without redoing them (slow)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hnnbench import records

pytestmark = pytest.mark.slow

SEEDS = (0, 1, 2, 3)


def _start(args: list[str], cwd: Path, log: Path) -> subprocess.Popen:
    exe = Path(sys.executable).parent / "hnnbench"
    env = {**os.environ, "HNNBENCH_PROGRESS": "log", "PYTHONUNBUFFERED": "1"}
    with open(log, "wb") as fh:
        # A session of its own: the kill below reaches the whole process group.
        return subprocess.Popen([str(exe), *args], cwd=cwd, stdout=fh, stderr=subprocess.STDOUT,
                                env=env, start_new_session=True)


def _finished(sweep: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in sweep.rglob("result.json")}


def _wait_mid_training(proc: subprocess.Popen, sweep: Path, log: Path, timeout: float) -> None:
    """Until at least one record exists and a later job has logged training progress."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, "the sweep ended before it could be interrupted:\n" + \
            log.read_text()[-3000:]
        done = len(_finished(sweep))
        text = log.read_text(errors="replace")
        if done and f"[{done + 1}/{len(SEEDS)}]" in text:
            later = text.split(f"[{done + 1}/{len(SEEDS)}]", 1)[1]
            if " step " in later:
                return
        time.sleep(0.1)
    raise AssertionError("no job reached mid-training in time:\n" + log.read_text()[-3000:])


def test_sigkill_mid_sweep_then_resume(tmp_path):
    sweep = tmp_path / "sweep"
    # Each job trains long enough (a few seconds) to be caught in the middle.
    args = ["-m", "system=spring", "model=mlp_torch", "profile=quick",
            f"seed={','.join(map(str, SEEDS))}", "system.steps=3000", "model.log_every=50",
            "device=cpu", f"hydra.sweep.dir={sweep}"]
    log = tmp_path / "first.log"
    proc = _start(args, tmp_path, log)
    try:
        _wait_mid_training(proc, sweep, log, timeout=600)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL

    survived = _finished(sweep)
    assert 1 <= len(survived) < len(SEEDS)
    for path, raw in survived.items():
        rec = json.loads(raw)  # complete, valid JSON
        assert rec["status"] == "ok", rec.get("error")
        assert path.read_bytes() == raw
    # The killed job left no record (and no torn one); leftovers of an atomic write are
    # hidden temporary files, which nothing reads.
    job_dirs = {p.parent for p in sweep.rglob("cli.log")} | {p.parent for p in survived}
    for directory in job_dirs:
        for path in directory.iterdir():
            if path.name == "result.json":
                assert records.read_record(path) is not None
    # Plant the debris of a kill during a write in the interrupted job's directory.
    unfinished = sorted(d for d in job_dirs if not (d / "result.json").exists())
    assert unfinished, "the interrupted job should have a directory"
    (unfinished[0] / ".result.4242.dead.tmp.json").write_text('{"status": "o')
    (unfinished[0] / ".weights.4242.dead.tmp").mkdir()

    # Resume: the same command into the same directory.
    log2 = tmp_path / "second.log"
    proc = _start(args, tmp_path, log2)
    assert proc.wait(timeout=900) == 0, log2.read_text()[-3000:]
    text = log2.read_text()
    assert text.count("already finished") == len(survived)

    final = {p: json.loads(p.read_bytes()) for p in sweep.rglob("result.json")}
    assert sorted(r["seed"] for r in final.values()) == list(SEEDS)
    assert all(r["status"] == "ok" for r in final.values())
    for path, raw in survived.items():  # not redone: byte for byte the same record
        assert path.read_bytes() == raw
        assert final[path]["created_at"] == json.loads(raw)["created_at"]
    assert not [p for p in sweep.rglob("*") if ".tmp" in p.name]
    assert "4 jobs: 4 ok" in text
