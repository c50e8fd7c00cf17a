"""Periodic coordinates inside the networks: one exact embedding for every family.

A system declares which positions are angles (:attr:`hnnbench.System.angles`: its
dynamics are 2π-periodic in them). Data and evaluation keep the angles as the system
gives them (continuous, or wrapped where the system says so); every network of every
family reads its angle inputs through one of these maps, before its first layer:

- ``"cos_sin"`` (the default): each angle ``θ`` becomes ``cos θ`` in its own input
  column, and ``sin θ`` is appended after the network's other inputs (in the order of
  the angles), so a network of ``w`` inputs with ``k`` angles has ``w + k`` input
  features. The network is then a smooth, exactly 2π-periodic function of each angle.
- ``"wrap"``: each angle is wrapped into ``[-π, π)`` (``θ - 2π floor((θ + π) / 2π)``),
  as the LNN paper's code does. Exactly periodic, but the network is not continuous
  across ``±π`` unless it learns to be.
- ``"none"``: the angle enters as it is (the protocol before this embedding).

The choice is ``model.angle_embedding``; the embedding is part of the network, so the
field, the learned energy and their derivatives (closed form in torch, autodiff in JAX)
all see it. docs/MODELS.md ("Periodic coordinates") gives the measurement behind the
default.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal

import numpy as np

__all__ = ["ANGLE_EMBEDDINGS", "Layout", "NetInput", "embed", "wrap"]

#: The values of ``model.angle_embedding``.
ANGLE_EMBEDDINGS = ("cos_sin", "wrap", "none")

#: Which slice of the family's working coordinates ``z = (q, v)`` a network reads.
Reads = Literal["z", "q", "p"]


@dataclass(frozen=True)
class NetInput:
    """What one network reads.

    Attributes:
        width: its input size ``w`` before the embedding (``d`` for a network of the
            whole state, ``n`` for one of the positions or momenta alone).
        angles: the columns of its input that are angles (sorted, each ``< width``).
        embedding: ``"cos_sin"``, ``"wrap"`` or ``"none"`` (module docstring).
    """

    width: int
    angles: tuple[int, ...] = ()
    embedding: str = "none"

    @property
    def active(self) -> bool:
        """Whether the network's inputs are changed at all."""
        return bool(self.angles) and self.embedding != "none"

    @property
    def features(self) -> int:
        """Inputs of the network's first layer: ``width`` plus one per angle under
        ``cos_sin``."""
        extra = len(self.angles) if self.active and self.embedding == "cos_sin" else 0
        return self.width + extra


@dataclass(frozen=True)
class Layout:
    """A model's networks on one system: the dimension ``d`` of the family's working
    coordinates and, per network name (in the family's order), what it reads."""

    d: int
    nets: tuple[tuple[str, NetInput], ...]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.nets)

    def __getitem__(self, name: str) -> NetInput:
        return dict(self.nets)[name]

    @staticmethod
    def build(
        d: int,
        shapes: Mapping[str, tuple[int, int]],
        reads: Mapping[str, str],
        angles: tuple[int, ...],
        embedding: str,
    ) -> Layout:
        """The layout of networks ``shapes`` (``{name: (width, d_out)}``) that read
        ``reads[name]`` (``"z"``, ``"q"`` or ``"p"``; default ``"z"``) of coordinates
        whose first ``d // 2`` are positions, ``angles`` among them."""
        nets = []
        for name, (width, _) in shapes.items():
            part = reads.get(name, "z")
            cols = () if part == "p" else tuple(sorted(angles))
            nets.append((name, NetInput(width, cols, embedding)))
        return Layout(d, tuple(nets))


def wrap(theta: np.ndarray) -> np.ndarray:
    """Angles ``theta`` wrapped into ``[-π, π)``."""
    return theta - 2.0 * math.pi * np.floor((theta + math.pi) / (2.0 * math.pi))


def embed(spec: NetInput, x: np.ndarray) -> np.ndarray:
    """The reference (numpy) embedding of inputs ``x`` ``(N, width)`` ->
    ``(N, features)``; the backends implement the same map in their own ops (tests
    compare them with this one)."""
    x = np.asarray(x, dtype=np.float64)
    if not spec.active:
        return x
    cols = list(spec.angles)
    out = x.copy()
    if spec.embedding == "wrap":
        out[:, cols] = wrap(x[:, cols])
        return out
    out[:, cols] = np.cos(x[:, cols])
    return np.concatenate([out, np.sin(x[:, cols])], axis=1)
