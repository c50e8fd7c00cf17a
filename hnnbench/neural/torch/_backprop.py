"""Hand-written backward passes of the training networks: an MLP's value and its
closed-form input gradient as :class:`torch.autograd.Function` s.

Autograd differentiates :class:`~hnnbench.neural.torch._nets.MLP`'s plain tensor
operations correctly, but eagerly, op by op: every elementwise factor of the input
gradient (``σ'(a)``, its products) is a node of its own with its own pass over an
``(N, hidden)`` array, and every node costs dispatch. Here each network call is one
node whose backward is written out: the activation's derivative is one fused kernel
(``tanh_backward``) wherever the math allows, the weight gradients of the two paths
through a layer accumulate into one array (``addmm_``), and no intermediate is kept
that the backward does not read. The arithmetic is the same as autograd's up to
rounding (``tests/integration/test_torch_backprop.py`` checks the values, the gradients with
respect to every parameter and the input, seed batches under ``torch.func.vmap``, and
every activation).

Only first-order reverse mode: these functions have no forward-mode rule, so
``torch.func.jacfwd`` and ``hessian`` do not go through them, and their backward passes
are ``once_differentiable`` (a second reverse pass raises instead of silently treating
the saved intermediates as constants); :class:`~hnnbench.neural.torch._nets.MLP`
keeps the plain operations for that (the tests' references, the LNN's Hessian).
``benchmarks/torch_step_options.py`` measures what they gain.

Layout of ``params``: ``w_0, b_0, ..., w_{m-1}, b_{m-1}, w_m`` for ``m`` hidden layers
(weights ``(out, in)``, no bias on the last layer).
"""

from __future__ import annotations

from typing import Any, Optional

import torch
from torch.autograd.function import once_differentiable

__all__ = ["input_gradient", "symplectic", "value"]

_tanh_backward = torch.ops.aten.tanh_backward
_sigmoid_backward = torch.ops.aten.sigmoid_backward


def _act(name: str, a: torch.Tensor) -> torch.Tensor:
    """``σ(a)``; tanh and sigmoid overwrite ``a`` (a fresh product only softplus's
    derivative reads again)."""
    if name == "tanh":
        return a.tanh_()
    if name == "sigmoid":
        return a.sigmoid_()
    return torch.nn.functional.softplus(a)


def _times_d1(
    name: str, grad: torch.Tensor, a: Optional[torch.Tensor], h: torch.Tensor
) -> torch.Tensor:
    """``grad ⊙ σ'(a)`` (``h = σ(a)``; ``a`` is read by softplus only), one kernel for
    tanh and sigmoid."""
    if name == "tanh":
        return _tanh_backward(grad, h)
    if name == "sigmoid":
        return _sigmoid_backward(grad, h)
    assert a is not None
    return grad * torch.sigmoid(a)


def _curvature(
    name: str, s: torch.Tensor, a: Optional[torch.Tensor], h: torch.Tensor
) -> tuple[torch.Tensor, float]:
    """``(c, k)`` with ``k · c = s ⊙ σ''(a) / σ'(a)`` (tanh: ``σ''/σ' = -2h``; sigmoid:
    ``1 - 2h``), or, for softplus, ``c = s ⊙ σ''(a)`` and ``k = 1``; ``s`` is
    overwritten."""
    if name == "tanh":
        return s.mul_(h), -2.0
    if name == "sigmoid":
        return s.mul_(1.0 - 2.0 * h), 1.0
    assert a is not None
    sig = torch.sigmoid(a)
    return s.mul_(sig).mul_(1.0 - sig), 1.0


#: A product whose result has at most this many columns, and four times as many rows,
#: is thin: MKL runs it ~3x faster transposed, ``(Bᵀ Aᵀ)ᵀ`` with ``Bᵀ`` contiguous
#: (spring, d = 2: (690, 200) x (200, 2) 109 µs as ``A @ B``, 33 µs transposed;
#: benchmarks/torch_step_options.py prints both).
_THIN = 8


def _thin(rows: int, cols: int) -> bool:
    return cols <= _THIN and rows > 4 * cols


def _mm(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``a @ b``, a thin product transposed (the result may be a transposed view)."""
    if _thin(a.shape[-2], b.shape[-1]):
        return (b.mT.contiguous() @ a.mT).mT
    return a @ b


def _gram(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``aᵀ b`` (a weight's gradient, ``(a.cols, b.cols)``), contiguous."""
    if _thin(a.shape[-1], b.shape[-1]):
        return (b.mT.contiguous() @ a).mT.contiguous()
    return a.mT @ b


def _add_gram(acc: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``acc + aᵀ b``, in place (``acc`` is a fresh gradient) except under
    ``torch.func`` transforms, which have no batching rule for ``addmm_``."""
    if _thin(a.shape[-1], b.shape[-1]) or torch._C._are_functorch_transforms_active():
        return acc + _gram(a, b)
    return acc.addmm_(a.mT, b)


def _forward(
    name: str, x: torch.Tensor, params: tuple[torch.Tensor, ...]
) -> tuple[list[Optional[torch.Tensor]], list[torch.Tensor]]:
    """Pre-activations ``a_k`` (softplus only, else ``None``) and layer inputs
    ``h_0 = x, h_1, ..., h_m``."""
    pre: list[Optional[torch.Tensor]] = []
    hs = [x]
    h = x
    for k in range(len(params) // 2):
        a = torch.addmm(params[2 * k + 1], h, params[2 * k].t())
        pre.append(a if name == "softplus" else None)
        h = _act(name, a)
        hs.append(h)
    return pre, hs


class _Value(torch.autograd.Function):
    """``f(x)`` ``(N, out)`` of an MLP; the backward is the layer-by-layer chain rule."""

    generate_vmap_rule = True

    @staticmethod
    def forward(name: str, x: torch.Tensor, *params: torch.Tensor) -> Any:
        pre, hs = _forward(name, x, params)
        out = _mm(hs[-1], params[-1].t())
        return (out, *hs[1:], *(a for a in pre if a is not None))

    @staticmethod
    def setup_context(ctx: Any, inputs: tuple[Any, ...], output: Any) -> None:
        name, x, *params = inputs
        saved = output[1:]
        ctx.mark_non_differentiable(*saved)
        ctx.set_materialize_grads(False)  # no zero gradients for the saved intermediates
        ctx.name, ctx.m = name, len(params) // 2
        ctx.save_for_backward(x, *params, *saved)

    @staticmethod
    @once_differentiable  # the saved tensors are constants: a second derivative would be wrong
    def backward(ctx: Any, grad_out: Optional[torch.Tensor], *_: Any) -> Any:
        m = ctx.m
        if grad_out is None:
            return (None,) * (2 * m + 3)
        name, saved = ctx.name, ctx.saved_tensors
        x, params = saved[0], saved[1 : 2 * m + 2]
        hs = [x, *saved[2 * m + 2 : 3 * m + 2]]
        pre = list(saved[3 * m + 2 :]) if name == "softplus" else [None] * m
        grads: list[Any] = [None] * len(params)
        grads[-1] = _gram(grad_out, hs[m])
        dh = grad_out @ params[-1]
        need_x = ctx.needs_input_grad[1]
        for k in range(m - 1, -1, -1):
            da = _times_d1(name, dh, pre[k], hs[k + 1])
            grads[2 * k] = _gram(da, hs[k])
            grads[2 * k + 1] = da.sum(0)
            if k > 0 or need_x:
                dh = da @ params[2 * k]
        return (None, dh if need_x else None, *grads)


class _InputGradient(torch.autograd.Function):
    """``∇ₓf`` ``(N, d)`` of a scalar-output MLP in closed form (the reverse sweep
    ``q_m = w_m``, ``t_k = q_{k+1} ⊙ σ'(a_k)``, ``q_k = t_k W_k``, ``∇ₓf = q_0``), and
    its backward: the sweep reversed, then the forward pass reversed, where each
    pre-activation gets both its paths, through ``σ'(a_k)`` (the sweep) and through
    ``h_{k+1}`` (the layers above)."""

    generate_vmap_rule = True

    @staticmethod
    def forward(name: str, x: torch.Tensor, *params: torch.Tensor) -> Any:
        pre, hs = _forward(name, x, params)
        m = len(params) // 2
        q = params[-1].expand(x.shape[0], -1)  # ∂f/∂h_m
        qs, ts = [q], []
        for k in range(m - 1, -1, -1):
            t = _times_d1(name, q, pre[k], hs[k + 1])
            q = _mm(t, params[2 * k])
            ts.append(t)
            qs.append(q)
        ts.reverse()
        qs.reverse()  # qs[k] = q_k; qs[0] is the output
        keep = (*hs[1:], *ts, *qs[1:m], *(a for a in pre if a is not None))
        return (qs[0], *keep)

    @staticmethod
    def setup_context(ctx: Any, inputs: tuple[Any, ...], output: Any) -> None:
        name, x, *params = inputs
        saved = output[1:]
        ctx.mark_non_differentiable(*saved)
        ctx.set_materialize_grads(False)  # no zero gradients for the saved intermediates
        ctx.name, ctx.m = name, len(params) // 2
        ctx.save_for_backward(x, *params, *saved)

    @staticmethod
    @once_differentiable  # the saved tensors are constants: a second derivative would be wrong
    def backward(ctx: Any, grad_q0: Optional[torch.Tensor], *_: Any) -> Any:
        m = ctx.m
        if grad_q0 is None:
            return (None,) * (2 * m + 3)
        name, saved = ctx.name, ctx.saved_tensors
        x, params = saved[0], saved[1 : 2 * m + 2]
        rest = saved[2 * m + 2 :]
        hs = [x, *rest[:m]]
        ts = rest[m : 2 * m]
        w_last = params[-1]
        qs: list[Any] = [None, *rest[2 * m : 3 * m - 1], w_last]  # q_1..q_m (q_m broadcast)
        pre = list(rest[3 * m - 1 :]) if name == "softplus" else [None] * m
        grads: list[Any] = [None] * len(params)
        # the sweep, reversed: Q_k = ∂L/∂q_k, T_k = ∂L/∂t_k; T_k ⊙ q_{k+1} = ∂L/∂σ'(a_k)
        big_q = grad_q0
        direct: list[tuple[torch.Tensor, float]] = []  # ∂L/∂a_k through σ'(a_k), scaled
        for k in range(m):
            big_t = big_q @ params[2 * k].t()
            grads[2 * k] = _gram(ts[k], big_q)
            big_q = _times_d1(name, big_t, pre[k], hs[k + 1])
            direct.append(_curvature(name, big_t.mul_(qs[k + 1]), pre[k], hs[k + 1]))
        grads[-1] = big_q.sum(0, keepdim=True)  # q_m = w_m broadcast over the batch
        # the forward pass, reversed; dh = ∂L/∂h_{k+1} through the layers above
        need_x = ctx.needs_input_grad[1]
        dh: Optional[torch.Tensor] = None  # none above h_m
        for k in range(m - 1, -1, -1):
            c, scale = direct[k]
            if name == "softplus":  # c = s ⊙ σ''(a): σ' applies to dh only
                da = c if dh is None else c.add_(_times_d1(name, dh, pre[k], hs[k + 1]))
            else:  # σ'(a) ⊙ (dh + scale · c)
                total = c.mul_(scale) if dh is None else dh.add_(c, alpha=scale)
                da = _times_d1(name, total, pre[k], hs[k + 1])
            grads[2 * k] = _add_gram(grads[2 * k], da, hs[k])
            grads[2 * k + 1] = da.sum(0)
            if k > 0 or need_x:
                dh = da @ params[2 * k]
        return (None, dh if need_x else None, *grads)


class _Symplectic(torch.autograd.Function):
    """``J g = (g_p, -g_q)`` along the last axis; its backward is ``Jᵀ G = (-G_p,
    G_q)``: one node instead of autograd's four (two slices, a negation, a
    concatenation), whose backward fills and adds zeros."""

    generate_vmap_rule = True

    @staticmethod
    def forward(grad: torch.Tensor) -> Any:
        n = grad.shape[-1] // 2
        return torch.cat([grad[..., n:], -grad[..., :n]], dim=-1)

    @staticmethod
    def setup_context(ctx: Any, inputs: tuple[Any, ...], output: Any) -> None:
        pass

    @staticmethod
    def backward(ctx: Any, g: torch.Tensor) -> Any:
        n = g.shape[-1] // 2
        return torch.cat([-g[..., n:], g[..., :n]], dim=-1)


def _apply(function: type[torch.autograd.Function], *args: Any) -> Any:
    """``function.apply(*args)``. Outside ``torch.func`` transforms this skips
    ``Function.apply``'s binding of the arguments to ``forward``'s signature with
    :mod:`inspect` (done on every call for a function with ``setup_context``: ~80 µs
    on a loaded core, a tenth of a two-body MLP step), which only the transforms (and
    ``torch.compile``'s tracing) need."""
    if torch._C._are_functorch_transforms_active() or torch.compiler.is_compiling():
        return function.apply(*args)
    return super(torch.autograd.Function, function).apply(*args)  # type: ignore[misc]


def value(activation: str, x: torch.Tensor, params: list[torch.Tensor]) -> torch.Tensor:
    """``f(x)`` ``(N, out)`` of the MLP with ``params`` (``w_0, b_0, ..., w_m``)."""
    return _apply(_Value, activation, x, *params)[0]


def input_gradient(activation: str, x: torch.Tensor, params: list[torch.Tensor]) -> torch.Tensor:
    """``∇ₓf`` ``(N, d)`` of the scalar-output MLP with ``params`` (``w_0, b_0, ...,
    w_m``, ``w_m`` of shape ``(1, hidden)``)."""
    return _apply(_InputGradient, activation, x, *params)[0]


def symplectic(grad: torch.Tensor) -> torch.Tensor:
    """``J g`` (``(g_q, g_p) -> (g_p, -g_q)`` along the last axis) as one autograd
    node."""
    return _apply(_Symplectic, grad)
