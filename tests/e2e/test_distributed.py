"""Real clusters on this machine: a one-node Slurm cluster (munge, slurmdbd, slurmctld,
slurmd) and a local Ray head, brought up by scripts/maintainer/cluster/ (installing what is
missing), and one small sweep through each launcher, whose records must equal the basic
launcher's bit for bit (as in tests/e2e/test_launchers.py). Also: a Slurm task cancelled
mid-run (``scancel``) is finished by re-running the sweep, nothing lost, nothing redone.

Marked ``distributed`` (``make test-distributed`` = ``pytest -m distributed``) and
``slow``. The fixtures skip, with the reason, only where the packages cannot be
installed (not root, no apt-get, the install failed); a cluster that installed but does
not start fails the tests."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import REPO, hnnbench, sweep_records

pytestmark = [pytest.mark.distributed, pytest.mark.slow]

CLUSTER = REPO / "scripts" / "maintainer" / "cluster"
#: spring x two JAX models x two seeds: 4 jobs, about 10-20 s each on one core.
SWEEP = (
    "-m",
    "system=spring",
    "model=hnn_jax,mlp_jax",
    "profile=quick",
    "seed=0,1",
    "system.steps=100",
    "system.eval_t_end=5",
)
KEYS = {("spring", m, s) for m in ("hnn_jax", "mlp_jax") for s in (0, 1)}
PARTITION = os.environ.get("HNNBENCH_SLURM_PARTITION", "local")
#: What a user types for a Slurm cluster (docs/SCALING.md): partition, a time limit,
#: one core and 2 GB per job, at most two array tasks at once.
SLURM = (
    "hydra/launcher=submitit_slurm",
    f"hydra.launcher.partition={PARTITION}",
    "hydra.launcher.timeout_min=15",
    "hydra.launcher.cpus_per_task=1",
    "hydra.launcher.mem_gb=2",
    "hydra.launcher.array_parallelism=2",
)
#: Ray stays on the loopback address (scripts/maintainer/cluster/ray.sh).
RAY_ENV = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0"}


def _script(name: str, *args: str, timeout: float = 900) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["bash", str(CLUSTER / name), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, "VENV": str(Path(sys.prefix))},
    )


def _last_lines(proc: subprocess.CompletedProcess[str], n: int = 5) -> str:
    return " | ".join((proc.stdout + proc.stderr).strip().splitlines()[-n:])


# Module scope: the daemons (and the Ray head) stop when these tests are done, before the
# rest of a full run, unless they were running before.
@pytest.fixture(scope="module")
def slurm_cluster() -> Any:
    """A one-node Slurm cluster on localhost; stopped afterwards if this started it."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        pytest.skip(
            "Slurm cluster: needs root (scripts/maintainer/cluster/slurm.sh installs "
            "packages and starts system daemons)"
        )
    if not shutil.which("sbatch") and not shutil.which("apt-get"):
        pytest.skip("Slurm cluster: slurm is not installed and there is no apt-get to install it")
    was_up = _script("slurm.sh", "status").stdout.count(": running") == 5
    proc = _script("slurm.sh", "install")
    if proc.returncode != 0:
        pytest.skip(f"Slurm cluster: the packages could not be installed: {_last_lines(proc)}")
    proc = _script("slurm.sh", "up", timeout=300)
    assert proc.returncode == 0, f"slurm.sh up failed: {_last_lines(proc, 30)}"
    yield PARTITION
    if not was_up:
        _script("slurm.sh", "down")


@pytest.fixture(scope="module")
def ray_head() -> Any:
    """A local Ray head on 127.0.0.1: its address, and the directory holding ray and the
    plugin (for PYTHONPATH; .venv stays without them). Stopped afterwards if this
    started it."""
    proc = _script("ray.sh", "install")
    if proc.returncode != 0:
        pytest.skip(f"Ray: ray/hydra-ray-launcher could not be installed: {_last_lines(proc)}")
    port = os.environ.get("RAY_PORT", "6379")
    was_up = _script("ray.sh", "status", timeout=60).returncode == 0 and _port_open(int(port))
    proc = _script("ray.sh", "up", timeout=300)
    assert proc.returncode == 0, f"ray.sh up failed: {_last_lines(proc, 30)}"
    site = _script("ray.sh", "site").stdout.strip()
    yield proc.stdout.strip().splitlines()[-1], site
    if not was_up:
        _script("ray.sh", "down", timeout=120)


def _port_open(port: int) -> bool:
    import socket

    with socket.socket() as s:
        s.settimeout(1)
        return s.connect_ex(("127.0.0.1", port)) == 0


class Sweep:
    """The sweep :data:`SWEEP` under one launcher, in its own directory and cache."""

    def __init__(
        self,
        root: Path,
        name: str,
        launcher: tuple[str, ...] = (),
        extra: tuple[str, ...] = (),
        env: dict[str, str] | None = None,
    ) -> None:
        self.cwd = root / name
        self.dir = self.cwd / "sweep"
        self.cache = self.cwd / "cache"
        self.args = [*SWEEP, *extra, *launcher, f"hydra.sweep.dir={self.dir}"]
        self.env = {
            "HNNBENCH_CACHE_DIR": str(self.cache),
            "HNNBENCH_PROGRESS": "log",
            **(env or {}),
        }

    def run(self, timeout: float = 900) -> subprocess.CompletedProcess[str]:
        self.cwd.mkdir(parents=True, exist_ok=True)
        return hnnbench(*self.args, cwd=self.cwd, env=self.env, timeout=timeout)

    def popen(self) -> subprocess.Popen[str]:
        self.cwd.mkdir(parents=True, exist_ok=True)
        exe = Path(sys.executable).parent / "hnnbench"
        return subprocess.Popen(
            [str(exe), *self.args],
            cwd=self.cwd,
            text=True,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            env={**os.environ, **self.env},
        )

    def records(self) -> dict[tuple[str, str, int], dict[str, Any]]:
        """By (system, model, seed), each with its ``path``; two records for a key fail."""
        return sweep_records(self.dir)


@pytest.fixture(scope="module")
def basic(tmp_path_factory: pytest.TempPathFactory) -> Sweep:
    """The reference: the same sweep under the basic launcher."""
    sweep = Sweep(tmp_path_factory.mktemp("distributed"), "basic")
    proc = sweep.run()
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    return sweep


def _assert_same_as_basic(basic: Sweep, other: Sweep) -> None:
    """``other``'s records equal ``basic``'s: ``scripts/maintainer/compare_records.py --rtol 0``
    over the metrics, and the data hashes, training curves and weights bit for bit."""
    a, b = basic.records(), other.records()
    assert set(a) == set(b) == KEYS, (set(a), set(b))
    script = REPO / "scripts" / "maintainer" / "compare_records.py"
    proc = subprocess.run(
        [
            sys.executable,
            str(script),
            str(basic.dir),
            str(other.dir),
            "--rtol",
            "0",
            "--ignore",
            "command",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    for key in KEYS:
        ra, rb = a[key], b[key]
        assert rb["status"] == "ok", (key, rb.get("error"))
        for field in ("dataset_sha256", "evaluation_sha256"):
            assert ra["data"][field] == rb["data"][field], (key, field)
        assert ra.get("history") == rb.get("history"), key
        assert ra["steps"] == rb["steps"] and ra["train"] == rb["train"], key
        weights = [r["path"].parent / "weights.safetensors" for r in (ra, rb)]
        assert weights[0].read_bytes() == weights[1].read_bytes(), key
        assert rb.get("cpu_pin") is not None, key  # one core per job under every launcher


def test_submitit_slurm_sweep_equals_the_basic_sweep(
    slurm_cluster: str, basic: Sweep, tmp_path: Path
) -> None:
    """An array job on the real cluster, configured as a user would (partition, time
    limit, one CPU and 2 GB per task, two tasks at once): every task ran under Slurm,
    and the records are the basic launcher's."""
    sweep = Sweep(tmp_path, "slurm", SLURM)
    proc = sweep.run()
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert f"{len(KEYS)} jobs: {len(KEYS)} ok" in proc.stdout, proc.stdout[-3000:]
    _assert_same_as_basic(basic, sweep)
    # The tasks saw the command's environment (sbatch exports it): its dataset cache.
    assert {p.parent.name for p in (sweep.cache / "datasets").glob("*/*.npz")} == {"spring"}
    # Really Slurm: submitit's per-task logs, named by the array job's id, and the jobs
    # are known to the accounting (sacct) as completed.
    logs = sorted((sweep.dir / ".submitit").glob("*_*/*_log.out"))
    assert len(logs) == len(KEYS), logs
    array_id = logs[0].parent.name.split("_")[0]
    acct = subprocess.run(
        ["sacct", "-n", "-X", "-P", "-o", "JobID,State,Partition,ReqCPUS", "-j", array_id],
        capture_output=True,
        text=True,
        timeout=60,
    )
    rows = [line.split("|") for line in acct.stdout.split()]
    assert len(rows) == len(KEYS), acct.stdout + acct.stderr
    assert {(r[1], r[2], r[3]) for r in rows} == {("COMPLETED", PARTITION, "1")}, rows


def _squeue(job_id: str) -> list[tuple[str, str]]:
    """(task id, state) of the array's tasks still queued or running (``all``: any job)."""
    select = [] if job_id == "all" else ["-j", job_id]
    out = subprocess.run(
        ["squeue", "-h", "-r", *select, "-o", "%i %T"], capture_output=True, text=True, timeout=30
    ).stdout
    return [tuple(line.split()) for line in out.splitlines() if line.strip()]  # type: ignore[misc]


def test_scancel_mid_run_then_rerun_finishes_every_job_once(
    slurm_cluster: str, tmp_path: Path
) -> None:
    """One task at a time; once the first record is written, the next task is cancelled
    with ``scancel`` while its job runs. The command reports the sweep unfinished;
    re-running it into the same directory finishes every job: one record each, and the
    records written before the cancel are kept as they were (not redone).

    The jobs train longer than the other tests' (a cancelled task is killed KillWait,
    5 s, after the cancel; a job of the shared sweep can finish within that): 20 000
    steps, about 15-30 s a job. At 3000 steps the jobs took 3-6 s once the JAX
    compilation cache of the earlier tests was warm, too short to be caught mid-run."""
    launcher = (*SLURM[:-1], "hydra.launcher.array_parallelism=1")
    sweep = Sweep(tmp_path, "scancel", launcher, extra=("system.steps=20000",))
    driver = sweep.popen()
    cancelled = None
    deadline = time.monotonic() + 600
    try:
        while time.monotonic() < deadline and driver.poll() is None:
            finished = set(sweep.records())
            for task, state in _squeue("all") if finished else []:
                log = sweep.dir / ".submitit" / task / f"{task}_0_log.out"
                text = log.read_text() if state == "RUNNING" and log.exists() else ""
                # Mid-run: the task's job has started and written no record yet. At
                # once: a job takes 15-30 s here, and a cancelled task has KillWait (5 s,
                # scripts/maintainer/cluster/slurm.sh) between SIGTERM, which submitit ignores, and
                # SIGKILL, in which it could still finish.
                started = re.search(r"(\w+) x (\w+) seed=(\d+): start", text)
                if started:
                    key = (started[1], started[2], int(started[3]))
                    if key not in finished and key not in set(sweep.records()):
                        subprocess.run(["scancel", task], check=True, timeout=30)
                        cancelled = (task, key)
                        break
            if cancelled:
                break
            time.sleep(0.3)
        assert cancelled, "no task was mid-run after the first record"
        out, _ = driver.communicate(timeout=600)
    finally:
        if driver.poll() is None:
            driver.kill()
            driver.wait()
    # The command reports the sweep unfinished (the other tasks ran to the end).
    assert f"{len(KEYS)} jobs: {len(KEYS)} ok" not in out, out[-3000:]
    task, key = cancelled
    array_id = task.split("_")[0]
    acct = subprocess.run(
        ["sacct", "-n", "-X", "-P", "-o", "JobID,State", "-j", task],
        capture_output=True,
        text=True,
        timeout=60,
    ).stdout
    assert "CANCELLED" in acct, acct
    # Let the rest of the array end (its tasks exit once the command is gone).
    for _ in range(240):
        if not _squeue(array_id):
            break
        time.sleep(0.5)
    assert not _squeue(array_id), _squeue(array_id)
    before = {
        key: (rec["path"].read_bytes(), rec["path"].stat().st_mtime_ns)
        for key, rec in sweep.records().items()
        if rec["status"] == "ok"
    }
    # The other tasks ran to the end (the command waited for them); the cancelled one
    # left no record.
    assert set(before) == KEYS - {key}, (key, before.keys())
    assert set(sweep.records()) == KEYS - {key}

    proc = sweep.run()  # the same command, the same directory
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    # Only the cancelled job ran again; the others were kept.
    assert f"1 jobs: 1 ok; {len(KEYS) - 1} kept from an earlier run" in proc.stdout, proc.stdout[
        -3000:
    ]
    after = sweep.records()  # fails on two records for one job
    assert set(after) == KEYS
    for key, (data, mtime) in before.items():
        assert after[key]["path"].read_bytes() == data, key  # not redone
        assert after[key]["path"].stat().st_mtime_ns == mtime, key
        # The job's log says it was skipped (Hydra names it after the job function's
        # module before 0.3: cli.log; hydra.job.name=hnnbench since).
        logs = "".join(p.read_text() for p in after[key]["path"].parent.glob("*.log"))
        assert "already finished (ok)" in logs, key
    assert after[cancelled[1]]["status"] == "ok"


def test_ray_sweep_on_a_running_head_equals_the_basic_sweep(
    ray_head: tuple[str, str], basic: Sweep, tmp_path: Path
) -> None:
    """``hydra/launcher=ray`` connecting to the head started by scripts/maintainer/cluster/ray.sh.
    Ray's workers are started by the head, not by ``hnnbench``, so they see neither the
    command's environment nor its launch context: the cache directory travels in Ray's
    ``runtime_env`` and ``pin_cpu=true`` pins each job to one core, as the command's
    own jobs are (docs/SCALING.md)."""
    address, site = ray_head
    cache = tmp_path / "ray" / "cache"
    ray = (
        "hydra/launcher=ray",
        f"hydra.launcher.ray.init.address={address}",
        # hydra-ray-launcher sets object_store_memory unless given; Ray refuses it
        # when connecting to a running cluster.
        "+hydra.launcher.ray.init.object_store_memory=null",
        f"+hydra.launcher.ray.init.runtime_env={{env_vars:{{HNNBENCH_CACHE_DIR:'{cache}'}}}}",
        "pin_cpu=true",
    )
    path = os.pathsep.join(p for p in (site, os.environ.get("PYTHONPATH", "")) if p)
    sweep = Sweep(tmp_path, "ray", ray, env={**RAY_ENV, "PYTHONPATH": path})
    proc = sweep.run()
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert f"Connecting to existing Ray cluster at address: {address}" in proc.stdout + proc.stderr
    assert f"{len(KEYS)} jobs: {len(KEYS)} ok" in proc.stdout, proc.stdout[-3000:]
    _assert_same_as_basic(basic, sweep)
    # The workers used the cache named in runtime_env (not the head's environment).
    assert {p.parent.name for p in (cache / "datasets").glob("*/*.npz")} == {"spring"}
