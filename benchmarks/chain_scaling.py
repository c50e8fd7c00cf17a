"""Scaling with the state dimension: the spring chain at N masses (a 2N-D state).

    python benchmarks/chain_scaling.py          # N = 2 5 10 20: hnn_torch hnn_jax mlp_torch
    python benchmarks/chain_scaling.py --models hnn_torch hnn_jax mlp_torch lnn_jax
    python benchmarks/chain_scaling.py --sizes 2 5 --steps 100 --timing-steps 50 --repeats 1

The system is ``spring_chain`` (docs/SYSTEMS_SPRING_CHAIN.md) at its paper settings,
with ``system.n_masses=N`` for each ``--sizes`` value (the data, the evaluation
trajectories and the training protocol are the system's: 80 training trajectories of 51
points, batch 500, lr 1e-3; the networks' width is the same at every N, only their
input and output sizes grow). Configs are composed and validated as a run's are
(``hnnbench._running.compose.compose`` + ``prepare_job``); datasets and evaluation trajectories
come from the cache a real run uses (``$HNNBENCH_CACHE_DIR``).

For each N and model, two figures:

- **ms per training step**: one untimed ``Model.fit`` of ``--timing-steps`` steps (JAX
  compilation, torch's first-call costs), then ``--repeats`` timed fits of as many
  steps, the repeats of all models interleaved; per fit, (wall time minus the compile
  time the fit reports) / steps, and the median over the repeats. As in
  ``benchmarks/train_step.py``, the test loss is logged at the interval of the
  paper-length run, so a short fit does the work per step of a real run. The ratio
  column divides by the same model's figure at the smallest N.
- **energy MSE** after one fit of ``--steps`` steps (seed ``--seed``): the
  ``energy_mse`` metric (docs/METRICS.md) on the evaluation trajectories, computed by
  ``hnnbench._running.evaluation.evaluate`` as a job does (batched float64 rollout at the harness
  tolerances), timed as "eval s" (which includes, for JAX, compiling the rollout). A
  rollout that diverges is reported as such.

One thread per process, and the process is pinned to one core (``--no-pin`` to leave it
free), as train_step.py does. The load average is printed first: on a shared machine the
absolute times are inflated and only the ratios measured side by side mean much.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import statistics
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Optional

os.environ.setdefault("OMP_NUM_THREADS", "1")

SYSTEM = "spring_chain"
HEADER = (
    "| N | state dim | model | batch | ms/step median | ms/step vs N={base} | "
    "JAX compile s | energy MSE after {steps} steps | eval s |"
)


@dataclass
class Cell:
    """One (N, model)."""

    n: int
    model: str
    job: Any
    system: Any
    data: Any
    traj: Any
    train: Any  # the paper protocol, steps replaced per fit
    cfg: Any  # the model config, logging at the paper run's interval
    ev: Any  # evaluation tolerances
    batch: int = 0
    times_ms: list[float] = field(default_factory=list)
    compile_s: float = 0.0
    energy_mse: Optional[float] = None
    status: str = ""
    eval_s: float = float("nan")

    @property
    def median(self) -> float:
        return statistics.median(self.times_ms) if self.times_ms else float("nan")


def prepare(n: int, model_name: str, overrides: Sequence[str]) -> Cell:
    """Compose, validate and load the data of one (N, model)."""
    from omegaconf import OmegaConf

    from hnnbench._contracts.errors import ConfigError
    from hnnbench._contracts.metric import EvaluationConfig
    from hnnbench._contracts.plugin import Dataset, TrainSettings, Trajectories
    from hnnbench._running import dataset_cache
    from hnnbench._running.compose import compose
    from hnnbench._running.config import prepare_job

    cfg = compose([f"system={SYSTEM}", f"model={model_name}", f"system.n_masses={n}", *overrides])
    job = prepare_job(cfg)
    system = job.system_cls(job.system_cfg)
    reason = (
        f"{model_name} is not a neural model (no training loop)"
        if getattr(job.model_cls, "family", None) is None
        else job.model_cls.unsupported_reason(system)
    )
    if reason is not None:
        raise ConfigError(f"{model_name} on {SYSTEM}: {reason}")
    ev = EvaluationConfig(**OmegaConf.to_container(cfg.evaluation, resolve=True))  # type: ignore[arg-type]
    data, _, _ = dataset_cache.cached(system, 0, "dataset", lambda: system.dataset(0), Dataset.load)
    traj, _, _ = dataset_cache.cached(
        system, 0, "evaluation", lambda: system.evaluation(0), Trajectories.load
    )
    paper = TrainSettings.resolve(job.system_cfg, job.model_cfg)
    every = job.model_cfg.log_interval(paper.steps)
    model_cfg = dataclasses.replace(job.model_cfg, log_every=every)
    n_train = len(data.train)
    batch = n_train if paper.batch_size is None else min(paper.batch_size, n_train)
    return Cell(n, model_name, job, system, data, traj, paper, model_cfg, ev, batch)


def timed_fit(cell: Cell, steps: int, seed: int) -> tuple[Any, float, float]:
    """One fit of ``steps`` steps: the model, wall seconds less compilation, compile s."""
    model = cell.job.model_cls(cell.cfg, cell.system, "cpu")
    train = dataclasses.replace(cell.train, steps=steps)
    start = time.perf_counter()
    model.fit(cell.data, train, seed, lambda *_: None)
    elapsed = time.perf_counter() - start
    compile_s = float(getattr(model, "timings", {}).get("compile_s", 0.0))
    return model, elapsed - compile_s, compile_s


def energy_after_fit(cell: Cell, steps: int, seed: int) -> None:
    """Train ``steps`` steps, then the energy MSE as a job computes it."""
    from hnnbench._contracts.errors import RolloutDiverged
    from hnnbench._registry.groups import metrics
    from hnnbench._running.evaluation import evaluate

    energy = [m for m in metrics() if m.name == "energy_mse"]
    try:
        model, _, _ = timed_fit(cell, steps, seed)
    except RolloutDiverged as err:  # training loss became non-finite
        cell.status = f"training diverged: {err}"
        return
    start = time.perf_counter()
    result = evaluate(cell.system, model, cell.data, cell.traj, cell.ev, metrics=energy)
    cell.eval_s = time.perf_counter() - start
    cell.energy_mse = result.metrics["energy_mse"]["mean"]
    if result.diverged:
        cell.status = result.diverged
    elif result.errors:
        cell.status = "; ".join(result.errors.values())


def _fmt(value: Optional[float], spec: str, suffix: str = "") -> str:
    return "—" if value is None or not math.isfinite(value) else f"{value:{spec}}{suffix}"


def markdown_table(cells: Sequence[Cell], steps: int) -> str:
    """One row per (N, model); the ratio is against the model's smallest N."""
    base_n = min(c.n for c in cells)
    base = {c.model: c.median for c in cells if c.n == base_n}
    lines = [HEADER.format(base=base_n, steps=steps), "|---|---|---|---|---|---|---|---|---|"]
    for c in sorted(cells, key=lambda c: c.n):  # stable: models in --models order
        ref = base.get(c.model)
        ratio = c.median / ref if ref and math.isfinite(ref) else None
        jax = c.job.model_cls.backend == "jax"
        mse = _fmt(c.energy_mse, ".3e")
        if c.status:
            mse = f"{mse} ({c.status.splitlines()[0][:60]})"
        lines.append(
            f"| {c.n} | {2 * c.n} | {c.model} | {c.batch} | {_fmt(c.median, '.3f')} | "
            f"{_fmt(ratio, '.2f', 'x')} | {_fmt(c.compile_s if jax else None, '.2f')} | "
            f"{mse} | {_fmt(c.eval_s, '.1f')} |"
        )
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--sizes",
        nargs="+",
        type=int,
        default=[2, 5, 10, 20],
        help="numbers of masses N (system.n_masses; default 2 5 10 20)",
    )
    parser.add_argument(
        "--models",
        nargs="+",
        default=["hnn_torch", "hnn_jax", "mlp_torch"],
        help="neural models (default: hnn_torch hnn_jax mlp_torch)",
    )
    parser.add_argument(
        "--steps", type=int, default=500, help="training steps before the energy MSE (default 500)"
    )
    parser.add_argument(
        "--timing-steps", type=int, default=100, help="steps per timed fit (default 100)"
    )
    parser.add_argument("--repeats", type=int, default=3, help="timed fits (default 3)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the energy-MSE fit")
    parser.add_argument(
        "--overrides",
        nargs="*",
        default=[],
        metavar="KEY=VALUE",
        help="more config overrides, e.g. system.eval_t_end=10",
    )
    parser.add_argument(
        "--no-pin", action="store_true", help="do not pin the process to one CPU core"
    )
    args = parser.parse_args(argv)
    if min(args.sizes) < 1 or args.steps < 1 or args.timing_steps < 1 or args.repeats < 1:
        parser.error("--sizes, --steps, --timing-steps and --repeats must be >= 1")
    pinned = None
    if not args.no_pin and hasattr(os, "sched_setaffinity"):
        pinned = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {pinned})

    from hnnbench._contracts.errors import HnnbenchError, RolloutDiverged, UnsupportedPair
    from hnnbench._running.job import _set_threads

    _set_threads(1)
    load = os.getloadavg()
    print(
        f"CPU cores: {os.cpu_count()}, load average {load[0]:.2f} {load[1]:.2f} "
        f"{load[2]:.2f}; one thread, pinned to core "
        f"{'— (not pinned)' if pinned is None else pinned}",
        flush=True,
    )

    cells: list[Cell] = []
    failures: list[str] = []
    for n in args.sizes:
        row: list[Cell] = []
        for model_name in args.models:
            try:
                cell = prepare(n, model_name, args.overrides)
                _, _, cell.compile_s = timed_fit(cell, args.timing_steps, 0)  # warm-up
            except (HnnbenchError, UnsupportedPair, RolloutDiverged) as err:  # bad name or
                # setting, a model that cannot run on the chain, training diverged
                failures.append(f"N={n} {model_name}: {err}")
                print(f"  N={n:<3d} {model_name:10s} FAILED: {err}", flush=True)
                continue
            row.append(cell)
            print(
                f"  N={n:<3d} {model_name:10s} warm-up done (compile "
                f"{cell.compile_s:.2f} s; {len(cell.data.train)} training points)",
                flush=True,
            )
        for rep in range(1, args.repeats + 1):
            for cell in row:
                _, seconds, _ = timed_fit(cell, args.timing_steps, rep)
                cell.times_ms.append(1e3 * seconds / args.timing_steps)
                print(
                    f"  N={n:<3d} {cell.model:10s} rep {rep}: {cell.times_ms[-1]:8.3f} ms/step",
                    flush=True,
                )
        for cell in row:
            energy_after_fit(cell, args.steps, args.seed)
            print(
                f"  N={n:<3d} {cell.model:10s} energy MSE after {args.steps} steps: "
                f"{_fmt(cell.energy_mse, '.3e')} {cell.status}".rstrip(),
                flush=True,
            )
        cells += row

    if cells:
        print(f"\n## {SYSTEM}: ms per training step and energy MSE against N\n")
        print(
            f"ms/step: median of {args.repeats} fits of {args.timing_steps} steps after "
            f"one warm-up fit, compilation excluded; paper protocol (batch, lr), test "
            f"loss at the paper run's interval. Energy MSE: one fit of {args.steps} "
            f"steps (seed {args.seed}), then the energy_mse metric on the evaluation "
            "trajectories.\n"
        )
        print(markdown_table(cells, args.steps))
    for line in failures:
        print(f"FAILED: {line}")
    return 1 if failures or not cells else 0


if __name__ == "__main__":
    sys.exit(main())
