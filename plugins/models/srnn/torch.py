"""The SRNN in torch: separable ``H = T(p) + V(q)``, leapfrog training loss."""

from __future__ import annotations

import torch

from hnnbench.neural.torch import MLP


def field(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    n = z.shape[-1] // 2
    return torch.cat(
        [nets["T"].input_gradient(z[:, n:]), -nets["V"].input_gradient(z[:, :n])], dim=-1
    )


def energy(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    n = z.shape[-1] // 2
    return nets["T"](z[:, n:])[:, 0] + nets["V"](z[:, :n])[:, 0]


def _leap(
    nets: dict[str, MLP],
    q: torch.Tensor,
    p: torch.Tensor,
    force: torch.Tensor,
    h: torch.Tensor | float,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """One leapfrog step from ``(q, p)`` with ``force = ∇V(q)`` given; returns the new
    ``(q, p, ∇V(q))``: the last half-kick's force is the next step's first."""
    p = p - 0.5 * h * force
    q = q + h * nets["T"].input_gradient(p)
    force = nets["V"].input_gradient(q)
    return q, p - 0.5 * h * force, force


def step(nets: dict[str, MLP], z: torch.Tensor, h: torch.Tensor | float) -> torch.Tensor:
    """One leapfrog step of size ``h`` (a number, or ``(W, 1)``) from states ``z``
    ``(W, 2n)`` (the map the SRNN trains through, and rolls out with under
    ``model.integrator=leapfrog``)."""
    n = z.shape[-1] // 2
    q, p = z[:, :n], z[:, n:]
    q, p, _ = _leap(nets, q, p, nets["V"].input_gradient(q), h)
    return torch.cat([q, p], dim=-1)


def window_loss(
    nets: dict[str, MLP], windows: torch.Tensor, dts: torch.Tensor, substeps: int = 1
) -> torch.Tensor:
    """Mean squared error of leapfrog predictions from each window's first state
    against its other states. ``windows`` ``(W, L, 2n)``, ``dts`` ``(W, L - 1)``.

    The steps of :func:`step`, chained, with each step's closing half-kick force reused
    by the next step's opening half-kick (as in the JAX implementation)."""
    n = windows.shape[-1] // 2
    q, p = windows[:, 0, :n], windows[:, 0, n:]
    force = nets["V"].input_gradient(q)
    predictions = []
    for k in range(windows.shape[1] - 1):
        h = (dts[:, k] / substeps)[:, None]
        for _ in range(substeps):
            q, p, force = _leap(nets, q, p, force, h)
        predictions.append(torch.cat([q, p], dim=-1))
    return torch.mean((torch.stack(predictions, dim=1) - windows[:, 1:]) ** 2)
