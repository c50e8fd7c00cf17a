"""Whole-sweep wall time: the basic launcher vs joblib, side by side in one run.

    python benchmarks/sweep.py                       # the quick sweep, all systems and models
    python benchmarks/sweep.py --warm                # the same, with caches filled first
    python benchmarks/sweep.py --overrides system=spring,pendulum model=mlp_torch,hnn_torch
    python benchmarks/sweep.py --overrides profile=paper seed=0 --n-jobs 4
    python benchmarks/sweep.py --from results/runs/paper_2026-11-22_10-00-00 [DIR ...]
    python benchmarks/sweep.py --launchers joblib_300mb joblib  # loky's own worker limit

    # The 30 jobs of the original benchmark (6 systems x MLP/HNN x torch/JAX + oracle,
    # paper profile, seed 0), as `make benchmark` runs them (joblib, one worker per core):
    python benchmarks/sweep.py --launchers joblib --n-jobs 2 --overrides profile=paper \
        system=spring,pendulum,real_pendulum,two_body,three_body,pixel_pendulum \
        model=mlp_torch,hnn_torch,mlp_jax,hnn_jax,oracle

Without ``--from`` it runs the same sweep once per launcher (by default ``basic``, then
``hydra/launcher=joblib hydra.launcher.n_jobs=N``) through the installed ``hnnbench``
console script, each into its own temporary sweep directory and with its own empty
cache (so each pays for generating the data and compiling the JAX functions; with
``--warm`` every one starts from one cache that a first, uncompared run filled), and
prints the wall time of each command, its CPU time (user + system, of the command and
its worker processes; CPU per wall second shows how many cores were kept busy), the
speed-up over the first launcher, and the per-job table read from the records'
``timings``. With ``--from`` it only summarises
existing sweep directories, e.g. a paper sweep run on another machine.

Wall time is the whole command: start-up (importing the backends), every job, and the
end-of-sweep summary and report. ``fit_s`` includes ``compile_s`` (JAX compilation of
the training step); ``eval_s`` includes the rollouts and their compilation. The span
of a sweep read with ``--from`` is first job start to last job end, from the records'
``created_at`` (whole seconds) and ``total_s``; it leaves out start-up and the report.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tabulate import tabulate

#: The sweep run by default; ``--overrides`` replaces these keys and adds others.
DEFAULT_OVERRIDES = {"system": "all", "model": "all", "profile": "quick"}
PHASES = ("data_s", "compile_s", "fit_s", "eval_s")
LAUNCHERS = ("basic", "joblib", "joblib_300mb", "submitit_local")
#: Environment of a launcher's command beyond the benchmark's own. ``joblib_300mb``:
#: joblib with loky's own worker memory-growth limit (300 MB), which replaced a worker
#: every few jobs before hnnbench raised it (hnnbench._sweeping.loky.WORKER_GROWTH).
LAUNCHER_ENV = {"joblib_300mb": {"HNNBENCH_WORKER_GROWTH_MB": "300"}}


@dataclass
class Sweep:
    """A finished sweep: where its records are, and how long its command took."""

    label: str
    directory: Path
    wall_s: float | None = None
    cpu_s: float | None = None  # user + system CPU time of the command and its workers
    returncode: int | None = None
    records: list[dict[str, Any]] = field(default_factory=list)


def hnnbench_exe() -> str:
    """The installed console script: next to this Python, else on ``$PATH``."""
    here = Path(sys.executable).parent / "hnnbench"
    if here.exists():
        return str(here)
    found = shutil.which("hnnbench")
    if found is None:
        sys.exit("sweep.py: the hnnbench console script is not installed (pip install -e .)")
    return found


def sweep_overrides(extra: list[str]) -> list[str]:
    """:data:`DEFAULT_OVERRIDES` updated with ``extra`` (``key=value`` each)."""
    merged = dict(DEFAULT_OVERRIDES)
    for text in extra:
        key, sep, value = text.partition("=")
        if not sep:
            sys.exit(f"sweep.py: override {text!r} is not KEY=VALUE")
        if key.lstrip("+~").startswith(("hydra.sweep", "hydra/launcher", "hydra.launcher")):
            sys.exit(f"sweep.py: {key} is set by this script (see --n-jobs, --launchers)")
        merged[key] = value
    return [f"{k}={v}" for k, v in merged.items()]


def launcher_args(name: str, n_jobs: int) -> list[str]:
    """Hydra overrides that select launcher ``name``."""
    if name == "basic":
        return []
    if name in ("joblib", "joblib_300mb"):
        return ["hydra/launcher=joblib", f"hydra.launcher.n_jobs={n_jobs}"]
    # submitit_local starts every job of a batch at once: batches of n_jobs.
    return ["hydra/launcher=submitit_local", f"hydra.sweeper.max_batch_size={n_jobs}"]


def load_records(directory: Path) -> list[dict[str, Any]]:
    """Every readable ``result.json`` below ``directory``."""
    out = []
    for path in sorted(directory.rglob("result.json")):
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if isinstance(record, dict) and "status" in record:
            out.append(record)
    return out


def run_sweep(
    label: str,
    args: list[str],
    root: Path,
    cache: Path | None = None,
    extra_env: dict[str, str] | None = None,
) -> Sweep:
    """Run ``hnnbench -m ARGS`` into ``root/label`` with ``cache`` as the hnnbench cache
    (datasets and JAX compilations; default: a fresh one, ``root/label/cache``) and
    ``extra_env`` set."""
    directory = root / label / "sweep"
    cache = root / label / "cache" if cache is None else cache
    log = root / label / "hnnbench.log"
    log.parent.mkdir(parents=True)
    command = [hnnbench_exe(), "-m", *args, f"hydra.sweep.dir={directory}"]
    env = {
        **os.environ,
        "HNNBENCH_CACHE_DIR": str(cache),
        "HNNBENCH_PROGRESS": "log",
        **(extra_env or {}),
    }
    print(f"[{label}] {' '.join(command[1:])}", flush=True)
    before = _children_cpu_s()
    start = time.perf_counter()
    with open(log, "wb") as fh:
        proc = subprocess.run(
            command, cwd=root / label, stdout=fh, stderr=subprocess.STDOUT, env=env, check=False
        )
    wall = time.perf_counter() - start
    cpu = _children_cpu_s() - before
    print(
        f"[{label}] exit {proc.returncode} after {wall:.1f} s wall, {cpu:.1f} s CPU; log: {log}",
        flush=True,
    )
    if proc.returncode != 0:
        print(log.read_text(errors="replace")[-3000:], file=sys.stderr)
    return Sweep(label, directory, wall, cpu, proc.returncode, load_records(directory))


def _children_cpu_s() -> float:
    """User + system CPU seconds of this process's finished children and theirs (the
    launcher's worker processes are waited for by the ``hnnbench`` process)."""
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _launcher_of(directory: Path) -> str:
    """The launcher named in a sweep's ``multirun.yaml`` (``?`` if unknown)."""
    path = directory / "multirun.yaml"
    try:
        from omegaconf import OmegaConf

        cfg = OmegaConf.load(path)
        target = str(OmegaConf.select(cfg, "hydra.launcher._target_", default="?"))
        n_jobs = OmegaConf.select(cfg, "hydra.launcher.n_jobs", default=None)
    except Exception:  # noqa: BLE001 - a summary never fails on a missing file
        return "?"
    name = target.rsplit(".", 1)[-1]
    return f"{name} (n_jobs={n_jobs})" if n_jobs is not None else name


def _span_s(records: list[dict[str, Any]]) -> float | None:
    """First job start to last job end, from ``created_at`` and ``total_s``."""
    starts, ends = [], []
    for rec in records:
        try:
            start = dt.datetime.fromisoformat(rec["created_at"]).timestamp()
        except (KeyError, TypeError, ValueError):
            continue
        starts.append(start)
        ends.append(start + float(rec.get("timings", {}).get("total_s", 0.0)))
    return max(ends) - min(starts) if starts else None


def _fmt(value: Any) -> str:
    return "" if value is None else f"{value:.1f}" if isinstance(value, float) else str(value)


def _table(rows: list[list[Any]], headers: list[str]) -> str:
    """A Markdown (GitHub) table; numbers (already formatted) right-aligned."""
    numeric = ("jobs", "seed", "speed-up", "job s per wall s", "cpu per wall s", "wall_min")
    align = ["right" if h in numeric or h.endswith("_s") else "left" for h in headers]
    return tabulate(rows, headers=headers, tablefmt="github", disable_numparse=True, colalign=align)


def job_table(records: list[dict[str, Any]]) -> str:
    """One row per job: identity, status, and the phases of ``timings``."""
    rows = []
    for rec in sorted(
        records, key=lambda r: (str(r.get("system")), str(r.get("model")), str(r.get("seed")))
    ):
        timings = rec.get("timings") or {}
        rows.append(
            [
                rec.get("system"),
                rec.get("model"),
                rec.get("seed"),
                rec.get("status"),
                *(_fmt(timings.get(k)) for k in ("total_s", *PHASES)),
            ]
        )
    return _table(rows, ["system", "model", "seed", "status", "total_s", *PHASES])


def totals(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Job count, statuses, and the sum of each timing over the jobs that have it
    (``None`` where none has it, e.g. ``compile_s`` without JAX models)."""
    sums: dict[str, float | None] = {}
    for key in ("total_s", *PHASES):
        values = [float(r["timings"][key]) for r in records if key in (r.get("timings") or {})]
        sums[key] = sum(values) if values else None
    counts = Counter(str(r.get("status")) for r in records)
    return {
        "jobs": len(records),
        "statuses": ", ".join(f"{n} {s}" for s, n in sorted(counts.items())),
        **sums,
    }


def comparison_table(sweeps: list[Sweep]) -> str:
    """Per sweep: wall time, the sum of job times, and the speed-up over the first."""
    base = sweeps[0].wall_s if sweeps[0].returncode == 0 else None
    rows = []
    for sweep in sweeps:
        tot = totals(sweep.records)
        wall = sweep.wall_s if sweep.returncode == 0 else None  # a failed run: no figure
        rows.append(
            [
                sweep.label if wall else f"{sweep.label} (failed, exit {sweep.returncode})",
                tot["jobs"],
                tot["statuses"],
                _fmt(wall),
                _fmt(wall / 60 if wall else None),
                _fmt(sweep.cpu_s),
                _fmt(sweep.cpu_s / wall) if wall and sweep.cpu_s else "",
                _fmt(tot["total_s"]),
                _fmt(tot["total_s"] / wall) if wall and tot["total_s"] else "",
                f"{base / wall:.2f}x" if base and wall else "",
            ]
        )
    return _table(
        rows,
        [
            "launcher",
            "jobs",
            "statuses",
            "wall_s",
            "wall_min",
            "cpu_s",
            "cpu per wall s",
            "sum of job total_s",
            "job s per wall s",
            "speed-up",
        ],
    )


def summary_table(sweeps: list[Sweep]) -> str:
    """Per existing sweep dir: launcher, job count, span, sum of each timing."""
    rows = []
    for sweep in sweeps:
        tot = totals(sweep.records)
        rows.append(
            [
                sweep.label,
                _launcher_of(sweep.directory),
                tot["jobs"],
                tot["statuses"],
                _fmt(_span_s(sweep.records)),
                *(_fmt(tot[k]) for k in ("total_s", *PHASES)),
            ]
        )
    return _table(
        rows,
        [
            "sweep",
            "launcher",
            "jobs",
            "statuses",
            "span_s",
            "sum total_s",
            *(f"sum {k}" for k in PHASES),
        ],
    )


def machine_line() -> str:
    """CPU count and load, which the wall times depend on."""
    load = " / ".join(f"{x:.2f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    cpu = platform.processor() or platform.machine()
    return (
        f"{platform.node()}: {os.cpu_count()} CPUs ({cpu}), Python "
        f"{platform.python_version()}, load average (1/5/15 min) {load}"
    )


def summarise(directories: list[Path]) -> int:
    """``--from``: tables of existing sweep directories."""
    sweeps = []
    for directory in directories:
        if not directory.is_dir():
            sys.exit(f"sweep.py: {directory}: no such directory")
        records = load_records(directory)
        if not records:
            sys.exit(f"sweep.py: no result.json under {directory}")
        sweeps.append(Sweep(str(directory), directory, records=records))
    print("## Sweeps\n")
    print(summary_table(sweeps))
    for sweep in sweeps:
        print(f"\n## Jobs of {sweep.label}\n")
        print(job_table(sweep.records))
    return 0


def benchmark(
    overrides: list[str], launchers: list[str], n_jobs: int, keep: Path | None, warm: bool = False
) -> int:
    """Run the sweep once per launcher, side by side; print the tables. ``warm``: first
    run it once with the basic launcher to fill one cache (datasets and JAX
    compilations), then time every launcher against that cache."""
    args = sweep_overrides(overrides)
    print(f"machine: {machine_line()}")
    print(f"sweep: hnnbench -m {' '.join(args)}\n")
    root = Path(tempfile.mkdtemp(prefix="hnnbench-sweep-bench-")) if keep is None else keep
    root.mkdir(parents=True, exist_ok=True)
    sweeps = []
    cache = None
    try:
        if warm:
            cache = root / "warm-cache"
            primed = run_sweep("warmup", args, root, cache)
            print(f"[warmup] filled {cache}; not compared below\n", flush=True)
            if primed.returncode != 0:
                return 1
        for name in launchers:
            label = name if name == "basic" else f"{name} n_jobs={n_jobs}"
            # The directory name goes into a Hydra override: no '=' or spaces in it.
            slug = name if name == "basic" else f"{name}_{n_jobs}"
            sweep = run_sweep(
                slug, [*args, *launcher_args(name, n_jobs)], root, cache, LAUNCHER_ENV.get(name)
            )
            sweep.label = label
            sweeps.append(sweep)
        print(f"\nmachine after: {machine_line()}\n")
        print("## Wall time\n")
        print(comparison_table(sweeps))
        for sweep in sweeps:
            print(f"\n## Jobs, {sweep.label}\n")
            print(job_table(sweep.records))
    finally:
        if keep is None:
            shutil.rmtree(root, ignore_errors=True)
        else:
            print(f"\nsweep directories kept under {root}")
    return 0 if all(s.returncode == 0 for s in sweeps) else 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="\n".join(__doc__.splitlines()[1:]),
    )
    parser.add_argument(
        "--overrides",
        nargs="+",
        default=[],
        metavar="KEY=VALUE",
        help="sweep overrides; replace the defaults "
        f"({' '.join(f'{k}={v}' for k, v in DEFAULT_OVERRIDES.items())}) "
        "key by key",
    )
    parser.add_argument(
        "--n-jobs", type=int, default=2, help="parallel jobs of the non-basic launchers (default 2)"
    )
    parser.add_argument(
        "--launchers",
        nargs="+",
        choices=LAUNCHERS,
        default=["basic", "joblib"],
        help="launchers to compare, in this order (default: basic joblib)",
    )
    parser.add_argument(
        "--keep",
        type=Path,
        default=None,
        metavar="DIR",
        help="keep the sweep directories and logs under DIR "
        "(default: a temporary directory, removed)",
    )
    parser.add_argument(
        "--warm",
        action="store_true",
        help="time every launcher with caches that one first, uncompared "
        "run filled (a user's second sweep); default: each starts "
        "empty",
    )
    parser.add_argument(
        "--from",
        dest="sources",
        nargs="+",
        type=Path,
        metavar="DIR",
        help="only summarise these existing sweep directories",
    )
    args = parser.parse_args(argv)
    if args.sources:
        return summarise(args.sources)
    if args.n_jobs < 1:
        parser.error("--n-jobs must be at least 1")
    return benchmark(args.overrides, args.launchers, args.n_jobs, args.keep, args.warm)


if __name__ == "__main__":
    sys.exit(main())
