import numpy as np
import pytest

from hnnbench._contracts.integrate import solve_batch
from hnnbench_plugins import metrics as builtin_metrics


def test_mse_and_per_point():
    pred = np.array([[0.0, 0.0], [1.0, 3.0]])
    target = np.array([[0.0, 2.0], [1.0, 1.0]])
    assert builtin_metrics.mse(pred, target) == pytest.approx(2.0)
    np.testing.assert_allclose(builtin_metrics.per_point_squared_error(pred, target), [2.0, 2.0])


def test_energy_and_rollout_errors():
    e_hat = np.array([[1.0, 2.0], [0.0, 0.0]])
    e_true = np.array([[1.0, 1.0], [1.0, 1.0]])
    np.testing.assert_allclose(builtin_metrics.energy_error_per_traj(e_hat, e_true), [0.5, 1.0])
    x = np.zeros((2, 3, 2))
    xh = x.copy()
    xh[1, :, 0] = 2.0
    np.testing.assert_allclose(builtin_metrics.rollout_error_per_traj(xh, x), [0.0, 2.0])


def test_summarize_mean_and_sem():
    s = builtin_metrics.summarize(np.array([1.0, 2.0, 3.0, 4.0]))
    assert s["mean"] == pytest.approx(2.5)
    assert s["sem"] == pytest.approx(np.std([1, 2, 3, 4], ddof=1) / 2)
    assert np.isnan(builtin_metrics.summarize(np.array([1.0]))["sem"])
    assert builtin_metrics.summarize(np.array([1.0, np.inf]))["mean"] == float("inf")


def test_valid_prediction_time():
    t = np.linspace(0, 4, 5)
    x = np.ones((2, 5, 2))
    xh = x.copy()
    xh[0, 3:] += 1.0  # exceeds at t=3 -> valid until t=2
    np.testing.assert_allclose(builtin_metrics.valid_prediction_time(xh, x, t, 0.1), [2.0, 4.0])
    xh[1, 0] = np.nan  # non-finite counts as exceeded at the start
    assert builtin_metrics.valid_prediction_time(xh, x, t, 0.1)[1] == 0.0


def test_reference_solver_closes_a_spring_period():
    f = lambda x: np.stack([2 * x[:, 1], -2 * x[:, 0]], axis=1)  # noqa: E731
    x0 = np.array([[1.0, 0.0], [0.0, 0.5]])
    t = np.linspace(0, np.pi, 7)  # one full period of the spring, omega = 2
    xs = solve_batch(f, x0, t, rtol=1e-12, atol=1e-12)
    assert xs.shape == (2, 7, 2)
    np.testing.assert_allclose(xs[:, -1], x0, atol=1e-9)
    np.testing.assert_allclose(xs[0, :, 0], np.cos(2 * t), atol=1e-9)


def test_a_metric_that_raises_is_recorded_unless_it_declares_errors_fail_job():
    from hnnbench._contracts.metric import Metric
    from hnnbench._contracts.plugin import Trajectories
    from hnnbench._running.evaluation import evaluate

    def broken(ctx):
        raise ValueError("a bug")

    traj = Trajectories(t=np.linspace(0.0, 1.0, 3), states=np.zeros((2, 3, 2)), dt=0.5)
    fine = Metric("fine", "always 1", lambda ctx: np.ones(4))
    optional = Metric("probe", "raises", broken, required=False)
    result = evaluate(None, None, None, traj, None, metrics=[fine, optional])  # type: ignore[arg-type]
    assert result.metrics["fine"]["mean"] == 1.0 and np.isnan(result.metrics["probe"]["mean"])
    assert result.errors == {"probe": "ValueError: a bug"} and result.diverged is None
    required = evaluate(
        None,
        None,
        None,
        traj,
        None,  # type: ignore[arg-type]
        metrics=[fine, Metric("needed", "raises", broken)],
    )
    assert required.errors == {"needed": "ValueError: a bug"}  # a plugin bug: recorded
    with pytest.raises(ValueError, match="a bug"):
        evaluate(
            None,
            None,
            None,
            traj,
            None,  # type: ignore[arg-type]
            metrics=[fine, Metric("core", "raises", broken, errors_fail_job=True)],
        )


def test_vpt_censored_check_floors_shares_at_a_quarter():
    """A share of 15 trajectories moves in steps of 1/15: 0 against 1/15 is no difference
    for the check (twins, regressions), while 1 against 0 is (docs/METRICS.md)."""
    rule = builtin_metrics.VPT_CENSORED.check
    assert rule.better == "higher" and rule.floor == 0.25
    assert rule.worsening(1 / 15, 0.0) == 1.0 and rule.worsening(0.0, 1 / 15) == 1.0
    assert rule.worsening(1.0, 0.0) == 4.0 > rule.factor
    assert rule.worsening(0.0, 1.0) < 1.0  # an improvement
