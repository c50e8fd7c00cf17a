"""Seeds trained as one batch against seeds trained one after the other.

    python benchmarks/seed_batch.py [--systems two_body real_pendulum] [--steps 1000]
    python benchmarks/seed_batch.py --seeds 10  # the six JAX twins, 10 seeds (the default)
    python benchmarks/seed_batch.py --jobs      # also whole jobs through the CLI
    python benchmarks/seed_batch.py --ops --models hnn_torch mlp_torch   # ATen calls per step

**Training** (default): for each (system, model), the same ``--seeds`` seeds (10 by
default, the protocol's seed plan; each its own data, initial weights and minibatches,
at the system's paper settings, ``--steps`` steps) are trained (a) by that many
``Model.fit`` calls in a row and (b) by one ``Model.fit_seeds`` call, the batch. Both
run once untimed first (JAX compilation, torch warm-up), then ``--repeats`` timed rounds,
interleaved; the medians give the throughput ratio (a) / (b).

**Jobs** (``--jobs``): the whole command a user runs,
``hnnbench -m system=S model=M seed=0,...,N-1`` against the same with ``seeds_per_job=N``
(each in a fresh process, caches warm: a warm-up run fills the dataset and JAX
compilation caches), so data loading, compilation, evaluation and process start-up
count too.

**ATen calls** (``--ops``, torch models): the number of ATen operator calls per
training step of one seed's fit and of the three seeds' batched fit (``torch.func.vmap``),
counted by a ``TorchDispatchMode`` as the difference between a fit of ``2k`` and one of
``k`` steps, and how many of them are views (``OpOverload.is_view``: no kernel, no data
moved). On a GPU, where one step's arithmetic is small, each call's host-side dispatch
is what a step costs; docs/SCALING.md, "GPUs", uses these counts.

Everything runs on one core with one thread (``taskset`` the script, as the harness
pins its jobs); the issue's target: three seeds in one job at least 2.5x the throughput
of three separate jobs on two_body (batch 200) and real_pendulum.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

TARGET = 2.5
#: The seeds of one pair (``--seeds`` sets it).
SEEDS: tuple[int, ...] = tuple(range(10))
#: The JAX twin of every family (the default ``--models``).
JAX_TWINS = ("mlp_jax", "hnn_jax", "dhnn_jax", "lnn_jax", "so_mlp_jax", "srnn_jax")


def _pair(system_name: str, model_name: str) -> tuple[Any, Any, list[Any], Any]:
    """One thread; the composed job, its system, the datasets of ``SEEDS`` (from the
    cache) and the protocol's training settings."""
    from hnnbench._contracts.plugin import Dataset, TrainSettings
    from hnnbench._running import dataset_cache
    from hnnbench._running.compose import compose
    from hnnbench._running.config import prepare_job
    from hnnbench._running.job import _set_threads

    _set_threads(1)
    job = prepare_job(compose([f"system={system_name}", f"model={model_name}"]))
    system = job.system_cls(job.system_cfg)
    datas = [
        dataset_cache.cached(system, s, "dataset", lambda s=s: system.dataset(s), Dataset.load)[0]
        for s in SEEDS
    ]
    return job, system, datas, TrainSettings.resolve(job.system_cfg, job.model_cfg)


def training(system_name: str, model_name: str, steps: int, repeats: int) -> tuple[float, float]:
    """Median seconds of separate fits of :data:`SEEDS` and of one batched fit."""
    from hnnbench._contracts.plugin import TrainSettings

    job, system, datas, protocol = _pair(system_name, model_name)
    train = TrainSettings(steps, protocol.batch_size, protocol.lr, protocol.weight_decay)

    def separate() -> None:
        for seed, data in zip(SEEDS, datas, strict=True):
            job.model_cls(job.model_cfg, system, "cpu").fit(data, train, seed, lambda *_: None)

    def batched() -> None:
        job.model_cls(job.model_cfg, system, "cpu").fit_seeds(
            datas, train, list(SEEDS), lambda *_: None
        )

    separate()
    batched()
    times: dict[str, list[float]] = {"separate": [], "batched": []}
    for _ in range(repeats):
        for name, fn in (("separate", separate), ("batched", batched)):
            start = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - start)
    return statistics.median(times["separate"]), statistics.median(times["batched"])


def aten_calls(
    system_name: str, model_name: str, steps: int = 20
) -> tuple[float, float, float, float]:
    """ATen calls per training step, one seed's fit and the batched fit of ``SEEDS``,
    and of those the views: ``(calls 1, calls batch, views 1, views batch)``."""
    import collections

    from torch.utils._python_dispatch import TorchDispatchMode

    from hnnbench._contracts.plugin import TrainSettings

    class Count(TorchDispatchMode):
        def __init__(self) -> None:
            super().__init__()
            self.calls: collections.Counter[bool] = collections.Counter()

        def __torch_dispatch__(
            self, func: Any, types: Any, args: Any = (), kwargs: Any = None
        ) -> Any:
            self.calls[bool(getattr(func, "is_view", False))] += 1
            return func(*args, **(kwargs or {}))

    job, system, datas, protocol = _pair(system_name, model_name)

    def count(n_steps: int, batched: bool) -> collections.Counter[bool]:
        train = TrainSettings(n_steps, protocol.batch_size, protocol.lr, protocol.weight_decay)
        model = job.model_cls(job.model_cfg, system, "cpu")
        with Count() as counter:
            if batched:
                model.fit_seeds(datas, train, list(SEEDS), lambda *_: None)
            else:
                model.fit(datas[0], train, SEEDS[0], lambda *_: None)
        return counter.calls

    out: list[float] = []
    for batched in (False, True):
        short, long = count(steps, batched), count(2 * steps, batched)
        out.append(sum(long.values()) - sum(short.values()))
        out.append(long[True] - short[True])
    one, one_views, batch, batch_views = (v / steps for v in out)
    return one, batch, one_views, batch_views


def jobs(system_name: str, model_name: str, steps: int) -> tuple[float, float]:
    """Wall seconds of the CLI sweep of :data:`SEEDS` without and with them as one job
    (``seeds_per_job``)."""
    exe = str(Path(sys.executable).parent / "hnnbench")
    common = [
        "-m",
        f"system={system_name}",
        f"model={model_name}",
        f"seed={','.join(map(str, SEEDS))}",
        f"system.steps={steps}",
        "device=cpu",
        "save_model=false",
    ]
    env = {**os.environ, "HNNBENCH_PROGRESS": "off"}
    out: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [exe, *common, f"hydra.sweep.dir={tmp}/warm"], check=True, capture_output=True, env=env
        )
        for i, extra in enumerate(([], [f"seeds_per_job={len(SEEDS)}"])):
            start = time.perf_counter()
            subprocess.run(
                [exe, *common, *extra, f"hydra.sweep.dir={tmp}/run{i}"],
                check=True,
                capture_output=True,
                env=env,
            )
            out.append(time.perf_counter() - start)
    return out[0], out[1]


def main() -> int:
    global SEEDS
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--systems", nargs="+", default=["two_body", "real_pendulum"])
    parser.add_argument("--models", nargs="+", default=list(JAX_TWINS))
    parser.add_argument(
        "--seeds",
        type=int,
        default=len(SEEDS),
        help="seeds of one pair: separate fits against one batch of them",
    )
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--jobs", action="store_true", help="also time whole CLI sweeps")
    parser.add_argument(
        "--ops", action="store_true", help="count ATen calls per step instead (torch models only)"
    )
    args = parser.parse_args()
    SEEDS = tuple(range(args.seeds))

    if args.ops:
        print(
            f"| system | model | ATen calls per step, 1 seed | {len(SEEDS)} seeds batched "
            "| of them views, 1 seed | batched |"
        )
        print("|---|---|---|---|---|---|")
        for system_name in args.systems:
            for model_name in (m for m in args.models if m.endswith("_torch")):
                one, batch, one_views, batch_views = aten_calls(system_name, model_name)
                print(
                    f"| {system_name} | {model_name} | {one:.1f} | {batch:.1f} "
                    f"| {one_views:.1f} | {batch_views:.1f} |",
                    flush=True,
                )
        return 0

    rows: list[tuple[Any, ...]] = []
    for system_name in args.systems:
        for model_name in args.models:
            sep, bat = training(system_name, model_name, args.steps, args.repeats)
            row: tuple[Any, ...] = (system_name, model_name, sep, bat)
            if args.jobs:
                row += jobs(system_name, model_name, args.steps)
            rows.append(row)
            print(
                f"  measured {system_name} x {model_name}: {len(SEEDS)} fits {sep:.2f} s, "
                f"one batch {bat:.2f} s, ratio {sep / bat:.2f}x",
                file=sys.stderr,
                flush=True,
            )
    n = len(SEEDS)
    head = f"| system | model | {n} fits s | 1 batched fit s | training ratio |"
    rule = "|---|---|---|---|---|"
    if args.jobs:
        head += f" {n} jobs s | 1 batched job s | job ratio |"
        rule += "---|---|---|"
    print(f"\n{len(SEEDS)} seeds, {args.steps} steps each, paper batch sizes; one core\n")
    print(head)
    print(rule)
    for row in rows:
        text = f"| {row[0]} | {row[1]} | {row[2]:.2f} | {row[3]:.2f} | {row[2] / row[3]:.2f}x |"
        if args.jobs:
            text += f" {row[4]:.1f} | {row[5]:.1f} | {row[4] / row[5]:.2f}x |"
        print(text)
    best = {s: max(r[2] / r[3] for r in rows if r[0] == s) for s in args.systems}
    print(
        "\nbest training ratio per system: "
        + ", ".join(
            f"{s} {v:.2f}x ({'meets' if v >= TARGET else 'below'} the {TARGET}x target)"
            for s, v in best.items()
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
