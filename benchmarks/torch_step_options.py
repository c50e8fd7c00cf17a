"""What makes the torch training step slower than JAX's, option by option, side by side.

    python benchmarks/torch_step_options.py                       # spring and two_body shapes
    python benchmarks/torch_step_options.py --shapes spring --steps 200 --repeats 5
    python benchmarks/torch_step_options.py --no-compile          # without torch.compile (~1 min)

One process, pinned to one core with one thread (as hnnbench runs its jobs). For the
MLP and the HNN at the paper's widths (d -> 200 -> 200 -> out, tanh, Adam with weight
decay) on two shapes, the spring's full batch (690 rows of d = 2: its training set
after the validation carve) and the two-body minibatch (200 rows of d = 8), it times
one training step built several ways, on the same data and initial weights:

- ``a47bd0f``: hnnbench's torch step before issue 29's work: :class:`MLP` networks
  (plain tensor operations that autograd differentiates op by op), the loss
  ``mean((f - y)**2)``, ``torch.optim.Adam(fused=True)`` with ``zero_grad``,
  ``backward`` and ``step``;
- ``+ direct Adam``: the same, the update by :class:`~hnnbench.neural.torch.FusedAdam`
  (the same fused kernel, called without the optimizer's per-step Python);
- ``+ mse_loss``: and ``F.mse_loss`` for the loss (one autograd node);
- ``hnnbench``: and :class:`~hnnbench.neural.torch.TrainingMLP` networks (value and
  input gradient each one autograd node with a hand-written backward,
  :mod:`hnnbench.neural.torch._backprop`): the step hnnbench runs now;
- ``hnnbench + flush denormals``: the same with ``torch.set_flush_denormal(True)``
  (XLA's CPU default) around the step;
- ``hnnbench + oneDNN tanh``: the same with the forward ``tanh`` computed by oneDNN's
  eltwise kernel (``torch.tanh(a.to_mkldnn()).to_dense()``, both layout conversions
  counted) in place of ATen's (within 1 ulp of float64 ``tanh`` here, like ATen's);
- ``hnnbench + sigmoid tanh``: the same with the forward ``tanh`` written as
  ``2 sigmoid(2a) - 1`` in place (ATen's float32 ``sigmoid`` kernel is several times
  cheaper than its ``tanh``; absolute error within a few ulps of 1, relative error
  large where ``|a|`` is tiny);
- ``hnnbench + fused linear-tanh``: the same with each hidden layer's forward product,
  bias and ``tanh`` as one oneDNN call (``torch.ops.mkldnn._linear_pointwise`` with its
  ``tanh`` post-op, the fusion inductor uses on CPU) in place of ``addmm`` then ATen's
  ``tanh_``: the issue's "fused activations";
- ``torch.func.grad``: the ``hnnbench`` loss differentiated by ``torch.func.grad`` over
  the parameter dict instead of ``torch.autograd.grad``;
- ``no autograd``: the step's gradient derived by hand and written as plain tensor
  operations, nothing recorded: the floor for eager torch with these kernels;
- ``no autograd + sigmoid tanh``: that floor with the sigmoid form of ``tanh``;
- ``torch.compile``: the ``a47bd0f`` step under ``torch.compile`` (inductor's C++
  code for forward, backward and the update; ``--compile-mode``; its compile time is
  printed apart, not counted, and set against the time it saves per step against
  ``hnnbench``: the steps after which it pays off), unless ``--no-compile``;
- ``JAX``: the same step as hnnbench's JAX backend runs it: one ``jax.jit``-compiled
  chunk of 10 steps (``lax.scan`` of ``value_and_grad`` and optax's Adam made equal to
  torch's), timed per step.

Each variant's gradient at the first step is compared with ``a47bd0f``'s (largest
difference relative to the largest entry), so every row computes the same step.
Median (and best) of ``--repeats`` runs of ``--steps`` steps each, after a warm-up;
the repeats of all variants are interleaved, so load changes hit every column alike.
Then per-op timings on the hidden layer's shape: torch's, XLA's, oneDNN's and the
sigmoid form's ``tanh`` (and torch's ``sigmoid``, for scale), the thin products in the
two orientations a step can dispatch them, and each float32 ``tanh``'s error against
float64's.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

#: name -> (rows, state dimension): the spring's full batch, the two-body minibatch.
SHAPES = {"spring": (690, 2), "two_body": (200, 8)}
HIDDEN = 200
LR, WEIGHT_DECAY = 1e-3, 1e-4
Step = Callable[[], Any]


def _pin(cpu: int | None) -> int | None:
    if not hasattr(os, "sched_setaffinity"):
        return None
    cpu = min(os.sched_getaffinity(0)) if cpu is None else cpu
    os.sched_setaffinity(0, {cpu})
    return cpu


def onednn_tanh(a: Any) -> Any:
    """``tanh(a)`` by oneDNN's eltwise kernel, both layout conversions included."""
    import torch

    return torch.tanh(a.to_mkldnn()).to_dense()


def sigmoid_tanh_(a: Any) -> Any:
    """``tanh(a) = 2 sigmoid(2a) - 1`` in place (ATen's float32 ``sigmoid`` is a much
    cheaper kernel than its ``tanh``); the absolute error is a few float32 ulps of 1,
    so the relative error grows where ``|a|`` is small (``op_timings`` prints both)."""
    return a.mul_(2.0).sigmoid_().mul_(2.0).sub_(1.0)


def initial_arrays(d: int, out: int, seed: int = 0) -> dict[str, Any]:
    """The network ``f`` (``d -> 200 -> 200 -> out``) with hnnbench's seeded initial
    weights, as numpy arrays."""
    from hnnbench.neural import NeuralConfig
    from hnnbench.neural._init import init_arrays

    cfg = NeuralConfig(name="options", hidden=HIDDEN, layers=3)
    return {f"f.{k}": v for k, v in init_arrays(seed, d, out, cfg).items()}


def torch_variants(
    n: int, d: int, hnn: bool, compile_mode: str | None
) -> tuple[dict[str, Step], dict[str, float], float]:
    """``{name: step}`` for one shape and family, each variant's gradient difference
    from the ``a47bd0f`` step (relative to its largest entry), and the seconds
    ``torch.compile`` took (NaN without it)."""
    import numpy as np
    import torch
    import torch.nn.functional as F

    from hnnbench.neural.torch import FusedAdam
    from hnnbench.neural.torch._nets import MLP, TrainingMLP, symplectic

    torch.set_num_threads(1)
    rng = np.random.default_rng(1)
    x = torch.as_tensor(rng.normal(size=(n, d)), dtype=torch.float32)
    y = torch.as_tensor(rng.normal(size=(n, d)), dtype=torch.float32)
    arrays = initial_arrays(d, 1 if hnn else d)

    def fresh() -> dict[str, torch.Tensor]:
        return {
            k: torch.as_tensor(v, dtype=torch.float32).clone().requires_grad_()
            for k, v in arrays.items()
        }

    def plain_symplectic(g: torch.Tensor) -> torch.Tensor:  # a47bd0f's
        return torch.cat([g[:, d // 2 :], -g[:, : d // 2]], dim=-1)

    def field(net: MLP) -> torch.Tensor:
        if not hnn:
            return net(x)
        j = symplectic if isinstance(net, TrainingMLP) else plain_symplectic
        return j(net.input_gradient(x))

    def loss_mean(cls: type[MLP]) -> Callable[[dict[str, torch.Tensor]], torch.Tensor]:
        return lambda p: torch.mean((field(cls.view(p, "f", 3, "tanh")) - y) ** 2)

    def loss_mse(cls: type[MLP]) -> Callable[[dict[str, torch.Tensor]], torch.Tensor]:
        return lambda p: F.mse_loss(field(cls.view(p, "f", 3, "tanh")), y)

    grads: dict[str, list[torch.Tensor]] = {}

    def swapped(
        attr: str, replacement: Callable[..., Any], loss: Callable[..., torch.Tensor]
    ) -> Callable[..., torch.Tensor]:
        """``loss`` with :mod:`hnnbench.neural.torch._backprop`'s ``attr`` replaced by
        ``replacement`` while it runs."""
        from hnnbench.neural.torch import _backprop

        plain = getattr(_backprop, attr)

        def patched(p: dict[str, torch.Tensor]) -> torch.Tensor:
            setattr(_backprop, attr, replacement)
            try:
                return loss(p)
            finally:
                setattr(_backprop, attr, plain)

        return patched

    def with_tanh(
        kernel: Callable[[torch.Tensor], torch.Tensor], loss: Callable[..., torch.Tensor]
    ) -> Callable[..., torch.Tensor]:
        """``loss`` with the hand-written backward's forward float32 ``tanh`` by
        ``kernel`` (the backward's ``tanh_backward`` reads its output, as before)."""
        from hnnbench.neural.torch import _backprop

        plain = _backprop._act

        def act(name: str, a: torch.Tensor) -> torch.Tensor:
            if name == "tanh" and a.dtype == torch.float32:
                return kernel(a)
            return plain(name, a)

        return swapped("_act", act, loss)

    def with_fused_linear_tanh(loss: Callable[..., torch.Tensor]) -> Callable[..., torch.Tensor]:
        """``loss`` with the hand-written backward's forward layers (product, bias,
        float32 ``tanh``) each one oneDNN call with a ``tanh`` post-op."""
        from hnnbench.neural.torch import _backprop

        plain = _backprop._forward
        fused = torch.ops.mkldnn._linear_pointwise

        def forward(name: str, x: torch.Tensor, params: tuple[torch.Tensor, ...]) -> Any:
            if name != "tanh" or x.dtype != torch.float32:
                return plain(name, x, params)
            hs = [x]
            for k in range(len(params) // 2):
                hs.append(fused(hs[-1], params[2 * k], params[2 * k + 1], "tanh", [], ""))
            return [None] * (len(params) // 2), hs

        return swapped("_forward", forward, loss)

    def optimizer_step(name: str, loss: Callable[..., torch.Tensor]) -> Step:
        params = fresh()
        grads[name] = list(torch.autograd.grad(loss(params), list(params.values())))
        opt = torch.optim.Adam(list(params.values()), lr=LR, weight_decay=WEIGHT_DECAY, fused=True)

        def one() -> None:
            value = loss(params)
            opt.zero_grad(set_to_none=True)
            value.backward()
            opt.step()

        return one

    def direct_step(
        name: str,
        loss: Callable[..., torch.Tensor],
        ftz: bool = False,
        tanh: Callable[[torch.Tensor], torch.Tensor] | None = None,
    ) -> Step:
        if tanh is not None:
            loss = with_tanh(tanh, loss)
        params = fresh()
        grads[name] = list(torch.autograd.grad(loss(params), list(params.values())))
        adam = FusedAdam(list(params.values()), LR, WEIGHT_DECAY)
        if not ftz:
            return lambda: adam.step(loss(params))

        def flushed() -> None:
            torch.set_flush_denormal(True)
            try:
                adam.step(loss(params))
            finally:
                torch.set_flush_denormal(False)

        return flushed

    def func_grad_step(name: str, loss: Callable[..., torch.Tensor]) -> Step:
        params = fresh()
        adam = FusedAdam(list(params.values()), LR, WEIGHT_DECAY)
        grad_fn = torch.func.grad(loss)
        grads[name] = list(grad_fn({k: v.detach() for k, v in params.items()}).values())

        def one() -> None:
            g = grad_fn({k: v.detach() for k, v in params.items()})
            with torch.no_grad():
                torch._foreach_add_(adam.steps, 1)
                torch._fused_adam_(
                    adam.params,
                    list(g.values()),
                    adam.exp_avg,
                    adam.exp_avg_sq,
                    [],
                    adam.steps,
                    lr=LR,
                    beta1=0.9,
                    beta2=0.999,
                    weight_decay=WEIGHT_DECAY,
                    eps=1e-8,
                    amsgrad=False,
                    maximize=False,
                )

        return one

    def manual_step(name: str, tanh_: Callable[[torch.Tensor], torch.Tensor] = torch.tanh_) -> Step:
        params = fresh()
        w1, b1, w2, b2, w3 = (
            params[f"f.linears.{i}.{kind}"].detach()
            for i, kind in ((0, "weight"), (0, "bias"), (1, "weight"), (1, "bias"), (2, "weight"))
        )
        adam = FusedAdam([w1, b1, w2, b2, w3], LR, WEIGHT_DECAY)
        tb = torch.ops.aten.tanh_backward
        half = d // 2
        scale = 2.0 / (n * d)

        def gradient() -> list[torch.Tensor]:
            h1 = tanh_(torch.addmm(b1, x, w1.t()))
            h2 = tanh_(torch.addmm(b2, h1, w2.t()))
            if not hnn:
                r = torch.mm(h2, w3.t()).sub_(y).mul_(scale)
                da2 = tb(r @ w3, h2)
                da1 = tb(da2 @ w2, h1)
                return [da1.t() @ x, da1.sum(0), da2.t() @ h1, da2.sum(0), r.t() @ h2]
            g2 = tb(w3.expand(n, -1), h2)
            u1 = g2 @ w2
            g1 = tb(u1, h1)
            g0 = g1 @ w1
            r = torch.cat([g0[:, half:], -g0[:, :half]], 1).sub_(y).mul_(scale)
            dg0 = torch.cat([-r[:, half:], r[:, :half]], 1)  # Jᵀ r
            gw1 = g1.t() @ dg0
            dg1 = dg0 @ w1.t()
            du1 = tb(dg1, h1)
            dh1 = dg1.mul_(u1).mul_(h1).mul_(-2.0)
            dg2 = du1 @ w2.t()
            gw2 = g2.t() @ du1
            gw3 = tb(dg2, h2).sum(0, keepdim=True)
            da2 = tb(dg2.mul_(w3).mul_(h2).mul_(-2.0), h2)
            gw2.addmm_(da2.t(), h1)
            dh1.addmm_(da2, w2)
            da1 = tb(dh1, h1)
            gw1.addmm_(da1.t(), x)
            return [gw1, da1.sum(0), gw2, da2.sum(0), gw3]

        grads[name] = gradient()

        def one() -> None:
            g = gradient()
            torch._foreach_add_(adam.steps, 1)
            torch._fused_adam_(
                adam.params,
                g,
                adam.exp_avg,
                adam.exp_avg_sq,
                [],
                adam.steps,
                lr=LR,
                beta1=0.9,
                beta2=0.999,
                weight_decay=WEIGHT_DECAY,
                eps=1e-8,
                amsgrad=False,
                maximize=False,
            )

        return one

    variants = {
        "a47bd0f": optimizer_step("a47bd0f", loss_mean(MLP)),
        "+ direct Adam": direct_step("+ direct Adam", loss_mean(MLP)),
        "+ mse_loss": direct_step("+ mse_loss", loss_mse(MLP)),
        "hnnbench": direct_step("hnnbench", loss_mse(TrainingMLP)),
        "hnnbench + flush denormals": direct_step(
            "hnnbench + flush denormals", loss_mse(TrainingMLP), ftz=True
        ),
        **(
            {
                "hnnbench + oneDNN tanh": direct_step(
                    "hnnbench + oneDNN tanh", loss_mse(TrainingMLP), tanh=onednn_tanh
                )
            }
            if torch.backends.mkldnn.is_available()
            else {}
        ),  # a build without oneDNN
        "hnnbench + sigmoid tanh": direct_step(
            "hnnbench + sigmoid tanh", loss_mse(TrainingMLP), tanh=sigmoid_tanh_
        ),
        **(
            {
                "hnnbench + fused linear-tanh": direct_step(
                    "hnnbench + fused linear-tanh", with_fused_linear_tanh(loss_mse(TrainingMLP))
                )
            }
            if torch.backends.mkldnn.is_available()
            else {}
        ),
        "torch.func.grad": func_grad_step("torch.func.grad", loss_mse(MLP)),
        "no autograd": manual_step("no autograd"),
        "no autograd + sigmoid tanh": manual_step("no autograd + sigmoid tanh", sigmoid_tanh_),
    }
    compile_s = float("nan")
    if compile_mode is not None:
        compiled = torch.compile(optimizer_step("torch.compile", loss_mean(MLP)), mode=compile_mode)
        start = time.perf_counter()
        compiled()
        compile_s = time.perf_counter() - start
        print(
            f"  torch.compile of the {'hnn' if hnn else 'mlp'} step ({n} x {d}): "
            f"{compile_s:.1f} s (not counted)",
            flush=True,
        )
        variants["torch.compile"] = compiled
    for swapped, plain in (
        ("hnnbench + sigmoid tanh", "hnnbench"),
        ("hnnbench + fused linear-tanh", "hnnbench"),
        ("no autograd + sigmoid tanh", "no autograd"),
    ):
        if swapped in grads and all(
            torch.equal(a, b) for a, b in zip(grads[swapped], grads[plain], strict=True)
        ):
            raise RuntimeError(
                f"{swapped!r} computed {plain!r}'s gradient bit for bit: "
                "its tanh kernel was not used"
            )
    reference = grads["a47bd0f"]
    diffs = {
        name: max(
            float((a - b).abs().max() / b.abs().max()) for a, b in zip(g, reference, strict=True)
        )
        for name, g in grads.items()
    }
    return variants, diffs, compile_s


def jax_step(n: int, d: int, hnn: bool, chunk: int = 10) -> Step:
    """hnnbench's JAX step: a jitted ``lax.scan`` chunk of ``chunk`` steps; each call
    is one step (a chunk runs on every ``chunk``-th call)."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from hnnbench.neural.jax import adam_like_torch

    rng = np.random.default_rng(1)
    x = jnp.asarray(rng.normal(size=(n, d)), jnp.float32)
    y = jnp.asarray(rng.normal(size=(n, d)), jnp.float32)
    arrays = initial_arrays(d, 1 if hnn else d)
    params = [
        jnp.asarray(arrays[f"f.linears.{i}.{kind}"], jnp.float32)
        for i, kind in ((0, "weight"), (0, "bias"), (1, "weight"), (1, "bias"), (2, "weight"))
    ]

    def net(ps: list[Any], xi: Any) -> Any:
        w1, b1, w2, b2, w3 = ps
        return w3 @ jnp.tanh(w2 @ jnp.tanh(w1 @ xi + b1) + b2)

    def loss(ps: list[Any]) -> Any:
        if hnn:
            g = jax.vmap(jax.grad(lambda xi: net(ps, xi)[0]))(x)
            f = jnp.concatenate([g[:, d // 2 :], -g[:, : d // 2]], axis=1)
        else:
            f = jax.vmap(lambda xi: net(ps, xi))(x)
        return jnp.mean((f - y) ** 2)

    opt = adam_like_torch(LR, WEIGHT_DECAY)

    @jax.jit
    def run(ps: Any, st: Any) -> Any:
        def body(carry: Any, _: Any) -> Any:
            ps, st = carry
            value, g = jax.value_and_grad(loss)(ps)
            updates, st = opt.update(g, st, ps)
            return (jax.tree.map(lambda p, u: p + u, ps, updates), st), value

        (ps, st), values = jax.lax.scan(body, (ps, st), None, length=chunk)
        return ps, st, values

    state: list[Any] = [params, opt.init(params), 0]
    state[0], state[1], values = run(state[0], state[1])
    np.asarray(values)

    def one() -> None:
        state[2] += 1
        if state[2] % chunk == 0:
            state[0], state[1], out = run(state[0], state[1])
            np.asarray(out)  # the host reads the chunk's losses, as hnnbench's loop does

    return one


def time_steps(fn: Step, steps: int) -> float:
    """Milliseconds per step of ``steps`` calls."""
    start = time.perf_counter()
    for _ in range(steps):
        fn()
    return (time.perf_counter() - start) / steps * 1e3


def op_timings(n: int, d: int) -> None:
    """Microseconds of each float32 tanh kernel on an ``(n, HIDDEN)`` activation (ATen's,
    XLA's, oneDNN's where torch has it, and ``2 sigmoid(2a) - 1`` in place), of
    ``torch.sigmoid``, of a hidden layer with and without its tanh (fused by oneDNN, or
    not), and of the thin ``d``-column products in both orientations; then
    each tanh kernel's largest absolute and relative error against float64 tanh."""
    import jax
    import jax.numpy as jnp
    import numpy as np
    import torch

    def best_us(fn: Callable[[], Any], reps: int = 300) -> float:
        for _ in range(20):
            fn()
        times = []
        for _ in range(5):
            start = time.perf_counter()
            for _ in range(reps):
                fn()
            times.append((time.perf_counter() - start) / reps * 1e6)
        return min(times)

    a = torch.randn(n, HIDDEN)
    w_out = torch.randn(d, HIDDEN)  # an output layer's weight, (out, in)
    w_hid, b_hid = torch.randn(HIDDEN, HIDDEN) / HIDDEN**0.5, torch.randn(HIDDEN)
    ja = jnp.asarray(a.numpy())
    jtanh = jax.jit(jnp.tanh)
    jtanh(ja).block_until_ready()
    rows = {
        f"torch.tanh ({n}, {HIDDEN})": best_us(lambda: torch.tanh(a)),
        f"XLA tanh ({n}, {HIDDEN})": best_us(lambda: jtanh(ja).block_until_ready()),
        **(
            {
                f"oneDNN tanh ({n}, {HIDDEN}), with both layout conversions": best_us(
                    lambda: onednn_tanh(a)
                )
            }
            if torch.backends.mkldnn.is_available()
            else {}
        ),
        f"2 sigmoid(2a) - 1 in place ({n}, {HIDDEN}), with a copy": best_us(
            lambda: sigmoid_tanh_(a.clone())
        ),
        f"  the copy alone ({n}, {HIDDEN})": best_us(lambda: a.clone()),
        f"torch.sigmoid ({n}, {HIDDEN})": best_us(lambda: torch.sigmoid(a)),
        f"a hidden layer ({n},{HIDDEN})x({HIDDEN},{HIDDEN}) + b: addmm": best_us(
            lambda: torch.addmm(b_hid, a, w_hid.t())
        ),
        "  the same, then ATen tanh_ (hnnbench's)": best_us(
            lambda: torch.addmm(b_hid, a, w_hid.t()).tanh_()
        ),
        **(
            {
                "  the same as one oneDNN call with a tanh post-op": best_us(
                    lambda: torch.ops.mkldnn._linear_pointwise(a, w_hid, b_hid, "tanh", [], "")
                )
            }
            if torch.backends.mkldnn.is_available()
            else {}
        ),
        f"({n},{HIDDEN})x({HIDDEN},{d}) as h @ w.t() (F.linear's)": best_us(lambda: a @ w_out.t()),
        "the same as (w @ h.t()).t()": best_us(lambda: (w_out @ a.t()).t()),
        f"({HIDDEN},{n})x({n},{d}) as g.t() @ x (a weight gradient)": best_us(
            lambda: a.t() @ a[:, :d]
        ),
        "the same as (x.t() @ g).t()": best_us(lambda: (a[:, :d].t() @ a).t()),
    }
    print(f"\n  ops, best of 5 x 300, microseconds ({n} rows, d = {d}):")
    for name, us in rows.items():
        print(f"    {name:58s} {us:8.1f}")
    grid = torch.linspace(-10.0, 10.0, 200_001)
    exact = torch.tanh(grid.double())
    kernels = {
        "torch.tanh": torch.tanh(grid),
        "XLA tanh": torch.as_tensor(np.array(jtanh(jnp.asarray(grid.numpy())))),
        "2 sigmoid(2a) - 1": sigmoid_tanh_(grid.clone()),
    }
    if torch.backends.mkldnn.is_available():
        kernels["oneDNN tanh"] = onednn_tanh(grid)
    print(
        "\n  float32 tanh against float64 tanh on 200001 points of [-10, 10]: "
        "largest absolute error, largest relative error (|tanh| >= 1e-30):"
    )
    for name, value in kernels.items():
        err = (value.double() - exact).abs()
        rel = (err / exact.abs().clamp_min(1e-30)).max()
        print(f"    {name:20s} {float(err.max()):.2e}  {float(rel):.2e}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--shapes", nargs="+", choices=list(SHAPES), default=list(SHAPES))
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--cpu", type=int, default=None, help="the core to pin to (default: the first allowed one)"
    )
    parser.add_argument(
        "--no-compile",
        action="store_true",
        help="leave out torch.compile (its compilation takes 10-60 s)",
    )
    parser.add_argument(
        "--compile-mode",
        default="default",
        help="torch.compile's mode (default, reduce-overhead, max-autotune-no-cudagraphs)",
    )
    args = parser.parse_args()
    cpu = _pin(args.cpu)
    print(
        f"load average {os.getloadavg()[0]:.2f}; {args.steps} steps x {args.repeats} "
        f"repeats, pinned to core {cpu}, one thread",
        flush=True,
    )
    summary = []
    for shape in args.shapes:
        n, d = SHAPES[shape]
        for family, hnn in (("mlp", False), ("hnn", True)):
            variants, diffs, compile_s = torch_variants(
                n, d, hnn, None if args.no_compile else args.compile_mode
            )
            variants["JAX"] = jax_step(n, d, hnn)
            times: dict[str, list[float]] = {k: [] for k in variants}
            for fn in variants.values():  # warm-up
                time_steps(fn, 20)
            for _ in range(args.repeats):
                for name, fn in variants.items():
                    times[name].append(time_steps(fn, args.steps))
            jax_ms = statistics.median(times["JAX"])
            base = statistics.median(times["a47bd0f"])
            print(
                f"\n  {shape} ({n} x {d}) {family} step: ms median / best, "
                "vs a47bd0f, vs JAX (medians), gradient vs a47bd0f's"
            )
            for name, values in times.items():
                ms = statistics.median(values)
                diff = diffs.get(name)
                print(
                    f"    {name:28s} {ms:7.3f} / {min(values):7.3f}   {ms / base:5.2f}x   "
                    f"{ms / jax_ms:5.2f}x   {'—' if diff is None else f'{diff:.1e}'}"
                )
                summary.append((shape, family, name, ms, ms / jax_ms))
            if "torch.compile" in times:
                saved = statistics.median(times["hnnbench"]) - statistics.median(
                    times["torch.compile"]
                )
                print(
                    f"    torch.compile saves {saved:.3f} ms per step against hnnbench's "
                    f"step: its {compile_s:.1f} s of compilation pay off after "
                    + (f"{compile_s / saved * 1e3:,.0f} steps" if saved > 0 else "never")
                )
        op_timings(n, d)
    print("\n| shape | family | " + " | ".join(dict.fromkeys(r[2] for r in summary)) + " |")
    names = list(dict.fromkeys(r[2] for r in summary))
    print("|---|---|" + "---|" * len(names))
    for shape in args.shapes:
        for family in ("mlp", "hnn"):
            cells = {r[2]: r for r in summary if r[0] == shape and r[1] == family}
            print(
                f"| {shape} | {family} | "
                + " | ".join(
                    f"{cells[k][3]:.3f} ({cells[k][4]:.2f}×)" if k in cells else "—" for k in names
                )
                + " |"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
