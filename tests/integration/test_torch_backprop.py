"""The torch training networks' hand-written backward passes
(:mod:`hnnbench.neural.torch._backprop`, :class:`TrainingMLP`) compute what autograd
computes through :class:`MLP`'s plain operations, and the direct fused Adam
(:class:`FusedAdam`) updates as ``torch.optim.Adam(fused=True)`` does."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from hnnbench.neural import NeuralConfig  # noqa: E402
from hnnbench.neural._embedding import NetInput  # noqa: E402
from hnnbench.neural._init import init_arrays  # noqa: E402
from hnnbench.neural.torch import FusedAdam, symplectic  # noqa: E402
from hnnbench.neural.torch._nets import MLP, TrainingMLP  # noqa: E402

# 60 rows, 2 or 4 inputs, 40 hidden units: the thin products (few columns, many rows)
# take the transposed orientation, the square ones the plain one
ROWS, HIDDEN = 60, 40
EMBEDDINGS = [None, NetInput(4, (0, 1), "cos_sin"), NetInput(4, (1,), "wrap")]


def params_of(
    seed: int,
    d_in: int,
    d_out: int,
    layers: int,
    activation: str,
    spec: NetInput | None,
    stack: int = 0,
) -> dict[str, torch.Tensor]:
    cfg = NeuralConfig(name="t", hidden=HIDDEN, layers=layers, activation=activation)
    width = d_in if spec is None else spec.features
    if stack:
        seeds = [init_arrays(seed + s, width, d_out, cfg) for s in range(stack)]
        return {
            f"f.{k}": torch.tensor(np.stack([w[k] for w in seeds])).requires_grad_()
            for k in seeds[0]
        }
    return {
        f"f.{k}": torch.tensor(v).requires_grad_()
        for k, v in init_arrays(seed, width, d_out, cfg).items()
    }


def value_and_gradients(
    cls: type[MLP],
    params: dict[str, torch.Tensor],
    method: str,
    x: torch.Tensor,
    target: torch.Tensor,
    layers: int,
    activation: str,
    spec: NetInput | None,
) -> tuple[torch.Tensor, list[torch.Tensor]]:
    net = cls.view(params, "f", layers, activation, spec)
    out = getattr(net, method)(x)
    loss = ((out - target[:, : out.shape[1]]) ** 2).sum()
    grads = torch.autograd.grad(loss, [x, *params.values()])
    return out.detach(), list(grads)


@pytest.mark.parametrize(
    ("spec", "d_in"),
    [(EMBEDDINGS[0], 2), *((s, 4) for s in EMBEDDINGS)],
    ids=["plain-d2", "plain-d4", "cos_sin", "wrap"],
)
@pytest.mark.parametrize("activation", ["tanh", "sigmoid", "softplus"])
@pytest.mark.parametrize("layers", [2, 3, 4])
def test_value_and_input_gradient_and_their_gradients_are_autograds(spec, d_in, activation, layers):
    """Values, and gradients with respect to every parameter and to the input (which
    the SRNN's leapfrog and the pixel models' latent states need), equal autograd's
    through the plain operations, in float64."""
    rng = np.random.default_rng(layers)
    target = torch.tensor(rng.normal(size=(ROWS, d_in)))
    for method, d_out in (("__call__", d_in), ("__call__", 1), ("input_gradient", 1)):
        params = params_of(layers, d_in, d_out, layers, activation, spec)
        results = []
        inputs = np.random.default_rng(0).normal(size=(ROWS, d_in)) * 2.0  # angles past ±π
        for cls in (MLP, TrainingMLP):
            x = torch.tensor(inputs, requires_grad=True)
            results.append(
                value_and_gradients(cls, params, method, x, target, layers, activation, spec)
            )
        (want, want_grads), (got, got_grads) = results
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14, err_msg=method)
        for g_want, g_got in zip(want_grads, got_grads, strict=True):
            np.testing.assert_allclose(
                g_got, g_want, rtol=1e-10, atol=1e-12 * float(g_want.abs().max()), err_msg=method
            )


@pytest.mark.parametrize("activation", ["tanh", "softplus"])
@pytest.mark.parametrize("method", ["__call__", "input_gradient"])
def test_seeds_as_one_batch_under_vmap(activation, method):
    """Under ``torch.func.vmap`` over stacked seeds (``fit_seeds``), the batch's losses
    and parameter gradients equal the plain operations'."""
    spec = NetInput(4, (0, 1), "cos_sin")
    params = params_of(3, 4, 1, 3, activation, spec, stack=3)
    rng = np.random.default_rng(5)
    x = torch.tensor(rng.normal(size=(3, ROWS, 4)))
    y = torch.tensor(rng.normal(size=(3, ROWS, 4)))

    def loss(cls: type[MLP]):
        def one(p: dict[str, torch.Tensor], xi: torch.Tensor, yi: torch.Tensor):
            out = getattr(cls.view(p, "f", 3, activation, spec), method)(xi)
            if method == "input_gradient":
                out = symplectic(out)
            return torch.mean((out - yi[:, : out.shape[1]]) ** 2)

        return one

    results = []
    for cls in (MLP, TrainingMLP):
        losses = torch.func.vmap(loss(cls))(params, x, y)
        grads = torch.autograd.grad(losses.sum(), list(params.values()))
        results.append((losses.detach(), grads))
    (want, want_grads), (got, got_grads) = results
    np.testing.assert_allclose(got, want, rtol=1e-12)
    for g_want, g_got in zip(want_grads, got_grads, strict=True):
        np.testing.assert_allclose(g_got, g_want, rtol=1e-10, atol=1e-14)


def test_symplectic_and_its_gradient():
    g = torch.tensor(np.random.default_rng(2).normal(size=(5, 6)), requires_grad=True)
    upstream = torch.tensor(np.random.default_rng(3).normal(size=(5, 6)))
    out = symplectic(g)
    np.testing.assert_array_equal(out.detach(), torch.cat([g[:, 3:], -g[:, :3]], 1).detach())
    (grad,) = torch.autograd.grad((out * upstream).sum(), g)
    # Jᵀ upstream: (-upstream_p, upstream_q)
    np.testing.assert_array_equal(grad, torch.cat([-upstream[:, 3:], upstream[:, :3]], 1))


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_fused_adam_is_torch_adam_to_the_bit(dtype):
    """Same updates as ``torch.optim.Adam(lr, weight_decay=wd, fused=True)`` over many
    steps, including a parameter the loss never reaches (no update, no step)."""
    rng = np.random.default_rng(4)
    start = [rng.normal(size=s) for s in ((5, 3), (4,), (2,))]
    ours = [torch.tensor(a, dtype=dtype, requires_grad=True) for a in start]
    theirs = [torch.tensor(a, dtype=dtype, requires_grad=True) for a in start]
    adam = FusedAdam(ours, lr=1e-2, weight_decay=1e-3)
    opt = torch.optim.Adam(theirs, lr=1e-2, weight_decay=1e-3, fused=True)

    def loss(p: list[torch.Tensor]) -> torch.Tensor:
        return torch.sin(p[0]).sum() + (p[1] ** 2).sum()  # p[2] unused

    for _ in range(60):
        adam.step(loss(ours))
        opt.zero_grad()
        loss(theirs).backward()
        opt.step()
    for a, b in zip(ours, theirs, strict=True):
        assert torch.equal(a, b)
    assert not torch.equal(ours[0], torch.tensor(start[0], dtype=dtype))
    assert torch.equal(ours[2], torch.tensor(start[2], dtype=dtype))
    assert [float(s) for s in adam.steps] == [60.0, 60.0, 0.0]


@pytest.mark.parametrize("method", ["__call__", "input_gradient"])
def test_a_second_derivative_through_the_training_network_raises(method):
    """The hand-written backward passes treat their saved intermediates as constants, so
    a second reverse pass through them would be wrong: it raises instead (a plugin that
    needs second derivatives uses :class:`MLP` or ``input_hessian``)."""
    params = params_of(0, 2, 1, 2, "tanh", None)
    net = TrainingMLP.view(params, "f", 2, "tanh", None)
    x = torch.tensor(np.random.default_rng(0).normal(size=(ROWS, 2)), requires_grad=True)
    out = getattr(net, method)(x).sum()
    (grad_x,) = torch.autograd.grad(out, [x], create_graph=True)
    # the first pass runs without a graph (not one that would leave the saved
    # intermediates out), so the second has nothing to differentiate
    assert grad_x.grad_fn is None
    with pytest.raises(RuntimeError, match="does not require grad|once_differentiable"):
        torch.autograd.grad(grad_x.sum(), list(params.values()))
