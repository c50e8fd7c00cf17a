"""The neural model: a family, a backend and a view, composed.

A built-in or third-party family is one :class:`~hnnbench.neural._family.Family`
declaration, one small implementation module per backend, and one entry point per
backend whose class is just::

    class HNNTorch(NeuralModel):
        family = HNN
        backend = "torch"

Everything else is here, once: seeded initial weights, the training loop (for one
seed or several seeds as one batch), float64 fields and rollouts, the learned energy,
pixel autoencoders and second-order coordinates (through the view), saving and
loading. Importing this module imports no backend; building a model imports its own.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar, Literal, Optional

import numpy as np

from hnnbench._contracts.datasets import with_validation
from hnnbench._contracts.errors import ConfigError, RolloutDiverged
from hnnbench._contracts.plugin import Dataset, FitResult, Model, Progress, System, TrainSettings
from hnnbench.neural import _views as views
from hnnbench.neural._backend import Inference, Weights, load_backend, missing_backend
from hnnbench.neural._config import NeuralConfig
from hnnbench.neural._embedding import Layout
from hnnbench.neural._family import BACKEND_ORDER, Family, bind
from hnnbench.neural._init import autoencoder_init_arrays, network_init_arrays
from hnnbench.neural._loop import train as run_training
from hnnbench.neural._views import Problem
from hnnbench.neural._weights import load_weights, save_weights

__all__ = ["NeuralModel"]

#: Rows per call when mapping whole splits through a network (bounds memory).
CHUNK = 4096


class NeuralModel(Model):
    """A neural model of one :class:`Family` on one backend (see the module docstring).

    Subclasses set ``family`` and ``backend``; ``observations`` follows the family.
    """

    Config = NeuralConfig
    cfg: NeuralConfig
    family: ClassVar[Family]
    weights_file: ClassVar[Optional[str]] = "weights.safetensors"
    #: The smoke profile: a narrower network (64 units), so a quick job takes seconds
    #: (docs/MODELS.md), and a rollout cap: a model that needs more steps than this over
    #: a quick evaluation horizon has diverged in all but name.
    profiles: ClassVar[dict[str, dict[str, Any]]] = {
        "quick": {"rollout_max_steps": 5000, "hidden": 64}
    }

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        family = cls.__dict__.get("family")
        if family is not None:
            cls.observations = tuple(family.observations)
            if family.order is not None and "order" not in cls.__dict__:
                offset = (
                    BACKEND_ORDER.index(cls.backend)
                    if cls.backend in BACKEND_ORDER
                    else len(BACKEND_ORDER)
                )
                cls.order = family.order + 0.1 * offset
            if not cls.__dict__.get("description"):
                cls.description = f"{family.title} ({cls.backend})"
            if family.search_space is not None and "search_space" not in cls.__dict__:
                cls.search_space = family.search_space
            if family.recipe is not None and "recipe" not in cls.__dict__:
                cls.recipe = dict(family.recipe)

    @classmethod
    def unsupported_reason(cls, system: System) -> Optional[str]:
        return super().unsupported_reason(system) or views.unsupported_reason(cls.family, system)

    @classmethod
    def requirements_missing(cls) -> Optional[str]:
        return missing_backend(cls.backend)

    def __init__(self, cfg: NeuralConfig, system: System, device: str = "auto") -> None:
        super().__init__(cfg, system, device)
        self.view = views.view_for(self.family, system)
        if cfg.loss != "mse" and (
            self.family.data != "derivatives" or isinstance(self.view, views.PixelView)
        ):
            trained_on = (
                "pixel observations"
                if isinstance(self.view, views.PixelView)
                else "trajectory windows"
            )
            raise ConfigError(
                f"model.loss={cfg.loss}: {self.name} trains on {trained_on} by its own "
                "objective; the loss choice applies to families trained on derivatives. "
                "Use model.loss=mse."
            )
        self._backend = load_backend(self.backend, cfg, device)
        self._impl = bind(
            importlib.import_module(self.family.implementations[self.backend]), self.field_options()
        )
        self._weights: Optional[Weights] = None
        self._inference: Optional[Inference] = None
        self.timings = self._backend.timings
        #: If set, :meth:`fit` starts every seed from these weights (flat names, e.g.
        #: another model's :meth:`get_weights`) instead of the seeded initial ones.
        self.warm_start: Optional[Weights] = None
        #: The median interval of the training windows (families that train on
        #: trajectory windows), in model time units; set by :meth:`fit`, saved.
        self.data_step: Optional[float] = None

    @property
    def device(self) -> str:
        return self._backend.device_name

    # -- weights --------------------------------------------------------------------
    def layout(self) -> Layout:
        """The family's networks on this system: what each reads, its angles and their
        embedding (``model.angle_embedding``)."""
        d = self.view.dim
        return Layout.build(
            d,
            self.family.networks(d),
            self.family.network_inputs,
            self.view.angles,
            self.cfg.angle_embedding,
        )

    def network_shapes(self) -> dict[str, tuple[int, int]]:
        """``{net: (input features, d_out)}`` of the family's networks on this system
        (input features: after the angle embedding)."""
        layout = self.layout()
        return {
            name: (layout[name].features, d_out)
            for name, (_, d_out) in self.family.networks(self.view.dim).items()
        }

    def initial_weights(self, seed: int, d_obs: Optional[int] = None) -> Weights:
        """The seeded float64 initial weights (flat names), the same for every backend;
        pixel models also need the observation size ``d_obs``."""
        nested = network_init_arrays(seed, self.network_shapes(), self.cfg)
        flat = {
            f"{net}.{key}": value for net, arrays in nested.items() for key, value in arrays.items()
        }
        if isinstance(self.view, views.PixelView):
            if d_obs is None:
                raise ValueError("pixel models need d_obs for their initial weights")
            ae = autoencoder_init_arrays(seed, d_obs, self.view.dim, self.cfg.hidden)
            flat.update({f"autoencoder.{k}": v for k, v in ae.items()})
        return flat

    def get_weights(self) -> Weights:
        """The trained weights (training dtype), flat names."""
        if self._weights is None:
            raise RuntimeError(f"{self.name}: call fit() or load() first")
        return dict(self._weights)

    def set_weights(self, weights: Weights) -> None:
        """Use these weights (cast to the training dtype), e.g. another backend's.

        Raises:
            ValueError: the names or shapes are not this model's layout.
        """
        self._check_layout(weights)
        dtype = np.dtype(self.cfg.dtype)
        self._weights = {k: np.asarray(v).astype(dtype, copy=False) for k, v in weights.items()}
        self._inference = None

    def _check_layout(self, weights: Weights) -> None:
        first = weights.get("autoencoder.encoder.0.weight")
        d_obs = None if first is None else int(np.shape(first)[1])
        expected = (
            self.initial_weights(0, d_obs)
            if (d_obs is not None or not isinstance(self.view, views.PixelView))
            else None
        )
        if expected is None:
            raise ValueError(
                f"{self.name} is a pixel model: its weights include an "
                "autoencoder (autoencoder.encoder.0.weight, ...)"
            )
        if set(weights) != set(expected):
            raise ValueError(
                f"weights do not match {self.name}: missing {sorted(set(expected) - set(weights))}"
                f", unexpected {sorted(set(weights) - set(expected))}"
            )
        for key, value in expected.items():
            if np.shape(weights[key]) != value.shape:
                raise ValueError(
                    f"weight {key} has shape {np.shape(weights[key])}, expected "
                    f"{value.shape} (model.hidden={self.cfg.hidden}, "
                    f"model.layers={self.cfg.layers})"
                )

    def _infer(self) -> Inference:
        if self._inference is None:
            self._inference = self._backend.inference(
                self.family, self._impl, self.get_weights(), self.layout()
            )
        return self._inference

    def field_options(self) -> tuple[tuple[str, Any], ...]:
        """Keyword options of the family's ``field`` and ``energy`` (hashable ``(name,
        value)`` pairs; default none): a family with its own config fields that change
        the field (the LNN's kinetic prior, the D-HNN's dissipation scale) overrides
        this, and its implementation functions take them as keyword arguments."""
        return ()

    # -- training -------------------------------------------------------------------
    def training_options(self) -> tuple[int, tuple[tuple[str, Any], ...]]:
        """``(window, options)``: states per trajectory window (0: the family's
        default) and the keyword options of the family's ``window_loss``; a family
        with its own config fields overrides this."""
        return 0, ()

    def _problems(self, data: Sequence[Dataset], seeds: Sequence[int]) -> list[Problem]:
        """Each seed's training problem; a dataset without a validation split (a fit
        outside a job) gets the job's one (:func:`hnnbench._contracts.datasets.with_validation`)."""
        integrator: Literal["rk4", "map"] = "map" if self.rolls_out_by_map() else "rk4"
        return [
            self.view.problem(
                d if d.valid is not None else with_validation(d, seed),
                *self.training_options(),
                integrator=integrator,
            )
            for d, seed in zip(data, seeds, strict=True)
        ]

    def _train(
        self,
        problems: Sequence[Problem],
        settings: TrainSettings,
        seeds: Sequence[int],
        progress: Progress,
    ) -> tuple[list[Any], list[Weights]]:
        """Train ``seeds`` (seed ``k`` on ``problems[k]``) in one program."""
        problem = problems[0] if len(problems) == 1 else Problem.stack(problems)
        d_obs = problems[0].train[0].shape[1] if problem.kind == "pixels" else None
        if self.warm_start is not None:
            self._check_layout(self.warm_start)
            initial = [dict(self.warm_start) for _ in seeds]
        else:
            initial = [self.initial_weights(seed, d_obs) for seed in seeds]
        trainer = self._backend.trainer(
            self.family, self._impl, problem, initial, settings, self.layout()
        )
        fits = run_training(
            trainer,
            problem.n,
            settings,
            seeds,
            self.cfg.log_interval(settings.steps),
            progress,
            self.cfg.lr_schedule,
            problem.criterion_name,
        )
        if problems[0].kind == "windows":
            self.data_step = float(np.median(problems[0].train[1]))
        return fits, self._backend.weights(trainer)

    def fit(self, data: Dataset, train: TrainSettings, seed: int, progress: Progress) -> FitResult:
        (fit,), (weights,) = self._train(self._problems([data], [seed]), train, [seed], progress)
        self.set_weights(weights)
        return FitResult(
            history=fit.history, steps=fit.steps, diverged=fit.diverged, selection=fit.selection
        )

    def fit_seeds(
        self,
        data: Sequence[Dataset],
        train: TrainSettings,
        seeds: Sequence[int],
        progress: Progress,
    ) -> list[tuple[Model, FitResult]]:
        """Train every seed in one program, their networks as one batch (``vmap``): each
        seed starts from its own initial weights and trains on its own data with its own
        minibatches, exactly as when it runs alone. Seeds whose data differ in shape
        train one after the other instead."""
        problems = self._problems(data, seeds)
        if not Problem.stackable(problems):
            return super().fit_seeds(data, train, seeds, progress)
        fits, weights = self._train(problems, train, seeds, progress)
        out: list[tuple[Model, FitResult]] = []
        for fit, w, problem in zip(fits, weights, problems, strict=True):
            model = self.copy()
            model.set_weights(w)
            if problem.kind == "windows":
                model.data_step = float(np.median(problem.train[1]))
            out.append(
                (
                    model,
                    FitResult(
                        history=fit.history,
                        steps=fit.steps,
                        diverged=fit.diverged,
                        selection=fit.selection,
                    ),
                )
            )
        return out

    def copy(self) -> NeuralModel:
        """An untrained model like this one, sharing its backend."""
        model = object.__new__(type(self))
        Model.__init__(model, self.cfg, self.system, self.requested_device)
        model.view = self.view
        model._backend, model._impl = self._backend, self._impl
        model._weights, model._inference = None, None
        model.warm_start, model.data_step = None, self.data_step
        model.timings = dict(self.timings)  # training timings so far; rollouts its own
        return model

    # -- inference ------------------------------------------------------------------
    def rolls_out_by_map(self) -> bool:
        """Whether the model rolls out with its family's own discrete map ``step``
        (:meth:`map_step`) rather than the adaptive solver on its field; the rollout
        selection criterion then uses the same map. ``False`` (the default)."""
        return False

    def map_step(self) -> Optional[float]:
        """The step size (model time units) of the family's own discrete map when the
        model rolls out with it instead of the adaptive Dormand-Prince solver (e.g. the
        SRNN's leapfrog, ``model.integrator=leapfrog``); ``None`` (the default): the
        solver. A family whose implementation defines ``step(nets, z, h)`` overrides
        this."""
        return None

    def time_derivative(self, x: np.ndarray) -> np.ndarray:
        z = self.view.to_model(x)
        return self.view.rate_out(z, self._infer().field(z))

    def rollout(
        self, x0: np.ndarray, t: np.ndarray, rtol: float = 1e-9, atol: float = 1e-9
    ) -> np.ndarray:
        z0 = self.view.to_model(np.atleast_2d(x0))
        times = np.asarray(t, dtype=np.float64) / self.view.time_unit
        start = time.perf_counter()
        step = self.map_step()
        try:
            if step is not None:
                zs = self._infer().map_rollout(z0, times, step)
            else:
                zs = self._infer().rollout(z0, times, rtol, atol, int(self.cfg.rollout_max_steps))
        finally:
            self.timings["rollout_s"] = self.timings.get("rollout_s", 0.0) + (
                time.perf_counter() - start
            )
        out = self.view.from_model(zs)
        if not np.all(np.isfinite(out)):
            raise RolloutDiverged("rollout produced non-finite states")
        return out

    def energy(self, x: np.ndarray) -> Optional[np.ndarray]:
        if not self.family.learned_energy:
            return None
        return self._infer().energy(self.view.to_model(x))

    def _chunked(self, fn: Any, a: np.ndarray) -> np.ndarray:
        parts = [fn(a[i : i + CHUNK]) for i in range(0, a.shape[0], CHUNK)]
        return np.concatenate(parts).astype(np.float64) if parts else np.zeros((0, 0))

    def encode(self, obs: np.ndarray) -> np.ndarray:
        if not isinstance(self.view, views.PixelView):
            return super().encode(obs)
        return self._chunked(self._infer().encode, np.asarray(obs))

    def decode(self, z: np.ndarray) -> Optional[np.ndarray]:
        if not isinstance(self.view, views.PixelView):
            return super().decode(z)
        return self._chunked(self._infer().decode, np.asarray(z))

    def loss(self, x: np.ndarray, dxdt: np.ndarray) -> float:
        if not isinstance(self.view, views.PixelView):
            return super().loss(x, dxdt)
        xs, x_next = self.view.pairs(x, dxdt, {})
        infer, total = self._infer(), 0.0
        for i in range(0, xs.shape[0], CHUNK):
            total += infer.objective(xs[i : i + CHUNK], x_next[i : i + CHUNK]) * len(
                xs[i : i + CHUNK]
            )
        return total / max(1, xs.shape[0])

    # -- persistence ----------------------------------------------------------------
    def _meta(self) -> dict[str, Any]:
        c = self.cfg
        return {
            "model": self.name,
            "family": self.family.name,
            "backend": self.backend,
            "dtype": c.dtype,
            "activation": c.activation,
            "layers": c.layers,
            "hidden": c.hidden,
            "time_unit": self.view.time_unit,
            "angle_embedding": c.angle_embedding,
            "data_step": self.data_step,
        }

    def save(self, path: Path) -> None:
        """Write the trained weights to ``path`` (safetensors, via numpy; the same
        format for every backend)."""
        save_weights(path, self.get_weights(), self._meta())

    def load(self, path: Path) -> None:
        weights, meta = load_weights(path)
        mine = self._meta()
        for key in ("family", "activation", "angle_embedding"):  # layers, hidden: the
            # layout check says
            if key in meta and meta[key] != mine[key]:
                raise ValueError(
                    f"{path} holds a model with {key}={meta[key]}, but this "
                    f"model has {key}={mine[key]}"
                )
        self.set_weights(weights)
        if meta.get("data_step") is not None:
            self.data_step = float(meta["data_step"])
        if isinstance(self.view, views.PixelView):
            self.view.time_unit = float(meta.get("time_unit", 1.0))
