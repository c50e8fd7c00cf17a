"""Start-up cost: ``hnnbench list`` against a bare ``import torch, jax``, and which
backends a job imports.

    python benchmarks/startup.py [--repeats 5]

Each command runs as a fresh process, the two interleaved ``--repeats`` times after a
warm-up (so both see the same file-system cache and load); the medians and their ratio
are printed. Then one quick torch job and one quick JAX job run in fresh processes,
which report whether the other backend was imported.

Targets (issue "One model core"): ``hnnbench list`` under half the time of
``python -c "import torch, jax"``; a torch job imports no JAX and a JAX job no torch.
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

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent

JOB = """
import sys, pathlib
from hnnbench._running.compose import compose
from hnnbench._running.job import run_job
overrides = ["system=spring", "model={model}", "profile=quick", "system.steps=20",
             "device=cpu", "save_model=false"]
record = run_job(compose(overrides), pathlib.Path(sys.argv[1]), overrides=overrides)[0].record
print(record["status"], "torch" in sys.modules, "jax" in sys.modules)
"""


def timed(cmd: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    commands = {
        "python -c 'import torch, jax'": [sys.executable, "-c", "import torch, jax"],
        "hnnbench list": [str(BIN / "hnnbench"), "list"],
    }
    for cmd in commands.values():  # warm-up: file-system cache, .pyc files
        timed(cmd)
    times: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(args.repeats):
        for name, cmd in commands.items():
            times[name].append(timed(cmd))
    print(f"start-up, median of {args.repeats} interleaved runs (s):")
    for name, values in times.items():
        print(
            f"  {name:32s} {statistics.median(values):6.3f}  "
            f"(min {min(values):.3f}, max {max(values):.3f})"
        )
    ratio = statistics.median(times["hnnbench list"]) / statistics.median(
        times["python -c 'import torch, jax'"]
    )
    print(
        f"  ratio list / import torch, jax: {ratio:.2f} (target < 0.5: "
        f"{'met' if ratio < 0.5 else 'missed'})"
    )

    print("backends imported by one quick job (fresh process each):")
    env = {**os.environ, "HNNBENCH_PROGRESS": "off"}
    ok = ratio < 0.5
    for model, own, other in (("mlp_torch", "torch", "jax"), ("mlp_jax", "jax", "torch")):
        with tempfile.TemporaryDirectory() as tmp:
            out = subprocess.run(
                [sys.executable, "-c", JOB.format(model=model), tmp],
                capture_output=True,
                text=True,
                env=env,
                check=True,
            )
        status, has_torch, has_jax = out.stdout.split()[-3:]
        imported = {"torch": has_torch == "True", "jax": has_jax == "True"}
        good = status == "ok" and imported[own] and not imported[other]
        ok &= good
        print(
            f"  {model:10s} status={status}  imports {own}: {imported[own]}  "
            f"imports {other}: {imported[other]}  -> {'ok' if good else 'FAILED'}"
        )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
