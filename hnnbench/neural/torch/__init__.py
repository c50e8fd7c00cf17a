"""The torch backend of the neural models: eager training chunks, float64 inference
with the batched Dormand-Prince of :mod:`hnnbench.neural.torch._ode`.

Several seeds train as one batch through :func:`torch.func.vmap` over stacked
parameters: each seed's loss is its own mean, the total is their sum, so each seed's
gradient, and its Adam update (element-wise), is its own.

On a CPU, the backend's training chunks and inference flush subnormal floats to zero
(``torch.set_flush_denormal``), as XLA does for the JAX twin, and give the caller's
setting back when they return: the torch SRNN on three_body otherwise slows more than
tenfold once its products reach subnormal values (docs/BENCHMARK_HISTORY.md,
"Subnormal floats").
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping, Sequence
from types import ModuleType
from typing import Any, Optional, TypeVar

import numpy as np
import torch
import torch.nn.functional as F

from hnnbench._contracts.device import device_request, gpu_device
from hnnbench._contracts.errors import RolloutDiverged
from hnnbench._contracts.plugin import TrainSettings
from hnnbench.neural._backend import (
    Weights,
    map_plan,
    rollout_min_step,
)
from hnnbench.neural._config import NeuralConfig
from hnnbench.neural._embedding import Layout
from hnnbench.neural._family import Family
from hnnbench.neural._views import Problem
from hnnbench.neural.torch._nets import (
    MLP,
    Autoencoder,
    FrozenMLP,
    Periodic,
    TrainingMLP,
    input_hessian,
    pixel_objective,
    pixel_objective_rows,
    symplectic,
)
from hnnbench.neural.torch._ode import SolverGaveUp, dopri5

__all__ = [
    "MLP",
    "FusedAdam",
    "Periodic",
    "TorchBackend",
    "TrainingMLP",
    "input_hessian",
    "resolve_device",
    "symplectic",
]

Params = dict[str, torch.Tensor]


_F = TypeVar("_F", bound=Callable[..., Any])


def _keeps_subnormals() -> bool:
    """Whether this thread's float arithmetic keeps subnormal results (not flushed)."""
    return float(torch.tensor(1e-38, dtype=torch.float32) * 0.01) != 0.0


def _flushing_subnormals(method: _F) -> _F:
    """``method`` with subnormal floats flushed to zero while it runs, and the caller's
    setting restored after (``torch.set_flush_denormal``; a no-op where the CPU cannot)."""

    @functools.wraps(method)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        kept = _keeps_subnormals()
        torch.set_flush_denormal(True)
        try:
            return method(*args, **kwargs)
        finally:
            if kept:
                torch.set_flush_denormal(False)

    return wrapper  # type: ignore[return-value]


def resolve_device(requested: str) -> torch.device:
    """``auto`` -> the first GPU if torch sees one, else the CPU; ``cpu``; ``cuda[:N]``.
    A GPU always carries its index (``cuda:0``), so both backends name it alike."""
    kind, index = device_request(requested)
    count = torch.cuda.device_count() if kind != "cpu" and torch.cuda.is_available() else 0
    if kind == "cpu" or (kind == "auto" and count == 0):
        return torch.device("cpu")
    if kind == "cuda":
        gpu_device(requested, index, count, "torch", "TORCH_SPEC=torch make setup")
    return torch.device("cuda", index)


def networks(
    params: Mapping[str, Any], layout: Layout, cfg: NeuralConfig, build: Callable[..., Any]
) -> dict[str, Any]:
    """``{net: network}`` of a layout (``build(params, net, layers, activation,
    inputs)``)."""
    return {
        name: build(params, name, cfg.layers, cfg.activation, inputs)
        for name, inputs in layout.nets
    }


def make_loss(
    impl: ModuleType,
    kind: str,
    layout: Layout,
    cfg: NeuralConfig,
    options: tuple[tuple[str, Any], ...] = (),
) -> Callable[..., torch.Tensor]:
    """``loss(params, *arrays) -> scalar`` of one seed for a :class:`Problem` kind; its
    networks are :class:`TrainingMLP` s (hand-written backward passes)."""

    def nets_of(params: Params) -> dict[str, MLP]:
        return networks(params, layout, cfg, TrainingMLP.view)

    objective = F.l1_loss if cfg.loss == "l1" else F.mse_loss

    def derivatives(params: Params, z: torch.Tensor, zdot: torch.Tensor) -> torch.Tensor:
        # mse_loss: the same value and gradient as mean((f - zdot)²), one autograd node;
        # l1_loss: mean(|f - zdot|) (NeuralConfig.loss)
        return objective(impl.field(nets_of(params), z), zdot)

    def windows(params: Params, windows: torch.Tensor, dts: torch.Tensor) -> torch.Tensor:
        return impl.window_loss(nets_of(params), windows, dts, **dict(options))

    def pixels(params: Params, x: torch.Tensor, x_next: torch.Tensor) -> torch.Tensor:
        return pixel_objective(impl.field, nets_of(params), Autoencoder(params), x, x_next)

    return {"derivatives": derivatives, "windows": windows, "pixels": pixels}[kind]


def rk4_step(field: Callable[..., torch.Tensor]) -> Callable[..., torch.Tensor]:
    """The classical Runge-Kutta step ``(nets, z, h) -> z'`` of ``field`` (``h``
    broadcasts against ``z``: a ``(M, 1)`` column of step sizes)."""

    def step(nets: Any, z: torch.Tensor, h: torch.Tensor) -> torch.Tensor:
        k1 = field(nets, z)
        k2 = field(nets, z + 0.5 * h * k1)
        k3 = field(nets, z + 0.5 * h * k2)
        k4 = field(nets, z + h * k3)
        return z + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    return step


def make_criterion(
    impl: ModuleType,
    criterion: str,
    layout: Layout,
    cfg: NeuralConfig,
    options: tuple[tuple[str, Any], ...] = (),
) -> Callable[..., torch.Tensor]:
    """``values(params, *arrays) -> (V,)``: the validation criterion of one seed per point
    or window (:data:`hnnbench.neural._views.Criterion`; docs/METRICS.md, "Checkpoint
    selection"), as the JAX backend computes it."""

    def nets_of(params: Params) -> dict[str, MLP]:
        return networks(params, layout, cfg, TrainingMLP.view)

    def field(params: Params, *arrays: torch.Tensor) -> torch.Tensor:
        z, zdot = arrays[:2]
        error = impl.field(nets_of(params), z) - zdot
        if criterion == "field:weighted":  # to the system's dx/dt, point by point
            error = torch.einsum("vij,vj->vi", arrays[2], error)
        return torch.mean(error**2, dim=1)

    def windows(params: Params, windows: torch.Tensor, dts: torch.Tensor) -> torch.Tensor:
        nets = nets_of(params)
        substeps = int(dict(options).get("substeps", 1))
        step = impl.step if criterion == "windows:map" else rk4_step(impl.field)
        n = windows.shape[-1] // 2
        z, predicted = windows[:, 0], []
        for k in range(dts.shape[1]):
            h = (dts[:, k] / substeps)[:, None]
            for _ in range(substeps):
                z = step(nets, z, h)
            predicted.append(z)
        error = torch.stack(predicted, dim=1)[..., :n] - windows[:, 1:, :n]
        return torch.mean(error**2, dim=(1, 2))

    def pixels(params: Params, x: torch.Tensor, x_next: torch.Tensor) -> torch.Tensor:
        return pixel_objective_rows(impl.field, nets_of(params), Autoencoder(params), x, x_next)

    return (
        pixels if criterion == "pixels" else (windows if criterion.startswith("windows") else field)
    )


class FusedAdam:
    """``torch.optim.Adam(params, lr, weight_decay=weight_decay, fused=True)``, called
    directly: the same fused kernel (one per parameter tensor for the whole update) and
    so the same updates to the last bit, without the optimizer's per-step Python (its
    hooks, grouping of tensors by device and dtype, and the gradients kept on the
    parameters and zeroed): 0.1-0.4 ms of each step on the spring and two-body shapes,
    up to a sixth of a two-body MLP step (``benchmarks/torch_step_options.py``). A
    parameter the loss does not reach gets no update and its step count stays, as
    there."""

    def __init__(self, params: list[torch.Tensor], lr: float, weight_decay: float) -> None:
        self.params = params
        self.lr, self.weight_decay = float(lr), float(weight_decay)
        with torch.no_grad():
            self.exp_avg = [
                torch.zeros_like(p, memory_format=torch.preserve_format) for p in params
            ]
            self.exp_avg_sq = [
                torch.zeros_like(p, memory_format=torch.preserve_format) for p in params
            ]
        # torch.optim.Adam's fused state: a float32 step count per parameter, on its device
        self.steps = [torch.zeros((), dtype=torch.float32, device=p.device) for p in params]

    def step(self, loss: torch.Tensor) -> None:
        """One update from the gradients of the scalar ``loss``."""
        grads = torch.autograd.grad(loss, self.params, allow_unused=True)
        live = [i for i, g in enumerate(grads) if g is not None]
        if not live:
            return

        def pick(items: Sequence[Any]) -> list[Any]:
            return list(items) if len(live) == len(items) else [items[i] for i in live]

        steps = pick(self.steps)
        with torch.no_grad():
            torch._foreach_add_(steps, 1)
            torch._fused_adam_(
                pick(self.params),
                pick(list(grads)),
                pick(self.exp_avg),
                pick(self.exp_avg_sq),
                [],
                steps,
                lr=self.lr,
                beta1=0.9,
                beta2=0.999,
                weight_decay=self.weight_decay,
                eps=1e-8,
                amsgrad=False,
                maximize=False,
            )


class TorchTrainer:
    """The parameters and Adam state of ``S`` seeds (stacked when ``S > 1``)."""

    def __init__(
        self,
        backend: TorchBackend,
        family: Family,
        impl: ModuleType,
        problem: Problem,
        initial: Sequence[Weights],
        settings: TrainSettings,
        layout: Layout,
    ) -> None:
        dev, dtype = backend.device, backend.dtype
        self.seeds = len(initial)
        self.loss = make_loss(impl, problem.kind, layout, backend.cfg, problem.options)
        self.criterion = make_criterion(
            impl, problem.criterion, layout, backend.cfg, problem.criterion_options
        )

        def tensor(a: np.ndarray) -> torch.Tensor:
            return torch.as_tensor(np.ascontiguousarray(a), device=dev).to(dtype)

        if self.seeds == 1:
            self.params = {k: tensor(v).clone().requires_grad_() for k, v in initial[0].items()}
        else:
            self.params = {
                k: tensor(np.stack([w[k] for w in initial])).requires_grad_() for k in initial[0]
            }
        self.stacked = problem.stacked
        self.train = tuple(tensor(a) for a in problem.train)
        self.valid = tuple(tensor(a) for a in problem.valid)
        self.adam = FusedAdam(list(self.params.values()), settings.lr, settings.weight_decay)
        self.device = dev
        self.kept: Optional[Params] = None  # the selected checkpoint (Trainer.keep)

    def _losses(
        self,
        arrays: tuple[torch.Tensor, ...],
        per_seed_rows: bool,
        fn: Optional[Callable[..., torch.Tensor]] = None,
    ) -> torch.Tensor:
        """Each seed's loss ``(S,)`` (a scalar when ``S == 1``), or of ``fn`` (the
        criterion: ``(S, V)``, or ``(V,)`` for one seed)."""
        fn = self.loss if fn is None else fn
        if self.seeds == 1:
            return fn(self.params, *arrays)
        dims = (0, *([0 if per_seed_rows else None] * len(arrays)))
        return torch.func.vmap(fn, in_dims=dims)(self.params, *arrays)

    def _rows(self, indices: np.ndarray) -> tuple[torch.Tensor, ...]:
        """The minibatch of one step: ``indices`` ``(S, B)`` into each seed's data."""
        idx = torch.from_numpy(indices).to(self.device)
        if self.seeds == 1:
            return tuple(a[idx[0]] for a in self.train)
        if self.stacked:  # each seed's rows of its own data: (S, B, ...)
            seed = torch.arange(self.seeds, device=self.device)[:, None]
            return tuple(a[seed, idx] for a in self.train)
        return tuple(a[idx] for a in self.train)  # shared data, per-seed rows

    @_flushing_subnormals
    def run_chunk(
        self, indices: Optional[np.ndarray], length: int, lrs: Optional[np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray]:
        losses = []
        for j in range(length):
            if lrs is not None:
                self.adam.lr = float(lrs[j])
            if indices is None:
                batch, per_seed = self.train, self.stacked
            else:
                batch, per_seed = self._rows(indices[:, j]), self.seeds > 1
            loss = self._losses(batch, per_seed)
            self.adam.step(loss if self.seeds == 1 else loss.sum())
            losses.append(loss.detach())
        with torch.no_grad():
            valid = self._losses(self.valid, self.stacked, self.criterion)
        out = torch.stack(losses).reshape(length, self.seeds).T
        return out.cpu().numpy(), valid.reshape(self.seeds, -1).cpu().numpy()

    def keep(self, seeds: np.ndarray) -> None:
        with torch.no_grad():
            if self.kept is None or self.seeds == 1:
                # (a batch's first keep copies every seed: one not chosen now has no
                # checkpoint yet, and gets its own at its first improvement)
                self.kept = {k: v.detach().clone() for k, v in self.params.items()}
                return
            mask = torch.as_tensor(np.asarray(seeds, dtype=bool), device=self.device)
            for k, v in self.params.items():
                self.kept[k][mask] = v.detach()[mask]

    def weights(self) -> list[Weights]:
        """Each seed's kept checkpoint (:meth:`keep`), else its current weights."""
        source = self.kept if self.kept is not None else self.params
        arrays = {k: v.detach().cpu().numpy().copy() for k, v in source.items()}
        if self.seeds == 1:
            return [arrays]
        return [{k: v[s].copy() for k, v in arrays.items()} for s in range(self.seeds)]


class TorchInference:
    """One seed's float64 field, energy and rollouts, and its pixel autoencoder in the
    training dtype."""

    def __init__(
        self,
        backend: TorchBackend,
        family: Family,
        impl: ModuleType,
        weights: Weights,
        layout: Layout,
    ) -> None:
        self.backend, self.impl = backend, impl
        cfg, dev = backend.cfg, backend.device
        self.nets64 = networks(
            weights,
            layout,
            cfg,
            lambda w, name, layers, act, inputs: FrozenMLP.from_weights(
                w, name, layers, act, torch.float64, dev, inputs
            ),
        )
        self.pixels = "autoencoder.encoder.0.weight" in weights
        if self.pixels:  # training-dtype autoencoder and dynamics, for the objective
            params = {
                k: torch.as_tensor(v, device=dev).to(backend.dtype) for k, v in weights.items()
            }
            self.ae = Autoencoder(params)
            self.nets = networks(params, layout, cfg, MLP.view)

    def _tensor(self, a: np.ndarray, dtype: torch.dtype) -> torch.Tensor:
        return torch.as_tensor(np.ascontiguousarray(a), device=self.backend.device).to(dtype)

    @_flushing_subnormals
    def field(self, z: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            out = self.impl.field(self.nets64, self._tensor(z, torch.float64))
        return out.cpu().numpy()

    @_flushing_subnormals
    def energy(self, z: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            out = self.impl.energy(self.nets64, self._tensor(z, torch.float64))
        return out.cpu().numpy()

    @_flushing_subnormals
    def rollout(
        self, z0: np.ndarray, t: np.ndarray, rtol: float, atol: float, max_steps: int
    ) -> np.ndarray:
        y0 = self._tensor(z0, torch.float64)
        try:
            with torch.no_grad():  # the fields need no autograd (closed-form gradients)
                ys = dopri5(
                    lambda y: self.impl.field(self.nets64, y),
                    y0,
                    np.asarray(t),
                    rtol=rtol,
                    atol=atol,
                    max_steps=max_steps,
                    min_step=rollout_min_step(t),
                )
        except SolverGaveUp as err:
            raise RolloutDiverged(f"dopri5 gave up: {err}") from None
        except torch.linalg.LinAlgError as err:  # e.g. a model's own singular solve
            raise RolloutDiverged(f"linear algebra failed: {err}".splitlines()[0]) from None
        return ys.permute(1, 0, 2).cpu().numpy()

    @_flushing_subnormals
    def map_rollout(self, z0: np.ndarray, t: np.ndarray, step: float) -> np.ndarray:
        steps, sizes = map_plan(t, step)
        z = self._tensor(z0, torch.float64)
        out = [z]
        with torch.no_grad():
            for m, h in zip(steps.tolist(), sizes.tolist(), strict=True):
                for _ in range(m):
                    z = self.impl.step(self.nets64, z, h)
                out.append(z)
        return torch.stack(out, dim=1).cpu().numpy()

    @_flushing_subnormals
    def encode(self, x: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return self.ae.encode(self._tensor(x, self.backend.dtype)).cpu().numpy()

    @_flushing_subnormals
    def decode(self, z: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return self.ae.decode(self._tensor(z, self.backend.dtype)).cpu().numpy()

    @_flushing_subnormals
    def objective(self, x: np.ndarray, x_next: np.ndarray) -> float:
        dtype = self.backend.dtype
        with torch.no_grad():
            return float(
                pixel_objective(
                    self.impl.field,
                    self.nets,
                    self.ae,
                    self._tensor(x, dtype),
                    self._tensor(x_next, dtype),
                )
            )


class TorchBackend:
    """The torch backend for one model: device, training dtype, timings."""

    name = "torch"

    def __init__(self, cfg: NeuralConfig, device: str) -> None:
        self.cfg = cfg
        self.device = resolve_device(device)
        self.dtype: torch.dtype = getattr(torch, cfg.dtype)
        self.device_name = str(self.device)
        self.timings: dict[str, float] = {}

    def trainer(
        self,
        family: Family,
        impl: ModuleType,
        problem: Problem,
        initial: Sequence[Weights],
        settings: TrainSettings,
        layout: Layout,
    ) -> TorchTrainer:
        return TorchTrainer(self, family, impl, problem, initial, settings, layout)

    def weights(self, trainer: Any) -> list[Weights]:
        return trainer.weights()

    def inference(
        self, family: Family, impl: ModuleType, weights: Weights, layout: Layout
    ) -> TorchInference:
        return TorchInference(self, family, impl, weights, layout)
