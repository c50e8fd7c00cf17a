"""Energy-MSE evaluation: hnnbench's batched rollout against a per-trajectory scipy loop.

    python benchmarks/eval_speed.py                      # spring, 4 models, paper settings
    python benchmarks/eval_speed.py --systems spring pendulum --repeats 5
    python benchmarks/eval_speed.py --steps 200 --repeats 1          # quick check

For each (system, model) it builds the paper-profile system, its dataset and its
evaluation trajectories (the same cache entries a real run uses, under
``$HNNBENCH_CACHE_DIR``), trains the model with ``Model.fit`` at the system's paper
settings (``--steps`` shortens training; the learned field only has to be realistic),
then times two ways of computing the ``energy_mse`` metric (docs/METRICS.md) on all
evaluation trajectories:

(a) **batched** (what :func:`hnnbench._running.evaluation.evaluate` does): one
    ``model.rollout(x0_all, t, rtol, atol)`` call from every initial state at once,
    the batch integrated as one system by the backend's adaptive Dormand-Prince 5(4)
    in float64 (hnnbench's own batched ``dopri5`` for torch, diffrax ``Dopri5`` for JAX), then the
    energy MSE with hnnbench's own functions (the true energy along each rollout,
    ``metrics.energy_error_per_traj``, ``metrics.summarize``).
(b) **scipy loop** (the 2019 code's way): for each trajectory separately,
    ``scipy.integrate.solve_ivp(fun, (t0, t1), x0, t_eval=t, method="RK45", ...)``
    where ``fun`` calls the model once per right-hand-side evaluation on a single state,
    ``model.time_derivative(x[None])[0]``, then the same energy MSE functions.

Both use the same tolerances: ``evaluation.rtol`` / ``evaluation.atol`` of the
harness config (conf/config.yaml, 1e-9 by default; ``--rtol`` / ``--atol`` override
them). scipy's ``RK45`` is the same Dormand-Prince 5(4) pair as ``dopri5``/``Dopri5``
and all three use an RMS error norm, so a tolerance means the same thing to each. One
difference remains: the batched solve takes one step-size sequence for the whole batch
and its RMS norm runs over every trajectory's components, where the loop adapts the step
to each trajectory alone. The two energy MSEs therefore agree to about the solver
tolerance, not bit for bit; their relative difference is printed.

Each path runs once untimed first (JIT compilation for JAX, first-call costs for
torch; the loop's warm-up integrates only the first trajectory, which is all its
single-state compilation needs), then ``--repeats`` timed times; the median is
reported. Timed: from the numpy initial states to the energy MSE, nothing else. The
scipy loop's right-hand-side evaluations (``sol.nfev``, summed over trajectories) and,
for torch, the batched solve's calls of the vector field are printed for context.
One thread per process (hnnbench's default). The target of the "Speed and scale"
issue: on spring (15 trajectories) the batched path is at least 20x faster.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Optional, TypeVar

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

#: The issue's target speed-up of the batched path over the scipy loop.
TARGET_SPEEDUP = 20.0

T = TypeVar("T")


@dataclass
class Row:
    """The measurements of one (system, model) pair."""

    system: str
    model: str
    n_traj: int
    n_points: int
    rtol: float
    atol: float
    fit_s: float
    batched_ms: float
    batched_min_ms: float
    loop_ms: float
    loop_min_ms: float
    loop_nfev: int
    batched_rhs_calls: Optional[int]
    energy_mse_batched: float
    energy_mse_loop: float

    @property
    def speedup(self) -> float:
        """Scipy-loop time / batched time (medians)."""
        return self.loop_ms / self.batched_ms

    @property
    def rel_diff(self) -> float:
        """``|a - b| / max(|a|, |b|)`` of the two energy MSEs (0 when both are 0)."""
        a, b = self.energy_mse_batched, self.energy_mse_loop
        scale = max(abs(a), abs(b))
        return abs(a - b) / scale if scale > 0 else 0.0


# --------------------------------------------------------------------------- the two paths


def energy_mse(system: Any, traj: Any, states_hat: np.ndarray) -> float:
    """The ``energy_mse`` metric's mean, computed as :func:`hnnbench._running.evaluation.evaluate`
    does: true energy along the rollout vs along the true trajectories."""
    from hnnbench_plugins import metrics as builtin_metrics

    def _energies(system: Any, states: np.ndarray) -> np.ndarray:
        # (M, T, 2n) -> (M, T), as hnnbench._running.evaluation does
        m, t, d = states.shape
        return system.energy(states.reshape(m * t, d)).reshape(m, t)

    e_true, e_hat = _energies(system, traj.states), _energies(system, states_hat)
    return builtin_metrics.summarize(builtin_metrics.energy_error_per_traj(e_hat, e_true))["mean"]


def batched_energy_mse(system: Any, model: Any, traj: Any, rtol: float, atol: float) -> float:
    """(a) hnnbench's path: one batched rollout of all initial states, then the metric."""
    from hnnbench._contracts.errors import RolloutDiverged

    states_hat = model.rollout(traj.x0, traj.t, rtol=rtol, atol=atol)
    if not np.all(np.isfinite(states_hat)):
        raise RolloutDiverged("batched rollout produced non-finite states")
    return energy_mse(system, traj, states_hat)


def loop_energy_mse(
    system: Any, model: Any, traj: Any, rtol: float, atol: float
) -> tuple[float, int]:
    """(b) the 2019-style path: ``solve_ivp(RK45)`` per trajectory, one model call per
    right-hand-side evaluation on a single state. Returns the metric and the summed
    ``nfev``."""
    from scipy.integrate import solve_ivp

    from hnnbench._contracts.errors import RolloutDiverged

    def fun(_t: float, x: np.ndarray) -> np.ndarray:
        return model.time_derivative(x[None])[0]

    t = np.asarray(traj.t, dtype=np.float64)
    rollouts: list[np.ndarray] = []
    nfev = 0
    for x0 in traj.x0:
        sol = solve_ivp(
            fun, (float(t[0]), float(t[-1])), x0, t_eval=t, method="RK45", rtol=rtol, atol=atol
        )
        if not sol.success or sol.y.shape[1] != t.shape[0]:
            raise RolloutDiverged(f"scipy RK45 failed: {sol.message}")
        rollouts.append(sol.y.T)
        nfev += int(sol.nfev)
    states_hat = np.stack(rollouts)
    if not np.all(np.isfinite(states_hat)):
        raise RolloutDiverged("scipy RK45 rollout produced non-finite states")
    return energy_mse(system, traj, states_hat), nfev


def timed(fn: Callable[[], T], repeats: int) -> tuple[float, float, T]:
    """Run ``fn`` ``repeats`` times; the median and minimum milliseconds and the last
    result."""
    times: list[float] = []
    result: Any = None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(1e3 * (time.perf_counter() - start))
    return statistics.median(times), min(times), result


@contextmanager
def counting_field_calls(model: Any) -> Iterator[list[int]]:
    """Count a neural model's calls of its family's vector field during a batched
    rollout (its solver calls the field once per right-hand-side evaluation, on the whole
    batch). Yields a one-element list holding the count.

    The hook is on the model's float64 :class:`~hnnbench.neural._backend.Inference`
    (``NeuralModel._infer()``): the torch backend's ``TorchInference.rollout`` calls
    ``self.impl.field(nets, y)`` (``impl`` is the family's torch module) at every
    evaluation, so ``impl`` is swapped, on that one object, for a proxy whose ``field``
    counts. Only meaningful for torch: a JAX rollout is one compiled program (diffrax),
    which calls the Python field once, while tracing.
    """
    count = [0]
    infer = model._infer()
    impl = infer.impl

    class Counted:
        def __getattr__(self, name: str) -> Any:
            return getattr(impl, name)

        @staticmethod
        def field(*args: Any, **kwargs: Any) -> Any:
            count[0] += 1
            return impl.field(*args, **kwargs)

    infer.impl = Counted()
    try:
        yield count
    finally:
        infer.impl = impl


# --------------------------------------------------------------------------- one pair


def measure(
    system_name: str,
    model_name: str,
    steps: Optional[int],
    repeats: int,
    seed: int,
    device: str,
    rtol: Optional[float],
    atol: Optional[float],
) -> Row:
    """Build, train and time one (system, model) pair."""
    from omegaconf import OmegaConf

    from hnnbench._contracts.errors import ConfigError
    from hnnbench._contracts.metric import EvaluationConfig
    from hnnbench._contracts.plugin import Dataset, TrainSettings, Trajectories
    from hnnbench._running import dataset_cache
    from hnnbench._running.compose import compose
    from hnnbench._running.config import prepare_job

    cfg = compose([f"system={system_name}", f"model={model_name}"])
    job = prepare_job(cfg)
    ev = EvaluationConfig(**OmegaConf.to_container(cfg.evaluation, resolve=True))  # type: ignore[arg-type]
    rtol = ev.rtol if rtol is None else rtol
    atol = ev.atol if atol is None else atol
    system = job.system_cls(job.system_cfg)
    if system.observation != "state":
        raise ConfigError(
            f"{system_name}: models see {system.observation}, not states; this benchmark "
            "integrates states only (choose a state system such as spring or pendulum)."
        )
    reason = job.model_cls.unsupported_reason(system)
    if reason is not None:
        raise ConfigError(f"{model_name} on {system_name}: {reason}")
    if job.model_cls.backend == "torch":
        import torch

        torch.set_num_threads(1)

    root = dataset_cache.cache_root()
    data, _, _ = dataset_cache.cached(
        system, seed, "dataset", lambda: system.dataset(seed), Dataset.load, root
    )
    traj, _, _ = dataset_cache.cached(
        system, seed, "evaluation", lambda: system.evaluation(seed), Trajectories.load, root
    )

    train = TrainSettings.resolve(job.system_cfg, job.model_cfg)
    if steps is not None:
        train = dataclasses.replace(train, steps=steps)
    model = job.model_cls(job.model_cfg, system, device)
    start = time.perf_counter()
    model.fit(data, train, seed, lambda *_: None)
    fit_s = time.perf_counter() - start

    # Warm-up: JIT compilation (JAX) and first-call costs, for each path's shapes.
    batched_energy_mse(system, model, traj, rtol, atol)
    first = dataclasses.replace(traj, states=traj.states[:1])
    loop_energy_mse(system, model, first, rtol, atol)

    batched_ms, batched_min, mse_batched = timed(
        lambda: batched_energy_mse(system, model, traj, rtol, atol), repeats
    )
    loop_ms, loop_min, (mse_loop, nfev) = timed(
        lambda: loop_energy_mse(system, model, traj, rtol, atol), repeats
    )

    rhs_calls: Optional[int] = None
    if job.model_cls.backend == "torch" and hasattr(model, "_infer"):  # untimed: how
        # many batched field calls (neural torch models)
        with counting_field_calls(model) as count:
            model.rollout(traj.x0, traj.t, rtol=rtol, atol=atol)
        rhs_calls = count[0]

    return Row(
        system=system_name,
        model=model_name,
        n_traj=int(traj.states.shape[0]),
        n_points=int(traj.t.shape[0]),
        rtol=rtol,
        atol=atol,
        fit_s=fit_s,
        batched_ms=batched_ms,
        batched_min_ms=batched_min,
        loop_ms=loop_ms,
        loop_min_ms=loop_min,
        loop_nfev=nfev,
        batched_rhs_calls=rhs_calls,
        energy_mse_batched=mse_batched,
        energy_mse_loop=mse_loop,
    )


# --------------------------------------------------------------------------- output


def markdown_table(rows: Sequence[Row]) -> str:
    """The results as a Markdown table."""
    lines = [
        "| system | model | traj | batched ms | scipy-loop ms | speed-up | "
        "loop RHS evals | batched RHS calls | energy MSE batched | energy MSE loop | "
        "rel. diff |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        calls = "—" if r.batched_rhs_calls is None else str(r.batched_rhs_calls)
        lines.append(
            f"| {r.system} | {r.model} | {r.n_traj} | {r.batched_ms:.1f} | {r.loop_ms:.1f} | "
            f"{r.speedup:.1f}x | {r.loop_nfev} | {calls} | {r.energy_mse_batched:.6e} | "
            f"{r.energy_mse_loop:.6e} | {r.rel_diff:.1e} |"
        )
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--systems", nargs="+", default=["spring"], help="state systems (default: spring)"
    )
    parser.add_argument(
        "--models", nargs="+", default=["mlp_torch", "hnn_torch", "mlp_jax", "hnn_jax"]
    )
    parser.add_argument(
        "--steps",
        type=int,
        default=None,
        help="training steps (default: the system's paper setting)",
    )
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per path")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--device", default="cpu", help="cpu (default), auto, cuda[:N]")
    parser.add_argument(
        "--rtol", type=float, default=None, help="default: evaluation.rtol of conf/config.yaml"
    )
    parser.add_argument(
        "--atol", type=float, default=None, help="default: evaluation.atol of conf/config.yaml"
    )
    args = parser.parse_args(argv)
    if args.repeats < 1 or (args.steps is not None and args.steps < 1):
        parser.error("--repeats and --steps must be >= 1")

    from hnnbench._contracts.errors import HnnbenchError, RolloutDiverged

    rows: list[Row] = []
    failures: list[str] = []
    for system_name in args.systems:
        for model_name in args.models:
            try:
                row = measure(
                    system_name,
                    model_name,
                    args.steps,
                    args.repeats,
                    args.seed,
                    args.device,
                    args.rtol,
                    args.atol,
                )
            except (HnnbenchError, RolloutDiverged) as err:  # bad name, unsupported, diverged
                failures.append(f"{system_name} / {model_name}: {err}")
                print(f"{system_name:10s} {model_name:10s} FAILED: {err}", flush=True)
                continue
            rows.append(row)
            print(
                f"{row.system:10s} {row.model:10s} {row.n_traj} traj x {row.n_points} pts, "
                f"rtol={row.rtol:g} atol={row.atol:g} (fit {row.fit_s:.1f} s)\n"
                f"    batched    {row.batched_ms:9.1f} ms (min {row.batched_min_ms:.1f})"
                f"  energy MSE {row.energy_mse_batched:.6e}\n"
                f"    scipy loop {row.loop_ms:9.1f} ms (min {row.loop_min_ms:.1f})"
                f"  energy MSE {row.energy_mse_loop:.6e}  ({row.loop_nfev} RHS evals)\n"
                f"    speed-up {row.speedup:.1f}x; energy MSE rel. diff {row.rel_diff:.1e}",
                flush=True,
            )

    if rows:
        print(
            f"\nMedian of {args.repeats} timed run(s) after one warm-up; "
            f"target: batched >= {TARGET_SPEEDUP:g}x faster on spring.\n"
        )
        print(markdown_table(rows))
    for line in failures:
        print(f"FAILED: {line}")
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
