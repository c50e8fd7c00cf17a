"""Every JAX family's ten seeds as one compiled program on a GPU, several pairs at once on
the device, against the CPU records of the same jobs (issue 52).

    python benchmarks/gpu_seed_batch.py --out DIR            # on the GPU machine
    python benchmarks/gpu_seed_batch.py --summarize DIR [DIR ...] [--cpu RECORDS_DIR] [--plan]
        [--freeze-cpu]

Parts, in order, each started only while ``--budget-s`` is not spent:

0. the datasets and evaluation sets of every system's seeds, generated into the cache by
   the standing-still reference (a cheap job per seed, ``--parallel`` processes at once),
   so no pair pays for them;
1. the pairs: for each ``--systems`` × ``--models``, the command a user runs,
   ``hnnbench -m system=S model=M seed=0,...,9 seeds_per_job=10 device=cuda``: one job
   training the ten seeds as one batch (``jax.vmap`` inside the compiled ``lax.scan``),
   each seed evaluated and recorded as a job of its own would be. ``--parallel`` pairs
   share the device at a time (``device_share=parallel``: each process takes a slot of
   the GPU and ``0.9 / parallel`` of its memory), the dearest pairs first;
2. XLA's kernel autotuning: ``--autotune-pair`` again with the autotuning level XLA
   defaults to (hnnbench turns it off on GPUs), its ``compile_s`` against part 1's. It is
   queued first among the pairs (a cheap pair), so the budget never skips it; it shares
   the device with the pairs as they do with each other.

``--summarize`` (here, with the CPU records, e.g. results/records or a re-publication's
sweep) prints per pair: the device's wall time, training time of the batch, compilation,
evaluation, against the CPU records' time for the same ten seeds; whether every seed's
metrics agree with its CPU record within the tolerance twins are held to (each metric's
``CheckRule``, both directions, as ``hnnbench check --rerun``); and with ``--plan`` an
extrapolation of the whole protocol plan's device time (every system, the JAX twin of
every family, seeds 0-9) from the measured ratios: an extrapolation, stated as one.
``--freeze-cpu`` first writes ``DIR/cpu_records.json`` (what the table reads of each CPU
record compared with); a folder that has one is compared with it, not with ``--cpu``, so
a committed table does not move when the leaderboard is re-published.

Output under ``DIR``: ``pairs/<S>-<M>/`` (the sweeps), ``*.log``, ``walls.json``,
``exits.json``, ``environment.txt``; ``--pack FILE`` writes every record, log and json
(no rollouts or weights) into one tar.gz, the one file a device call brings back.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tarfile
import time
from pathlib import Path
from typing import Any, Optional

REPO = Path(__file__).resolve().parents[1]
JAX_TWINS = ("mlp_jax", "hnn_jax", "dhnn_jax", "lnn_jax", "so_mlp_jax", "srnn_jax")
#: Most expensive first (measured CPU cost order of the published protocol), so the
#: longest pairs start early when several share the device.
DEAREST_FIRST = ("srnn_jax", "lnn_jax", "dhnn_jax", "hnn_jax", "mlp_jax", "so_mlp_jax")
#: The protocol plan the extrapolation covers.
PLAN_SEEDS = 10


def _hnnbench() -> list[str]:
    code = "import sys; from hnnbench._entry.command import main; sys.exit(main())"
    return [sys.executable, "-c", code]


def _env(parallel: int, extra: dict[str, str] | None = None) -> dict[str, str]:
    """A job's environment: progress lines, and JAX taking ``0.9 / parallel`` of the
    device's memory as it needs it (what ``device_share=parallel`` sets, here for every
    part, the single autotuning pair too: the conditions of the earlier runs)."""
    env = {
        **os.environ,
        "HNNBENCH_PROGRESS": "log",
        "XLA_PYTHON_CLIENT_PREALLOCATE": "false",
        "XLA_PYTHON_CLIENT_MEM_FRACTION": f"{0.9 / max(1, parallel):.4f}",
        # every compilation timed as on a fresh machine (no persistent cache hits)
        "JAX_ENABLE_COMPILATION_CACHE": "false",
    }
    env.update(extra or {})
    return env


def _environment(out: Path) -> str:
    code = (
        "import platform, os\n"
        "print('python', platform.python_version(), os.cpu_count(), 'CPUs')\n"
        "import jax\nprint('jax', jax.__version__, jax.devices())\n"
        "import hnnbench\nprint('hnnbench', getattr(hnnbench, '__version__', '?'))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        env=_env(1),
        cwd=REPO,
        check=False,
    )
    text = (proc.stdout + proc.stderr[-800:]).strip()
    try:
        smi = subprocess.run(
            ["nvidia-smi", "-L"], capture_output=True, text=True, check=False
        ).stdout
    except OSError:
        smi = "no nvidia-smi"
    text += "\n" + smi.strip()
    (out / "environment.txt").write_text(text + "\n")
    return text


def measure(args: argparse.Namespace) -> int:
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    print(_environment(out), flush=True)
    start = time.perf_counter()
    walls: dict[str, float] = {}
    exits: dict[str, int] = {}
    seeds = ",".join(str(s) for s in range(args.seeds))
    # device_share: each process sees one GPU's slot (a machine of several GPUs spreads
    # the pairs over them); the memory share is the environment's (_env).
    common = [
        f"profile={args.profile}",
        "save_model=false",
        f"device={args.device}",
        f"device_share={args.parallel}",
    ]

    def spent() -> float:
        return time.perf_counter() - start

    def launch(name: str, argv: list[str], env: dict[str, str]) -> tuple[str, Any, float]:
        log = (out / f"{name}.log").open("w")
        proc = subprocess.Popen(
            [*_hnnbench(), *argv], stdout=log, stderr=subprocess.STDOUT, env=env, cwd=REPO
        )
        return name, proc, time.perf_counter()

    def run_all(jobs: list[tuple[str, list[str], dict[str, str]]], parallel: int) -> None:
        queue = list(jobs)
        running: list[tuple[str, Any, float]] = []
        while queue or running:
            while queue and len(running) < parallel and spent() < args.budget_s:
                running.append(launch(*queue.pop(0)))
            if queue and spent() >= args.budget_s:
                for name, _, _ in queue:
                    print(
                        f"skipped ({spent():.0f} s of {args.budget_s:.0f} s spent): {name}",
                        flush=True,
                    )
                queue = []
            time.sleep(0.5)
            for item in list(running):
                name, proc, began = item
                rc = proc.poll()
                if rc is None and time.perf_counter() - began > args.job_timeout_s:
                    proc.kill()
                    rc = 124
                if rc is not None:
                    running.remove(item)
                    walls[name] = time.perf_counter() - began
                    exits[name] = rc
                    print(
                        f"[{spent():6.0f} s] {name}: exit {rc}, {walls[name]:.1f} s wall",
                        flush=True,
                    )

    warm = [
        (
            f"data-{system}",
            [
                "-m",
                f"system={system}",
                "model=standing_still",
                f"seed={seeds}",
                *common,
                f"hydra.sweep.dir={out / 'data' / system}",
            ],
            _env(args.parallel),
        )
        for system in args.systems
    ]
    run_all(warm, args.parallel)
    order = [m for m in DEAREST_FIRST if m in args.models] + [
        m for m in args.models if m not in DEAREST_FIRST
    ]

    def batch(
        part: str, system: str, model: str, env: dict[str, str]
    ) -> tuple[str, list[str], dict[str, str]]:
        """The user's command for one pair, its ten seeds as one batch."""
        argv = ["-m", f"system={system}", f"model={model}", f"seed={seeds}"]
        argv += [f"seeds_per_job={args.seeds}", *common]
        argv += [f"hydra.sweep.dir={out / part / f'{system}-{model}'}"]
        return f"{part.rstrip('s')}-{system}-{model}", argv, env

    pairs = [
        batch("pairs", system, model, _env(args.parallel))
        for model in order
        for system in args.systems
    ]
    if args.autotune_pair:
        system, model = args.autotune_pair.split(":")
        autotune = _env(args.parallel, {"XLA_FLAGS": "--xla_gpu_autotune_level=4"})
        pairs.insert(0, batch("autotune", system, model, autotune))
    run_all(pairs, args.parallel)
    (out / "walls.json").write_text(json.dumps(walls, indent=1) + "\n")
    (out / "exits.json").write_text(json.dumps(exits, indent=1) + "\n")
    print(f"done in {spent():.0f} s", flush=True)
    if args.pack:
        pack(out, Path(args.pack))
    failed = sorted(k for k, rc in exits.items() if rc != 0)
    return 1 if failed else 0


def pack(out: Path, target: Path) -> None:
    """Every record, log, json and text file under ``out`` (no arrays) into ``target``."""
    target.parent.mkdir(parents=True, exist_ok=True)
    with tarfile.open(target, "w:gz") as tar:
        for path in sorted(out.rglob("*")):
            if path.is_file() and path.suffix in (".json", ".log", ".txt", ".yaml", ".csv"):
                tar.add(path, arcname=str(path.relative_to(out.parent)))


# --------------------------------------------------------------------------- summary


def _records(directory: Path) -> dict[tuple[str, str, int], dict[str, Any]]:
    out = {}
    for path in sorted(directory.rglob("result.json")):
        rec = json.loads(path.read_text())
        out[(rec["system"], rec["model"], int(rec["seed"]))] = rec
    return out


#: Beside a run folder: the CPU records its table compared with, as they were when it was
#: summarized (``--freeze-cpu``), so the committed table does not move when the
#: leaderboard is re-published.
FROZEN = "cpu_records.json"


def _slim(rec: dict[str, Any]) -> dict[str, Any]:
    """What a comparison reads of a CPU record: status, job time, metric means."""
    metrics = rec.get("metrics") or {}
    return {
        "system": rec["system"],
        "model": rec["model"],
        "seed": rec["seed"],
        "status": rec.get("status"),
        "timings": {"total_s": (rec.get("timings") or {}).get("total_s")},
        "metrics": {k: {"mean": (v or {}).get("mean")} for k, v in metrics.items()},
    }


def freeze_cpu(outs: list[Path], cpu_dir: Path) -> list[Path]:
    """Write ``cpu_records.json`` beside each run folder's records: the CPU record of
    every job it ran, from ``cpu_dir`` as it is now."""
    cpu = _records(Path(cpu_dir))
    written = []
    for out in outs:
        keys = sorted(_records(Path(out) / "pairs"))
        frozen = [_slim(cpu[k]) for k in keys if k in cpu]
        (Path(out) / FROZEN).write_text(json.dumps(frozen, indent=1) + "\n")
        written.append(Path(out) / FROZEN)
    return written


def _cpu_records(out: Path, cpu: dict[Any, dict[str, Any]]) -> dict[Any, dict[str, Any]]:
    """The frozen CPU records beside ``out`` where there are some, else ``cpu``."""
    frozen = out / FROZEN
    if not frozen.is_file():
        return cpu
    return {(r["system"], r["model"], int(r["seed"])): r for r in json.loads(frozen.read_text())}


def _tolerances() -> dict[str, Any]:
    from hnnbench import _registry as registry

    return {m.name: m for m in registry.metrics()}


def _agree(gpu: dict[str, Any], cpu: dict[str, Any], declared: dict[str, Any]) -> list[str]:
    """The metrics of a GPU record not within the twins' tolerance of its CPU record
    (``CheckRule.worsening`` within the rule's factor, both directions)."""
    bad = []
    if gpu.get("status") != cpu.get("status"):
        return [f"status {gpu.get('status')} vs {cpu.get('status')}"]
    for name, metric in declared.items():
        a = (gpu.get("metrics") or {}).get(name, {}).get("mean")
        b = (cpu.get("metrics") or {}).get(name, {}).get("mean")
        if a is None or b is None:
            continue
        a, b = float(a), float(b)
        if math.isnan(a) and math.isnan(b):
            continue
        rule = metric.check
        worse = max(rule.worsening(b, a), rule.worsening(a, b))
        if not worse <= rule.factor:
            bad.append(f"{name} {a:.3g} vs {b:.3g}")
    return bad


def _largest(recs: list[dict[str, Any]], key: str, default: float = 0.0) -> float:
    """The largest ``timings[key]`` over a pair's seed records (its slowest seed)."""
    return max(((r.get("timings") or {}).get(key, default) for r in recs), default=default)


def _table(
    out: Path, cpu: dict[Any, dict[str, Any]], declared: dict[str, Any]
) -> tuple[list[str], Optional[str], dict[str, list[tuple[float, int]]]]:
    """One run folder's table rows, its autotuning line (if it ran that part), and per
    model its (CPU / device ratio, pairs sharing)."""
    walls = json.loads((out / "walls.json").read_text()) if (out / "walls.json").is_file() else {}
    gpu = _records(out / "pairs")
    rows = []
    ratios: dict[str, list[tuple[float, int]]] = {}

    def pair(recs: dict[Any, dict[str, Any]], system: str, model: str) -> list[dict[str, Any]]:
        return [r for (s, m, _), r in sorted(recs.items()) if (s, m) == (system, model)]

    for system, model in sorted({(s, m) for s, m, _ in gpu}):
        recs = pair(gpu, system, model)
        ok = sum(r.get("status") == "ok" for r in recs)
        share = int((recs[0].get("config") or {}).get("device_share") or 1)
        wall = walls.get(f"pair-{system}-{model}")
        eval_s = sum((r.get("timings") or {}).get("eval_s", 0.0) for r in recs)
        twins = [cpu.get((system, model, int(r["seed"]))) for r in recs]
        cpu_total = sum((c.get("timings") or {}).get("total_s", 0.0) for c in twins if c)
        have = [(g, c) for g, c in zip(recs, twins, strict=True) if c]
        bad = [(g["seed"], d) for g, c in have for d in _agree(g, c, declared)]
        agree = f"{len(have) - len({s for s, _ in bad})}/{len(have)} seeds" + (
            f" (off: {'; '.join(f'seed {s}: {d}' for s, d in bad[:3])})" if bad else ""
        )
        ratio = cpu_total / wall if wall and cpu_total else math.nan
        if math.isfinite(ratio):
            ratios.setdefault(model, []).append((ratio, share))
        rows.append(
            f"| {system} | {model} | {ok}/{len(recs)} | {share} | "
            f"{wall or math.nan:.1f} | {_largest(recs, 'batch_fit_s'):.1f} | "
            f"{_largest(recs, 'compile_s'):.1f} | {eval_s:.1f} | "
            f"{cpu_total:.0f} | {ratio:.2f}× | {agree} |"
        )
    auto = _records(out / "autotune")
    note = None
    if auto:
        system, model, _ = next(iter(auto))
        tuned, base = pair(auto, system, model), pair(gpu, system, model)
        note = (
            f"Autotuning ({system} {model}, {out.name}): compile "
            f"{_largest(tuned, 'compile_s', math.nan):.1f} s and batch fit "
            f"{_largest(tuned, 'batch_fit_s', math.nan):.1f} s "
            f"at XLA's default level, against {_largest(base, 'compile_s', math.nan):.1f} s and "
            f"{_largest(base, 'batch_fit_s', math.nan):.1f} s with hnnbench's (off)."
        )
    return rows, note, ratios


def summarize(outs: list[Path], cpu_dir: Path, plan: bool) -> str:
    """Each run folder's table (in the order given; against its frozen CPU records where
    it has them, else ``cpu_dir``'s), then with ``plan`` one extrapolation from the
    ratios of them all."""
    declared = _tolerances()
    cpu: dict[Any, dict[str, Any]] = {}
    if any(not (Path(out) / FROZEN).is_file() for out in outs):
        cpu = _records(Path(cpu_dir))
    lines = [
        "| system | model | seeds ok | pairs sharing | device wall s | batch fit s "
        "| compile s | eval s | CPU total s (the same jobs) | CPU / device "
        "| metrics within twin tolerance |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    ratios: dict[str, list[tuple[float, int]]] = {}
    notes: list[str] = []
    for out in outs:
        rows, note, found = _table(Path(out), _cpu_records(Path(out), cpu), declared)
        lines += rows
        notes += [note] if note else []
        for model, values in found.items():
            ratios.setdefault(model, []).extend(values)
    lines += ["", *notes] if notes else []
    if plan and ratios:
        lines += ["", _extrapolation(ratios)]
    return "\n".join(lines)


def _extrapolation(ratios: dict[str, list[tuple[float, int]]]) -> str:
    """The whole protocol plan's device time, extrapolated: per family, its throughput is
    the CPU job time one device second did (a pair's CPU / device ratio times the pairs
    that shared the device with it; geometric mean over the pairs measured), applied to
    the published CPU job costs (hnnbench/resources/job_costs.csv) of every system."""
    import csv

    costs = REPO / "hnnbench" / "resources" / "job_costs.csv"
    if not costs.is_file():
        found = list(REPO.glob("hnnbench/**/job_costs.csv"))
        if not found:
            return "No job costs to extrapolate from."
        costs = found[0]
    cpu_s = device_s = 0.0
    shares = sorted({share for values in ratios.values() for _, share in values})
    for row in csv.DictReader(costs.open()):
        model = row["model"]
        if row["profile"] != "paper" or model not in ratios:
            continue
        seconds = float(row["seconds"]) * PLAN_SEEDS
        rate = math.exp(statistics.fmean(math.log(r * k) for r, k in ratios[model]))
        cpu_s += seconds
        device_s += seconds / rate
    return (
        f"Extrapolation (not a measurement): the protocol plan's JAX twins of "
        f"{', '.join(sorted(ratios))} (every system, {PLAN_SEEDS} seeds) cost "
        f"{cpu_s / 3600:.1f} job hours on the 2-core machine's published job times. At each "
        f"family's measured throughput (a pair's CPU / device ratio times the "
        f"{' or '.join(str(k) for k in shares)} pairs sharing the device with it, geometric "
        f"mean over the pairs measured), with as many pairs at a time and no idle tail, "
        f"the device would take {device_s / 3600:.2f} hours ({device_s / 60:.0f} min)."
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--out", type=Path)
    parser.add_argument("--summarize", type=Path, nargs="+", metavar="DIR")
    parser.add_argument("--cpu", type=Path, default=REPO / "results" / "records")
    parser.add_argument("--plan", action="store_true")
    parser.add_argument("--systems", nargs="+", default=["real_pendulum", "two_body"])
    parser.add_argument("--models", nargs="+", default=list(JAX_TWINS))
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--parallel", type=int, default=4)
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--profile", default="paper")
    parser.add_argument("--budget-s", type=float, default=420.0)
    parser.add_argument("--job-timeout-s", type=float, default=400.0)
    parser.add_argument("--autotune-pair", default="real_pendulum:mlp_jax")
    parser.add_argument("--pack", type=Path)
    parser.add_argument(
        "--freeze-cpu",
        action="store_true",
        help=f"with --summarize: first write DIR/{FROZEN}, the --cpu records compared with",
    )
    args = parser.parse_args(argv)
    if args.summarize and args.freeze_cpu:
        freeze_cpu(args.summarize, args.cpu)
    if args.summarize:
        print(summarize(args.summarize, args.cpu, args.plan))
        return 0
    if args.out is None:
        parser.error("--out DIR (or --summarize DIR)")
    return measure(args)


if __name__ == "__main__":
    raise SystemExit(main())
