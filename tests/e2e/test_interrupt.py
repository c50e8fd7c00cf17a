"""Killing a sweep loses nothing: finished records survive intact, and re-running the
same command into the same directory finishes the rest without redoing them (slow)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hnnbench import _record as records

pytestmark = pytest.mark.slow

SEEDS = (0, 1, 2, 3)


def _start(args: list[str], cwd: Path, log: Path) -> subprocess.Popen:
    exe = Path(sys.executable).parent / "hnnbench"
    env = {**os.environ, "HNNBENCH_PROGRESS": "log", "PYTHONUNBUFFERED": "1"}
    with open(log, "wb") as fh:
        # A session of its own: the kill below reaches the whole process group.
        return subprocess.Popen(
            [str(exe), *args],
            cwd=cwd,
            stdout=fh,
            stderr=subprocess.STDOUT,
            env=env,
            start_new_session=True,
        )


def _finished(sweep: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in sweep.rglob("result.json")}


def _wait_mid_training(proc: subprocess.Popen, sweep: Path, log: Path, timeout: float) -> None:
    """Until at least one record exists and a later job has logged training progress."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, (
            "the sweep ended before it could be interrupted:\n" + log.read_text()[-3000:]
        )
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
    args = [
        "-m",
        "system=spring",
        "model=mlp_torch",
        "profile=quick",
        f"seed={','.join(map(str, SEEDS))}",
        "system.steps=3000",
        "model.log_every=50",
        "device=cpu",
        f"hydra.sweep.dir={sweep}",
    ]
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
    job_dirs = {p.parent for p in sweep.rglob("hnnbench.log")} | {p.parent for p in survived}
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
    redone = len(SEEDS) - len(survived)
    assert (
        f"this run: {redone} jobs: {redone} ok; {len(survived)} kept from an earlier run" in text
    ), text[-3000:]


def _workers_of(pid: int) -> list[int]:
    """The process ids whose parent is ``pid`` (Linux /proc)."""
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_workers_stop_when_the_command_is_killed_alone(tmp_path):
    """``kill -9`` of the ``hnnbench`` process only (not its process group): its joblib
    workers notice within seconds and exit instead of training on as orphans; the
    interrupted jobs leave no record."""
    sweep = tmp_path / "sweep"
    args = [
        "-m",
        "system=spring",
        "model=mlp_torch",
        "profile=quick",
        "seed=0,1",
        "system.steps=200000",
        "model.log_every=50",
        "device=cpu",
        "hydra/launcher=joblib",
        "hydra.launcher.n_jobs=2",
        f"hydra.sweep.dir={sweep}",
    ]
    log = tmp_path / "first.log"
    proc = _start(args, tmp_path, log)
    try:
        deadline = time.monotonic() + 600
        while len(list(sweep.rglob("hnnbench.log"))) < 2:  # both jobs started
            assert time.monotonic() < deadline and proc.poll() is None, log.read_text()[-3000:]
            time.sleep(0.2)
        time.sleep(5)  # into training (its progress log comes only every 50000 steps)
        workers = [
            w
            for w in _workers_of(proc.pid)
            if "popen_loky"  # not its tracker
            in Path(f"/proc/{w}/cmdline").read_bytes().decode(errors="replace")
        ]
        assert workers, "no joblib worker found"
        os.kill(proc.pid, signal.SIGKILL)  # the command alone
        proc.wait(timeout=60)
        deadline = time.monotonic() + 120
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.5)
        assert not [w for w in workers if _alive(w)], "orphaned workers still running"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    assert not list(sweep.rglob("result.json"))  # no record of an unfinished job
    logs = "".join(p.read_text() for p in sweep.rglob("hnnbench.log"))
    assert "the hnnbench command that started this job has gone" in logs, logs[-2000:]
