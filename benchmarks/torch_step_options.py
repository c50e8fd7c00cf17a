"""What makes the torch training step slower than JAX's, option by option, side by side.

    python benchmarks/torch_step_options.py                  # spring, full batch 750
    python benchmarks/torch_step_options.py --batch 200 --steps 300 --repeats 5

One process, pinned to one core with one thread (as hnnbench runs its jobs). It times
the MLP and HNN training steps of the spring at the paper's shape (2 -> 200 -> 200 ->
out, tanh, Adam with weight decay), written directly in torch the way hnnbench's torch
backend computes them (``F.linear`` layers; the HNN's closed-form input gradient), and
changes one thing at a time:

- ``baseline``: hnnbench's torch step (Adam, default ``foreach`` implementation);
- ``adam-fused``: ``torch.optim.Adam(fused=True)``;
- ``adam-single``: ``torch.optim.Adam(foreach=False)`` (a loop over parameters);
- ``tanh-sigmoid``: ``tanh(a) = 2 sigmoid(2a) - 1`` in a custom autograd function whose
  backward is ``tanh_backward`` (one fused kernel), in place of ``torch.tanh``;
- ``compile``: the whole step (forward, backward, Adam) under ``torch.compile``
  (inductor's C++ code; its compile time is printed apart and not counted).

Next to them, the same step in JAX (``jax.jit`` of forward, backward and optax Adam, the
hnnbench JAX backend's structure), and per-op timings of torch's and XLA's ``tanh`` on
the hidden layer's shape, so the ratios can be read against the op that dominates.
Median of ``--repeats`` runs of ``--steps`` steps each, after a warm-up; the repeats of
all variants are interleaved, so load changes hit every column alike.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")


def _pin(cpu: int) -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {cpu})


def torch_variants(n: int, hidden: int, out: int, hnn: bool) -> dict[str, Callable[[], None]]:
    import torch
    import torch.nn.functional as F

    torch.set_num_threads(1)
    gen = torch.Generator().manual_seed(0)
    x = torch.randn(n, 2, generator=gen)
    y = torch.randn(n, 2, generator=gen)

    class FastTanh(torch.autograd.Function):
        @staticmethod
        def forward(a: torch.Tensor) -> torch.Tensor:  # type: ignore[override]
            return torch.sigmoid(a * 2.0).mul_(2.0).sub_(1.0)

        @staticmethod
        def setup_context(ctx: Any, inputs: Any, output: torch.Tensor) -> None:
            ctx.save_for_backward(output)

        @staticmethod
        def backward(ctx: Any, grad: torch.Tensor) -> torch.Tensor:  # type: ignore[override]
            (h,) = ctx.saved_tensors
            return torch.ops.aten.tanh_backward(grad, h)

    def params() -> list[torch.Tensor]:
        shapes = [(hidden, 2), (hidden,), (hidden, hidden), (hidden,), (out, hidden)]
        return [(torch.randn(*s, generator=gen) * 0.1).requires_grad_() for s in shapes]

    def loss_of(act: Callable[[torch.Tensor], torch.Tensor]) -> Callable[..., torch.Tensor]:
        def mlp(ps: list[torch.Tensor]) -> torch.Tensor:
            w1, b1, w2, b2, w3 = ps
            h = act(F.linear(act(F.linear(x, w1, b1)), w2, b2))
            return torch.mean((F.linear(h, w3) - y) ** 2)

        def hnn_loss(ps: list[torch.Tensor]) -> torch.Tensor:  # closed-form input gradient
            w1, b1, w2, b2, w3 = ps
            h1 = act(F.linear(x, w1, b1))
            h2 = act(F.linear(h1, w2, b2))
            g = (w3.expand(n, -1) * (1 - h2 * h2)) @ w2
            g = (g * (1 - h1 * h1)) @ w1
            field = torch.cat([g[:, 1:], -g[:, :1]], dim=1)
            return torch.mean((field - y) ** 2)

        return hnn_loss if hnn else mlp

    def step(act: Callable[[torch.Tensor], torch.Tensor], **adam: Any) -> Callable[[], None]:
        ps = params()
        opt = torch.optim.Adam(ps, lr=1e-3, weight_decay=1e-4, **adam)
        loss = loss_of(act)

        def one() -> None:
            value = loss(ps)
            opt.zero_grad(set_to_none=True)
            value.backward()
            opt.step()

        return one

    variants = {
        "baseline": step(torch.tanh),
        "adam-fused": step(torch.tanh, fused=True),
        "adam-single": step(torch.tanh, foreach=False),
        "tanh-sigmoid": step(FastTanh.apply),
    }
    compiled = torch.compile(step(torch.tanh))
    start = time.perf_counter()
    compiled()
    print(f"  torch.compile of the {'hnn' if hnn else 'mlp'} step: "
          f"{time.perf_counter() - start:.1f} s (not counted)", flush=True)
    variants["compile"] = compiled
    return variants


def jax_step(n: int, hidden: int, out: int, hnn: bool) -> Callable[[], None]:
    import jax
    import jax.numpy as jnp
    import numpy as np
    import optax

    rng = np.random.default_rng(0)
    x = jnp.asarray(rng.normal(size=(n, 2)), jnp.float32)
    y = jnp.asarray(rng.normal(size=(n, 2)), jnp.float32)
    shapes = [(hidden, 2), (hidden,), (hidden, hidden), (hidden,), (out, hidden)]
    ps = [jnp.asarray(rng.normal(size=s) * 0.1, jnp.float32) for s in shapes]

    def mlp(ps: list[Any]) -> Any:
        w1, b1, w2, b2, w3 = ps
        h = jnp.tanh(jnp.tanh(x @ w1.T + b1) @ w2.T + b2)
        return jnp.mean((h @ w3.T - y) ** 2)

    def hnn_loss(ps: list[Any]) -> Any:
        w1, b1, w2, b2, w3 = ps

        def h_of(xi: Any) -> Any:
            return (jnp.tanh(jnp.tanh(xi @ w1.T + b1) @ w2.T + b2) @ w3.T)[0]

        g = jax.vmap(jax.grad(h_of))(x)
        return jnp.mean((jnp.concatenate([g[:, 1:], -g[:, :1]], 1) - y) ** 2)

    loss = hnn_loss if hnn else mlp
    opt = optax.chain(optax.add_decayed_weights(1e-4), optax.adam(1e-3))
    state = [ps, opt.init(ps)]

    @jax.jit
    def update(ps: Any, st: Any) -> Any:
        grads = jax.grad(loss)(ps)
        upd, st = opt.update(grads, st, ps)
        return optax.apply_updates(ps, upd), st

    def one() -> None:
        state[0], state[1] = update(state[0], state[1])

    one()
    jax.block_until_ready(state[0])

    def synced() -> None:
        one()

    synced.block = lambda: jax.block_until_ready(state[0])  # type: ignore[attr-defined]
    return synced


def time_steps(fn: Callable[[], None], steps: int) -> float:
    start = time.perf_counter()
    for _ in range(steps):
        fn()
    block = getattr(fn, "block", None)
    if block is not None:
        block()
    return (time.perf_counter() - start) / steps * 1e3


def op_timings(n: int, hidden: int) -> None:
    import jax
    import jax.numpy as jnp
    import torch

    a = torch.randn(n, hidden)
    ja = jnp.asarray(a.numpy())
    jtanh = jax.jit(jnp.tanh)
    jtanh(ja).block_until_ready()

    def med(fn: Callable[[], Any], reps: int = 500) -> float:
        for _ in range(20):
            fn()
        times = []
        for _ in range(5):
            start = time.perf_counter()
            for _ in range(reps):
                fn()
            times.append((time.perf_counter() - start) / reps * 1e6)
        return statistics.median(times)

    rows = {
        "torch.tanh": med(lambda: torch.tanh(a)),
        "2 sigmoid(2a) - 1": med(lambda: torch.sigmoid(a * 2).mul_(2).sub_(1)),
        "torch.sigmoid": med(lambda: torch.sigmoid(a)),
        "jax.numpy.tanh (XLA)": med(lambda: jtanh(ja).block_until_ready()),
    }
    print(f"\n  one op on ({n}, {hidden}) float32, microseconds (median of 5 x 500):")
    for name, us in rows.items():
        print(f"    {name:24s} {us:8.1f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=750)
    parser.add_argument("--hidden", type=int, default=200)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--cpu", type=int, default=0)
    args = parser.parse_args()
    _pin(args.cpu)
    print(f"load average {os.getloadavg()[0]:.2f}; batch {args.batch}, hidden {args.hidden}, "
          f"{args.steps} steps x {args.repeats} repeats, one core, one thread", flush=True)
    for family, out, hnn in (("mlp", 2, False), ("hnn", 1, True)):
        variants = torch_variants(args.batch, args.hidden, out, hnn)
        variants["jax"] = jax_step(args.batch, args.hidden, out, hnn)
        times: dict[str, list[float]] = {k: [] for k in variants}
        for fn in variants.values():  # warm-up
            time_steps(fn, 10)
        for _ in range(args.repeats):
            for name, fn in variants.items():
                times[name].append(time_steps(fn, args.steps))
        jax_ms = statistics.median(times["jax"])
        base = statistics.median(times["baseline"])
        print(f"\n  {family} step, ms (median)   vs torch baseline   vs JAX")
        for name, values in times.items():
            ms = statistics.median(values)
            print(f"    {name:14s} {ms:8.3f}       {ms / base:6.2f}x         {ms / jax_ms:6.2f}x")
    op_timings(args.batch, args.hidden)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
