"""Model outputs are checked against their documented shapes and dtypes before the
evaluation uses them (hnnbench._contracts.outputs): a rollout of the wrong shape used to broadcast
against the true trajectories and score; now the job is ``failed`` with one line naming
the method, the expected and the actual shape."""

from __future__ import annotations

import numpy as np
import pytest

import hnnbench
from hnnbench import _registry as registry
from hnnbench._contracts.errors import ModelOutputError
from hnnbench._contracts.metric import EvalContext, EvaluationConfig
from hnnbench._contracts.outputs import checked, checked_scalar


class _Truth(hnnbench.Model):
    """The system's own field, rolled out correctly (a test's oracle): every output
    right, so each subclass below breaks exactly one."""

    version = "1"

    def fit(self, data, train, seed, progress):
        return hnnbench.FitResult(history={}, steps=0)

    def time_derivative(self, x):
        return self.system.vector_field(x)

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
        return hnnbench.solve_batch(
            self.time_derivative, x0, t, rtol=rtol, atol=atol, method="RK45"
        )

    def energy(self, x):
        return self.system.energy(x)


class _Model:
    """A stand-in with whatever outputs a case sets (the context only calls methods)."""

    class cfg:  # noqa: N801 - mirrors Model.cfg.name
        name = "stub"

    def __init__(self, **outputs):
        self.outputs = outputs

    def __getattr__(self, method):
        if method in ("time_derivative", "rollout", "energy", "encode", "decode", "loss"):
            return lambda *args, **kw: self.outputs[method]
        raise AttributeError(method)


def _context(model, pixels=False):
    from types import SimpleNamespace

    m, t_len, d = 3, 7, 2
    t = np.linspace(0.0, 1.0, t_len)
    states = np.zeros((m, t_len, d))
    obs = np.zeros((m, t_len, 16)) if pixels else None
    traj = SimpleNamespace(t=t, states=states, observations=obs, x0=states[:, 0])
    split = SimpleNamespace(
        x=np.zeros((10, d)), dxdt=np.zeros((10, d)), extras={"state": np.zeros((10, d))}
    )
    data = SimpleNamespace(train=split, test=split)
    system = SimpleNamespace(
        observation="pixels" if pixels else "state", energy=lambda x: np.zeros(len(x))
    )
    return EvalContext(system, model, data, traj, EvaluationConfig())  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("outputs", "ask", "message"),
    [
        (
            {"time_derivative": np.zeros((10, 1))},
            lambda c: c.loss_values("train"),
            "stub.time_derivative returned shape (10, 1), expected (N, D) like its targets "
            "= (10, 2)",
        ),
        (
            {"time_derivative": np.zeros((10, 2), dtype=np.float32)},
            lambda c: c.loss_values("train"),
            "stub.time_derivative returned dtype float32",
        ),
        (
            {"rollout": np.zeros((3, 7))},
            lambda c: c.rollout(),
            "stub.rollout returned shape (3, 7), expected (M, T, d)",
        ),
        (
            {"rollout": np.zeros((3, 7, 2), dtype=np.int64)},
            lambda c: c.rollout(),
            "stub.rollout returned dtype int64",
        ),
        (
            {"rollout": np.zeros((3, 7, 2)), "energy": np.zeros((21, 1))},
            lambda c: c.states_hat(),
            "stub.energy returned shape (21, 1), expected (N,) or None = (21,)",
        ),
        ({"rollout": np.zeros((3, 7, 2)), "energy": None}, lambda c: c.states_hat(), None),
    ],
)
def test_each_output_is_checked(outputs, ask, message):
    ctx = _context(_Model(**outputs))
    if message is None:
        ask(ctx)
        return
    with pytest.raises(ModelOutputError) as err:
        ask(ctx)
    assert str(err.value).startswith(message), str(err.value)


def test_pixel_outputs_are_checked():
    ok = {"encode": np.zeros((3, 4), dtype=np.float32), "rollout": np.zeros((3, 7, 4))}
    ctx = _context(_Model(**ok, decode=np.zeros((21, 16), dtype=np.float32)), pixels=True)
    assert ctx.pixel_errors().shape == (3,)
    ctx = _context(_Model(**ok, decode=np.zeros((21, 15))), pixels=True)
    with pytest.raises(
        ModelOutputError,
        match=r"stub.decode returned shape \(21, 15\), "
        r"expected \(N, D_obs\) like the frames",
    ):
        ctx.pixel_errors()
    ctx = _context(_Model(encode=np.zeros((2, 4)), rollout=ok["rollout"]), pixels=True)
    with pytest.raises(ModelOutputError, match=r"stub.encode returned shape \(2, 4\)"):
        ctx.z0()
    ctx = _context(_Model(loss=np.zeros(3)), pixels=True)
    with pytest.raises(
        ModelOutputError,
        match=r"stub.loss returned shape \(3,\), expected a "
        "scalar",
    ):
        ctx.loss_values("test")


def test_right_outputs_pass_through_uncopied():
    """A correct model's arrays are used as they are: no copy, no conversion."""
    rollout = np.zeros((3, 7, 2))
    assert checked(_Model(), "rollout", rollout, (3, 7, 2), "(M, T, d)") is rollout
    latents = np.zeros((3, 4), dtype=np.float32)
    assert checked(_Model(), "encode", latents, (3, None), "(N, k)", float64=False) is latents
    assert checked_scalar(_Model(), "loss", np.float32(0.5)) == 0.5


def test_the_default_loss_checks_the_field_shape():
    system = registry.get_class("system", "spring")(registry.get_class("system", "spring").Config())
    model = _Truth(hnnbench.ModelConfig(name="truth"), system)
    x = np.random.default_rng(0).normal(size=(8, 2))
    assert model.loss(x, system.vector_field(x)) == 0.0
    with pytest.raises(ModelOutputError, match="truth.time_derivative returned shape"):
        model.loss(x, np.zeros((8, 1)))
