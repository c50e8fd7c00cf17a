"""The SRNN's training loss with and without the shared half-kick, side by side.

    python benchmarks/srnn_window_loss.py                  # the paper spring's windows
    python benchmarks/srnn_window_loss.py --system pendulum --repeats 7

The SRNN trains through leapfrog steps (kick, drift, kick). Each step's closing
half-kick evaluates the force ``∇V(q)`` at the very ``q`` where the next step's opening
half-kick needs it, so the training loss (``window_loss`` in
``hnnbench_plugins.models.srnn.{jax,torch}``) carries it from step to step: ``2k + 1``
network gradient evaluations for ``k`` steps instead of ``3k``. This script times the
loss and its gradient (one training step's work, Adam apart) both ways in each
backend, on one training step's windows (the protocol's batch, or the whole training
set where it trains full-batch) at the paper widths, float32, one thread:

- ``chain of step``: the implementation's ``step`` chained (each step its own three
  force evaluations: the loss before the shared half-kick; in JAX under ``lax.scan``
  over the intervals, as it ran);
- ``window_loss``: the implementation's loss, as hnnbench trains.

Both give the same loss (printed; they differ only in the rounding of the gradient's
accumulation). Best of ``--repeats`` runs of ``--steps`` evaluations each, the two
interleaved so load changes hit both alike, and the ratio.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable


def _best(fn: Callable[[], object], steps: int) -> float:
    start = time.perf_counter()
    for _ in range(steps):
        fn()
    return (time.perf_counter() - start) / steps


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--system", default="spring")
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)

    import equinox as eqx
    import jax
    import jax.numpy as jnp
    import torch

    from hnnbench import _registry as registry
    from hnnbench._contracts.datasets import with_validation
    from hnnbench.neural.jax._nets import nets_from_weights
    from hnnbench.neural.torch import networks
    from hnnbench.neural.torch._nets import TrainingMLP
    from hnnbench_plugins.models.srnn import SRNNJax
    from hnnbench_plugins.models.srnn import jax as srnn_jax
    from hnnbench_plugins.models.srnn import torch as srnn_torch

    torch.set_num_threads(1)
    system_cls = registry.get_class("system", args.system)
    system = system_cls(registry.config_defaults("system", args.system))
    cfg = registry.config_defaults("model", "srnn_jax")
    model = SRNNJax(cfg, system, "cpu")
    problem = model.view.problem(with_validation(system.dataset(0), 0), *model.training_options())
    windows, dts = problem.train
    batch = system.cfg.batch_size  # one training step's windows: the protocol's batch
    if batch is not None and batch < len(windows):
        windows, dts = windows[:batch], dts[:batch]
    layout, weights = model.layout(), model.initial_weights(0)
    print(
        f"{args.system}: {windows.shape[0]} windows of {windows.shape[1]} states a step, "
        f"networks {cfg.layers - 1} x {cfg.hidden} {cfg.activation}, float32, 1 thread"
    )

    def chain(step: Callable, w: object, d: object, stack: Callable, mean: Callable) -> object:
        state, predictions = w[:, 0], []  # type: ignore[index]
        for k in range(w.shape[1] - 1):  # type: ignore[attr-defined]
            state = step(state, d[:, k][:, None])  # type: ignore[index]
            predictions.append(state)
        return mean((stack(predictions, 1) - w[:, 1:]) ** 2)  # type: ignore[index]

    # JAX: value and gradient, compiled
    nets = nets_from_weights(weights, layout, cfg.layers, cfg.activation, jnp.float32)
    params, static = eqx.partition(nets, eqx.is_inexact_array)
    wj, dj = jnp.asarray(windows, jnp.float32), jnp.asarray(dts, jnp.float32)

    def jax_loss(kind: str) -> tuple[Callable[[], object], float]:
        def loss(p: object) -> jax.Array:
            n = eqx.combine(p, static)
            if kind == "window_loss":
                return srnn_jax.window_loss(n, wj, dj)

            def interval(z: jax.Array, h: jax.Array) -> tuple[jax.Array, jax.Array]:
                z = srnn_jax.step(n, z, h[:, None])
                return z, z

            # the steps under lax.scan, as the loss ran them before the shared half-kick
            _, out = jax.lax.scan(interval, wj[:, 0], jnp.swapaxes(dj, 0, 1))
            return jnp.mean((jnp.swapaxes(out, 0, 1) - wj[:, 1:]) ** 2)

        step = jax.jit(jax.value_and_grad(loss))
        value = float(jax.block_until_ready(step(params))[0])
        return (lambda: jax.block_until_ready(step(params))), value

    # torch: value and gradient, eager
    tparams = {
        k: torch.as_tensor(v, dtype=torch.float32).clone().requires_grad_()
        for k, v in weights.items()
    }
    wt, dt = (
        torch.as_tensor(windows, dtype=torch.float32),
        torch.as_tensor(dts, dtype=torch.float32),
    )

    def torch_loss(kind: str) -> tuple[Callable[[], object], float]:
        def step() -> float:
            n = networks(tparams, layout, cfg, TrainingMLP.view)
            if kind == "window_loss":
                loss = srnn_torch.window_loss(n, wt, dt)
            else:
                loss = chain(lambda z, h: srnn_torch.step(n, z, h), wt, dt, torch.stack, torch.mean)
            torch.autograd.grad(loss, list(tparams.values()))
            return float(loss.detach())

        return step, step()

    kinds = ("chain of step", "window_loss")
    for backend, build in (("jax", jax_loss), ("torch", torch_loss)):
        built = {k: build(k) for k in kinds}
        times: dict[str, list[float]] = {k: [] for k in kinds}
        for _ in range(args.repeats):
            for k in kinds:
                times[k].append(_best(built[k][0], args.steps))
        best = {k: min(v) for k, v in times.items()}
        print(
            f"{backend:6s} "
            + "  ".join(f"{k}: {best[k] * 1e3:.2f} ms (loss {built[k][1]:.9g})" for k in kinds)
            + f"  ratio {best['window_loss'] / best['chain of step']:.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
