"""The torch models' batched Dormand-Prince solver against independent solvers."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from scipy.integrate import solve_ivp  # noqa: E402

from hnnbench.neural.torch._ode import SolverGaveUp, dopri5  # noqa: E402


def pendulum(y: torch.Tensor) -> torch.Tensor:
    """The paper's pendulum field for ``(N, 2)`` states, H = 3(1 - cos q) + p^2."""
    return torch.stack([2.0 * y[:, 1], -3.0 * torch.sin(y[:, 0])], dim=-1)


def reference(y0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``(N, T, 2)`` from scipy's DOP853 at a much tighter tolerance."""
    return np.stack(
        [
            solve_ivp(
                lambda _t, y: [2.0 * y[1], -3.0 * np.sin(y[0])],
                (t[0], t[-1]),
                y,
                t_eval=t,
                rtol=1e-13,
                atol=1e-13,
                method="DOP853",
            ).y.T
            for y in y0
        ]
    )


@pytest.fixture(scope="module")
def problem():
    y0 = np.random.default_rng(0).uniform(-1.5, 1.5, size=(6, 2))
    return y0, np.linspace(0.0, 10.0, 57)


# Bounds: global error over t in [0, 10]; torchdiffeq gives 2.3e-4 and 1.4e-7 here.
@pytest.mark.parametrize("tol, bound", [(1e-6, 3e-4), (1e-9, 3e-7)])
def test_matches_a_tight_reference_at_the_requested_times(problem, tol, bound):
    y0, t = problem
    ys = dopri5(pendulum, torch.tensor(y0), t, rtol=tol, atol=tol, max_steps=10_000)
    assert ys.shape == (len(t), *y0.shape) and ys.dtype == torch.float64
    err = np.abs(ys.permute(1, 0, 2).numpy() - reference(y0, t)).max()
    assert err < bound, err


def test_agrees_with_torchdiffeq_dopri5(problem):
    torchdiffeq = pytest.importorskip("torchdiffeq")
    y0, t = problem
    ours = dopri5(pendulum, torch.tensor(y0), t, rtol=1e-9, atol=1e-9, max_steps=10_000)
    theirs = torchdiffeq.odeint(
        lambda _t, y: pendulum(y),
        torch.tensor(y0),
        torch.tensor(t),
        rtol=1e-9,
        atol=1e-9,
        method="dopri5",
    )
    np.testing.assert_allclose(ours.numpy(), theirs.numpy(), atol=2e-7)


def test_backward_in_time_returns_to_the_start(problem):
    y0, t = problem
    forward = dopri5(pendulum, torch.tensor(y0), t, rtol=1e-10, atol=1e-10, max_steps=10_000)
    back = dopri5(pendulum, forward[-1], t[::-1].copy(), rtol=1e-10, atol=1e-10, max_steps=10_000)
    np.testing.assert_allclose(back[-1].numpy(), y0, atol=1e-7)
    np.testing.assert_allclose(back.flip(0).numpy(), forward.numpy(), atol=1e-7)


def test_single_time_returns_the_initial_state():
    y0 = torch.tensor([[0.3, -0.2]], dtype=torch.float64)
    np.testing.assert_array_equal(dopri5(pendulum, y0, np.array([0.0]), 1e-9, 1e-9, 10)[0], y0)


def test_gives_up_on_blow_up_and_on_the_step_budget(problem):
    y0, t = problem
    with pytest.raises(SolverGaveUp, match="rollout_max_steps"):
        dopri5(pendulum, torch.tensor(y0), t, rtol=1e-9, atol=1e-9, max_steps=5)
    with pytest.raises(SolverGaveUp):  # dy/dt = y^2 blows up at t = 1
        dopri5(
            lambda y: y * y,
            torch.ones((2, 1), dtype=torch.float64),
            np.array([0.0, 2.0]),
            rtol=1e-9,
            atol=1e-9,
            max_steps=100_000,
        )
