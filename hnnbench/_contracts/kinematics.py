"""Kinematics: the map between canonical ``(q, p)`` and velocity coordinates ``(q, q̇)``
that second-order models need, and its tangent maps (:class:`Kinematics`,
:class:`LinearKinematics`, :class:`MassMatrixKinematics`; docs/MODELS.md, "Velocity
coordinates"). Pure numpy.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

__all__ = [
    "Kinematics",
    "LinearKinematics",
    "MassMatrixKinematics",
    "identity_kinematics",
]


def _split(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[-1] // 2
    return x[..., :n], x[..., n:]


class Kinematics(ABC):
    """The map between canonical states ``(q, p)`` and velocity states ``(q, q̇)``.

    Every method takes and returns float64 arrays of shape ``(N, 2n)`` (any leading
    batch shape works for the built-in implementations).
    """

    @abstractmethod
    def to_velocity(self, x: np.ndarray) -> np.ndarray:
        """``(q, p) -> (q, q̇)``."""

    @abstractmethod
    def to_canonical(self, v: np.ndarray) -> np.ndarray:
        """``(q, q̇) -> (q, p)``, the inverse of :meth:`to_velocity`."""

    @abstractmethod
    def velocity_rate(self, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        """``(q̇, q̈)`` of a trajectory through ``x`` with canonical derivative ``xdot``."""

    @abstractmethod
    def canonical_rate(self, v: np.ndarray, vdot: np.ndarray) -> np.ndarray:
        """``(q̇, ṗ)`` of a trajectory through velocity state ``v`` with derivative
        ``vdot = (q̇, q̈)``."""


class LinearKinematics(Kinematics):
    """``q̇ = A p`` with a constant invertible ``(n, n)`` matrix ``A`` (or a scalar).

    For a Hamiltonian ``H = p^T A p / 2 + V(q)``, ``A`` is the inverse mass matrix:
    ``A = 2`` for the paper's spring and pendulum (``H = ... + p^2``), ``A = 1 / m`` for
    point masses.
    """

    def __init__(self, velocity_per_momentum: float | np.ndarray) -> None:
        a = np.asarray(velocity_per_momentum, dtype=np.float64)
        self.a: np.ndarray
        self.a_inv: np.ndarray
        self.scalar = a.ndim == 0
        if self.scalar:
            if not a != 0:
                raise ValueError("LinearKinematics needs a non-zero velocity_per_momentum")
            self.a, self.a_inv = a, 1.0 / a
        else:
            self.a, self.a_inv = a, np.linalg.inv(a)

    def _apply(self, matrix: np.ndarray, y: np.ndarray) -> np.ndarray:
        return matrix * y if self.scalar else y @ matrix.T

    def to_velocity(self, x: np.ndarray) -> np.ndarray:
        q, p = _split(x)
        return np.concatenate([q, self._apply(self.a, p)], axis=-1)

    def to_canonical(self, v: np.ndarray) -> np.ndarray:
        q, qdot = _split(v)
        return np.concatenate([q, self._apply(self.a_inv, qdot)], axis=-1)

    def velocity_rate(self, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        qdot, pdot = _split(xdot)
        return np.concatenate([qdot, self._apply(self.a, pdot)], axis=-1)

    def canonical_rate(self, v: np.ndarray, vdot: np.ndarray) -> np.ndarray:
        qdot, qddot = _split(vdot)
        return np.concatenate([qdot, self._apply(self.a_inv, qddot)], axis=-1)


def identity_kinematics() -> LinearKinematics:
    """``q̇ = p``: for states whose second half already is the velocity (measured
    angles and angular velocities, unit point masses)."""
    return LinearKinematics(1.0)


class MassMatrixKinematics(Kinematics):
    """``p = M(q) q̇`` with a symmetric positive-definite mass matrix ``M(q)``.

    Args:
        mass: ``q (N, n) -> M (N, n, n)``.
        mass_rate: ``(q (N, n), q̇ (N, n)) -> Ṁ (N, n, n)``, the time derivative
            ``sum_k ∂M/∂q_k q̇_k`` along a motion with velocity ``q̇``.

    Then ``q̈ = M⁻¹ (ṗ − Ṁ q̇)`` and ``ṗ = M q̈ + Ṁ q̇``.
    """

    def __init__(
        self,
        mass: Callable[[np.ndarray], np.ndarray],
        mass_rate: Callable[[np.ndarray, np.ndarray], np.ndarray],
    ) -> None:
        self.mass = mass
        self.mass_rate = mass_rate

    @staticmethod
    def _matvec(m: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.einsum("...ij,...j->...i", m, y)

    def to_velocity(self, x: np.ndarray) -> np.ndarray:
        q, p = _split(x)
        return np.concatenate([q, np.linalg.solve(self.mass(q), p[..., None])[..., 0]], axis=-1)

    def to_canonical(self, v: np.ndarray) -> np.ndarray:
        q, qdot = _split(v)
        return np.concatenate([q, self._matvec(self.mass(q), qdot)], axis=-1)

    def velocity_rate(self, x: np.ndarray, xdot: np.ndarray) -> np.ndarray:
        q, p = _split(x)
        qdot, pdot = _split(xdot)
        m = self.mass(q)
        rhs = pdot - self._matvec(self.mass_rate(q, qdot), qdot)
        qddot = np.linalg.solve(m, rhs[..., None])[..., 0]
        return np.concatenate([qdot, qddot], axis=-1)

    def canonical_rate(self, v: np.ndarray, vdot: np.ndarray) -> np.ndarray:
        q, qdot = _split(v)
        _, qddot = _split(vdot)
        pdot = self._matvec(self.mass(q), qddot) + self._matvec(self.mass_rate(q, qdot), qdot)
        return np.concatenate([qdot, pdot], axis=-1)
