"""The JAX backend of the neural models: equinox networks, optax's Adam made equal to
torch's, compiled training chunks, diffrax rollouts.

- Training is jit-compiled and stays on the device: one compiled call runs a chunk of
  optimizer steps with :func:`jax.lax.scan` and returns each step's loss and the validation
  loss after the chunk, so the host only wakes up to log. Compilation is timed apart
  (``timings["compile_s"]``) and cached per process, so later fits of the same shapes
  (other seeds, learning rates) compile nothing. Several seeds train as one batch by
  ``jax.vmap`` over the parameter and optimizer pytrees and the minibatch indices.
- Rollouts use diffrax (Dopri5, PID step-size control) in float64. The batch of
  initial states is integrated as one system (one step-size sequence, error norm over
  the whole batch), as the torch backend does. A solve that stops early raises
  :class:`~hnnbench._contracts.errors.RolloutDiverged`; nothing is silently truncated.

Importing this module enables 64-bit floats in JAX (``jax_enable_x64``), which float64
rollouts need; training runs in ``cfg.dtype`` (parameters and data cast explicitly).
It also turns on JAX's persistent compilation cache in ``<cache root>/jax-compilation``
(:func:`hnnbench._contracts.paths.cache_root`, which a job's ``cache_dir`` moves), unless
``JAX_COMPILATION_CACHE_DIR`` names
another place or ``JAX_ENABLE_COMPILATION_CACHE=false`` turns it off. For the rollout
to be cacheable it must hold no host callbacks, so equinox's in-graph error checks
answer with NaN (``EQX_ON_ERROR=nan``, unless set otherwise) instead of calling back to
raise; a NaN rollout is recorded as diverged, like a solver failure.

On a GPU, XLA's kernel autotuning is off (``--xla_gpu_autotune_level=0`` is added to
``XLA_FLAGS`` at import unless they name that flag already): it times candidate kernels
for every product while compiling, which for these small networks cost more than it
saved (a two-body ``mlp_jax`` job on an H100: compilation 35.5 s with it, 5.1 s without;
docs/SCALING.md, "GPUs"). The CPU backend ignores the flag.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable, Sequence
from types import ModuleType
from typing import Any, Optional

import numpy as np

os.environ.setdefault("EQX_ON_ERROR", "nan")  # read when equinox is imported


def _gpu_autotuning_off() -> None:
    """Add ``--xla_gpu_autotune_level=0`` to ``XLA_FLAGS`` unless the variable names
    that flag already (the module docstring says why). This sets the variable for the
    whole process; JAX reads it when it starts its GPU backend, so it has no effect where
    that happened before this module was imported (a level given through a
    ``--flagfile`` is not seen, and the flag is added after it)."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_gpu_autotune_level" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} --xla_gpu_autotune_level=0".strip()


_gpu_autotuning_off()

import diffrax  # noqa: E402
import equinox as eqx  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import optax  # noqa: E402

from hnnbench._contracts import paths  # noqa: E402
from hnnbench._contracts.device import device_request, gpu_device  # noqa: E402
from hnnbench._contracts.errors import RolloutDiverged  # noqa: E402
from hnnbench._contracts.plugin import TrainSettings  # noqa: E402
from hnnbench.neural._backend import (  # noqa: E402
    Weights,
    map_plan,
    rollout_min_step,
    stall_text,
)
from hnnbench.neural._config import NeuralConfig  # noqa: E402
from hnnbench.neural._embedding import Layout  # noqa: E402
from hnnbench.neural._family import Family  # noqa: E402
from hnnbench.neural._views import Problem  # noqa: E402
from hnnbench.neural.jax._nets import (  # noqa: E402
    Nets,
    nets_from_weights,
    nets_to_weights,
    pixel_objective,
    pixel_objective_rows,
    symplectic,
)

__all__ = ["JaxBackend", "Nets", "adam_like_torch", "device_name", "resolve_device", "symplectic"]

jax.config.update("jax_enable_x64", True)

#: The compilation-cache folder this module chose (anything else is the user's own).
_cache_chosen: Optional[str] = None


def use_compilation_cache() -> None:
    """Point JAX's persistent compilation cache at ``<cache root>/jax-compilation``
    (:func:`hnnbench._contracts.paths.jax_compilation_cache_dir`, which follows a job's
    ``cache_dir``), unless the user chose another folder (``JAX_COMPILATION_CACHE_DIR``
    or ``jax.config``). Called at import and whenever a JAX model is built."""
    global _cache_chosen
    current = getattr(jax.config, "jax_compilation_cache_dir", None)
    if current and current != _cache_chosen:
        return
    target = str(paths.jax_compilation_cache_dir())
    if current == target:
        return
    jax.config.update("jax_compilation_cache_dir", target)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)
    if current:  # JAX opens its cache once; it would keep writing to the old folder
        from jax.experimental.compilation_cache import compilation_cache

        compilation_cache.reset_cache()
    _cache_chosen = target


use_compilation_cache()
# Probing for absent accelerators (TPU, GPU) logs an INFO line per backend, which the
# CLI's INFO-level logging would print on every run.
logging.getLogger("jax._src.xla_bridge").setLevel(logging.WARNING)

Field = Callable[[Nets, jax.Array], jax.Array]


# --------------------------------------------------------------------------- device


def _gpus() -> list[Any]:
    try:
        return list(jax.devices("gpu"))
    except RuntimeError:  # no GPU backend
        return []


def resolve_device(requested: str) -> Any:
    """``auto`` -> the first GPU if JAX sees one, else the CPU; ``cpu``; ``cuda[:N]``."""
    kind, index = device_request(requested)
    if kind == "cpu":
        return jax.devices("cpu")[0]
    gpus = _gpus()
    if kind == "auto":
        return gpus[0] if gpus else jax.devices("cpu")[0]
    gpu_device(requested, index, len(gpus), "jax", "pip install 'jax[cuda12]'")
    return gpus[index]


def device_name(device: Any) -> str:
    """Torch-style name of a JAX device: ``cpu`` or ``cuda:N``."""
    return "cpu" if device.platform == "cpu" else f"cuda:{device.id}"


# --------------------------------------------------------------------------- training


def adam_like_torch(lr: Any, weight_decay: Any) -> optax.GradientTransformation:
    """``torch.optim.Adam(lr, weight_decay=wd)`` in optax.

    torch adds ``wd * param`` to the gradient *before* the moment estimates (coupled L2,
    not AdamW's decoupled decay), and puts ``eps = 1e-8`` outside the square root of the
    bias-corrected second moment, as ``optax.adam`` does.
    """
    return optax.chain(adam_direction(weight_decay), optax.scale(-lr))


def adam_direction(weight_decay: Any) -> optax.GradientTransformation:
    """:func:`adam_like_torch` without its learning rate: the update direction, which
    the training chunk scales by each step's rate (``-lr_k · direction``: the same
    arithmetic as ``optax.adam``'s ``scale(-lr)``)."""
    return optax.chain(
        optax.add_decayed_weights(weight_decay),
        optax.scale_by_adam(b1=0.9, b2=0.999, eps=1e-8, eps_root=0.0),
    )


def _loss(
    kind: str,
    impl: ModuleType,
    options: tuple[tuple[str, Any], ...],
    static: Any,
    params: Any,
    *arrays: jax.Array,
) -> jax.Array:
    """One seed's loss on a batch of a :class:`~hnnbench.neural._views.Problem`
    (``kind`` is the problem's, with ``:l1`` appended for the mean absolute error of a
    derivatives problem, ``NeuralConfig.loss``)."""
    nets = eqx.combine(params, static)
    if kind.startswith("derivatives"):
        z, zdot = arrays
        error = impl.field(nets, z) - zdot
        return jnp.mean(jnp.abs(error)) if kind.endswith(":l1") else jnp.mean(error**2)
    if kind == "windows":
        return impl.window_loss(nets, *arrays, **dict(options))
    return pixel_objective(impl.field, nets, *arrays)


def rk4_step(field: Callable[..., jax.Array]) -> Callable[..., jax.Array]:
    """The classical Runge-Kutta step ``(nets, z, h) -> z'`` of ``field`` (``h``
    broadcasts against ``z``: a ``(M, 1)`` column of step sizes)."""

    def step(nets: Any, z: jax.Array, h: jax.Array) -> jax.Array:
        k1 = field(nets, z)
        k2 = field(nets, z + 0.5 * h * k1)
        k3 = field(nets, z + 0.5 * h * k2)
        k4 = field(nets, z + h * k3)
        return z + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)

    return step


def criterion_values(
    criterion: str,
    impl: ModuleType,
    options: tuple[tuple[str, Any], ...],
    nets: Any,
    *arrays: jax.Array,
) -> jax.Array:
    """The validation criterion of one seed per point or window, ``(V,)``
    (:data:`hnnbench.neural._views.Criterion`; docs/METRICS.md, "Checkpoint
    selection")."""
    if criterion.startswith("field"):
        z, zdot = arrays[:2]
        error = impl.field(nets, z) - zdot
        if criterion == "field:weighted":  # to the system's dx/dt, point by point
            error = jnp.einsum("vij,vj->vi", arrays[2], error)
        return jnp.mean(error**2, axis=1)
    if criterion.startswith("windows"):
        windows, dts = arrays
        substeps = int(dict(options).get("substeps", 1))
        step = impl.step if criterion == "windows:map" else rk4_step(impl.field)
        n = windows.shape[-1] // 2

        def interval(z: jax.Array, dt: jax.Array) -> tuple[jax.Array, jax.Array]:
            h = (dt / substeps)[:, None]
            for _ in range(substeps):
                z = step(nets, z, h)
            return z, z

        _, predicted = jax.lax.scan(interval, windows[:, 0], jnp.swapaxes(dts, 0, 1))
        error = jnp.swapaxes(predicted, 0, 1)[..., :n] - windows[:, 1:, :n]
        return jnp.mean(error**2, axis=(1, 2))
    return pixel_objective_rows(impl.field, nets, *arrays)


def scan_steps(
    loss_fn: Callable[..., jax.Array],
    optimizer: Any,
    params: Any,
    opt_state: Any,
    idx: Optional[jax.Array],
    arrays: tuple[jax.Array, ...],
    lrs: jax.Array,
    length: int,
) -> tuple[Any, Any, jax.Array]:
    """``length`` optimizer steps of ``loss_fn(params, *batch)`` under ``lax.scan``;
    ``idx`` is ``(length, batch)`` row indices or ``None`` (full batch), ``lrs`` the
    ``(length,)`` learning rates, ``optimizer`` the update direction
    (:func:`adam_direction`). Returns the new params, optimizer state and the
    ``(length,)`` losses, each taken before its update."""

    def step(carry: tuple[Any, Any], xs: tuple[Optional[jax.Array], jax.Array]) -> Any:
        params, opt_state = carry
        batch_idx, lr = xs
        batch = arrays if batch_idx is None else tuple(a[batch_idx] for a in arrays)
        loss, grads = jax.value_and_grad(loss_fn)(params, *batch)
        direction, opt_state = optimizer.update(grads, opt_state, params)
        updates = jax.tree.map(lambda u: (-lr).astype(u.dtype) * u, direction)
        return (optax.apply_updates(params, updates), opt_state), loss

    (params, opt_state), losses = jax.lax.scan(step, (params, opt_state), (idx, lrs), length=length)
    return params, opt_state, losses


def _chunk(
    kind: str,
    impl: ModuleType,
    options: tuple[tuple[str, Any], ...],
    static: Any,
    criterion: tuple[str, tuple[tuple[str, Any], ...]],
    length: int,
    params: Any,
    opt_state: Any,
    idx: Optional[jax.Array],
    train: tuple[jax.Array, ...],
    valid: tuple[jax.Array, ...],
    lrs: jax.Array,
    weight_decay: jax.Array,
) -> tuple[Any, Any, jax.Array, jax.Array]:
    """One chunk of ``length`` steps at the ``(length,)`` learning rates ``lrs``, then
    the validation criterion per point (:func:`criterion_values`; ``criterion`` is its
    kind and options). ``lrs`` and ``weight_decay`` are traced, so one executable
    serves every learning rate and schedule."""
    optimizer = adam_direction(weight_decay)

    def loss_fn(p: Any, *batch: jax.Array) -> jax.Array:
        return _loss(kind, impl, options, static, p, *batch)

    params, opt_state, losses = scan_steps(
        loss_fn, optimizer, params, opt_state, idx, train, lrs, length
    )
    values = criterion_values(criterion[0], impl, criterion[1], eqx.combine(params, static), *valid)
    return params, opt_state, losses, values


def _batched_chunk(
    kind: str,
    impl: ModuleType,
    options: tuple[tuple[str, Any], ...],
    static: Any,
    criterion: tuple[str, tuple[tuple[str, Any], ...]],
    length: int,
    stacked: bool,
    params: Any,
    opt_state: Any,
    idx: Optional[jax.Array],
    train: tuple[jax.Array, ...],
    valid: tuple[jax.Array, ...],
    lrs: jax.Array,
    weight_decay: jax.Array,
) -> tuple[Any, Any, jax.Array, jax.Array]:
    """:func:`_chunk` for stacked seeds: ``vmap`` over params, optimizer state, indices
    and, when ``stacked``, each seed's own data (hyperparameters shared)."""

    def one(p: Any, o: Any, i: Optional[jax.Array], tr: Any, te: Any) -> Any:
        return _chunk(
            kind, impl, options, static, criterion, length, p, o, i, tr, te, lrs, weight_decay
        )

    data = 0 if stacked else None
    return jax.vmap(one, in_axes=(0, 0, None if idx is None else 0, data, data))(
        params, opt_state, idx, train, valid
    )


_CHUNKS = {
    False: jax.jit(_chunk, static_argnums=(0, 1, 2, 3, 4, 5)),
    True: jax.jit(_batched_chunk, static_argnums=(0, 1, 2, 3, 4, 5, 6)),
}
#: Compiled chunks of this process, keyed by loss, layout, length, argument shapes and
#: device: a sweep reuses them across seeds.
_COMPILED: dict[Any, Any] = {}
_COMPILED_MAX = 32


def _compiled(batched: bool, statics: tuple[Any, ...], args: tuple[Any, ...]) -> tuple[Any, float]:
    """The executable for one chunk and the seconds spent compiling it (0.0 if cached)."""
    leaves, treedef = jax.tree_util.tree_flatten(args)
    avals = tuple((leaf.shape, str(leaf.dtype), str(leaf.sharding)) for leaf in leaves)
    key = (batched, statics, treedef, avals)
    if key in _COMPILED:
        return _COMPILED[key], 0.0
    start = time.perf_counter()
    with jax.default_matmul_precision("highest"):  # no TF32 on GPUs: as torch by default
        compiled = _CHUNKS[batched].lower(*statics, *args).compile()
    seconds = time.perf_counter() - start
    if len(_COMPILED) >= _COMPILED_MAX:
        _COMPILED.pop(next(iter(_COMPILED)))
    _COMPILED[key] = compiled
    return compiled, seconds


def _stack(trees: Sequence[Any]) -> Any:
    return jax.tree.map(lambda *leaves: jnp.stack(leaves), *trees)


class JaxTrainer:
    """The parameters and optimizer state of ``S`` seeds (stacked when ``S > 1``)."""

    def __init__(
        self,
        backend: JaxBackend,
        family: Family,
        impl: ModuleType,
        problem: Problem,
        initial: Sequence[Weights],
        settings: TrainSettings,
        layout: Layout,
    ) -> None:
        self.backend = backend
        self.seeds = len(initial)
        cfg, dtype = backend.cfg, backend.dtype
        trees = [nets_from_weights(w, layout, cfg.layers, cfg.activation, dtype) for w in initial]
        tree = trees[0] if self.seeds == 1 else _stack(trees)
        params, self.static = eqx.partition(tree, eqx.is_inexact_array)
        optimizer = adam_direction(settings.weight_decay)
        opt_state = optimizer.init(params) if self.seeds == 1 else jax.vmap(optimizer.init)(params)
        self.params, self.opt_state = backend.place(params), backend.place(opt_state)
        self.stacked = problem.stacked
        self.train = tuple(backend.array(a) for a in problem.train)
        self.valid = tuple(backend.array(a) for a in problem.valid)
        self.kept: Any = None  # the selected checkpoint (Trainer.keep)
        self.lr = settings.lr
        self.weight_decay = backend.array(settings.weight_decay)
        kind = f"{problem.kind}:l1" if cfg.loss == "l1" else problem.kind
        self.statics = (
            kind,
            impl,
            problem.options,
            self.static,
            (problem.criterion, problem.criterion_options),
        )

    def run_chunk(
        self, indices: Optional[np.ndarray], length: int, lrs: Optional[np.ndarray]
    ) -> tuple[Any, Any]:
        idx = None
        if indices is not None:
            block = indices[0] if self.seeds == 1 else indices
            idx = self.backend.place(jnp.asarray(block, dtype=jnp.int32))
        rates = np.full(length, self.lr) if lrs is None else np.asarray(lrs)
        args = (
            self.params,
            self.opt_state,
            idx,
            self.train,
            self.valid,
            self.backend.array(rates),
            self.weight_decay,
        )
        batched = self.seeds > 1
        statics = (*self.statics, length, *((self.stacked,) if batched else ()))
        compiled, seconds = _compiled(batched, statics, args)
        timings = self.backend.timings
        timings["compile_s"] = timings.get("compile_s", 0.0) + seconds
        self.params, self.opt_state, losses, valid = compiled(*args)
        return losses, valid

    def keep(self, seeds: np.ndarray) -> None:
        # JAX arrays are immutable and the chunk donates no buffer: keeping a reference
        # is a copy. A batch's first keep takes every seed (one not chosen now gets its
        # own at its first improvement).
        if self.kept is None or self.seeds == 1:
            self.kept = self.params
            return
        mask = jnp.asarray(np.asarray(seeds, dtype=bool))
        self.kept = jax.tree.map(
            lambda new, old: jnp.where(mask.reshape((-1,) + (1,) * (new.ndim - 1)), new, old),
            self.params,
            self.kept,
        )

    def weights(self) -> list[Weights]:
        """Each seed's kept checkpoint (:meth:`keep`), else its current weights."""
        nets = eqx.combine(self.kept if self.kept is not None else self.params, self.static)
        if self.seeds == 1:
            return [nets_to_weights(nets)]
        return [nets_to_weights(nets, s) for s in range(self.seeds)]


# --------------------------------------------------------------------------- inference


@eqx.filter_jit
def _apply(fn: Field, nets: Nets, z: jax.Array) -> jax.Array:
    return fn(nets, z)


@eqx.filter_jit
def _solve(
    field: Field,
    nets: Nets,
    y0: jax.Array,
    t: jax.Array,
    rtol: jax.Array,
    atol: jax.Array,
    min_step: jax.Array,
    max_steps: int,
) -> tuple[jax.Array, jax.Array]:
    """Dopri5 from the ``(M, D)`` batch ``y0`` over ``t``, the batch integrated as one
    system; returns ``ys (M, T, D)`` and the diffrax result code (0: success). A
    proposed step below ``min_step`` ends the solve (``dt_min_reached``: the stall
    rule, :func:`hnnbench.neural._backend.rollout_min_step`)."""
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(lambda _t, y, _args: field(nets, y)),
        diffrax.Dopri5(),
        t0=t[0],
        t1=t[-1],
        dt0=None,
        y0=y0,
        saveat=diffrax.SaveAt(ts=t),
        stepsize_controller=diffrax.PIDController(
            rtol=rtol, atol=atol, dtmin=min_step, force_dtmin=False
        ),
        max_steps=max_steps,
        throw=False,
    )
    return jnp.swapaxes(sol.ys, 0, 1), sol.result._value


@eqx.filter_jit
def _map_solve(
    step: Callable[[Nets, jax.Array, jax.Array], jax.Array],
    nets: Nets,
    y0: jax.Array,
    counts: jax.Array,
    sizes: jax.Array,
) -> jax.Array:
    """``counts[k]`` steps of ``step`` of size ``sizes[k]`` per interval from the
    ``(M, D)`` batch ``y0``; ``(M, T, D)`` with ``y0`` first."""

    def interval(z: jax.Array, plan: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
        m, h = plan
        z = jax.lax.fori_loop(0, m, lambda _, y: step(nets, y, h), z)
        return z, z

    _, zs = jax.lax.scan(interval, y0, (counts, sizes))
    return jnp.concatenate([y0[:, None], jnp.swapaxes(zs, 0, 1)], axis=1)


#: Rows per call of the float64 field and energy (:meth:`JaxInference.field`): each
#: compiles once per job for this shape instead of once per array size (the training,
#: validation and test sets, the rollouts: four compilations of about a second each for
#: an LNN).
ROWS = 1024

#: diffrax's result code of a step size below ``dtmin`` (the stall rule).
_STALLED = int(diffrax.RESULTS.dt_min_reached._value)  # type: ignore[attr-defined]


def _result_message(code: int) -> str:
    try:
        return str(diffrax.RESULTS._index_to_message[code]).splitlines()[0]
    except (AttributeError, IndexError):  # private diffrax API moved
        return f"diffrax result code {code}"


@eqx.filter_jit
def _encode(nets: Nets, x: jax.Array) -> jax.Array:
    assert nets.autoencoder is not None
    return jax.vmap(nets.autoencoder.encode)(x)


@eqx.filter_jit
def _decode(nets: Nets, z: jax.Array) -> jax.Array:
    assert nets.autoencoder is not None
    return jax.vmap(nets.autoencoder.decode)(z)


@eqx.filter_jit
def _objective(field: Field, nets: Nets, x: jax.Array, x_next: jax.Array) -> jax.Array:
    return pixel_objective(field, nets, x, x_next)


class JaxInference:
    """One seed's float64 field, energy and rollouts, and its pixel autoencoder in the
    training dtype."""

    def __init__(
        self,
        backend: JaxBackend,
        family: Family,
        impl: ModuleType,
        weights: Weights,
        layout: Layout,
    ) -> None:
        self.backend, self.impl = backend, impl
        cfg = backend.cfg
        self.nets64 = backend.place(
            nets_from_weights(weights, layout, cfg.layers, cfg.activation, jnp.float64)
        )
        self.nets = backend.place(
            nets_from_weights(weights, layout, cfg.layers, cfg.activation, backend.dtype)
        )

    def field(self, z: np.ndarray) -> np.ndarray:
        return self._rows(self.impl.field, z)

    def energy(self, z: np.ndarray) -> np.ndarray:
        return self._rows(self.impl.energy, z)

    def _rows(self, fn: Field, z: np.ndarray) -> np.ndarray:
        """``fn`` of the ``(N, D)`` rows ``z`` in float64, in blocks of :data:`ROWS` rows
        (the last one padded with copies of its last row), so that one compiled program
        serves every array size of a job."""
        z = np.asarray(z, dtype=np.float64)
        n = z.shape[0]
        padded = np.empty((max(1, -(-n // ROWS)) * ROWS, *z.shape[1:]), dtype=np.float64)
        padded[:n] = z
        padded[n:] = z[-1] if n else 0.0
        outs = [
            _apply(fn, self.nets64, self.backend.array(padded[i : i + ROWS], jnp.float64))
            for i in range(0, padded.shape[0], ROWS)
        ]  # dispatched, then gathered
        return np.concatenate([np.asarray(o, dtype=np.float64) for o in outs])[:n]

    def rollout(
        self, z0: np.ndarray, t: np.ndarray, rtol: float, atol: float, max_steps: int
    ) -> np.ndarray:
        array = self.backend.array
        min_step = rollout_min_step(t)
        ys, codes = _solve(
            self.impl.field,
            self.nets64,
            array(z0, jnp.float64),
            array(t, jnp.float64),
            jnp.float64(rtol),
            jnp.float64(atol),
            jnp.float64(min_step),
            int(max_steps),
        )
        out, code = np.asarray(ys, dtype=np.float64), int(np.asarray(codes))
        if code != 0:
            finite = np.all(np.isfinite(out), axis=(0, 2))
            reached = float(t[np.flatnonzero(finite)[-1]]) if finite.any() else float(t[0])
            why = (
                f"the step size fell below {stall_text(min_step)}"
                if code == _STALLED
                else f"{_result_message(code)} (model.rollout_max_steps={max_steps})"
            )
            raise RolloutDiverged(
                f"dopri5 gave up after t={reached:g} (of {float(t[0]):g}..{float(t[-1]):g}): {why}"
            )
        return out

    def map_rollout(self, z0: np.ndarray, t: np.ndarray, step: float) -> np.ndarray:
        counts, sizes = map_plan(t, step)
        array = self.backend.array
        out = _map_solve(
            self.impl.step,
            self.nets64,
            array(z0, jnp.float64),
            jax.device_put(jnp.asarray(counts, dtype=jnp.int32), self.backend.device),
            array(sizes, jnp.float64),
        )
        return np.asarray(out, dtype=np.float64)

    def encode(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(_encode(self.nets, self.backend.array(x)))

    def decode(self, z: np.ndarray) -> np.ndarray:
        return np.asarray(_decode(self.nets, self.backend.array(z)))

    def objective(self, x: np.ndarray, x_next: np.ndarray) -> float:
        array = self.backend.array
        return float(_objective(self.impl.field, self.nets, array(x), array(x_next)))


class JaxBackend:
    """The JAX backend for one model: device, training dtype, timings."""

    name = "jax"

    def __init__(self, cfg: NeuralConfig, device: str) -> None:
        use_compilation_cache()
        self.cfg = cfg
        self.device = resolve_device(device)
        self.dtype = jnp.dtype(cfg.dtype)
        self.device_name = device_name(self.device)
        self.timings: dict[str, float] = {}

    def place(self, tree: Any) -> Any:
        return jax.device_put(tree, self.device)

    def array(self, x: Any, dtype: Any = None) -> jax.Array:
        # cast by numpy (the same rounding): JAX would compile a cast per shape
        return jax.device_put(np.asarray(x, dtype=np.dtype(dtype or self.dtype)), self.device)

    def trainer(
        self,
        family: Family,
        impl: ModuleType,
        problem: Problem,
        initial: Sequence[Weights],
        settings: TrainSettings,
        layout: Layout,
    ) -> JaxTrainer:
        return JaxTrainer(self, family, impl, problem, initial, settings, layout)

    def weights(self, trainer: Any) -> list[Weights]:
        return trainer.weights()

    def inference(
        self, family: Family, impl: ModuleType, weights: Weights, layout: Layout
    ) -> JaxInference:
        return JaxInference(self, family, impl, weights, layout)
