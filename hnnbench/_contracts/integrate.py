"""The reference integrator shared by systems and numpy models.

:func:`solve_batch`: scipy's adaptive solvers (DOP853 by default) over a batch of
initial states, integrated as one flattened system.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hnnbench._contracts.errors import RolloutDiverged

#: A batched vector field: ``(M, D) -> (M, D)``.
VectorField = Callable[[np.ndarray], np.ndarray]

__all__ = ["VectorField", "solve_batch"]


def solve_batch(
    f: VectorField,
    x0: np.ndarray,
    t: np.ndarray,
    rtol: float = 1e-9,
    atol: float = 1e-9,
    method: str = "DOP853",
) -> np.ndarray:
    """Integrate ``dx/dt = f(x)`` from each row of ``x0`` ``(M, D)`` over ``t`` ``(T,)``.

    The batch is solved as one system of ``M * D`` equations (one adaptive step size for
    all), which is as accurate per trajectory as solving each alone. ``t`` may decrease.

    Returns:
        ``(M, T, D)`` float64 states, ``out[:, 0] == x0``.
    """
    from scipy.integrate import solve_ivp  # imported when used: listing plugins stays fast

    x0 = np.asarray(x0, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    m, d = x0.shape

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        return np.asarray(f(y.reshape(m, d)), dtype=np.float64).reshape(-1)

    sol = solve_ivp(
        rhs,
        (float(t[0]), float(t[-1])),
        x0.reshape(-1),
        t_eval=t,
        rtol=rtol,
        atol=atol,
        method=method,
    )
    if not sol.success or sol.y.shape[1] != t.shape[0] or not np.all(np.isfinite(sol.y)):
        raise RolloutDiverged(f"scipy {method} failed: {sol.message}")
    return sol.y.T.reshape(t.shape[0], m, d).transpose(1, 0, 2)
