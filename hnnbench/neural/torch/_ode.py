"""A batched adaptive Dormand-Prince 5(4) solver in torch ops, for the rollouts.

Why not torchdiffeq: on the paper-sized problems (15 states of 2-12 numbers) the cost
is per-step Python and op dispatch, not arithmetic, and torchdiffeq's generic machinery
spent about 40 % of a rollout there (benchmarks/README.md). This module does the same
mathematics with little around it: the DOPRI5 tableau with FSAL, one step size for the
whole batch (error is the RMS over every element, as torchdiffeq's default), and
Hairer's 4th-order dense output to report the requested times without shortening
steps to hit them. The fields are autonomous (``f(y)``), so the stage times are not
needed. Everything stays on the tensors' device, so it runs on a GPU too.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from hnnbench.neural._backend import stall_text

__all__ = ["dopri5", "SolverGaveUp"]

Field = Callable[[torch.Tensor], torch.Tensor]

# Dormand & Prince (1980) coefficients: stage matrix A (rows 2-6), 5th-order weights B
# (= row 7 of A, so the last stage is FSAL), and E = B - B* (the 4th-order embedded
# weights' difference, for the error estimate).
A = (
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
)
B = (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84)
E = (71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)
# Hairer, Norsett & Wanner's continuous extension of DOPRI5 (their code's CONTD5).
D = (
    -12715105075 / 11282082432,
    0.0,
    87487479700 / 32700410799,
    -10690763975 / 1880347072,
    701980252875 / 199316789632,
    -1453857185 / 822651844,
    69997945 / 29380423,
)

SAFETY, MIN_FACTOR, MAX_FACTOR = 0.9, 0.2, 10.0


class SolverGaveUp(RuntimeError):
    """The step size underflowed, the state became non-finite, or the step budget ran out."""


def _tableau(
    dtype: torch.dtype, device: torch.device
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """``(A, E, D)`` as tensors. ``A`` is ``(6, 6)``: the stage rows 2-6 and, as its last
    row, the 5th-order weights ``B``, zero-padded on the right; ``E`` and ``D`` are
    ``(1, 7)`` rows."""
    a = torch.zeros((6, 6), dtype=dtype)
    for i, row in enumerate((*A, B[:6])):
        a[i, : len(row)] = torch.tensor(row, dtype=dtype)
    e = torch.tensor([E], dtype=dtype)
    d = torch.tensor([D], dtype=dtype)
    return a.to(device), e.to(device), d.to(device)


def _initial_step(
    f: Field, y0: torch.Tensor, f0: torch.Tensor, direction: float, rtol: float, atol: float
) -> float:
    """Hairer's starting step: the order-5 guess from two field evaluations."""
    scale = atol + rtol * y0.abs()
    d0 = float(torch.sqrt(torch.mean((y0 / scale) ** 2)))
    d1 = float(torch.sqrt(torch.mean((f0 / scale) ** 2)))
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    f1 = f(y0 + direction * h0 * f0)
    d2 = float(torch.sqrt(torch.mean(((f1 - f0) / scale) ** 2))) / h0
    if max(d1, d2) <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1 / 5)
    return min(100 * h0, h1)


def dopri5(
    f: Field,
    y0: torch.Tensor,
    t: np.ndarray,
    rtol: float,
    atol: float,
    max_steps: int,
    min_step: float = 0.0,
) -> torch.Tensor:
    """Integrate ``dy/dt = f(y)`` from ``y0`` ``(N, D)`` and report ``y`` at ``t`` ``(T,)``.

    ``t`` is monotonic (increasing or decreasing) and starts at the initial time.
    Returns ``(T, N, D)`` in ``y0``'s dtype and device. Raises :class:`SolverGaveUp`
    after ``max_steps`` steps, or when the step size the controller proposes (after a
    step is accepted or rejected, before it is shortened to end on ``t[-1]``) falls
    below ``min_step``, as diffrax's ``PIDController(dtmin=..., force_dtmin=False)``.

    The seven stage derivatives live as rows of one ``(7, N*D)`` tensor, so each stage
    state, the 5th-order solution, the error estimate and the dense output are a single
    ``addmm``/``mm`` against a tableau row: a step costs about 20 tensor operations
    besides its six field evaluations.
    """
    t = np.asarray(t, dtype=np.float64)
    out = torch.empty((len(t), *y0.shape), dtype=y0.dtype, device=y0.device)
    out[0] = y0
    if len(t) == 1:
        return out
    shape, size = y0.shape, y0.numel()
    a, e, d = _tableau(y0.dtype, y0.device)
    ks = torch.empty((7, size), dtype=y0.dtype, device=y0.device)  # stage derivatives
    norm = 1.0 / np.sqrt(size)  # RMS = norm * 2-norm
    direction = 1.0 if t[-1] > t[0] else -1.0
    span = abs(t[-1] - t[0])
    t_now, y = float(t[0]), y0.reshape(1, size)
    ks[0] = f(y0).reshape(size)
    h = _initial_step(f, y0, ks[0].view(shape), direction, rtol, atol)
    nxt, steps = 1, 0
    nonfinite_at: float | None = None
    while nxt < len(t):
        if steps >= max_steps:
            raise SolverGaveUp(f"more than {max_steps} steps (rollout_max_steps)")
        if h <= 1e-14 * max(1.0, span):
            why = " after non-finite trial states" if nonfinite_at == t_now else ""
            raise SolverGaveUp(f"step size underflow ({h:.3g}) at t={t_now:.6g}{why}")
        remaining = abs(t[-1] - t_now)
        h = min(h, remaining)
        hs = direction * h
        for i in range(5):  # stages 2-6
            stage = torch.addmm(y, a[i : i + 1, : i + 1], ks[: i + 1], alpha=hs)
            ks[i + 1] = f(stage.view(shape)).reshape(size)
        y_new = torch.addmm(y, a[5:6], ks[:6], alpha=hs)
        ks[6] = f(y_new.view(shape)).reshape(size)  # FSAL: the next step's first stage
        steps += 1
        scale = torch.maximum(y.abs(), y_new.abs()).mul_(rtol).add_(atol)
        err_norm = h * norm * float(torch.linalg.vector_norm(torch.mm(e, ks).div_(scale)))
        if not np.isfinite(err_norm):  # a trial step into overflow: reject, shrink
            h *= MIN_FACTOR
            nonfinite_at = t_now
            _check_stall(h, min_step, t_now, nonfinite_at == t_now)
            continue
        if err_norm <= 1.0:
            t_new = t_now + hs
            # Report every requested time inside (t_now, t_new] by dense output.
            last = nxt
            while last < len(t) and (t[last] - t_new) * direction <= 1e-12 * span:
                last += 1
            if last > nxt:
                dense = _dense(t[nxt:last], t_now, hs, y, y_new, ks, d)
                out[nxt:last] = dense.view(last - nxt, *shape)
                nxt = last
            t_now, y = t_new, y_new
            ks[0] = ks[6]
            factor = MAX_FACTOR if err_norm == 0.0 else SAFETY * err_norm**-0.2
            h = h * min(MAX_FACTOR, max(MIN_FACTOR, factor))
        else:
            h = h * max(MIN_FACTOR, SAFETY * err_norm**-0.2)
        _check_stall(h, min_step, t_now, nonfinite_at == t_now)
    return out


def _check_stall(h: float, min_step: float, t_now: float, nonfinite: bool) -> None:
    """Raise :class:`SolverGaveUp` when the proposed step ``h`` is below ``min_step``."""
    if h < min_step:
        why = " after non-finite trial states" if nonfinite else ""
        raise SolverGaveUp(
            f"the step size fell to {h:.3g} at t={t_now:.6g}{why}, below {stall_text(min_step)}"
        )


def _dense(
    times: np.ndarray,
    t0: float,
    hs: float,
    y0: torch.Tensor,
    y1: torch.Tensor,
    ks: torch.Tensor,
    d: torch.Tensor,
) -> torch.Tensor:
    """The continuous extension at ``times`` ``(M,)`` inside the step from ``y0`` to
    ``y1`` (rows ``(1, N*D)``; ``ks`` the step's ``(7, N*D)`` stages): ``(M, N*D)``."""
    r2 = y1 - y0
    r3 = hs * ks[0:1] - r2
    r4 = r2 - hs * ks[6:7] - r3
    r5 = torch.mm(d, ks).mul_(hs)
    theta = torch.as_tensor((times - t0) / hs, dtype=y0.dtype, device=y0.device)[:, None]
    one_minus = 1.0 - theta
    return y0 + theta * (r2 + one_minus * (r3 + theta * (r4 + one_minus * r5)))
