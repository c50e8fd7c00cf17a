"""The second-order MLP in torch: ``(q, q̇)' = (q̇, g(q, q̇))``."""

from __future__ import annotations

import torch

from hnnbench.neural.torch import MLP


def field(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    n = z.shape[-1] // 2
    return torch.cat([z[:, n:], nets["g"](z)], dim=-1)
