"""The SRNN in torch: separable ``H = T(p) + V(q)``, leapfrog training loss."""

from __future__ import annotations

import torch

from hnnbench.neural.torch import MLP


def field(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    n = z.shape[-1] // 2
    return torch.cat([nets["T"].input_gradient(z[:, n:]),
                      -nets["V"].input_gradient(z[:, :n])], dim=-1)


def energy(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    n = z.shape[-1] // 2
    return nets["T"](z[:, n:])[:, 0] + nets["V"](z[:, :n])[:, 0]


def step(nets: dict[str, MLP], z: torch.Tensor, h: torch.Tensor | float) -> torch.Tensor:
    """One leapfrog step of size ``h`` (a number, or ``(W, 1)``) from states ``z``
    ``(W, 2n)`` (the map the SRNN trains through, and rolls out with under
    ``model.integrator=leapfrog``)."""
    n = z.shape[-1] // 2
    q, p = z[:, :n], z[:, n:]
    p = p - 0.5 * h * nets["V"].input_gradient(q)
    q = q + h * nets["T"].input_gradient(p)
    p = p - 0.5 * h * nets["V"].input_gradient(q)
    return torch.cat([q, p], dim=-1)


def window_loss(nets: dict[str, MLP], windows: torch.Tensor, dts: torch.Tensor,
                substeps: int = 1) -> torch.Tensor:
    """Mean squared error of leapfrog predictions from each window's first state
    against its other states. ``windows`` ``(W, L, 2n)``, ``dts`` ``(W, L - 1)``."""
    state = windows[:, 0]
    predictions = []
    for k in range(windows.shape[1] - 1):
        h = (dts[:, k] / substeps)[:, None]
        for _ in range(substeps):
            state = step(nets, state, h)
        predictions.append(state)
    return torch.mean((torch.stack(predictions, dim=1) - windows[:, 1:]) ** 2)
