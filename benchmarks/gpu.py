"""The GPU path, measured: whole jobs with ``device=cuda`` in both backends, their time
against the same jobs on the CPU, and ``seeds_per_job=3`` against three separate jobs on
the GPU.

    python benchmarks/gpu.py --out DIR                     # on a machine with a GPU
    python benchmarks/gpu.py --out DIR --budget-s 420      # stop starting jobs after 420 s
    python benchmarks/gpu.py --summarize DIR               # the tables again, from DIR

Every job is the command a user runs (``hnnbench system=S model=M seed=0 device=cuda``,
paper profile unless ``--profile``), each a fresh process, one after another, so no two
jobs share the GPU. In order, each part started only while ``--budget-s`` is not spent:

1. ``--systems`` × ``--models``: one job each, ``device=cuda``, seed 0;
2. the seed batch, on ``--batch-system`` for each of ``--batch-models``:
   ``-m seed=0,1,2 device=cuda`` (three jobs in one process, the basic launcher) and the
   same with ``seeds_per_job=3`` (one job training the three seeds as one batch); the
   three seeds' datasets are generated into the cache first, so neither side pays for
   them (the batch table shows each side's ``data_s``);
3. the CPU baseline on this host: ``--cpu-system`` × ``--models`` with ``device=cpu``
   (``threads=1``, as the published records ran).

The tables compare each GPU job's record with (a) this host's ``device=cpu`` record of the
same job, where part 3 ran it, and (b) the published record of the same job
(``results/records/<system>/<model>/seed0``), which ran on the project's 2-core CPU
machine. Ratios are CPU time / GPU time of the record's ``fit_s`` (training) and
``total_s`` (the job: data, compilation, training, evaluation, rollouts); > 1 means the
GPU is faster. The seed batch's ratio is the wall time of the three separate jobs'
process over the batch's.

Records land under ``DIR/<part>/...`` as the CLI writes them (``save_model=false``);
``DIR/summary.md`` holds the tables, ``DIR/environment.txt`` what the host has (read
in a child process, so this process never holds the GPU), ``DIR/walls.json`` and
``DIR/exits.json`` each job's wall seconds and exit status. The script exits 1 when a
job it started failed or ran past ``--job-timeout-s``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
PUBLISHED = REPO / "results" / "records"
SEEDS = (0, 1, 2)


def _hnnbench() -> list[str]:
    """The CLI, as this interpreter runs it (a console script may not be on PATH)."""
    return [
        sys.executable,
        "-c",
        "import sys; from hnnbench._entry.command import main; sys.exit(main())",
    ]


#: Each job's environment: progress lines in its log, and JAX allocating GPU memory as
#: it needs it rather than 75 % of the card up front.
JOB_ENV = {"HNNBENCH_PROGRESS": "log", "XLA_PYTHON_CLIENT_PREALLOCATE": "false"}


def _run(args: list[str], log: Path, timeout_s: float) -> tuple[float, int]:
    """Run the CLI with ``args``; its output to ``log``. Returns (wall s, exit status;
    124 when it ran past ``timeout_s`` and was killed)."""
    start = time.perf_counter()
    with log.open("w") as out:
        try:
            rc = subprocess.run(
                [*_hnnbench(), *args],
                stdout=out,
                stderr=subprocess.STDOUT,
                env={**os.environ, **JOB_ENV},
                timeout=timeout_s,
                cwd=REPO,
            ).returncode
        except subprocess.TimeoutExpired:
            rc = 124
    return time.perf_counter() - start, rc


_ENVIRONMENT = """
import os, platform
print(f"XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r}")
print(f"python {platform.python_version()} on {platform.machine()}, {os.cpu_count()} CPUs")
try:
    import torch
    gpu = torch.cuda.get_device_name(0) if torch.cuda.is_available() else "no GPU"
    print(f"torch {torch.__version__}, CUDA {torch.version.cuda}, {gpu}")
except Exception as exc:
    print(f"torch: {exc!r}")
try:
    import jax
    print(f"jax {jax.__version__}, devices {jax.devices()}")
except Exception as exc:
    print(f"jax: {exc!r}")
"""


def environment() -> str:
    """Python, torch (CUDA, the GPU's name) and JAX (its devices), as a job sees them:
    read in a child process, so that this process starts no GPU backend."""
    proc = subprocess.run(
        [sys.executable, "-c", _ENVIRONMENT],
        capture_output=True,
        text=True,
        env={**os.environ, **JOB_ENV},
        cwd=REPO,
        check=False,
    )
    return (proc.stdout + proc.stderr[-500:]).strip()


def warm_datasets(system: str, model: str, seeds: tuple[int, ...]) -> None:
    """Generate ``system``'s datasets and evaluation sets of ``seeds`` into the cache
    (a child process, the CPU only), as a job would."""
    code = (
        "import functools, sys\n"
        "from hnnbench._running import dataset_cache as cache\n"
        "from hnnbench._running.compose import compose\n"
        "from hnnbench._running.config import prepare_job\n"
        "from hnnbench._contracts.plugin import Dataset, Trajectories\n"
        f"job = prepare_job(compose(['system={system}', 'model={model}']))\n"
        "system = job.system_cls(job.system_cfg)\n"
        f"for seed in {list(seeds)}:\n"
        "    cache.cached(system, seed, 'dataset', functools.partial(system.dataset, seed),\n"
        "                 Dataset.load)\n"
        "    cache.cached(system, seed, 'evaluation',\n"
        "                 functools.partial(system.evaluation, seed), Trajectories.load)\n"
    )
    subprocess.run(
        [sys.executable, "-c", code], check=True, cwd=REPO, env={**os.environ, **JOB_ENV}
    )


def _records(directory: Path) -> list[dict[str, Any]]:
    """Every record under ``directory``, in path order."""
    return [json.loads(p.read_text()) for p in sorted(directory.rglob("result.json"))]


#: Beside a run's records: what the published CPU records of its jobs held when it ran
#: (their timings and test loss), so that its tables stay what they were when the
#: leaderboard is re-published (``--freeze-published``).
FROZEN = "published.json"


def _published(
    system: str, model: str, seed: int = 0, out: Path | None = None
) -> dict[str, Any] | None:
    """The published (CPU) record of the job as the run at ``out`` compared it (its
    frozen copy), else as results/records holds it now; None when there is none."""
    frozen = out / FROZEN if out is not None else None
    if frozen is not None and frozen.is_file():
        return json.loads(frozen.read_text()).get(f"{system}/{model}/seed{seed}")
    path = PUBLISHED / system / model / f"seed{seed}" / "result.json"
    return json.loads(path.read_text()) if path.is_file() else None


def freeze_published(out: Path, rev: str | None = None) -> Path:
    """Write ``out/published.json``: for each job of the run's GPU records, the
    published record's status, timings and test loss, from results/records as it is now or at
    git revision ``rev``."""
    import subprocess

    kept: dict[str, Any] = {}
    for rec in _records(out / "gpu"):
        key = f"{rec['system']}/{rec['model']}/seed{rec.get('seed', 0)}"
        relative = f"results/records/{key}/result.json"
        if rev is None:
            path = REPO / relative
            text = path.read_text() if path.is_file() else None
        else:
            proc = subprocess.run(
                ["git", "show", f"{rev}:{relative}"], cwd=REPO, capture_output=True, text=True
            )
            text = proc.stdout if proc.returncode == 0 else None
        if text is None:
            continue
        full = json.loads(text)
        test_loss = (full.get("metrics") or {}).get("test_loss")
        kept[key] = {
            "status": full.get("status"),
            "timings": {k: (full.get("timings") or {}).get(k) for k in ("fit_s", "total_s")},
            "metrics": {"test_loss": test_loss} if test_loss is not None else {},
            "environment": {"git_commit": (full.get("environment") or {}).get("git_commit")},
        }
    path = out / FROZEN
    path.write_text(json.dumps(kept, indent=1, sort_keys=True) + "\n")
    return path


def measure(args: argparse.Namespace) -> int:
    """Run the three parts (module docstring) into ``args.out``; print and write the
    tables. Returns 1 if a job failed or was stopped at its limit, else 0."""
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    env_text = environment()
    (out / "environment.txt").write_text(env_text + "\n")
    print(env_text, flush=True)
    start = time.perf_counter()
    common = [f"profile={args.profile}", "save_model=false"]
    walls: dict[str, float] = {}
    exits: dict[str, int] = {}

    def budget_left(what: str) -> bool:
        spent = time.perf_counter() - start
        if spent > args.budget_s:
            print(
                f"skipped ({spent:.0f} s of the {args.budget_s:.0f} s budget spent): {what}",
                flush=True,
            )
            return False
        return True

    def job(part: str, name: str, overrides: list[str], multirun: bool = False) -> None:
        if not budget_left(f"{part}/{name}"):
            return
        directory = out / part / name
        directory.parent.mkdir(parents=True, exist_ok=True)
        key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
        argv = (["-m"] if multirun else []) + [*overrides, *common, f"{key}={directory}"]
        wall, rc = _run(argv, out / part / f"{name}.log", args.job_timeout_s)
        walls[f"{part}/{name}"] = wall
        exits[f"{part}/{name}"] = rc
        print(
            f"[{time.perf_counter() - start:6.0f} s] {part}/{name}: exit {rc}, {wall:.1f} s wall",
            flush=True,
        )

    for system in args.systems:
        for model in args.models:
            job(
                "gpu",
                f"{system}-{model}",
                [f"system={system}", f"model={model}", "seed=0", f"device={args.device}"],
            )
    if args.batch_models and budget_left("the seed batch's datasets"):
        warm_datasets(args.batch_system, args.batch_models[0], SEEDS)
    for model in args.batch_models:
        seeds = "seed=" + ",".join(map(str, SEEDS))
        base = [f"system={args.batch_system}", f"model={model}", seeds, f"device={args.device}"]
        job("batch", f"{model}-separate", base, multirun=True)
        job(
            "batch",
            f"{model}-seeds_per_job3",
            [*base, f"seeds_per_job={len(SEEDS)}"],
            multirun=True,
        )
    for model in args.models if args.cpu_models is None else args.cpu_models:
        job(
            "cpu",
            f"{args.cpu_system}-{model}",
            [f"system={args.cpu_system}", f"model={model}", "seed=0", "device=cpu"],
        )
    (out / "walls.json").write_text(json.dumps(walls, indent=1) + "\n")
    (out / "exits.json").write_text(json.dumps(exits, indent=1) + "\n")
    freeze_published(out)
    summarize(out)
    failed = sorted(k for k, rc in exits.items() if rc != 0)
    if failed:
        print(
            f"{len(failed)} job(s) failed or ran past the limit: {', '.join(failed)}",
            file=sys.stderr,
        )
    return 1 if failed else 0


def _ratio(cpu: float | None, gpu: float | None) -> str:
    """``cpu / gpu`` as ``1.23×``; ``—`` where either is missing."""
    return f"{cpu / gpu:.2f}×" if cpu and gpu else "—"


def _t(rec: dict[str, Any] | None, key: str) -> float | None:
    """A timing (seconds) of an ``ok`` record, else None."""
    if not rec or rec.get("status") != "ok":
        return None
    value = rec.get("timings", {}).get(key)
    return float(value) if value is not None else None


def _s(value: float | None) -> str:
    """Seconds to one decimal; ``—`` for None."""
    return f"{value:.1f}" if value is not None else "—"


def summarize(out: Path) -> str:
    """The tables, from the records under ``out``; written to ``out/summary.md``."""

    def read(name: str) -> dict[str, Any]:
        path = out / name
        return json.loads(path.read_text()) if path.is_file() else {}

    walls, exits = read("walls.json"), read("exits.json")
    host_cpu = {(r["system"], r["model"]): r for r in _records(out / "cpu")}
    lines = [
        "| system | model | GPU status | device | GPU fit s | GPU total s "
        "| this host's CPU fit / total s | fit: CPU / GPU (this host) "
        "| published CPU fit / total s | fit: CPU / GPU (published) "
        "| total: CPU / GPU (published) | test loss GPU / published |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for rec in _records(out / "gpu"):
        system, model = rec["system"], rec["model"]
        pub, host = _published(system, model, out=out), host_cpu.get((system, model))
        losses = [
            ((r or {}).get("metrics", {}).get("test_loss") or {}).get("mean") for r in (rec, pub)
        ]
        loss_text = " / ".join(f"{v:.3g}" if isinstance(v, float) else "—" for v in losses)
        lines.append(
            f"| {system} | {model} | {rec['status']} | {rec.get('device')} "
            f"| {_s(_t(rec, 'fit_s'))} | {_s(_t(rec, 'total_s'))} "
            f"| {_s(_t(host, 'fit_s'))} / {_s(_t(host, 'total_s'))} "
            f"| {_ratio(_t(host, 'fit_s'), _t(rec, 'fit_s'))} "
            f"| {_s(_t(pub, 'fit_s'))} / {_s(_t(pub, 'total_s'))} "
            f"| {_ratio(_t(pub, 'fit_s'), _t(rec, 'fit_s'))} "
            f"| {_ratio(_t(pub, 'total_s'), _t(rec, 'total_s'))} | {loss_text} |"
        )
    recorded = {f"{r['system']}-{r['model']}" for r in _records(out / "gpu")}
    for key, wall in sorted(walls.items()):
        part, name = key.split("/", 1)
        if part == "gpu" and name not in recorded:
            system, model = name.split("-", 1)
            rc = exits.get(key)
            how = ("stopped at the job limit" if rc == 124 else f"exit {rc}") if rc else ""
            lines.append(
                f"| {system} | {model} | no record: the process ran {wall:.1f} s"
                f"{', ' + how if how else ''} (see its log) |" + " — |" * 9
            )
    lines += [
        "",
        "| model | three separate jobs: wall s | seeds_per_job=3: wall s "
        "| throughput ratio | data s in them (separate / batch) "
        "| records (separate / batch) |",
        "|---|---|---|---|---|---|",
    ]
    for key in sorted(walls):
        part, name = key.split("/", 1)
        if part != "batch" or not name.endswith("-separate"):
            continue
        model = name[: -len("-separate")]
        sep, bat = walls.get(key), walls.get(f"batch/{model}-seeds_per_job3")
        r_sep = _records(out / "batch" / name)
        r_bat = _records(out / "batch" / f"{model}-seeds_per_job3")
        data = [sum(_t(r, "data_s") or 0.0 for r in rs) for rs in (r_sep, r_bat)]
        statuses = [",".join(r["status"] for r in rs) or "—" for rs in (r_sep, r_bat)]
        lines.append(
            f"| {model} | {_s(sep)} | {_s(bat)} | {_ratio(sep, bat)} "
            f"| {data[0]:.1f} / {data[1]:.1f} | {statuses[0]} / {statuses[1]} |"
        )
    text = "\n".join(lines) + "\n"
    (out / "summary.md").write_text(text)
    print(text, flush=True)
    return text


def main() -> int:
    """The command line (module docstring)."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", help="where the records and summary go")
    parser.add_argument("--summarize", metavar="DIR", help="print the tables of a finished run")
    parser.add_argument("--profile", default="paper")
    parser.add_argument("--systems", nargs="*", default=["two_body", "pixel_pendulum"])
    parser.add_argument(
        "--models", nargs="+", default=["hnn_torch", "hnn_jax", "mlp_torch", "mlp_jax"]
    )
    parser.add_argument(
        "--device", default="cuda", help="the device of parts 1 and 2 (cpu to try the script here)"
    )
    parser.add_argument("--batch-system", default="two_body")
    parser.add_argument("--batch-models", nargs="*", default=["hnn_jax", "hnn_torch"])
    parser.add_argument("--cpu-system", default="two_body")
    parser.add_argument(
        "--cpu-models",
        nargs="*",
        default=None,
        help="the models of part 3 (default: --models; none: skip it)",
    )
    parser.add_argument(
        "--budget-s",
        type=float,
        default=480.0,
        help="start no job after this many seconds (default 480)",
    )
    parser.add_argument("--job-timeout-s", type=float, default=240.0)
    parser.add_argument(
        "--freeze-published",
        metavar="DIR",
        help="write DIR/published.json: the published CPU records its tables compare with",
    )
    parser.add_argument("--at", metavar="REV", help="with --freeze-published: a git revision")
    args = parser.parse_args()
    if args.freeze_published:
        print(freeze_published(Path(args.freeze_published), args.at))
        return 0
    if args.summarize:
        summarize(Path(args.summarize))
        return 0
    if not args.out:
        parser.error("--out DIR is required (or --summarize DIR)")
    return measure(args)


if __name__ == "__main__":
    raise SystemExit(main())
