"""The torch rollout solver: hnnbench's own batched Dormand-Prince against torchode.

    python benchmarks/ode_solvers.py [--systems spring two_body] [--repeats 5]

For each system, a torch model (``hnn_torch`` and ``mlp_torch``) is trained briefly at
the system's paper settings (``--steps``; the field only has to be realistic), then its
float64 field is integrated from all evaluation initial states over the evaluation grid
at the harness tolerances (rtol = atol = 1e-9) by

(a) ``hnnbench.neural.torch._ode.dopri5``: one step size for the whole batch, RMS error
    norm over every component, Hairer's dense output (what the harness uses);
(b) torchode (``Dopri5`` + ``IntegralController`` + ``AutoDiffAdjoint``): a step size
    per trajectory, its own error norm and interpolation.

Both run once untimed, then ``--repeats`` times; medians and their ratio are printed
side by side, with the largest difference between the two solutions (they agree to
about the tolerance, not bit for bit). The issue's rule: switch to torchode if it is
no more than 1.2x slower than the own solver; otherwise keep the own solver.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

RULE = 1.2


def median_time(fn: Any, repeats: int) -> tuple[float, Any]:
    fn()
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def measure(
    system_name: str, model_name: str, steps: int, repeats: int
) -> tuple[str, str, float, float, int, int, float]:
    """Train one model briefly; time both solvers on its evaluation rollouts."""
    import torch
    import torchode as to

    from hnnbench._contracts.plugin import Dataset, TrainSettings, Trajectories
    from hnnbench._running import dataset_cache
    from hnnbench._running.compose import compose
    from hnnbench._running.config import prepare_job
    from hnnbench.neural.torch._ode import dopri5

    job = prepare_job(compose([f"system={system_name}", f"model={model_name}"]))
    system = job.system_cls(job.system_cfg)
    data, _, _ = dataset_cache.cached(system, 0, "dataset", lambda: system.dataset(0), Dataset.load)
    traj, _, _ = dataset_cache.cached(
        system, 0, "evaluation", lambda: system.evaluation(0), Trajectories.load
    )
    protocol = TrainSettings.resolve(job.system_cfg, job.model_cfg)
    model = job.model_cls(job.model_cfg, system, "cpu")
    model.fit(
        data,
        TrainSettings(steps, protocol.batch_size, protocol.lr, protocol.weight_decay),
        0,
        lambda *_: None,
    )
    infer = model._infer()
    field, nets = infer.impl.field, infer.nets64  # type: ignore[attr-defined]
    y0 = torch.as_tensor(model.view.to_model(traj.x0), dtype=torch.float64)
    t = np.asarray(traj.t, dtype=np.float64)
    calls = {"own": 0, "torchode": 0}

    def f_own(y: torch.Tensor) -> torch.Tensor:
        calls["own"] += 1
        return field(nets, y)

    def own() -> np.ndarray:
        with torch.no_grad():
            ys = dopri5(f_own, y0, t, rtol=1e-9, atol=1e-9, max_steps=50_000)
        return ys.permute(1, 0, 2).numpy()

    def f_to(_t: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        calls["torchode"] += 1
        return field(nets, y)

    term = to.ODETerm(f_to)
    solver = to.AutoDiffAdjoint(
        to.Dopri5(term=term), to.IntegralController(atol=1e-9, rtol=1e-9, term=term)
    )
    t_eval = torch.as_tensor(t).expand(y0.shape[0], -1)

    def torchode() -> np.ndarray:
        with torch.no_grad():
            sol = solver.solve(to.InitialValueProblem(y0=y0, t_eval=t_eval))
        return sol.ys.numpy()

    t_own, a = median_time(own, repeats)
    calls_own = calls["own"] // (repeats + 1)
    t_to, b = median_time(torchode, repeats)
    calls_to = calls["torchode"] // (repeats + 1)
    return (system_name, model_name, t_own, t_to, calls_own, calls_to, float(np.max(np.abs(a - b))))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--systems", nargs="+", default=["spring", "two_body"])
    parser.add_argument("--models", nargs="+", default=["mlp_torch", "hnn_torch"])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    import torch

    torch.set_num_threads(1)
    rows = [
        measure(system_name, model_name, args.steps, args.repeats)
        for system_name in args.systems
        for model_name in args.models
    ]
    print(
        "| system | model | own dopri5 ms | torchode ms | torchode / own | field calls own"
        " / torchode | max abs difference |"
    )
    print("|---|---|---|---|---|---|---|")
    worst = 0.0
    for system_name, model_name, t_own, t_to, c_own, c_to, diff in rows:
        ratio = t_to / t_own
        worst = max(worst, ratio)
        print(
            f"| {system_name} | {model_name} | {1000 * t_own:.1f} | {1000 * t_to:.1f} | "
            f"{ratio:.2f}x | {c_own} / {c_to} | {diff:.1e} |"
        )
    verdict = "switch to torchode" if worst <= RULE else "keep the own solver"
    print(f"\nslowest torchode / own: {worst:.2f}x (rule: switch if <= {RULE}x) -> {verdict}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
