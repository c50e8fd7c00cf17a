"""Networks of the torch backend, as functions of parameter tensors.

Training networks are *views* on a flat ``{name: tensor}`` parameter dict, so one
definition serves one seed and, under :func:`torch.func.vmap`, a batch of seeds. Their
operations are ``nn.Linear``'s (``F.linear``); the trainer's :class:`TrainingMLP`
computes the same values with hand-written backward passes. Rollouts use :class:`FrozenMLP`, a
detached float64 copy with pre-transposed weights and one ``addmm`` per layer: an ODE
solve calls the network thousands of times on a handful of states, where per-call
overhead, not arithmetic, decides the cost.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Optional

import numpy as np
import torch
import torch.nn.functional as F

from hnnbench.neural._embedding import NetInput
from hnnbench.neural._init import AE_LAYERS
from hnnbench.neural._views import CC_WEIGHT, DYNAMICS_WEIGHT
from hnnbench.neural.torch import _backprop

__all__ = [
    "MLP",
    "Autoencoder",
    "FrozenMLP",
    "TrainingMLP",
    "Periodic",
    "activate",
    "activation_grad",
    "input_hessian",
    "pixel_objective",
    "pixel_objective_rows",
    "symplectic",
]


def symplectic(grad: torch.Tensor) -> torch.Tensor:
    """``(dH/dq, dH/dp) -> (dH/dp, -dH/dq)`` along the last axis: ``J ∇H``; while
    autograd records, one node with its backward written out."""
    if grad.requires_grad and torch.is_grad_enabled():
        return _backprop.symplectic(grad)
    n = grad.shape[-1] // 2
    return torch.cat([grad[..., n:], -grad[..., :n]], dim=-1)


def activate(name: str, a: torch.Tensor) -> torch.Tensor:
    """The activation ``name`` (``tanh``, ``sigmoid`` or ``softplus``) at ``a``."""
    if name == "tanh":
        return torch.tanh(a)
    if name == "sigmoid":
        return torch.sigmoid(a)
    return F.softplus(a)


def activation_grad(name: str, a: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
    """Derivative of the activation ``name`` at pre-activation ``a`` (``h`` its value)."""
    if name == "tanh":
        return 1.0 - h * h
    if name == "sigmoid":
        return h * (1.0 - h)
    return torch.sigmoid(a)


def curvature_of(name: str, h: torch.Tensor, slope: torch.Tensor) -> torch.Tensor:
    """Second derivative of the activation ``name`` from its value ``h`` and its first
    derivative ``slope`` (tanh: ``-2 h σ'``; sigmoid: ``σ' (1 - 2h)``; softplus, whose
    ``σ'`` is the logistic ``s``: ``s (1 - s)``), without evaluating it again."""
    if name == "tanh":
        return -2.0 * h * slope
    if name == "sigmoid":
        return slope * (1.0 - 2.0 * h)
    return slope * (1.0 - slope)


class Periodic:
    """The angle embedding of one network's inputs (:mod:`hnnbench.neural._embedding`)
    in torch, with its first and second derivatives for the closed-form gradients and
    Hessians. ``x`` is ``(N, w)``; the embedded inputs ``u`` are ``(N, features)``.
    Built only for a network with angles and an embedding other than ``none``."""

    def __init__(self, spec: NetInput, device: Optional[torch.device] = None) -> None:
        self.kind = spec.embedding
        self.width = spec.width
        self.angles = spec.angles
        self.cols = torch.tensor(spec.angles, dtype=torch.long, device=device)

    @staticmethod
    def of(spec: Optional[NetInput], device: Optional[torch.device] = None) -> Optional[Periodic]:
        """The embedding of ``spec``, or ``None`` where it changes nothing."""
        return Periodic(spec, device) if spec is not None and spec.active else None

    def _cols(self, x: torch.Tensor) -> torch.Tensor:
        return self.cols if self.cols.device == x.device else self.cols.to(x.device)

    def embed(self, x: torch.Tensor) -> torch.Tensor:
        """``u(x)`` ``(N, features)``."""
        cols = self._cols(x)
        theta = x.index_select(-1, cols)
        if self.kind == "wrap":
            wrapped = theta - 2.0 * math.pi * torch.floor((theta + math.pi) / (2.0 * math.pi))
            return x.index_copy(-1, cols, wrapped)
        return torch.cat([x.index_copy(-1, cols, torch.cos(theta)), torch.sin(theta)], dim=-1)

    def pull(self, x: torch.Tensor, grad_u: torch.Tensor) -> torch.Tensor:
        """The gradient with respect to ``x`` ``(N, w)`` of a function whose gradient
        with respect to ``u`` is ``grad_u`` ``(N, features)``."""
        if self.kind == "wrap":
            return grad_u
        cols = self._cols(x)
        theta = x.index_select(-1, cols)
        g_cos, g_sin = grad_u.index_select(-1, cols), grad_u[..., self.width :]
        return grad_u[..., : self.width].index_copy(
            -1, cols, g_sin * torch.cos(theta) - g_cos * torch.sin(theta)
        )

    def first_tangent(self, w: torch.Tensor, x: torch.Tensor) -> torch.Tensor:
        """``∂(W u(x))/∂x`` transposed, ``(N, w, out)``, for a first-layer weight ``w``
        ``(out, features)``."""
        n = x.shape[0]
        wt = w.t()  # (features, out)
        base = wt[: self.width].expand(n, -1, -1)
        if self.kind == "wrap":
            return base
        cols = self._cols(x)
        theta = x.index_select(-1, cols)[:, :, None]  # (N, k, 1)
        rows = (
            torch.cos(theta) * wt[self.width :][None]
            - torch.sin(theta) * wt.index_select(0, cols)[None]
        )  # (N, k, out)
        return base.index_copy(1, cols, rows)

    def curvature(
        self, x: torch.Tensor, grad_u: torch.Tensor, hess: torch.Tensor, first_row: int
    ) -> torch.Tensor:
        """``hess`` ``(N, w - first_row, w)`` plus the embedding's own second-derivative
        term ``Σ_j ∂f/∂u_j ∂²u_j/∂x²`` (diagonal, in the angle columns)."""
        if self.kind == "wrap":
            return hess
        cols = self._cols(x)
        theta = x.index_select(-1, cols)
        diag = -(
            grad_u.index_select(-1, cols) * torch.cos(theta)
            + grad_u[..., self.width :] * torch.sin(theta)
        )  # (N, k)
        keep = [j for j, c in enumerate(self.angles) if c >= first_row]
        if not keep:  # e.g. the LNN's velocity rows: no angle among them
            return hess
        columns = [self.angles[j] for j in keep]
        extra = torch.zeros_like(hess)
        extra[:, [c - first_row for c in columns], columns] = diag[:, keep]
        return hess + extra


def input_hessian(
    weights: Sequence[torch.Tensor],
    biases: Sequence[torch.Tensor],
    activation: str,
    x: torch.Tensor,
    first_row: int = 0,
    periodic: Optional[Periodic] = None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Value ``(N,)``, input gradient ``(N, d)`` and the rows ``first_row:`` of the input
    Hessian ``(N, d - first_row, d)`` of a scalar-output MLP (``(out, in)`` weights, an
    activation between layers, no bias on the last), in closed form.

    The Hessian of such a network is ``sum_k J_kᵀ diag(δ_k ⊙ σ''(a_k)) J_k`` over its
    hidden layers (its linear maps have no curvature): ``a_k`` the layer's
    pre-activation, ``J_k = ∂a_k/∂x`` carried forward with the values (``d`` tangents,
    one batched product per layer), ``δ_k = ∂f/∂h_k`` carried backward with the
    gradient. Plain tensor operations: autograd differentiates it for training (one
    backward pass, no nested ``torch.func`` transforms), and rollouts run it without
    autograd. ``periodic``: the network's angle embedding, applied before its first
    layer (its Jacobian enters the first tangent, its curvature the angle diagonal).
    """
    n, d = x.shape
    slopes, jac = [], []  # σ'(a_k) and ∂a_k/∂x of each hidden layer
    h, tangent = (x if periodic is None else periodic.embed(x)), None  # tangent: ∂h/∂x
    for w, b in zip(weights[:-1], biases, strict=True):
        a = F.linear(h, w, b)
        if tangent is not None:
            ja = F.linear(tangent, w)  # (N, d, out)
        elif periodic is None:
            ja = w.t().expand(n, d, -1)
        else:
            ja = periodic.first_tangent(w, x)
        h = activate(activation, a)
        slope = activation_grad(activation, a, h)
        tangent = ja * slope[:, None, :]
        slopes.append((h, slope))
        jac.append(ja)
    value = F.linear(h, weights[-1])[:, 0]
    delta = weights[-1].expand(n, -1)  # ∂f/∂h of the last hidden layer, (N, width)
    hess = x.new_zeros(n, d - first_row, d)
    for k in range(len(weights) - 2, -1, -1):
        hk, slope = slopes[k]
        ja = jac[k]
        curvature = delta * curvature_of(activation, hk, slope)  # (N, width)
        hess = hess + (ja[:, first_row:, :] * curvature[:, None, :]) @ ja.transpose(1, 2)
        delta = (delta * slope) @ weights[k]
    if periodic is None:
        return value, delta, hess
    return value, periodic.pull(x, delta), periodic.curvature(x, delta, hess, first_row)


class MLP:
    """``len(weights)`` linear layers (``(out, in)`` weights) with an activation between
    them; the last has no bias. Maps ``(N, d_in)`` to ``(N, d_out)``."""

    def __init__(
        self,
        weights: Sequence[torch.Tensor],
        biases: Sequence[torch.Tensor],
        activation: str,
        periodic: Optional[Periodic] = None,
    ) -> None:
        self.weights, self.biases, self.activation = list(weights), list(biases), activation
        #: The angle embedding before the first layer (``None``: the inputs as they are).
        self.periodic = periodic

    @classmethod
    def view(
        cls,
        params: Mapping[str, torch.Tensor],
        net: str,
        layers: int,
        activation: str,
        inputs: Optional[NetInput] = None,
    ) -> MLP:
        """The network ``net`` of a flat parameter dict (``"<net>.linears.<i>.weight"``);
        ``inputs``: what it reads (its angle embedding)."""
        weights = [params[f"{net}.linears.{i}.weight"] for i in range(layers)]
        biases = [params[f"{net}.linears.{i}.bias"] for i in range(layers - 1)]
        return cls(weights, biases, activation, Periodic.of(inputs))

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        h = x if self.periodic is None else self.periodic.embed(x)
        for w, b in zip(self.weights[:-1], self.biases, strict=True):
            h = activate(self.activation, F.linear(h, w, b))
        return F.linear(h, self.weights[-1])

    def input_gradient(self, x: torch.Tensor) -> torch.Tensor:
        """Gradient ``(N, d_in)`` of the scalar output with respect to ``x``, in closed
        form (a reverse sweep through the layers), so training on it needs one
        backward pass instead of a double backward. Requires ``d_out == 1``."""
        pre, post = [], []
        h = x if self.periodic is None else self.periodic.embed(x)
        for w, b in zip(self.weights[:-1], self.biases, strict=True):
            a = F.linear(h, w, b)
            h = activate(self.activation, a)
            pre.append(a)
            post.append(h)
        g = self.weights[-1].expand(x.shape[0], -1)  # (N, hidden)
        for i in range(len(self.weights) - 2, -1, -1):
            g = (g * activation_grad(self.activation, pre[i], post[i])) @ self.weights[i]
        return g if self.periodic is None else self.periodic.pull(x, g)

    def input_hessian(
        self, x: torch.Tensor, first_row: int = 0
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """:func:`input_hessian` of this network (``d_out == 1``)."""
        return input_hessian(
            self.weights, self.biases, self.activation, x, first_row, self.periodic
        )


class TrainingMLP(MLP):
    """The training networks' :class:`MLP`: the same values, with the value and the
    input gradient each one autograd node whose backward is written out
    (:mod:`hnnbench.neural.torch._backprop`: the HNN's spring step 15% faster than
    through the plain operations, ``benchmarks/torch_step_options.py``). Reverse mode
    only (no ``torch.func.jacfwd``/``hessian`` through it); the angle embedding's maps
    around the network stay plain operations. The input Hessian is :class:`MLP`'s."""

    def _params(self) -> list[torch.Tensor]:
        out = []
        for w, b in zip(self.weights[:-1], self.biases, strict=True):
            out += [w, b]
        return [*out, self.weights[-1]]

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        u = x if self.periodic is None else self.periodic.embed(x)
        return _backprop.value(self.activation, u, self._params())

    def input_gradient(self, x: torch.Tensor) -> torch.Tensor:
        if self.periodic is None:
            return _backprop.input_gradient(self.activation, x, self._params())
        grad_u = _backprop.input_gradient(self.activation, self.periodic.embed(x), self._params())
        return self.periodic.pull(x, grad_u)


class FrozenMLP:
    """An inference-only MLP from numpy weights, in ``dtype`` (float64 for rollouts):
    same ``__call__`` and ``input_gradient`` as :class:`MLP`, from detached,
    pre-transposed weights with one ``addmm`` per layer and no autograd."""

    def __init__(
        self,
        weights: Sequence[np.ndarray],
        biases: Sequence[np.ndarray],
        activation: str,
        dtype: torch.dtype,
        device: torch.device,
        inputs: Optional[NetInput] = None,
    ) -> None:
        def tensor(a: np.ndarray) -> torch.Tensor:  # a copy, never a view of ``a``
            return torch.from_numpy(np.array(a, copy=True)).to(device=device, dtype=dtype)

        self.weights = [tensor(w) for w in weights]  # (out, in)
        self.weights_t = [w.t().contiguous() for w in self.weights]  # (in, out)
        self.biases = [tensor(b) for b in biases]
        self.activation = activation
        self.periodic = Periodic.of(inputs, device)

    @classmethod
    def from_weights(
        cls,
        weights: Mapping[str, np.ndarray],
        net: str,
        layers: int,
        activation: str,
        dtype: torch.dtype,
        device: torch.device,
        inputs: Optional[NetInput] = None,
    ) -> FrozenMLP:
        return cls(
            [weights[f"{net}.linears.{i}.weight"] for i in range(layers)],
            [weights[f"{net}.linears.{i}.bias"] for i in range(layers - 1)],
            activation,
            dtype,
            device,
            inputs,
        )

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        h = x if self.periodic is None else self.periodic.embed(x)
        for w_t, b in zip(self.weights_t[:-1], self.biases, strict=True):
            h = activate(self.activation, torch.addmm(b, h, w_t))
        return h @ self.weights_t[-1]

    def input_gradient(self, x: torch.Tensor) -> torch.Tensor:
        """As :meth:`MLP.input_gradient` ``(N, d_in)``; requires ``d_out == 1``."""
        pre, post = [], []
        h = x if self.periodic is None else self.periodic.embed(x)
        for w_t, b in zip(self.weights_t[:-1], self.biases, strict=True):
            a = torch.addmm(b, h, w_t)
            h = activate(self.activation, a)
            pre.append(a)
            post.append(h)
        g = self.weights[-1]  # (1, hidden), broadcast over the batch
        for i in range(len(self.weights) - 2, -1, -1):
            g = (g * activation_grad(self.activation, pre[i], post[i])) @ self.weights[i]
        return g if self.periodic is None else self.periodic.pull(x, g)

    def input_hessian(
        self, x: torch.Tensor, first_row: int = 0
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """As :meth:`MLP.input_hessian`."""
        return input_hessian(
            self.weights, self.biases, self.activation, x, first_row, self.periodic
        )


class Autoencoder:
    """The 2019 pixel autoencoder over parameter tensors: ``d -> h -> (2 residual h)
    -> latent`` and a mirrored decoder, ReLU (``"autoencoder.encoder.<i>.weight"``...)."""

    def __init__(self, params: Mapping[str, torch.Tensor]) -> None:
        def stack(half: str) -> list[tuple[torch.Tensor, torch.Tensor]]:
            return [
                (params[f"autoencoder.{half}.{i}.weight"], params[f"autoencoder.{half}.{i}.bias"])
                for i in range(AE_LAYERS)
            ]

        self.encoder, self.decoder = stack("encoder"), stack("decoder")

    @staticmethod
    def _run(layers: list[tuple[torch.Tensor, torch.Tensor]], x: torch.Tensor) -> torch.Tensor:
        h = torch.relu(F.linear(x, *layers[0]))
        for w, b in layers[1:-1]:
            h = h + torch.relu(F.linear(h, w, b))
        return F.linear(h, *layers[-1])

    def encode(self, x: torch.Tensor) -> torch.Tensor:
        return self._run(self.encoder, x)

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        return self._run(self.decoder, z)


def pixel_objective(
    field: Callable[[Any, torch.Tensor], torch.Tensor],
    nets: Any,
    ae: Autoencoder,
    x: torch.Tensor,
    x_next: torch.Tensor,
) -> torch.Tensor:
    """The 2019 pixel loss on pairs of consecutive inputs ``x -> x_next`` (scalar):
    reconstruction + canonical coordinates (``z_p`` tied to the frame-to-frame change
    of ``z_q``) + 0.1 x one Euler step (dt = 1) of the latent dynamics ``field``."""
    z, z_next = ae.encode(x), ae.encode(x_next)
    n = z.shape[1] // 2
    reconstruction = torch.mean((ae.decode(z) - x) ** 2)
    canonical = torch.mean((z[:, n:] - (z_next[:, :n] - z[:, :n])) ** 2)
    dynamics = torch.mean((z_next - (z + field(nets, z))) ** 2)
    return reconstruction + CC_WEIGHT * canonical + DYNAMICS_WEIGHT * dynamics


def pixel_objective_rows(
    field: Callable[[Any, torch.Tensor], torch.Tensor],
    nets: Any,
    ae: Autoencoder,
    x: torch.Tensor,
    x_next: torch.Tensor,
) -> torch.Tensor:
    """:func:`pixel_objective` of each pair, ``(N,)`` (each term's mean over its row):
    their mean is the objective, up to rounding."""
    z, z_next = ae.encode(x), ae.encode(x_next)
    n = z.shape[1] // 2
    reconstruction = torch.mean((ae.decode(z) - x) ** 2, dim=1)
    canonical = torch.mean((z[:, n:] - (z_next[:, :n] - z[:, :n])) ** 2, dim=1)
    dynamics = torch.mean((z_next - (z + field(nets, z))) ** 2, dim=1)
    return reconstruction + CC_WEIGHT * canonical + DYNAMICS_WEIGHT * dynamics
