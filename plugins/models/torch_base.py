"""Shared machinery of the PyTorch models: device, training loop, float64 rollouts."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from hnnbench.api import Dataset, FitResult, Model, Progress, System, TrainSettings
from hnnbench.errors import ConfigError, RolloutDiverged, require_backend
from hnnbench_plugins.models.neural import BatchStream, NeuralConfig, init_arrays

require_backend("torch", "torch")

import torch  # noqa: E402
from torch import nn  # noqa: E402

from hnnbench_plugins.models.torch_ode import SolverGaveUp, dopri5  # noqa: E402


def resolve_device(requested: str) -> torch.device:
    """``auto`` -> the GPU if one is there, else the CPU."""
    if requested == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if requested.startswith("cuda") and not torch.cuda.is_available():
        raise ConfigError(
            f"device={requested} was requested but torch sees no CUDA GPU: use device=cpu "
            "or device=auto."
        )
    return torch.device(requested)


def activate(name: str, a: torch.Tensor) -> torch.Tensor:
    """The activation ``name`` (``tanh``, ``sigmoid`` or ``softplus``) at ``a``."""
    if name == "tanh":
        return torch.tanh(a)
    if name == "sigmoid":
        return torch.sigmoid(a)
    return nn.functional.softplus(a)


def activation_grad(name: str, a: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
    """Derivative of the activation ``name`` at pre-activation ``a`` (``h`` its value)."""
    if name == "tanh":
        return 1.0 - h * h
    if name == "sigmoid":
        return h * (1.0 - h)
    return torch.sigmoid(a)


class MLP(nn.Module):
    """``layers`` linear layers with an activation between them; the last has no bias.

    Built with torch's default init; :meth:`TorchModel.build` then loads the seeded
    orthogonal weights of :func:`~hnnbench_plugins.models.neural.init_arrays` (the same
    as the JAX twin's).
    """

    def __init__(self, d_in: int, d_out: int, cfg: NeuralConfig) -> None:
        super().__init__()
        dims = [d_in] + [cfg.hidden] * (cfg.layers - 1) + [d_out]
        self.linears = nn.ModuleList(
            nn.Linear(a, b, bias=i < cfg.layers - 1)
            for i, (a, b) in enumerate(zip(dims[:-1], dims[1:], strict=True))
        )
        self.activation = cfg.activation

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = x
        for layer in self.linears[:-1]:
            h = activate(self.activation, layer(h))
        return self.linears[-1](h)

    def input_gradient(self, x: torch.Tensor) -> torch.Tensor:
        """Gradient of the scalar output with respect to ``x`` ``(N, d_in)``.

        Computed in closed form (a reverse sweep through the layers), so training on it
        needs one backward pass instead of a double backward through autograd.
        Requires ``d_out == 1``.
        """
        pre, post = [], []
        h = x
        for layer in self.linears[:-1]:
            a = layer(h)
            h = activate(self.activation, a)
            pre.append(a)
            post.append(h)
        g = self.linears[-1].weight.expand(x.shape[0], -1)  # (N, hidden)
        for i in range(len(self.linears) - 2, -1, -1):
            g = (g * activation_grad(self.activation, pre[i], post[i])) @ self.linears[i].weight
        return g


class FrozenMLP:
    """An inference-only copy of an :class:`MLP` in another dtype, for rollouts.

    Same ``__call__`` and ``input_gradient`` as the module, computed from detached,
    pre-transposed weights with one ``addmm`` per layer and no module dispatch: an ODE
    solve calls the network thousands of times on a handful of states, where the
    per-call overhead, not the arithmetic, decides the cost.
    """

    def __init__(self, net: MLP, dtype: torch.dtype) -> None:
        with torch.no_grad():  # copies, also where the dtype is already the same
            weights = [layer.weight.detach().to(dtype).clone() for layer in net.linears]
            self.weights = weights  # (out, in)
            self.weights_t = [w.t().contiguous() for w in weights]  # (in, out)
            self.biases = [layer.bias.detach().to(dtype).clone() for layer in net.linears[:-1]]
        self.activation = net.activation

    def __call__(self, x: torch.Tensor) -> torch.Tensor:
        h = x
        for w_t, b in zip(self.weights_t[:-1], self.biases, strict=True):
            h = activate(self.activation, torch.addmm(b, h, w_t))
        return h @ self.weights_t[-1]

    def input_gradient(self, x: torch.Tensor) -> torch.Tensor:
        """As :meth:`MLP.input_gradient` ``(N, d_in)``; requires ``d_out == 1``."""
        pre, post = [], []
        h = x
        for w_t, b in zip(self.weights_t[:-1], self.biases, strict=True):
            a = torch.addmm(b, h, w_t)
            h = activate(self.activation, a)
            pre.append(a)
            post.append(h)
        g = self.weights[-1]  # (1, hidden), broadcast over the batch
        for i in range(len(self.weights) - 2, -1, -1):
            g = (g * activation_grad(self.activation, pre[i], post[i])) @ self.weights[i]
        return g


#: What :meth:`TorchModel.field` receives: the training module or a frozen copy.
Network = MLP | FrozenMLP


class TorchModel(Model):
    """Base of the PyTorch models: subclasses define ``output_dim`` and ``field``."""

    Config = NeuralConfig
    cfg: NeuralConfig
    backend = "torch"
    output_scalar: ClassVar[bool] = False

    def __init__(self, cfg: NeuralConfig, system: System, device: str = "auto") -> None:
        super().__init__(cfg, system, device)
        self._device = resolve_device(device)
        self._dtype = getattr(torch, cfg.dtype)
        self.net: MLP | None = None
        self._net64: FrozenMLP | None = None

    @property
    def device(self) -> str:
        return str(self._device)

    # -- to implement ---------------------------------------------------------------
    def field(self, net: Network, x: torch.Tensor) -> torch.Tensor:
        """``dx/dt`` ``(N, D)`` from the network (differentiable when ``net`` is the
        training :class:`MLP`)."""
        raise NotImplementedError

    # -- network ----------------------------------------------------------------------
    def build(self, d_in: int, seed: int) -> MLP:
        """The seeded initial network (:func:`~hnnbench_plugins.models.neural.init_arrays`,
        shared with the JAX twin) in the training dtype, on the model's device."""
        d_out = 1 if self.output_scalar else d_in
        net = MLP(d_in, d_out, self.cfg).to(device=self._device, dtype=self._dtype)
        arrays = init_arrays(seed, d_in, d_out, self.cfg)
        net.load_state_dict({k: torch.from_numpy(v) for k, v in arrays.items()})  # casts
        return net

    def _require_net(self) -> MLP:
        if self.net is None:
            raise RuntimeError(f"{self.name}: call fit() or load() first")
        return self.net

    def _float64_net(self) -> FrozenMLP:
        """The trained network, frozen in float64 (cached until the next fit/load)."""
        if self._net64 is None:
            self._net64 = FrozenMLP(self._require_net(), torch.float64)
        return self._net64

    def _tensor(self, x: np.ndarray, dtype: Any | None = None) -> torch.Tensor:
        arr = np.ascontiguousarray(x)
        return torch.as_tensor(arr, dtype=dtype or self._dtype, device=self._device)

    # -- training ---------------------------------------------------------------------
    def fit(
        self, data: Dataset, train: TrainSettings, seed: int, progress: Progress
    ) -> FitResult:
        x, dxdt = self._tensor(data.train.x), self._tensor(data.train.dxdt)
        x_test, dxdt_test = self._tensor(data.test.x), self._tensor(data.test.dxdt)
        net = self.net = self.build(x.shape[1], seed)
        self._net64 = None
        opt = torch.optim.Adam(net.parameters(), lr=train.lr, weight_decay=train.weight_decay)
        n = x.shape[0]
        full = train.batch_size is None or train.batch_size >= n
        stream = None if full else BatchStream(seed, n, int(train.batch_size))
        every = self.cfg.log_interval(train.steps)
        history: dict[str, list[float]] = {"step": [], "train_loss": [], "test_loss": []}
        for step in range(1, train.steps + 1):
            if stream is None:
                xb, yb = x, dxdt
            else:
                idx = torch.from_numpy(stream.next()).to(self._device)
                xb, yb = x[idx], dxdt[idx]
            loss = torch.mean((self.field(net, xb) - yb) ** 2)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            if step % every == 0 or step == train.steps:
                train_loss = float(loss.detach())
                test_loss = float(torch.mean((self.field(net, x_test) - dxdt_test) ** 2).detach())
                history["step"].append(step)
                history["train_loss"].append(train_loss)
                history["test_loss"].append(test_loss)
                progress(step, {"train_loss": train_loss, "test_loss": test_loss})
                if not (np.isfinite(train_loss) and np.isfinite(test_loss)):
                    raise RolloutDiverged(
                        f"loss became non-finite at step {step} "
                        f"(train {train_loss:.3g}, test {test_loss:.3g})"
                    )
        return FitResult(history=history, steps=train.steps)

    # -- inference --------------------------------------------------------------------
    def time_derivative(self, x: np.ndarray) -> np.ndarray:
        net = self._float64_net()
        xt = self._tensor(x, torch.float64)
        with torch.no_grad():
            out = self.field(net, xt)
        return out.cpu().numpy()

    def rollout(
        self, x0: np.ndarray, t: np.ndarray, rtol: float = 1e-9, atol: float = 1e-9
    ) -> np.ndarray:
        net = self._float64_net()
        y0 = self._tensor(x0, torch.float64)
        start = time.perf_counter()
        try:
            with torch.no_grad():  # the fields need no autograd (closed-form gradients)
                ys = dopri5(lambda y: self.field(net, y), y0, np.asarray(t),
                            rtol=rtol, atol=atol, max_steps=self.cfg.rollout_max_steps)
        except SolverGaveUp as err:
            raise RolloutDiverged(f"dopri5 gave up: {err}") from None
        self.timings["rollout_s"] = self.timings.get("rollout_s", 0.0) + (
            time.perf_counter() - start
        )
        out = ys.permute(1, 0, 2).cpu().numpy()
        if not np.all(np.isfinite(out)):
            raise RolloutDiverged("rollout produced non-finite states")
        return out

    # -- persistence ------------------------------------------------------------------
    def save(self, path: Path) -> None:
        from safetensors.torch import save_file

        net = self._require_net()
        save_file({k: v.detach().cpu().contiguous() for k, v in net.state_dict().items()},
                  str(path))

    def load(self, path: Path) -> None:
        from safetensors.torch import load_file

        state = load_file(str(path))
        d_in = state["linears.0.weight"].shape[1]
        net = self.build(d_in, seed=0)
        net.load_state_dict(state)
        self.net, self._net64 = net, None
