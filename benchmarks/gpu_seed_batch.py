"""Every JAX family's ten seeds as one compiled program on a GPU, several pairs at once on
the device, against the CPU records of the same jobs (issue 52).

    python benchmarks/gpu_seed_batch.py --out DIR            # on the GPU machine
    python benchmarks/gpu_seed_batch.py --summarize DIR --cpu RECORDS_DIR [--plan]

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
   defaults to (hnnbench turns it off on GPUs), its ``compile_s`` against part 1's.

``--summarize`` (here, with the CPU records, e.g. results/records or a re-publication's
sweep) prints per pair: the device's wall time, training time of the batch, compilation,
evaluation, against the CPU records' time for the same ten seeds; whether every seed's
metrics agree with its CPU record within the tolerance twins are held to (each metric's
``CheckRule``, both directions, as ``hnnbench check --rerun``); and with ``--plan`` an
extrapolation of the whole protocol plan's device time (every system, the JAX twin of
every family, seeds 0-9) from the measured ratios: an extrapolation, stated as one.

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
from typing import Any

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
        queue, running = list(jobs), []
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
    pairs = [
        (
            f"pair-{system}-{model}",
            [
                "-m",
                f"system={system}",
                f"model={model}",
                f"seed={seeds}",
                f"seeds_per_job={args.seeds}",
                *common,
                f"hydra.sweep.dir={out / 'pairs' / f'{system}-{model}'}",
            ],
            _env(args.parallel),
        )
        for model in order
        for system in args.systems
    ]
    run_all(pairs, args.parallel)
    if args.autotune_pair:
        system, model = args.autotune_pair.split(":")
        run_all(
            [
                (
                    f"autotune-{system}-{model}",
                    [
                        "-m",
                        f"system={system}",
                        f"model={model}",
                        f"seed={seeds}",
                        f"seeds_per_job={args.seeds}",
                        *common,
                        f"hydra.sweep.dir={out / 'autotune' / f'{system}-{model}'}",
                    ],
                    _env(1, {"XLA_FLAGS": "--xla_gpu_autotune_level=4"}),
                )
            ],
            1,
        )
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


def summarize(out: Path, cpu_dir: Path, plan: bool) -> str:
    out = Path(out)
    walls = json.loads((out / "walls.json").read_text()) if (out / "walls.json").is_file() else {}
    gpu = _records(out / "pairs")
    cpu = _records(Path(cpu_dir))
    declared = _tolerances()
    lines = [
        "| system | model | seeds ok | device wall s | batch fit s | compile s | eval s "
        "| CPU total s (the same jobs) | CPU / device | metrics within twin tolerance |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    ratios: dict[str, list[float]] = {}
    pairs = sorted({(s, m) for s, m, _ in gpu})
    for system, model in pairs:
        seeds = sorted(k for s, m, k in gpu if (s, m) == (system, model))
        recs = [gpu[(system, model, k)] for k in seeds]
        ok = sum(r.get("status") == "ok" for r in recs)
        wall = walls.get(f"pair-{system}-{model}")
        timings = [r.get("timings") or {} for r in recs]
        fit = max((t.get("batch_fit_s", 0.0) for t in timings), default=0.0)
        compile_s = max((t.get("compile_s", 0.0) for t in timings), default=0.0)
        eval_s = sum(t.get("eval_s", 0.0) for t in timings)
        twins = [cpu.get((system, model, k)) for k in seeds]
        cpu_total = sum((c.get("timings") or {}).get("total_s", 0.0) for c in twins if c)
        have = [(g, c) for g, c in zip(recs, twins, strict=True) if c]
        bad = [(g["seed"], d) for g, c in have for d in _agree(g, c, declared)]
        agree = f"{len(have) - len({s for s, _ in bad})}/{len(have)} seeds" + (
            f" (off: {'; '.join(f'seed {s}: {d}' for s, d in bad[:3])})" if bad else ""
        )
        ratio = cpu_total / wall if wall and cpu_total else math.nan
        if math.isfinite(ratio):
            ratios.setdefault(model, []).append(ratio)
        lines.append(
            f"| {system} | {model} | {ok}/{len(recs)} | "
            f"{wall or math.nan:.1f} | {fit:.1f} | {compile_s:.1f} | {eval_s:.1f} | "
            f"{cpu_total:.0f} | {ratio:.2f}× | {agree} |"
        )
    auto = _records(out / "autotune")
    if auto:
        (system, model, _), rec = next(iter(auto.items()))
        base = gpu.get((system, model, 0))
        lines += [
            "",
            f"Autotuning ({system} {model}): compile "
            f"{(rec.get('timings') or {}).get('compile_s', math.nan):.1f} s at XLA's "
            f"default level against "
            f"{((base or {}).get('timings') or {}).get('compile_s', math.nan):.1f} s "
            "with hnnbench's (off).",
        ]
    if plan and ratios:
        lines += ["", _extrapolation(ratios)]
    text = "\n".join(lines)
    return text


def _extrapolation(ratios: dict[str, list[float]]) -> str:
    """The whole protocol plan's device time, extrapolated from the measured CPU / device
    ratios per family (their geometric mean over the systems measured) applied to the
    published CPU job costs (hnnbench/resources/job_costs.csv) of every system."""
    import csv

    costs = REPO / "hnnbench" / "resources" / "job_costs.csv"
    if not costs.is_file():
        found = list(REPO.glob("hnnbench/**/job_costs.csv"))
        if not found:
            return "No job costs to extrapolate from."
        costs = found[0]
    cpu_s = device_s = 0.0
    for row in csv.DictReader(costs.open()):
        model = row["model"]
        if row["profile"] != "paper" or model not in ratios:
            continue
        seconds = float(row["seconds"]) * PLAN_SEEDS
        ratio = math.exp(statistics.fmean(math.log(r) for r in ratios[model]))
        cpu_s += seconds
        device_s += seconds / ratio
    return (
        f"Extrapolation (not a measurement): the protocol plan's JAX twins (every "
        f"system, {PLAN_SEEDS} seeds) cost {cpu_s / 3600:.1f} CPU hours on the 2-core "
        f"machine's published job times; at the measured per-family ratios (geometric "
        f"mean over the systems measured) one pair at a time on the device would take "
        f"{device_s / 3600:.2f} device hours, before several pairs share it."
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--out", type=Path)
    parser.add_argument("--summarize", type=Path)
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
    args = parser.parse_args(argv)
    if args.summarize:
        print(summarize(args.summarize, args.cpu, args.plan))
        return 0
    if args.out is None:
        parser.error("--out DIR (or --summarize DIR)")
    return measure(args)


if __name__ == "__main__":
    raise SystemExit(main())
