"""A re-implementation of the 2019 training loop (Greydanus et al.), for timing only.

Written from the description of the original training scripts in ``REFERENCE.md`` and
the "Speed and scale" issue, not copied from them. It reproduces what one step of the
original cost, so that ``benchmarks/train_step.py`` can compare hnnbench's training step
with it on the same data:

- The network: ``in -> 200 -> 200 -> out`` (``hidden`` units), tanh, orthogonal weight
  init, no bias on the last layer. The baseline outputs ``dx/dt`` directly
  (``out = input_dim``). The HNN outputs two channels ``(F1, F2)``; with the original's
  default ``field_type="solenoidal"`` only ``F2`` is used as ``H``, and
  ``dx/dt = dF2/dx @ M.T`` with the canonical permutation ``M`` (so ``(dH/dp, -dH/dq)``).
  The input gradient is taken with ``torch.autograd.grad(F2.sum(), x,
  create_graph=True)``, so training needs a double backward through autograd. The
  conservative and solenoidal fields start as zero tensors and are summed, as there.
- The data tensors are created with ``requires_grad=True`` (train and test, baseline
  too), as the original did; ``loss.backward()`` therefore also accumulates a gradient
  into the whole training tensor (through the minibatch indexing), every step.
- One step: a batch (``torch.randperm(n)[:batch]`` or the full set), MSE against the
  clean targets, ``backward``, all parameter gradients concatenated into one vector (the
  original's gradient statistics), an Adam step (coupled L2 weight decay) and
  ``zero_grad``; then the test loss on a test batch (a fresh ``randperm`` batch of the
  test set, or the whole test set when training is full batch) with the same
  ``create_graph`` time derivative, outside ``no_grad``; both losses are stored as
  Python floats (``.item()``) every step.

Deliberately left out (they cost nothing or are off by default in the original): the
``input_noise`` term added to the predictions (0 by default there) and printing.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch
from torch import nn


class MLP2019(nn.Module):
    """Three linear layers, tanh between them, orthogonal init, no bias on the last."""

    def __init__(self, input_dim: int, hidden: int, output_dim: int) -> None:
        super().__init__()
        self.linear1 = nn.Linear(input_dim, hidden)
        self.linear2 = nn.Linear(hidden, hidden)
        self.linear3 = nn.Linear(hidden, output_dim, bias=False)
        for layer in (self.linear1, self.linear2, self.linear3):
            nn.init.orthogonal_(layer.weight)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = torch.tanh(self.linear1(x))
        h = torch.tanh(self.linear2(h))
        return self.linear3(h)


class HNN2019(nn.Module):
    """The original's model wrapper: a baseline (``dx/dt = net(x)``) or an HNN whose
    two output channels are the potentials of a conservative and a solenoidal field."""

    def __init__(
        self, input_dim: int, net: nn.Module, baseline: bool, field_type: str = "solenoidal"
    ) -> None:
        super().__init__()
        self.net = net
        self.baseline = baseline
        self.field_type = field_type
        n = input_dim
        eye = torch.eye(n)
        # canonical coordinates (q, p): M maps dH/dx to (dH/dp, -dH/dq) via grad @ M.T
        self.register_buffer("M", torch.cat([eye[n // 2 :], -eye[: n // 2]]))

    def forward(self, x: torch.Tensor) -> Any:
        y = self.net(x)
        if self.baseline:
            return y
        return y.split(1, 1)

    def time_derivative(self, x: torch.Tensor) -> torch.Tensor:
        if self.baseline:
            return self.net(x)
        f1, f2 = self.forward(x)
        conservative = torch.zeros_like(x)
        solenoidal = torch.zeros_like(x)
        if self.field_type != "solenoidal":
            d_f1 = torch.autograd.grad(f1.sum(), x, create_graph=True)[0]
            conservative = d_f1 @ torch.eye(*self.M.shape)
        if self.field_type != "conservative":
            d_f2 = torch.autograd.grad(f2.sum(), x, create_graph=True)[0]
            solenoidal = d_f2 @ self.M.t()
        return conservative + solenoidal


def _l2_loss(u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    return (u - v).pow(2).mean()


def make_2019(
    data: Any,
    arch: str,
    batch_size: int | None,
    lr: float = 1e-3,
    weight_decay: float = 0.0,
    seed: int = 0,
    hidden: int = 200,
) -> tuple[Callable[[], None], dict[str, list[float]]]:
    """Build the 2019-style loop on ``data`` (an hnnbench ``Dataset``) and return
    ``(step, stats)``: ``step()`` runs one training step plus the per-step test loss,
    appending to ``stats["train_loss"]`` and ``stats["test_loss"]`` (see the module
    docstring). ``arch``: ``"mlp"`` (the
    baseline) or ``"hnn"``."""
    if arch not in ("mlp", "hnn"):
        raise ValueError(f"arch must be 'mlp' or 'hnn', not {arch!r}")
    baseline = arch == "mlp"
    torch.manual_seed(seed)
    f32 = torch.float32
    x = torch.tensor(np.asarray(data.train.x), requires_grad=True, dtype=f32)
    test_x = torch.tensor(np.asarray(data.test.x), requires_grad=True, dtype=f32)
    dxdt = torch.tensor(np.asarray(data.train.dxdt), dtype=f32)
    test_dxdt = torch.tensor(np.asarray(data.test.dxdt), dtype=f32)
    d = x.shape[1]
    net = MLP2019(d, hidden, d if baseline else 2)
    model = HNN2019(d, net, baseline=baseline)
    optim = torch.optim.Adam(model.parameters(), lr, weight_decay=weight_decay)
    n, n_test = x.shape[0], test_x.shape[0]
    full = batch_size is None or batch_size >= n
    stats: dict[str, list[float]] = {"train_loss": [], "test_loss": []}
    grads: list[torch.Tensor] = []  # the last concatenated gradient vector

    def step() -> None:
        if full:
            xb, yb = x, dxdt
        else:
            ixs = torch.randperm(n)[:batch_size]
            xb, yb = x[ixs], dxdt[ixs]
        dxdt_hat = model.time_derivative(xb)
        loss = _l2_loss(yb, dxdt_hat)
        loss.backward()
        grad = torch.cat([p.grad.flatten() for p in model.parameters()]).clone()
        optim.step()
        optim.zero_grad()

        if full:
            tx, ty = test_x, test_dxdt
        else:
            test_ixs = torch.randperm(n_test)[:batch_size]
            tx, ty = test_x[test_ixs], test_dxdt[test_ixs]
        test_hat = model.time_derivative(tx)  # with create_graph, graph kept, as there
        test_loss = _l2_loss(ty, test_hat)

        stats["train_loss"].append(loss.item())
        stats["test_loss"].append(test_loss.item())
        grads[:] = [grad]  # kept for the grad norm / std the original printed

    return step, stats


def fit_2019(
    data: Any,
    arch: str,
    steps: int,
    batch_size: int | None,
    lr: float = 1e-3,
    weight_decay: float = 0.0,
    seed: int = 0,
    hidden: int = 200,
    warmup: int = 5,
    threads: int = 1,
    block: int = 0,
    block_times: list[float] | None = None,
) -> float:
    """Run the 2019-style loop (see the module docstring) for ``warmup`` untimed steps,
    then ``steps`` timed ones; return the wall seconds per timed step. float32,
    ``threads`` torch threads. With ``block > 0`` and a ``block_times`` list, the
    seconds per step of each consecutive block of ``block`` timed steps are appended to
    it too (for a load-robust best-block figure)."""
    torch.set_num_threads(threads)
    step, _ = make_2019(data, arch, batch_size, lr, weight_decay, seed, hidden)
    for _ in range(warmup):
        step()
    start = last = time.perf_counter()
    for i in range(1, steps + 1):
        step()
        if block > 0 and block_times is not None and i % block == 0:
            now = time.perf_counter()
            block_times.append((now - last) / block)
            last = now
    return (time.perf_counter() - start) / steps
