"""Training throughput: hnnbench's step (torch and JAX) against the 2019 training loop
and against this machine's fp32 matmul roofline, measured side by side.

    python benchmarks/train_step.py                       # spring and two_body, paper settings
    python benchmarks/train_step.py --systems spring --steps 500 --repeats 5
    python benchmarks/train_step.py --steps 100 --repeats 1 --steps-2019 50   # quick check
    python benchmarks/train_step.py --skip-2019           # hnnbench and roofline only
    python benchmarks/train_step.py --systems spring --skip-2019 --models \
        mlp_torch mlp_jax hnn_torch hnn_jax dhnn_torch dhnn_jax lnn_torch lnn_jax \
        so_mlp_torch so_mlp_jax srnn_torch srnn_jax       # ms/step of every family

``--models`` takes any neural model (``<family>_<backend>``: the families mlp, hnn,
dhnn, lnn, so_mlp, srnn, each as torch and jax; default: mlp and hnn on both backends);
a model that cannot run on a system (``hnnbench list`` says why) is skipped with a
note. For each system it builds the paper-profile dataset (``system.dataset(0)``, the
same cache entry a real run uses) and, for each model, times ``Model.fit`` for ``--steps``
steps ``--repeats`` times, after one untimed warm-up fit (JAX compilation and torch's
first-call costs are excluded; compile time is measured inside ``fit`` and printed
separately, never counted in a step). The batch size, learning rate and weight decay
are the paper's, and the test loss is logged at the interval of the paper-length run
(``model.log_every`` is set to ``log_interval(paper steps)``: every 10 steps on spring,
every 50 on two_body), so a short benchmark fit does the same work per step as a real
run. Two figures per model: **median** = wall time of a whole fit / steps, median over
the repeats (setup and logging included, what a run sees); **best** = the fastest
logging interval of all timed fits (time between two of ``fit``'s progress calls /
steps in it), a load-robust estimate of the per-step cost on an idle machine, since
on a shared machine a whole fit rarely runs without being preempted. The repeats of
all models (and of the 2019 loop) are interleaved, so load changes hit every column
alike.

Compared with:

1. **The 2019 loop** (``benchmarks/loop2019.py``, ``fit_2019``): a re-implementation
   of the original training script on the same data, batch and optimizer settings:
   eager PyTorch, the HNN's input gradient by ``autograd.grad(..., create_graph=True)``
   (double backward), the test loss on a test batch every step with the same
   ``create_graph`` derivative, losses stored with ``.item()`` every step, the
   gradient vector concatenated every step. It is slow, so it runs ``--steps-2019``
   steps per repeat (after 5 warm-up steps; its "best" is the fastest block of as many
   steps as hnnbench's logging interval); a paper-length total (two_body: 10,000
   steps) is *extrapolated* as per-step x steps, for both loops. The 2019 code had
   only the baseline MLP and the HNN, so the other families get no 2019 figure ("—").
2. **The matmul roofline** (``benchmarks/roofline.py``): the matrix products of one
   hnnbench training step plus 1/``log_every`` of a test-loss evaluation (what a
   step of the timed fit does on average), recorded from the torch model's own ``fit``
   (and checked with ``FlopCounterMode``; the JAX step's dot FLOPs are read from the
   optimised HLO of the training chunk JAX ``fit`` compiles and agree for mlp, hnn and
   dhnn; lnn, so_mlp and srnn compute their derivatives differently in the two
   backends, or loop inside the loss, and a warning says where they differ), each
   divided by the best fp32 rate measured on this
   machine, single thread, for that ``(M, K) x (K, N)`` shape (torch ``mm`` or JAX
   ``dot_general``, any operand layout, either orientation ``C`` or ``C.T``; the
   roofline as dispatched, without the orientation freedom, and ``total FLOPs / peak
   rate`` are printed too). The roofline is per (system, architecture), the same for
   both backends, and ``% of roofline = roofline time / measured step time``.

One thread per process (hnnbench's default: ``OMP_NUM_THREADS=1``, torch's
``set_num_threads(1)``), and the whole process is pinned to one core
(``os.sched_setaffinity``; ``--no-pin`` to turn off, ``--cpu`` to choose the core):
XLA's CPU runtime keeps its own thread pool whatever ``OMP_NUM_THREADS`` says and was
seen running large dots faster than one core can (rates above 100 GFLOP/s with
process CPU time above wall time on a 2-core machine), which would make both its
timings and the roofline's rates multi-core figures.
The machine's load average is printed first: on a busy machine the absolute figures are
inflated and only the side-by-side ratios mean much.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

#: The "Speed and scale" issue's targets.
TARGET_ROOFLINE = 0.70  # spring, full batch, HNN, faster backend: >= 70% of the roofline
TARGET_SPEEDUP = 5.0  # two_body, batch 200, 10k steps: >= 5x faster than the 2019 loop
#: The architectures of the 2019 code (benchmarks/loop2019.py).
ARCHS_2019 = ("mlp", "hnn")


@dataclass
class Entry:
    """One (system, model) of hnnbench."""

    system: str
    model: str
    arch: str
    backend: str
    job: Any
    cfg: Any
    train: Any  # the timed fit's settings (``--steps`` steps)
    paper_steps: int
    every: int
    times_ms: list[float] = field(default_factory=list)  # per fit: wall / steps
    interval_ms: list[float] = field(default_factory=list)  # per logging interval
    compile_s: float = 0.0

    @property
    def median(self) -> float:
        return statistics.median(self.times_ms)

    @property
    def best(self) -> float:
        return min(self.interval_ms) if self.interval_ms else min(self.times_ms)

    @property
    def batch(self) -> int:
        return self.train.batch_size


@dataclass
class Arch:
    """One (system, architecture): the 2019 loop and the FLOP counts."""

    system: str
    arch: str
    batch: int
    n_train: int
    paper_steps: int
    every: int
    lr: float
    weight_decay: float
    times_2019_ms: list[float] = field(default_factory=list)
    blocks_2019_ms: list[float] = field(default_factory=list)
    torch_mm: dict[str, Any] = field(default_factory=dict)
    jax_flops: dict[str, float] = field(default_factory=dict)
    mm_2019: Counter = field(default_factory=Counter)
    roofline_ms: float = float("nan")  # per-shape rates, either orientation
    dispatched_roofline_ms: float = float("nan")  # per-shape rates, as dispatched
    peak_roofline_ms: float = float("nan")  # total FLOPs / peak rate

    @property
    def median_2019(self) -> Optional[float]:
        return statistics.median(self.times_2019_ms) if self.times_2019_ms else None

    @property
    def best_2019(self) -> Optional[float]:
        if self.blocks_2019_ms:
            return min(self.blocks_2019_ms)
        return min(self.times_2019_ms) if self.times_2019_ms else None

    @property
    def has_2019(self) -> bool:
        return self.arch in ARCHS_2019

    def flops_per_step(self) -> float:
        from roofline import total_flops

        return total_flops(self.torch_mm["step"]) + total_flops(self.torch_mm["eval"]) / self.every


def _fmt(value: Optional[float], spec: str = ".2f", suffix: str = "") -> str:
    return "—" if value is None or value != value else f"{value:{spec}}{suffix}"


def _ratio(a: Optional[float], b: Optional[float], spec: str = ".1f", suffix: str = "x") -> str:
    return _fmt(a / b if a and b else None, spec, suffix)


def _pct(a: float, b: float) -> str:
    return f"{100 * a / b:.0f}%"


def time_fit(entry: Entry, system: Any, data: Any, rep: int) -> tuple[float, float, list[float]]:
    """One fit of ``entry``: (wall seconds without compilation, compile seconds, seconds
    per step of each logging interval but the first, which holds the fit's setup)."""
    model = entry.job.model_cls(entry.cfg, system, "cpu")
    marks: list[tuple[int, float]] = []

    def progress(step: int, _: Any) -> None:
        marks.append((step, time.perf_counter()))

    start = time.perf_counter()
    model.fit(data, entry.train, rep, progress)
    elapsed = time.perf_counter() - start
    compile_s = model.timings.get("compile_s", 0.0)
    intervals = [
        (t1 - t0) / (s1 - s0) for (s0, t0), (s1, t1) in zip(marks[:-1], marks[1:], strict=True)
    ]
    return elapsed - compile_s, compile_s, intervals


def training_rows(job: Any, system: Any, data: Any) -> int:
    """Rows the model's training loop draws its minibatches from: the training points,
    or, for a family trained on trajectory windows (srnn), the windows. Raises
    :class:`~hnnbench._contracts.errors.UnsupportedPair` where the data has none."""
    from hnnbench import with_validation

    model = job.model_cls(job.model_cfg, system, "cpu")
    return model.view.problem(with_validation(data, 0), *model.training_options()).n


def bench_system(
    system_name: str, models: Sequence[str], args: argparse.Namespace
) -> tuple[list[Entry], list[Arch]]:
    from loop2019 import fit_2019, make_2019
    from roofline import jax_fit_flops, record_matmuls, torch_fit_matmuls

    from hnnbench._contracts.errors import UnsupportedPair
    from hnnbench._contracts.plugin import TrainSettings
    from hnnbench._running.compose import compose
    from hnnbench._running.config import prepare_job

    entries: list[Entry] = []
    system = data = None
    for model_name in models:
        job = prepare_job(compose([f"system={system_name}", f"model={model_name}"]))
        if system is None:
            system = job.system_cls(job.system_cfg)
            data = system.dataset(0)
        family = getattr(job.model_cls, "family", None)
        reason = (
            f"{model_name} is not a neural model (no training loop)"
            if family is None
            else job.model_cls.unsupported_reason(system)
        )
        if reason is None:
            try:
                n = training_rows(job, system, data)
            except UnsupportedPair as err:
                reason = str(err)
        if reason is not None:
            print(f"  skipped {system_name} {model_name}: {reason}", flush=True)
            continue
        paper = TrainSettings.resolve(job.system_cfg, job.model_cfg)
        paper = dataclasses.replace(
            paper, batch_size=n if paper.batch_size is None else min(paper.batch_size, n)
        )
        every = job.model_cfg.log_interval(paper.steps)
        arch, backend = family.name, job.model_cls.backend
        entries.append(
            Entry(
                system_name,
                model_name,
                arch,
                backend,
                job,
                dataclasses.replace(job.model_cfg, log_every=every),
                dataclasses.replace(paper, steps=args.steps),
                paper.steps,
                every,
            )
        )
    archs: dict[str, Arch] = {}
    for e in entries:
        if e.arch not in archs:
            archs[e.arch] = Arch(
                system_name,
                e.arch,
                e.batch,
                len(data.train),
                e.paper_steps,
                e.every,
                e.train.lr,
                e.train.weight_decay,
            )
    archs_2019 = [ar for ar in archs.values() if ar.has_2019] if not args.skip_2019 else []

    def batch_2019(ar: Arch) -> Optional[int]:
        return None if ar.batch >= ar.n_train else ar.batch

    def run_2019(ar: Arch, steps: int, blocks: Optional[list[float]] = None) -> float:
        return 1e3 * fit_2019(
            data,
            ar.arch,
            steps,
            batch_2019(ar),
            ar.lr,
            ar.weight_decay,
            seed=0,
            warmup=5,
            block=ar.every,
            block_times=blocks,
        )

    # warm-up: one untimed fit per model (JAX compiles here), a few 2019 steps
    for e in entries:
        _, e.compile_s, _ = time_fit(e, system, data, 0)
        print(f"  warm-up {system_name} {e.model}: compile {e.compile_s:.2f} s", flush=True)
    for ar in archs_2019:
        run_2019(ar, 2)
    for rep in range(1, args.repeats + 1):
        for e in entries:
            seconds, comp, intervals = time_fit(e, system, data, rep)
            if comp > 0:
                print(f"  note: {e.model} compiled again ({comp:.2f} s, excluded)")
            e.times_ms.append(1e3 * seconds / args.steps)
            e.interval_ms += [1e3 * t for t in intervals]
            print(
                f"  {system_name:9s} {e.model:10s} rep {rep}: {e.times_ms[-1]:8.3f} "
                f"ms/step (best interval so far {e.best:.3f})",
                flush=True,
            )
        for ar in archs_2019:
            blocks: list[float] = []
            ar.times_2019_ms.append(run_2019(ar, args.steps_2019, blocks))
            ar.blocks_2019_ms += [1e3 * t for t in blocks]
            print(
                f"  {system_name:9s} 2019-{ar.arch:5s} rep {rep}: "
                f"{ar.times_2019_ms[-1]:8.3f} ms/step (best block so far "
                f"{_fmt(ar.best_2019, '.3f')})",
                flush=True,
            )

    # FLOP counts: torch twin's fit (recorded), JAX chunk (XLA), 2019 step (recorded)
    for ar in archs.values():
        print(f"  counting FLOPs of {system_name} {ar.arch} ...", flush=True)
        twin = prepare_job(compose([f"system={system_name}", f"model={ar.arch}_torch"]))
        train = next(e.train for e in entries if e.arch == ar.arch)
        ar.torch_mm = torch_fit_matmuls(twin.model_cls, twin.model_cfg, system, data, train)
        jax_entry = next((e for e in entries if e.arch == ar.arch and e.backend == "jax"), None)
        jax_job = jax_entry.job if jax_entry else None
        if jax_job is None:
            try:
                jax_job = prepare_job(compose([f"system={system_name}", f"model={ar.arch}_jax"]))
            except Exception:  # noqa: BLE001  JAX not installed: no XLA count
                jax_job = None
        if jax_job is not None:
            ar.jax_flops = jax_fit_flops(jax_job.model_cls, jax_job.model_cfg, system, data, train)
        if ar.has_2019:
            step, _ = make_2019(data, ar.arch, batch_2019(ar), ar.lr, ar.weight_decay)
            step()
            ar.mm_2019, _ = record_matmuls(step, flop_counter=False)
    return entries, list(archs.values())


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--systems", nargs="+", default=["spring", "two_body"])
    parser.add_argument(
        "--models", nargs="+", default=["mlp_torch", "hnn_torch", "mlp_jax", "hnn_jax"]
    )
    parser.add_argument(
        "--steps", type=int, default=300, help="hnnbench steps per timed fit (default 300)"
    )
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--steps-2019",
        type=int,
        default=200,
        help="timed steps of the 2019 loop per repeat (default 200)",
    )
    parser.add_argument("--skip-2019", action="store_true", help="do not time the 2019 loop")
    parser.add_argument(
        "--rate-budget",
        type=float,
        default=2.0,
        help="max seconds per shape and backend for the matmul rates",
    )
    parser.add_argument(
        "--no-pin", action="store_true", help="do not pin the process to one CPU core"
    )
    parser.add_argument(
        "--cpu", type=int, default=None, help="the core to pin to (default: the first allowed one)"
    )
    args = parser.parse_args(argv)
    pinned = None
    if not args.no_pin and hasattr(os, "sched_setaffinity"):
        if "jax" in sys.modules or "torch" in sys.modules:
            print("WARNING: jax/torch already imported: threads they started are not pinned")
        pinned = args.cpu if args.cpu is not None else min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {pinned})

    import torch

    torch.set_num_threads(1)
    from roofline import (
        measure_rates,
        peak_rate,
        roofline_seconds,
        shape_rate,
        total_flops,
        transposed,
    )

    load = os.getloadavg()
    print(
        f"CPU cores: {os.cpu_count()}, load average {load[0]:.2f} {load[1]:.2f} "
        f"{load[2]:.2f}; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}, "
        f"torch threads {torch.get_num_threads()}, pinned to core "
        f"{'— (not pinned)' if pinned is None else pinned}, "
        f"XLA_FLAGS={os.environ.get('XLA_FLAGS', '')!r}",
        flush=True,
    )
    entries: list[Entry] = []
    archs: list[Arch] = []
    for system_name in args.systems:
        e, a = bench_system(system_name, args.models, args)
        entries += e
        archs += a
    if not entries:
        print("no model to time (every one was skipped)")
        return 1

    # rates for every product of every step, evaluation and 2019 step
    all_mm: set[Any] = set()
    for ar in archs:
        all_mm |= set(ar.torch_mm["step"]) | set(ar.torch_mm["eval"]) | set(ar.mm_2019)
    print(
        f"  measuring fp32 matmul rates for {len(all_mm)} products and their transposes ...",
        flush=True,
    )
    rates = measure_rates(all_mm, budget_s=args.rate_budget)
    peak = peak_rate(rates)
    for ar in archs:
        step_mm, eval_mm, w = ar.torch_mm["step"], ar.torch_mm["eval"], 1.0 / ar.every
        ar.roofline_ms = 1e3 * (
            roofline_seconds(step_mm, rates) + roofline_seconds(eval_mm, rates, w)
        )
        ar.dispatched_roofline_ms = 1e3 * (
            roofline_seconds(step_mm, rates, either_orientation=False)
            + roofline_seconds(eval_mm, rates, w, either_orientation=False)
        )
        ar.peak_roofline_ms = 1e3 * ar.flops_per_step() / peak
    by_arch = {(a.system, a.arch): a for a in archs}
    best_entry: dict[tuple[str, str], Entry] = {}
    for ar in archs:
        cands = [e for e in entries if e.system == ar.system and e.arch == ar.arch]
        best_entry[(ar.system, ar.arch)] = min(cands, key=lambda e: e.median)

    print("\n## hnnbench training step vs the 2019 loop and the matmul roofline\n")
    print(
        "ms/step as median (whole fits) / best (fastest logging interval; 2019: "
        "fastest block of as many steps). Speed-up = 2019 / this model; "
        "% of roofline = roofline ms / ms per step.\n"
    )
    print(
        "| system | model | batch | test loss every | ms/step median / best | "
        "JAX compile s | 2019 loop ms/step median / best | speed-up vs 2019 "
        "median / best | matmul MFLOP/step | roofline ms | % of roofline median / best |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for e in entries:
        ar = by_arch[(e.system, e.arch)]
        print(
            f"| {e.system} | {e.model} | {e.batch} | {e.every} | "
            f"{e.median:.3f} / {e.best:.3f} | "
            f"{_fmt(e.compile_s if e.backend == 'jax' else None)} | "
            f"{_fmt(ar.median_2019, '.3f')} / {_fmt(ar.best_2019, '.3f')} | "
            f"{_ratio(ar.median_2019, e.median)} / {_ratio(ar.best_2019, e.best)} | "
            f"{ar.flops_per_step() / 1e6:.1f} | {ar.roofline_ms:.3f} | "
            f"{_pct(ar.roofline_ms, e.median)} / {_pct(ar.roofline_ms, e.best)} |"
        )

    print(
        "\n## Faster hnnbench backend (by median) vs the 2019 loop; paper-length totals "
        "(extrapolated: median per-step x paper steps)\n"
    )
    print(
        "Ceiling = 2019 best ms/step / roofline ms: the speed-up a step running all "
        "its matrix products at the measured rates, and nothing else, would reach "
        "(best, not median, like the rates: both are load-robust).\n"
    )
    print(
        "| system | arch | batch | 2019 ms/step | hnnbench ms/step (backend) | "
        "speed-up median / best | ceiling | paper steps | 2019 total s (extrap.) | "
        "hnnbench total s (extrap.) | + JAX compile s (once) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for ar in archs:
        b = best_entry[(ar.system, ar.arch)]
        m2019 = ar.median_2019
        print(
            f"| {ar.system} | {ar.arch} | {ar.batch} | {_fmt(m2019, '.3f')} | "
            f"{b.median:.3f} ({b.backend}) | {_ratio(m2019, b.median)} / "
            f"{_ratio(ar.best_2019, b.best)} | {_ratio(ar.best_2019, ar.roofline_ms)} | "
            f"{ar.paper_steps} | "
            f"{_fmt(m2019 * ar.paper_steps / 1e3 if m2019 else None, '.1f')} | "
            f"{b.median * ar.paper_steps / 1e3:.1f} | "
            f"{_fmt(b.compile_s if b.backend == 'jax' else None)} |"
        )

    print("\n## FLOPs per training step (matrix products only, unless noted) and rooflines\n")
    print(
        "| system | arch | step: torch recorded | step: FlopCounterMode | "
        "step: JAX HLO dots | step: XLA cost_analysis (all ops) | test eval: torch / "
        "JAX dots | eval every | per step incl. eval / every | 2019 loop per step (its "
        "test batch included) | roofline ms | as dispatched | total / peak rate |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")

    def mega(value: Optional[float]) -> str:
        return _fmt(None if value is None else value / 1e6, ".1f", " M")

    for ar in archs:
        t, j = ar.torch_mm, ar.jax_flops
        print(
            f"| {ar.system} | {ar.arch} | {mega(total_flops(t['step']))} | "
            f"{mega(t['step_flopcounter'])} | {mega(j.get('step_dot'))} | "
            f"{mega(j.get('step_xla'))} | {mega(total_flops(t['eval']))} / "
            f"{mega(j.get('eval_dot'))} | {ar.every} | {mega(ar.flops_per_step())} | "
            f"{mega(total_flops(ar.mm_2019) if ar.has_2019 else None)} | "
            f"{ar.roofline_ms:.3f} | "
            f"{ar.dispatched_roofline_ms:.3f} | {ar.peak_roofline_ms:.3f} |"
        )
    for ar in archs:
        t, j = ar.torch_mm, ar.jax_flops
        if t["step_flopcounter"] != total_flops(t["step"]):
            print(f"WARNING: {ar.system} {ar.arch}: recorded products and FlopCounterMode disagree")
        if j and (
            j["step_dot"] != total_flops(t["step"]) or j["eval_dot"] != total_flops(t["eval"])
        ):
            print(
                f"WARNING: {ar.system} {ar.arch}: torch and JAX dot FLOPs differ (see "
                "roofline.jax_fit_flops; the roofline uses the torch count)"
            )

    print(
        "\n## fp32 matmul rates, one thread (GFLOP/s; ᵀ: the operand is a transposed "
        "view; 'shape best' is over every layout and both orientations)\n"
    )
    print("| product (M,K)x(K,N) | torch mm | JAX dot_general | shape best | appears in |")
    print("|---|---|---|---|---|")
    for mm, r in sorted(rates.items()):
        where = sorted(
            {
                f"{ar.system}/{ar.arch}" + tag
                for ar in archs
                for tag, c in (
                    (" step", ar.torch_mm["step"]),
                    (" eval", ar.torch_mm["eval"]),
                    (" 2019", ar.mm_2019),
                )
                if mm in c
            }
        )
        if not where:
            twin = transposed(mm)
            where = [f"(transpose of {twin})"]
        print(
            f"| {mm} | {r['torch'] / 1e9:.1f} | {r['jax'] / 1e9:.1f} | "
            f"{shape_rate(rates, mm) / 1e9:.1f} | {', '.join(where)} |"
        )
    print(f"\nPeak over all shapes: {peak / 1e9:.1f} GFLOP/s.")

    def cell(e: Optional[Entry]) -> str:
        return "—" if e is None else f"{e.median:.3f} / {e.best:.3f}"

    print("\n## ms per training step by family, torch / JAX (median; best)\n")
    print(
        "| system | family | torch ms/step median / best | JAX ms/step median / best | "
        "torch / JAX median | best |"
    )
    print("|---|---|---|---|---|---|")
    by_model = {(e.system, e.arch, e.backend): e for e in entries}
    for system_name in args.systems:
        for arch in dict.fromkeys(e.arch for e in entries if e.system == system_name):
            t_e = by_model.get((system_name, arch, "torch"))
            j_e = by_model.get((system_name, arch, "jax"))
            both = t_e is not None and j_e is not None
            print(
                f"| {system_name} | {arch} | {cell(t_e)} | {cell(j_e)} | "
                f"{_ratio(t_e.median, j_e.median, '.2f') if both else '—'} | "
                f"{_ratio(t_e.best, j_e.best, '.2f') if both else '—'} |"
            )

    print('\n## Targets (issue "Speed and scale")\n')
    for (system_name, arch), b in best_entry.items():
        ar = by_arch[(system_name, arch)]
        if system_name == "spring" and arch == "hnn":
            fast = min(
                (e for e in entries if e.system == "spring" and e.arch == "hnn"),
                key=lambda e: e.best,
            )
            print(
                f"- spring, full batch, HNN, faster backend: {b.model} "
                f"{_pct(ar.roofline_ms, b.median)} of the matmul roofline by median, "
                f"{fast.model} {_pct(ar.roofline_ms, fast.best)} by best interval "
                f"(target >= {100 * TARGET_ROOFLINE:.0f}%; as dispatched: "
                f"{_pct(ar.dispatched_roofline_ms, b.median)} / "
                f"{_pct(ar.dispatched_roofline_ms, fast.best)})"
            )
        if system_name == "two_body" and ar.median_2019:
            fast = min(
                (e for e in entries if e.system == system_name and e.arch == arch),
                key=lambda e: e.best,
            )
            print(
                f"- two_body, batch {ar.batch}, {ar.paper_steps} steps, {arch.upper()}: "
                f"{b.model} {ar.median_2019 / b.median:.1f}x faster than the 2019 loop "
                f"by median, {fast.model} {ar.best_2019 / fast.best:.1f}x by best "
                f"interval (target >= {TARGET_SPEEDUP:.0f}x; ceiling at the matmul "
                f"roofline: {ar.best_2019 / ar.roofline_ms:.1f}x)"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
