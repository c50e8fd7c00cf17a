"""Median milliseconds per training step, torch vs JAX, measured side by side.

    python benchmarks/train_step.py                       # spring and two_body, paper settings
    python benchmarks/train_step.py --systems spring --steps 500 --repeats 5

For each (system, model) it builds the paper-profile dataset, then times
``Model.fit`` for ``--steps`` steps ``--repeats`` times (after one warm-up fit, so JAX
compilation and torch's first-call costs are excluded; compile time is printed
separately). Fits log losses at the model's default interval, as real runs do. The
figure is wall time / steps; the median over repeats is printed, with the torch/JAX
ratio per architecture. One thread per process (hnnbench's default).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--systems", nargs="+", default=["spring", "two_body"])
    parser.add_argument("--models", nargs="+",
                        default=["mlp_torch", "mlp_jax", "hnn_torch", "hnn_jax"])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    import dataclasses

    from hnnbench.api import TrainSettings
    from hnnbench.config import compose, prepare_job

    rows = []
    for system_name in args.systems:
        for model_name in args.models:
            job = prepare_job(compose([f"system={system_name}", f"model={model_name}"]))
            system = job.system_cls(job.system_cfg)
            data = system.dataset(0)
            if "torch" in model_name:
                import torch

                torch.set_num_threads(1)
            train = dataclasses.replace(
                TrainSettings.resolve(job.system_cfg, job.model_cfg), steps=args.steps
            )
            times, compile_s = [], 0.0
            for rep in range(args.repeats + 1):
                model = job.model_cls(job.model_cfg, system, "cpu")
                start = time.perf_counter()
                model.fit(data, train, rep, lambda *_: None)
                elapsed = time.perf_counter() - start - model.timings.get("compile_s", 0.0)
                if rep == 0:
                    compile_s = model.timings.get("compile_s", 0.0)
                    continue
                times.append(1e3 * elapsed / args.steps)
            ms = statistics.median(times)
            rows.append((system_name, model_name, train.batch_size or len(data.train), ms,
                         min(times), compile_s))
            print(f"{system_name:10s} {model_name:10s} batch={rows[-1][2]:6d} "
                  f"median {ms:7.3f} ms/step (min {min(times):.3f}; compile {compile_s:.2f} s)",
                  flush=True)

    print("\n| system | model | batch | median ms/step | min ms/step | JAX compile s |")
    print("|---|---|---|---|---|---|")
    for system_name, model_name, batch, ms, lo, comp in rows:
        print(f"| {system_name} | {model_name} | {batch} | {ms:.3f} | {lo:.3f} | {comp:.2f} |")
    print("\n| system | arch | torch / JAX time per step |")
    print("|---|---|---|")
    by_key = {(r[0], r[1]): r[3] for r in rows}
    for system_name in args.systems:
        for arch in ("mlp", "hnn"):
            t = by_key.get((system_name, f"{arch}_torch"))
            j = by_key.get((system_name, f"{arch}_jax"))
            if t and j:
                print(f"| {system_name} | {arch} | {t / j:.2f}x |")


if __name__ == "__main__":
    main()
