"""The baseline MLP in torch: ``ż = f(z)``."""

from __future__ import annotations

import torch

from hnnbench.neural.torch import MLP


def field(nets: dict[str, MLP], z: torch.Tensor) -> torch.Tensor:
    return nets["f"](z)
