"""One small sweep through three real Hydra launchers: basic (in-process, one job after
another), joblib (a pool of two worker processes) and submitit_local (one process per
job). The records must agree: training is seeded and deterministic on one CPU core,
whatever process runs it, so data, training curves, weights and metrics are identical
bit for bit (see :func:`test_launchers_reproduce_the_basic_sweep`).
Each launcher must also produce the end-of-sweep summary, hand the job processes the
caller's environment, and resume (slow)."""

from __future__ import annotations

import csv
import math
import os
import shlex
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from conftest import REPO, hnnbench, sweep_records

pytestmark = pytest.mark.slow

#: The quick sweep, trimmed (two systems, two trained models, fewer steps, a shorter
#: evaluation horizon) so that three launchers and two resumes stay within a minute or
#: two on two cores: each job costs a process start under submitit.
SWEEP = (
    "-m",
    "system=spring,pendulum",
    "model=mlp_torch,hnn_torch,hnn_jax",
    "profile=quick",
    "seed=0",
    "system.steps=100",
    "system.eval_t_end=5",
)
#: hnn_jax is in because XLA's results depend on its thread count: every launcher's jobs
#: pin their process to one core (hnnbench._running.affinity), so XLA runs one thread everywhere.
KEYS = {(s, m, 0) for s in ("spring", "pendulum") for m in ("mlp_torch", "hnn_torch", "hnn_jax")}
N = len(KEYS)
#: Relative tolerance of the metric comparison: none. Every job evaluates on arrays
#: as loaded from the dataset cache, whoever built them (hnnbench._running.dataset_cache.cached).
RTOL = 0.0
LAUNCHERS: dict[str, tuple[str, ...]] = {
    "basic": (),
    "joblib": ("hydra/launcher=joblib", "hydra.launcher.n_jobs=2"),
    # submitit's local executor starts every job of a batch at once; the timeout only
    # bounds a hung job (the default is 60 minutes).
    "submitit_local": ("hydra/launcher=submitit_local", "hydra.launcher.timeout_min=15"),
}


#: One pixel pair at quick sizes (issue 21: its training is the most sensitive to how a
#: job is launched, through XLA's thread count and the chunked JAX training loop).
PIXEL_SWEEP = (
    "-m",
    "system=pixel_pendulum",
    "model=hnn_jax",
    "profile=quick",
    "seed=0",
    "system.steps=100",
)
PIXEL_KEY = ("pixel_pendulum", "hnn_jax", 0)


class Sweep:
    """One finished sweep: its command line, output and directories."""

    def __init__(self, name: str, root: Path, sweep: tuple[str, ...] = SWEEP) -> None:
        self.name = name
        self.dir = root / name / "sweep"
        self.cache = root / name / "cache"
        self.args = [*sweep, *LAUNCHERS[name], f"hydra.sweep.dir={self.dir}"]
        self.cwd = root / name

    def run(self) -> subprocess.CompletedProcess[str]:
        """Run the sweep with its own dataset cache (set through the environment)."""
        self.cwd.mkdir(parents=True, exist_ok=True)
        return hnnbench(
            *self.args,
            cwd=self.cwd,
            timeout=900,
            env={"HNNBENCH_CACHE_DIR": str(self.cache), "HNNBENCH_PROGRESS": "log"},
        )

    def records(self) -> dict[tuple[str, str, int], dict[str, Any]]:
        """The records by (system, model, seed), each with its ``path``."""
        return sweep_records(self.dir)


Sweeps = dict[str, tuple[Sweep, "subprocess.CompletedProcess[str]"]]


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory: pytest.TempPathFactory) -> Sweeps:
    """Each launcher's sweep, run once for the whole module."""
    root = tmp_path_factory.mktemp("launchers")
    out = {}
    for name in LAUNCHERS:
        sweep = Sweep(name, root)
        out[name] = (sweep, sweep.run())
    return out


@pytest.mark.parametrize("launcher", list(LAUNCHERS))
def test_sweep_completes_with_summary(sweeps: Sweeps, launcher: str) -> None:
    """Every job ok, and the end-of-sweep summary (table, summary.csv, report) written."""
    sweep, proc = sweeps[launcher]
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    recs = sweep.records()
    assert set(recs) == KEYS
    for key, rec in recs.items():
        assert rec["status"] == "ok", (launcher, key, rec["error"])
        assert set(rec["timings"]) >= {"data_s", "fit_s", "eval_s", "total_s", "cpu_s"}
        assert rec["timings"]["cpu_s"] > 0
    # Every launcher's jobs pin their process to a core (hnnbench._running.affinity).
    pins = {rec.get("cpu_pin") for rec in recs.values()}
    if hasattr(os, "sched_getaffinity") and len(os.sched_getaffinity(0)) > 1:
        assert None not in pins and pins <= set(os.sched_getaffinity(0)), pins
    # The end-of-sweep callback ran once, in the launching process, over every record.
    assert f"{N} jobs: {N} ok" in proc.stdout, proc.stdout[-3000:]
    with open(sweep.dir / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {(r["system"], r["model"], int(r["seed"])) for r in rows} == KEYS
    assert {r["status"] for r in rows} == {"ok"}
    assert (sweep.dir / "leaderboard.csv").exists()


@pytest.fixture(scope="module")
def pixel_sweeps(tmp_path_factory: pytest.TempPathFactory) -> Sweeps:
    """The pixel pair under the basic and the joblib launcher."""
    root = tmp_path_factory.mktemp("pixel_launchers")
    out = {}
    for name in ("basic", "joblib"):
        sweep = Sweep(name, root, PIXEL_SWEEP)
        out[name] = (sweep, sweep.run())
    return out


def _close(a: float, b: float) -> bool:
    """Equal, both NaN, or within :data:`RTOL` of each other."""
    return a == b or (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=RTOL)


@pytest.mark.parametrize("launcher", [n for n in LAUNCHERS if n != "basic"])
def test_launchers_reproduce_the_basic_sweep(sweeps: Sweeps, launcher: str) -> None:
    """Same keys; the same data, training curves, weights and metrics, bit for bit.

    Two things make that hold: every job evaluates on arrays as loaded from the dataset
    cache, whichever job built them (a freshly built array can be a transposed view, and
    numpy sums in memory order), and every job's process is pinned to one core, so XLA
    runs one thread whatever the launcher (hnnbench._running.affinity).
    """
    _assert_same_records(sweeps, launcher, KEYS)


def test_pixel_pair_is_the_same_under_joblib(pixel_sweeps: Sweeps) -> None:
    """The pixel pendulum's HNN (JAX, latent model on an autoencoder): the same record,
    weights and training curve under joblib as in the launching process."""
    for name, (_, proc) in pixel_sweeps.items():
        assert proc.returncode == 0, (name, proc.stdout[-2000:] + proc.stderr[-3000:])
    _assert_same_records(pixel_sweeps, "joblib", {PIXEL_KEY})
    rec = pixel_sweeps["basic"][0].records()[PIXEL_KEY]
    assert rec["status"] == "ok", rec["error"]


def _assert_same_records(sweeps: Sweeps, launcher: str, keys: set[Any]) -> None:
    """``launcher``'s records equal the basic launcher's bit for bit (see above)."""
    base, other = sweeps["basic"][0].records(), sweeps[launcher][0].records()
    assert set(base) == set(other) == keys
    for key in keys:
        a, b = base[key], other[key]
        for field in ("dataset_sha256", "evaluation_sha256"):
            assert a["data"][field] == b["data"][field], (launcher, key, field)
        assert a.get("history") == b.get("history"), (launcher, key)  # bitwise
        weights = [r["path"].parent / "weights.safetensors" for r in (a, b)]
        assert weights[0].read_bytes() == weights[1].read_bytes(), (launcher, key)
        assert a["steps"] == b["steps"] and a["train"] == b["train"], key
        assert a["config"] == b["config"], key
        assert set(a["metrics"]) == set(b["metrics"]), key
        for name, ma in a["metrics"].items():
            for stat in ("mean", "sem"):
                x, y = ma[stat], b["metrics"][name][stat]
                assert _close(x, y), (launcher, key, name, stat, x, y)


@pytest.mark.parametrize("launcher", [n for n in LAUNCHERS if n != "basic"])
def test_job_processes_get_the_environment(sweeps: Sweeps, launcher: str) -> None:
    """Worker processes see the caller's environment: the cache dir, the command line
    and the job count set by ``hnnbench`` before Hydra starts."""
    sweep, _ = sweeps[launcher]
    entries = list((sweep.cache / "datasets").glob("*/*.npz"))
    # spring and pendulum: a dataset and an evaluation set each.
    assert {p.parent.name for p in entries} == {"spring", "pendulum"}, entries
    assert len(entries) == 4, entries
    typed = shlex.join(["hnnbench", *sweep.args])
    for key, rec in sweep.records().items():
        assert rec["command"] == typed, key
        log = (rec["path"].parent / "hnnbench.log").read_text()
        assert f"/{N}] " in log, (key, log[-1000:])


@pytest.mark.parametrize("launcher", [n for n in LAUNCHERS if n != "basic"])
def test_resume_skips_finished_jobs(sweeps: Sweeps, launcher: str) -> None:
    """The same command into the same directory redoes nothing, and summarises again."""
    sweep, _ = sweeps[launcher]
    before = {key: rec["path"].read_bytes() for key, rec in sweep.records().items()}
    (sweep.dir / "summary.csv").unlink()
    proc = sweep.run()
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    after = {key: rec["path"].read_bytes() for key, rec in sweep.records().items()}
    assert after == before  # not one record rewritten
    assert f"this run: 0 jobs: none run; {N} kept from an earlier run" in proc.stdout, proc.stdout[
        -2000:
    ]
    assert (sweep.dir / "summary.csv").exists()
    for key, rec in sweep.records().items():
        assert "already finished (ok)" in (rec["path"].parent / "hnnbench.log").read_text(), key


def test_sweep_benchmark_summarises_existing_sweeps(sweeps: Sweeps) -> None:
    """``benchmarks/sweep.py --from`` reads the launchers' sweep dirs into Markdown tables."""
    dirs = [str(sweeps[name][0].dir) for name in LAUNCHERS]
    proc = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "sweep.py"), "--from", *dirs],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    sweep_rows = [line for line in lines if line.startswith(tuple(f"| {d} " for d in dirs))]
    assert len(sweep_rows) == len(LAUNCHERS), proc.stdout
    for row, launcher in zip(
        sweep_rows, ("BasicLauncher", "JoblibLauncher (n_jobs=2)", "LocalLauncher"), strict=True
    ):
        assert launcher in row and f"| {N} ok " in row, row
    headers = [line.split("|") for line in lines if line.startswith("| system ")]
    assert len(headers) == len(LAUNCHERS), proc.stdout
    assert [h.strip() for h in headers[0][1:-1]] == [
        "system",
        "model",
        "seed",
        "status",
        "total_s",
        "data_s",
        "compile_s",
        "fit_s",
        "eval_s",
    ]
    job_rows = [line for line in lines if line.startswith(("| spring ", "| pendulum "))]
    assert len(job_rows) == len(LAUNCHERS) * N and all("| ok " in r for r in job_rows), job_rows


def test_a_users_own_launcher_file_on_the_searchpath_is_accepted(tmp_path: Path) -> None:
    """A ``hydra.searchpath`` reads config files chosen on the command line: refused in
    one line unless a developer allows such overrides (issue 48); then
    ``hydra/launcher=<name>`` from that directory passes the up-front check and runs, and
    a typo of it gets a did-you-mean."""
    conf = tmp_path / "myconf" / "hydra" / "launcher"
    conf.mkdir(parents=True)
    (conf / "my_local.yaml").write_text(
        "# @package hydra.launcher\n"
        "_target_: hydra._internal.core_plugins.basic_launcher.BasicLauncher\n"
    )
    searchpath = f"hydra.searchpath=[file://{tmp_path / 'myconf'}]"
    refused = hnnbench(
        "-m", "system=spring", "model=oracle", "profile=quick", searchpath, cwd=tmp_path
    )
    assert refused.returncode == 2 and "HNNBENCH_ALLOW_CODE_OVERRIDES=1" in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1, refused.stderr
    allow = {"HNNBENCH_ALLOW_CODE_OVERRIDES": "1"}
    typo = hnnbench(
        "-m",
        "system=spring",
        "model=oracle",
        "profile=quick",
        "hydra/launcher=my_locl",
        searchpath,
        cwd=tmp_path,
        env=allow,
    )
    assert typo.returncode == 2 and "Did you mean 'my_local'" in typo.stderr, typo.stderr
    proc = hnnbench(
        "-m",
        "system=spring",
        "model=oracle",
        "profile=quick",
        "hydra/launcher=my_local",
        searchpath,
        f"hydra.sweep.dir={tmp_path / 'sweep'}",
        cwd=tmp_path,
        env=allow,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "1 jobs: 1 ok" in proc.stdout, proc.stdout[-2000:]


_HELD: list[bytes] = []


def _grow_by(megabytes: int, limit_mb: str | None) -> int:
    """In a loky worker: keep ``megabytes`` of touched memory (a job's kept programs);
    with ``limit_mb``, first what every hnnbench job does under that setting ("": the
    default)."""
    import time

    from hnnbench._sweeping.loky import WORKER_GROWTH_ENV, set_worker_growth

    if limit_mb is not None:
        os.environ[WORKER_GROWTH_ENV] = limit_mb
        set_worker_growth()
    _HELD.append(b"\x01" * (megabytes * 1024 * 1024))  # touched, so resident
    time.sleep(1.2)  # loky checks a worker's memory at most once a second
    return os.getpid()


def _pid() -> int:
    return os.getpid()


@pytest.mark.filterwarnings("ignore:A worker stopped while some jobs")
@pytest.mark.parametrize(("limit_mb", "replaced"), [(None, True), ("", False), ("300", True)])
def test_a_joblib_worker_is_not_replaced_for_the_memory_a_few_jobs_keep(limit_mb, replaced):
    """loky replaces a worker whose memory grew 300 MB since its first task; hnnbench's
    jobs raise that limit (a replacement re-imports torch, JAX and Hydra), so a worker
    that kept 400 MB runs the next job itself; HNNBENCH_WORKER_GROWTH_MB=300 restores
    loky's own limit."""
    pytest.importorskip("psutil")  # loky checks memory only with psutil
    from joblib.externals.loky import get_reusable_executor

    executor = get_reusable_executor(max_workers=1, reuse=False)  # joblib's worker pool
    try:
        first = executor.submit(_pid).result()  # loky's reference size: after a first task
        grown = executor.submit(_grow_by, 400, limit_mb).result()
        after = executor.submit(_pid).result()
    finally:
        executor.shutdown(wait=True)
    assert first == grown != os.getpid()
    assert (after != grown) is replaced


@pytest.mark.parametrize(
    ("text", "limit"),
    [
        ("", 2_000_000_000),
        ("300", 300_000_000),
        ("0", 2_000_000_000),
        ("²", 2_000_000_000),
        ("lots", 2_000_000_000),
    ],
)
def test_the_worker_growth_setting_is_read_in_megabytes_and_a_bad_one_is_one_line(
    monkeypatch, caplog, text, limit
):
    from hnnbench._sweeping import loky

    monkeypatch.setenv(loky.WORKER_GROWTH_ENV, text)
    monkeypatch.setattr(loky, "_growth_warned", False)
    assert loky.worker_growth() == limit
    assert loky.worker_growth() == limit
    warned = [r.getMessage() for r in caplog.records if loky.WORKER_GROWTH_ENV in r.getMessage()]
    assert len(warned) == (text not in ("", "300"))  # once, however many jobs ask
    if warned:
        assert "expected a whole number of megabytes" in warned[0]
