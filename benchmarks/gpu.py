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
   same with ``seeds_per_job=3`` (one job training the three seeds as one batch);
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
``DIR/summary.md`` holds the tables and ``DIR/environment.txt`` what the host has.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
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
    return [sys.executable, "-c", "import sys; from hnnbench._cli import main; sys.exit(main())"]


def _run(args: list[str], log: Path, timeout_s: float) -> tuple[float, int]:
    """Run the CLI with ``args``; its output to ``log``. Returns (wall s, exit status)."""
    env = {**os.environ, "HNNBENCH_PROGRESS": "log", "XLA_PYTHON_CLIENT_PREALLOCATE": "false"}
    start = time.perf_counter()
    with log.open("w") as out:
        try:
            rc = subprocess.run([*_hnnbench(), *args], stdout=out, stderr=subprocess.STDOUT,
                                env=env, timeout=timeout_s, cwd=REPO).returncode
        except subprocess.TimeoutExpired:
            rc = 124
    return time.perf_counter() - start, rc


def _records(directory: Path) -> list[dict[str, Any]]:
    return [json.loads(p.read_text()) for p in sorted(directory.rglob("result.json"))]


def _published(system: str, model: str, seed: int = 0) -> dict[str, Any] | None:
    path = PUBLISHED / system / model / f"seed{seed}" / "result.json"
    return json.loads(path.read_text()) if path.is_file() else None


def environment() -> str:
    lines = [f"XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r}",
             f"python {platform.python_version()} on {platform.machine()}, "
             f"{os.cpu_count()} CPUs"]
    try:
        import torch
        lines.append(f"torch {torch.__version__}, CUDA {torch.version.cuda}, "
                     f"available {torch.cuda.is_available()}"
                     + (f", {torch.cuda.get_device_name(0)}" if torch.cuda.is_available()
                        else ""))
    except Exception as exc:  # noqa: BLE001 - a report of what is there
        lines.append(f"torch: {exc!r}")
    try:
        import jax
        lines.append(f"jax {jax.__version__}, devices {jax.devices()}")
    except Exception as exc:  # noqa: BLE001
        lines.append(f"jax: {exc!r}")
    return "\n".join(lines)


def measure(args: argparse.Namespace) -> None:
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    (out / "environment.txt").write_text(environment() + "\n")
    print(environment(), flush=True)
    start = time.perf_counter()
    common = [f"profile={args.profile}", "save_model=false"]
    walls: dict[str, float] = {}

    def budget_left(what: str) -> bool:
        spent = time.perf_counter() - start
        if spent > args.budget_s:
            print(f"skipped ({spent:.0f} s of the {args.budget_s:.0f} s budget spent): {what}",
                  flush=True)
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
        print(f"[{time.perf_counter() - start:6.0f} s] {part}/{name}: exit {rc}, "
              f"{wall:.1f} s wall", flush=True)

    for system in args.systems:
        for model in args.models:
            job("gpu", f"{system}-{model}",
                [f"system={system}", f"model={model}", "seed=0", f"device={args.device}"])
    for model in args.batch_models:
        seeds = "seed=" + ",".join(map(str, SEEDS))
        base = [f"system={args.batch_system}", f"model={model}", seeds, f"device={args.device}"]
        job("batch", f"{model}-separate", base, multirun=True)
        job("batch", f"{model}-seeds_per_job3", [*base, f"seeds_per_job={len(SEEDS)}"],
            multirun=True)
    for model in args.models if args.cpu_models is None else args.cpu_models:
        job("cpu", f"{args.cpu_system}-{model}",
            [f"system={args.cpu_system}", f"model={model}", "seed=0", "device=cpu"])
    (out / "walls.json").write_text(json.dumps(walls, indent=1) + "\n")
    summarize(out)


def _ratio(cpu: float | None, gpu: float | None) -> str:
    return f"{cpu / gpu:.2f}×" if cpu and gpu else "—"


def _t(rec: dict[str, Any] | None, key: str) -> float | None:
    if not rec or rec.get("status") != "ok":
        return None
    value = rec.get("timings", {}).get(key)
    return float(value) if value is not None else None


def _s(value: float | None) -> str:
    return f"{value:.1f}" if value is not None else "—"


def summarize(out: Path) -> str:
    """The tables, from the records under ``out``; written to ``out/summary.md``."""
    walls = json.loads((out / "walls.json").read_text()) if (out / "walls.json").is_file() else {}
    host_cpu = {(r["system"], r["model"]): r for r in _records(out / "cpu")}
    lines = ["| system | model | GPU status | device | GPU fit s | GPU total s "
             "| this host's CPU fit / total s | fit: CPU / GPU (this host) "
             "| published CPU fit / total s | fit: CPU / GPU (published) "
             "| total: CPU / GPU (published) | test loss GPU / published |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for rec in _records(out / "gpu"):
        system, model = rec["system"], rec["model"]
        pub, host = _published(system, model), host_cpu.get((system, model))
        losses = [((r or {}).get("metrics", {}).get("test_loss") or {}).get("mean")
                  for r in (rec, pub)]
        loss_text = " / ".join(f"{v:.3g}" if isinstance(v, float) else "—" for v in losses)
        lines.append(
            f"| {system} | {model} | {rec['status']} | {rec.get('device')} "
            f"| {_s(_t(rec, 'fit_s'))} | {_s(_t(rec, 'total_s'))} "
            f"| {_s(_t(host, 'fit_s'))} / {_s(_t(host, 'total_s'))} "
            f"| {_ratio(_t(host, 'fit_s'), _t(rec, 'fit_s'))} "
            f"| {_s(_t(pub, 'fit_s'))} / {_s(_t(pub, 'total_s'))} "
            f"| {_ratio(_t(pub, 'fit_s'), _t(rec, 'fit_s'))} "
            f"| {_ratio(_t(pub, 'total_s'), _t(rec, 'total_s'))} | {loss_text} |")
    recorded = {f"{r['system']}-{r['model']}" for r in _records(out / "gpu")}
    for key, wall in sorted(walls.items()):
        part, name = key.split("/", 1)
        if part == "gpu" and name not in recorded:
            system, model = name.split("-", 1)
            lines.append(f"| {system} | {model} | no record: the process ran {wall:.1f} s "
                         "(see its log) |" + " — |" * 9)
    lines += ["", "| model | three separate jobs: wall s | seeds_per_job=3: wall s "
              "| throughput ratio | records (separate / batch) |", "|---|---|---|---|---|"]
    for key in sorted(walls):
        part, name = key.split("/", 1)
        if part != "batch" or not name.endswith("-separate"):
            continue
        model = name[: -len("-separate")]
        sep, bat = walls.get(key), walls.get(f"batch/{model}-seeds_per_job3")
        n_sep = [r["status"] for r in _records(out / "batch" / name)]
        n_bat = [r["status"] for r in _records(out / "batch" / f"{model}-seeds_per_job3")]
        lines.append(f"| {model} | {_s(sep)} | {_s(bat)} | {_ratio(sep, bat)} "
                     f"| {','.join(n_sep) or '—'} / {','.join(n_bat) or '—'} |")
    text = "\n".join(lines) + "\n"
    (out / "summary.md").write_text(text)
    print(text, flush=True)
    return text


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", help="where the records and summary go")
    parser.add_argument("--summarize", metavar="DIR", help="print the tables of a finished run")
    parser.add_argument("--profile", default="paper")
    parser.add_argument("--systems", nargs="*", default=["two_body", "pixel_pendulum"])
    parser.add_argument("--models", nargs="+",
                        default=["hnn_torch", "hnn_jax", "mlp_torch", "mlp_jax"])
    parser.add_argument("--device", default="cuda",
                        help="the device of parts 1 and 2 (cpu to try the script here)")
    parser.add_argument("--batch-system", default="two_body")
    parser.add_argument("--batch-models", nargs="*", default=["hnn_jax", "hnn_torch"])
    parser.add_argument("--cpu-system", default="two_body")
    parser.add_argument("--cpu-models", nargs="*", default=None,
                        help="the models of part 3 (default: --models; none: skip it)")
    parser.add_argument("--budget-s", type=float, default=480.0,
                        help="start no job after this many seconds (default 480)")
    parser.add_argument("--job-timeout-s", type=float, default=240.0)
    args = parser.parse_args()
    if args.summarize:
        summarize(Path(args.summarize))
        return 0
    if not args.out:
        parser.error("--out DIR is required (or --summarize DIR)")
    measure(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
