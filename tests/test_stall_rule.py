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
        dopri5(field, y0, T, rtol=1e-9, atol=1e-9, max_steps=10**6,
               min_step=rollout_min_step(T))
    assert calls[0] < 5000, calls  # without the rule: the budget, 10^6 steps
    # A field that needs no tiny step is unaffected.
    ys = dopri5(lambda y: -y, y0, T, rtol=1e-9, atol=1e-9, max_steps=10_000,
                min_step=rollout_min_step(T))
    assert np.allclose(ys[:, 0, 0].numpy(), np.exp(-T), rtol=1e-7)


def test_jax_solver_stops_at_the_stall_not_the_budget():
    pytest.importorskip("jax")
    import jax.numpy as jnp

    from hnnbench.neural import jax as backend

    def field(_nets, y):
        return y * y

    ys, code = backend._solve(field, None, jnp.ones((1, 1)), jnp.asarray(T),
                              jnp.float64(1e-9), jnp.float64(1e-9),
                              jnp.float64(rollout_min_step(T)), 10**6)
    assert int(code) == backend._STALLED
    ys = np.asarray(ys)[0, :, 0]
    finite = np.isfinite(ys)
    # Saved up to the blow-up, nothing after: it stopped there, not at the budget.
    assert finite[T < BLOW_UP_AT - 0.05].all() and not finite[T > BLOW_UP_AT].any()
    ys, code = backend._solve(lambda _n, y: -y, None, jnp.ones((1, 1)), jnp.asarray(T),
                              jnp.float64(1e-9), jnp.float64(1e-9),
                              jnp.float64(rollout_min_step(T)), 10_000)
    assert int(code) == 0
    assert np.allclose(np.asarray(ys)[0, :, 0], np.exp(-T), rtol=1e-7)


@pytest.mark.slow
@pytest.mark.parametrize("model", ["lnn_torch", "lnn_jax"])
def test_a_stalling_lnn_job_is_diverged_in_seconds(model, tmp_path):
    """The quick LNN (seed 0) on the measured double pendulum stalls at t = 0.05-0.06 of
    its first rollout; both twins record it ``diverged`` by the stall rule, in seconds.
    (The quick two-body LNN stalled before it had its declared kinetic term, and its
    torch twin took 513 s when it ran to the step budget; it now trains.)"""
    from conftest import hnnbench

    from hnnbench._records import read_record

    pytest.importorskip("torch" if model.endswith("torch") else "jax")
    proc = hnnbench("system=real_double_pendulum", f"model={model}", "profile=quick",
                    f"hydra.run.dir={tmp_path}", cwd=tmp_path, timeout=600)
    assert proc.returncode == 1, proc.stderr[-2000:]  # a single run: 0 only when ok
    record = read_record(tmp_path / "result.json")
    assert record is not None
    assert record["status"] == "diverged" and "stall limit" in record["error"], record["error"]
    assert record["timings"]["total_s"] < 120
