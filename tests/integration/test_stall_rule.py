"""The stall rule (hnnbench.neural._backend.rollout_min_step): a neural rollout whose
solver step size falls below 1e-8 of its span is diverged at once, the same way in the
torch and the JAX solver."""

from __future__ import annotations

import numpy as np
import pytest

from hnnbench.neural._backend import MIN_STEP_FRACTION, rollout_min_step

T = np.linspace(0.0, 2.0, 21)
BLOW_UP_AT = 1.0  # y' = y^2 from y(0) = 1: y = 1 / (1 - t)


def test_the_limit_is_a_fraction_of_the_span():
    assert rollout_min_step(T) == pytest.approx(2.0 * MIN_STEP_FRACTION)
    assert rollout_min_step(T[::-1]) == rollout_min_step(T)  # backwards too
    assert rollout_min_step(np.zeros(0)) == 0.0


def test_torch_solver_stops_at_the_stall_not_the_budget():
    torch = pytest.importorskip("torch")
    from hnnbench.neural.torch._ode import SolverGaveUp, dopri5

    calls = [0]

    def field(y):
        calls[0] += 1
        return y * y

    y0 = torch.ones((1, 1), dtype=torch.float64)
    with pytest.raises(SolverGaveUp, match=r"at t=0\.99\d*.*below the stall limit 2e-08"):
        dopri5(field, y0, T, rtol=1e-9, atol=1e-9, max_steps=10**6, min_step=rollout_min_step(T))
    assert calls[0] < 5000, calls  # without the rule: the budget, 10^6 steps
    # A field that needs no tiny step is unaffected.
    ys = dopri5(
        lambda y: -y, y0, T, rtol=1e-9, atol=1e-9, max_steps=10_000, min_step=rollout_min_step(T)
    )
    assert np.allclose(ys[:, 0, 0].numpy(), np.exp(-T), rtol=1e-7)


def test_jax_solver_stops_at_the_stall_not_the_budget():
    pytest.importorskip("jax")
    import jax.numpy as jnp

    from hnnbench.neural import jax as backend

    def field(_nets, y):
        return y * y

    ys, code = backend._solve(
        field,
        None,
        jnp.ones((1, 1)),
        jnp.asarray(T),
        jnp.float64(1e-9),
        jnp.float64(1e-9),
        jnp.float64(rollout_min_step(T)),
        10**6,
    )
    assert int(code) == backend._STALLED
    ys = np.asarray(ys)[0, :, 0]
    finite = np.isfinite(ys)
    # Saved up to the blow-up, nothing after: it stopped there, not at the budget.
    assert finite[T < BLOW_UP_AT - 0.05].all() and not finite[T > BLOW_UP_AT].any()
    ys, code = backend._solve(
        lambda _n, y: -y,
        None,
        jnp.ones((1, 1)),
        jnp.asarray(T),
        jnp.float64(1e-9),
        jnp.float64(1e-9),
        jnp.float64(rollout_min_step(T)),
        10_000,
    )
    assert int(code) == 0
    assert np.allclose(np.asarray(ys)[0, :, 0], np.exp(-T), rtol=1e-7)


class _Exploding:
    """A model whose rollout grows exponentially, e^{t}·x0 (finite all along)."""

    class cfg:  # noqa: N801 - mirrors Model.cfg.name
        name = "exploding"

    def __init__(self, rate: float) -> None:
        self.rate = rate

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
        t = np.asarray(t, dtype=np.float64)
        return np.asarray(x0)[:, None, :] * np.exp(self.rate * (t - t[0]))[None, :, None]

    def energy(self, x):
        return None


@pytest.mark.parametrize("rate, diverged", [(0.0, False), (0.2, False), (1.0, True)])
def test_the_state_bound_marks_a_blow_up_diverged_and_spares_a_drift(rate, diverged):
    """The same rule for every model and backend (``EvalContext.roll``): over the
    spring's horizon of 20, e^{0.2 t} (x55) stays inside 100x the data's largest norm,
    e^{t} does not, and is diverged with the time it left the bound."""
    from hnnbench._contracts.errors import RolloutDiverged
    from hnnbench._contracts.metric import STATE_BOUND, EvalContext, EvaluationConfig
    from hnnbench_plugins.systems.spring import Spring, SpringConfig

    system = Spring(SpringConfig(name="spring", n_traj=10, eval_n_traj=3))
    ctx = EvalContext(
        system, _Exploding(rate), system.dataset(0), system.evaluation(0), EvaluationConfig()
    )
    assert ctx.state_bound() == pytest.approx(
        STATE_BOUND
        * max(
            np.linalg.norm(system.dataset(0).train.x, axis=-1).max(),
            np.linalg.norm(system.evaluation(0).states, axis=-1).max(),
        )
    )
    if diverged:
        with pytest.raises(RolloutDiverged, match="left the state bound at t="):
            ctx.rollout()
    else:
        assert ctx.rollout().shape == (3, 100, 2)


def test_angles_are_left_out_of_the_state_bound():
    """A double-pendulum angle that keeps turning (q1 = 50 t) is no blow-up."""
    from hnnbench._contracts.metric import EvalContext, EvaluationConfig
    from hnnbench_plugins.systems.double_pendulum import DoublePendulum, DoublePendulumConfig

    system = DoublePendulum(DoublePendulumConfig(name="double_pendulum", n_traj=4, eval_n_traj=2))
    traj = system.evaluation(0)

    class Turning(_Exploding):
        def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
            out = np.repeat(np.asarray(x0)[:, None, :], len(t), axis=1).copy()
            out[:, :, 0] += 50.0 * np.asarray(t)[None, :]
            return out

    ctx = EvalContext(system, Turning(0.0), system.dataset(0), traj, EvaluationConfig())
    assert ctx.rollout().shape[1] == len(traj.t)
