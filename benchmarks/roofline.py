"""A matmul roofline for hnnbench's training step: FLOPs counted, fp32 matmul rates
measured on this machine for the same shapes.

- :func:`torch_fit_matmuls` records every matrix product (``aten.mm``, ``addmm``,
  ``bmm``, ``baddbmm``, ``mv``, ``addmv``, ``dot``) that hnnbench's own torch
  ``Model.fit`` dispatches, with its shape and operand layout, by running ``fit`` for
  one step and for two steps (both logging the test loss once, at the end): the
  difference is one training step (forward + backward + Adam), the rest is one test-loss
  evaluation. It is cross-checked with ``torch.utils.flop_counter.FlopCounterMode``.
- :func:`jax_fit_flops` runs hnnbench's own JAX ``Model.fit`` for one step, keeps
  the training chunk it compiles (one ``lax.scan`` step plus the test loss), and reads
  XLA's ``cost_analysis()`` (all ops, dots and elementwise) and the dot FLOPs from the
  optimised HLO, split into the step and the test evaluation.
- :func:`measure_rates` times each distinct ``(M, K) x (K, N)`` product, single thread,
  with torch (``torch.mm(..., out=)`` in a loop, the recorded operand layouts) and with
  JAX (``R`` dots inside one jitted ``fori_loop``, so dispatch is amortised); the best
  rate of the two is the machine's rate for that shape.
- :func:`roofline_seconds`: the sum over the step's matmuls of ``FLOPs / rate(shape)``.
  A per-shape sum rather than ``total FLOPs / best rate``, because the thin products of
  a 2-input network (``K = 2`` or ``N = 2``) cannot run at the rate of a square one (the
  single-rate figure can be had from :func:`peak_rate`). The rate of a shape is the best
  over the layouts measured and, by default, over the two orientations of the product
  (``C = A @ B`` or ``C.T = B.T @ A.T``, the same FLOPs on the same data): BLAS is
  several times slower on some thin products in one orientation than in the other, and
  a roofline should not credit a step for the slower one.

Only matrix products count: activations, the loss, Adam, indexing and Python overhead
are what the roofline leaves out, so ``roofline / measured`` is the fraction of the
step's time that is matmul work done at the machine's measured rate.
"""

from __future__ import annotations

import dataclasses
import re
import time
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True, order=True)
class Matmul:
    """One ``(m, k) x (k, n)`` product, ``batch`` of them; ``trans_a``/``trans_b``: the
    operand is a transposed (column-major) view."""

    m: int
    k: int
    n: int
    trans_a: bool = False
    trans_b: bool = False
    batch: int = 1

    @property
    def flops(self) -> int:
        return 2 * self.batch * self.m * self.k * self.n

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.m, self.k, self.n)

    def __str__(self) -> str:
        ta, tb = "ᵀ" if self.trans_a else "", "ᵀ" if self.trans_b else ""
        b = f"{self.batch}×" if self.batch > 1 else ""
        return f"{b}({self.m},{self.k}){ta}x({self.k},{self.n}){tb}"


def total_flops(matmuls: Iterable[Matmul] | Counter) -> int:
    if isinstance(matmuls, Counter):
        return sum(mm.flops * c for mm, c in matmuls.items())
    return sum(mm.flops for mm in matmuls)


# --------------------------------------------------------------------------- torch


def _is_transposed(t: Any) -> bool:
    return t.dim() == 2 and t.shape[0] > 1 and t.shape[1] > 1 and t.stride(0) == 1


def _recorder() -> Any:
    import torch
    from torch.utils._python_dispatch import TorchDispatchMode

    aten = torch.ops.aten

    class MatmulRecorder(TorchDispatchMode):
        """Records the matrix products dispatched while it is active."""

        def __init__(self) -> None:
            super().__init__()
            self.matmuls: list[Matmul] = []

        def __torch_dispatch__(self, func, types, args=(), kwargs=None):  # noqa: ANN001
            kwargs = kwargs or {}
            packet = getattr(func, "overloadpacket", None)
            if packet in (aten.mm, aten.addmm):
                a, b = (args[0], args[1]) if packet is aten.mm else (args[1], args[2])
                self.matmuls.append(
                    Matmul(a.shape[0], a.shape[1], b.shape[1], _is_transposed(a), _is_transposed(b))
                )
            elif packet in (aten.bmm, aten.baddbmm):
                a, b = (args[0], args[1]) if packet is aten.bmm else (args[1], args[2])
                self.matmuls.append(Matmul(a.shape[1], a.shape[2], b.shape[2], batch=a.shape[0]))
            elif packet in (aten.mv, aten.addmv):
                a, v = (args[0], args[1]) if packet is aten.mv else (args[1], args[2])
                self.matmuls.append(Matmul(a.shape[0], a.shape[1], 1, _is_transposed(a)))
            elif packet is aten.dot:
                self.matmuls.append(Matmul(1, args[0].shape[0], 1))
            return func(*args, **kwargs)

    return MatmulRecorder


def record_matmuls(fn: Any, flop_counter: bool = True) -> tuple[Counter, int]:
    """Run ``fn()`` and return the matrix products it dispatched (a Counter of
    :class:`Matmul`) and ``FlopCounterMode``'s total for the same call (-1 without
    ``flop_counter``: its module hooks break ``autograd.grad`` on a leaf tensor, which
    the 2019 loop does)."""
    from contextlib import nullcontext

    from torch.utils.flop_counter import FlopCounterMode

    recorder = _recorder()()
    counter = FlopCounterMode(display=False) if flop_counter else None
    with counter or nullcontext(), recorder:
        fn()
    return Counter(recorder.matmuls), int(counter.get_total_flops()) if counter else -1


def torch_fit_matmuls(
    model_cls: Any, model_cfg: Any, system: Any, data: Any, train: Any, seed: int = 0
) -> dict[str, Any]:
    """The matrix products of one training step and of one test-loss evaluation of the
    torch model's own ``fit`` on the CPU. Returns ``{"step": Counter, "eval": Counter,
    "step_flopcounter": int, "eval_flopcounter": int}``."""
    import torch

    torch.set_num_threads(1)
    cfg = dataclasses.replace(model_cfg, log_every=10**9)  # log once, at the last step

    def fit(steps: int) -> Any:
        model = model_cls(cfg, system, "cpu")
        settings = dataclasses.replace(train, steps=steps)
        return lambda: model.fit(data, settings, seed, lambda *_: None)

    one, one_fc = record_matmuls(fit(1))  # 1 step + 1 evaluation
    two, two_fc = record_matmuls(fit(2))  # 2 steps + 1 evaluation
    step = two - one
    evaluation = one - step
    if step - one:  # one fit step must be part of the 1-step fit
        raise RuntimeError("torch fit matmuls are not 'steps x step + evaluation'")
    step_fc = two_fc - one_fc
    return {
        "step": step,
        "eval": evaluation,
        "step_flopcounter": step_fc,
        "eval_flopcounter": one_fc - step_fc,
    }


# --------------------------------------------------------------------------- JAX

_INSTR = re.compile(r"^\s*(?:ROOT\s+)?%([\w.\-]+) = (\w+)\[([\d,]*)\]")
_DOT_OPERANDS = re.compile(r"\bdot\(([^)]*)\)")
_LHS_CONTRACTING = re.compile(r"lhs_contracting_dims=\{([\d,]*)\}")


def hlo_dot_flops(hlo_text: str) -> list[tuple[int, str]]:
    """``(FLOPs, op_name metadata)`` of every ``dot`` in an (optimised) HLO module text:
    ``2 * prod(output shape) * prod(lhs contracting sizes)``. A dot inside a ``while``
    body is listed once."""
    shapes: dict[str, tuple[int, ...]] = {}
    lines = hlo_text.splitlines()
    for line in lines:
        m = _INSTR.match(line)
        if m:
            dims = tuple(int(v) for v in m.group(3).split(",") if v)
            shapes[m.group(1)] = dims
    out = []
    for line in lines:
        if " dot(" not in line:
            continue
        m, d = _INSTR.match(line), _DOT_OPERANDS.search(line)
        c = _LHS_CONTRACTING.search(line)
        if not m or not d or not c:
            continue
        operands, contracting = d.group(1), c.group(1)
        lhs_name = re.findall(r"%([\w.\-]+)", operands)[0]
        lhs = shapes[lhs_name]
        k = int(np.prod([lhs[int(c)] for c in contracting.split(",") if c]))
        out_shape = tuple(int(v) for v in m.group(3).split(",") if v)
        meta = re.search(r'op_name="([^"]*)"', line)
        out.append((2 * int(np.prod(out_shape)) * k, meta.group(1) if meta else ""))
    return out


def _cost(compiled: Any) -> dict[str, float]:
    cost = compiled.cost_analysis()
    if isinstance(cost, (list, tuple)):
        cost = cost[0] if cost else {}
    return dict(cost or {})


def jax_fit_flops(
    model_cls: Any, model_cfg: Any, system: Any, data: Any, train: Any, seed: int = 0
) -> dict[str, float]:
    """FLOPs of one training step and one validation evaluation of the JAX model's own
    ``fit``, from the chunk it compiles (here of length 1). Returns ``step_dot`` /
    ``eval_dot`` (dot FLOPs in the optimised HLO: the step's dots sit in the ``while``
    of the chunk's ``lax.scan``, the selection criterion's after it) and ``step_xla`` / ``eval_xla``
    (XLA's ``cost_analysis()["flops"]``, all ops; XLA counts a ``while`` body once, so
    the chunk's figure is one step plus the evaluation, and the evaluation is compiled
    alone to split them). A loop inside the loss (SRNN's leapfrog ``lax.scan``) is a
    ``while`` too, whose dots are counted once, not once per iteration: for such a
    family the JAX figures are per loop iteration, below the torch count.

    The hook: ``fit`` runs for one step (one chunk of length 1) while the JAX backend's
    ``_compiled`` (which lowers and compiles, or finds in its cache, the executable of a
    training chunk) is wrapped to keep the executable and its arguments; the selection
    criterion is then compiled alone (``hnnbench.neural.jax.criterion_values``), with
    the same parameters and the same validation arrays.
    """
    import equinox as eqx
    import jax

    import hnnbench.neural.jax as jx

    seen: dict[str, Any] = {}
    original = jx._compiled

    def keep(batched: bool, statics: tuple[Any, ...], args: tuple[Any, ...]) -> Any:
        compiled, seconds = original(batched, statics, args)
        seen.update(compiled=compiled, statics=statics, args=args)
        return compiled, seconds

    cfg = dataclasses.replace(model_cfg, log_every=10**9)  # one chunk: one step
    jx._compiled = keep
    try:
        model = model_cls(cfg, system, "cpu")
        model.fit(data, dataclasses.replace(train, steps=1), seed, lambda *_: None)
    finally:
        jx._compiled = original
    if "compiled" not in seen:
        raise RuntimeError(f"{model_cls.__name__}: fit compiled no JAX training chunk")
    chunk = seen["compiled"]
    _, impl, _, static, criterion = seen["statics"][:5]
    params, valid = seen["args"][0], seen["args"][4]  # the chunk's validation arrays

    def evaluate(p: Any, *arrays: Any) -> Any:  # the chunk's criterion, alone
        return jx.criterion_values(
            criterion[0], impl, criterion[1], eqx.combine(p, static), *arrays
        )

    with jax.default_matmul_precision("highest"):  # as the backend compiles its chunks
        evaluation = jax.jit(evaluate).lower(params, *valid).compile()
    dots = hlo_dot_flops(chunk.as_text())

    def in_step(name: str) -> bool:  # "jit(_chunk)/while/...": the scan over the steps
        return name.split("/")[1:2] == ["while"]

    step_dot = sum(f for f, name in dots if in_step(name))
    eval_dot = sum(f for f, name in dots if not in_step(name))
    eval_alone = sum(f for f, _ in hlo_dot_flops(evaluation.as_text()))
    chunk_xla = _cost(chunk).get("flops", float("nan"))
    eval_xla = _cost(evaluation).get("flops", float("nan"))
    return {
        "step_dot": step_dot,
        "eval_dot": eval_dot,
        "eval_dot_alone": eval_alone,
        "step_xla": chunk_xla - eval_xla,
        "eval_xla": eval_xla,
    }


# --------------------------------------------------------------------------- rates


def _best_of(fn: Any, reps: int, rounds: int, budget_s: float) -> float:
    """Smallest seconds per call of ``fn(reps)`` (which runs ``reps`` products) over up
    to ``rounds`` rounds, stopping early past ``budget_s``."""
    best, start = float("inf"), time.perf_counter()
    for _ in range(rounds):
        t = time.perf_counter()
        fn(reps)
        best = min(best, (time.perf_counter() - t) / reps)
        if time.perf_counter() - start > budget_s:
            break
    return best


def _reps_for(mm: Matmul, target_s: float = 2e-3, guess_rate: float = 2e10) -> int:
    return int(max(1, min(2000, target_s * guess_rate / mm.flops)))


def torch_rate(mm: Matmul, rounds: int = 30, budget_s: float = 2.0) -> float:
    """FLOP/s of ``torch.mm`` for this shape and operand layout, one thread."""
    import torch

    torch.set_num_threads(1)
    gen = torch.Generator().manual_seed(0)
    a = (
        torch.rand(mm.k, mm.m, generator=gen).t()
        if mm.trans_a
        else torch.rand(mm.m, mm.k, generator=gen)
    )
    b = (
        torch.rand(mm.n, mm.k, generator=gen).t()
        if mm.trans_b
        else torch.rand(mm.k, mm.n, generator=gen)
    )
    c = torch.empty(mm.m, mm.n)

    def run(reps: int) -> None:
        for _ in range(reps):
            torch.mm(a, b, out=c)

    run(3)
    return mm.flops / mm.batch / _best_of(run, _reps_for(mm), rounds, budget_s)


_JAX_LOOPS: dict[Any, Any] = {}


def jax_rate(mm: Matmul, rounds: int = 30, budget_s: float = 2.0) -> float:
    """FLOP/s of ``R`` jitted ``dot_general`` calls in one ``fori_loop`` (the same
    contraction layout as the torch operands), so that dispatch is amortised. The
    product is carried and returned (XLA must compute all of it) and each iteration
    perturbs the smaller operand by ``0 * c[0, 0]`` (XLA cannot hoist the product out of
    the loop); that elementwise cost is counted against the rate."""
    import jax
    import jax.numpy as jnp

    reps = _reps_for(mm)
    a_shape = (mm.k, mm.m) if mm.trans_a else (mm.m, mm.k)
    b_shape = (mm.n, mm.k) if mm.trans_b else (mm.k, mm.n)
    dims = (((0 if mm.trans_a else 1,), (1 if mm.trans_b else 0,)), ((), ()))
    perturb_a = mm.m * mm.k <= mm.k * mm.n
    key = (a_shape, b_shape, dims, reps)
    if key not in _JAX_LOOPS:

        def loop(a: Any, b: Any) -> Any:
            def body(_: Any, carry: Any) -> Any:
                a, b, _c = carry
                c = jax.lax.dot_general(a, b, dims, precision=jax.lax.Precision.HIGHEST)
                s = c[0, 0]
                if perturb_a:
                    a = a + 0.0 * s
                else:
                    b = b + 0.0 * s
                return a, b, c

            c0 = jnp.zeros((mm.m, mm.n), jnp.float32)
            return jax.lax.fori_loop(0, reps, body, (a, b, c0))[2]

        _JAX_LOOPS[key] = jax.jit(loop)
    fn = _JAX_LOOPS[key]
    rng = np.random.default_rng(0)
    a = jnp.asarray(rng.random(a_shape), jnp.float32)
    b = jnp.asarray(rng.random(b_shape), jnp.float32)
    fn(a, b).block_until_ready()

    def run(_: int) -> None:
        fn(a, b).block_until_ready()

    return mm.flops / mm.batch / _best_of(run, reps, rounds, budget_s)


def transposed(mm: Matmul) -> Matmul:
    """The same product computed transposed, ``C.T = B.T @ A.T``: ``(n, k) x (k, m)``
    with the operand layouts that make it read the same memory."""
    return Matmul(mm.n, mm.k, mm.m, not mm.trans_b, not mm.trans_a, mm.batch)


def measure_rates(
    matmuls: Iterable[Matmul],
    backends: Iterable[str] = ("torch", "jax"),
    budget_s: float = 2.0,
    with_transposed: bool = True,
) -> dict[Matmul, dict[str, float]]:
    """``{matmul (batch 1): {"torch": FLOP/s, "jax": FLOP/s, "best": FLOP/s}}`` for
    each distinct product (shape and layout) in ``matmuls`` and, with
    ``with_transposed``, for its transposed twin (:func:`transposed`)."""
    todo = {dataclasses.replace(m, batch=1) for m in matmuls}
    if with_transposed:
        todo |= {transposed(m) for m in todo}
    rates: dict[Matmul, dict[str, float]] = {}
    for mm in sorted(todo):
        r: dict[str, float] = {}
        if "torch" in backends:
            r["torch"] = torch_rate(mm, budget_s=budget_s)
        if "jax" in backends:
            r["jax"] = jax_rate(mm, budget_s=budget_s)
        r["best"] = max(r.values())
        rates[mm] = r
    return rates


def shape_rate(
    rates: dict[Matmul, dict[str, float]], mm: Matmul, either_orientation: bool = True
) -> float:
    """The best measured rate for ``mm``'s shape over every layout measured (and, with
    ``either_orientation``, for the transposed product ``(n, k) x (k, m)`` too: the same
    FLOPs on the same data, which a library is free to compute either way)."""
    shapes = {mm.shape}
    if either_orientation:
        shapes.add((mm.n, mm.k, mm.m))
    return max(r["best"] for m, r in rates.items() if m.shape in shapes)


def peak_rate(rates: dict[Matmul, dict[str, float]]) -> float:
    """The best rate measured over all shapes."""
    return max(r["best"] for r in rates.values())


def roofline_seconds(
    matmuls: Counter,
    rates: dict[Matmul, dict[str, float]],
    weight: float = 1.0,
    either_orientation: bool = True,
) -> float:
    """``weight * sum(FLOPs / rate(shape))`` over ``matmuls`` (a Counter)."""
    return weight * sum(
        mm.flops * c / shape_rate(rates, mm, either_orientation) for mm, c in matmuls.items()
    )
