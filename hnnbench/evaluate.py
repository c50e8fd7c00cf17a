"""The evaluation: every registered metric, computed the same way for every model.

:func:`evaluate` builds an :class:`EvalContext` for one trained model and asks each
registered :class:`~hnnbench.metric.Metric` (``hnnbench.metrics`` entry points) for
its value. The context computes what metrics share, once and only when asked: the
rollout from the evaluation trajectories' initial states, the map from a model's
latents to physical states (identity for state models; a linear probe fitted on the
training set for models with an encoder), energies along both. docs/METRICS.md is the
reference for what each number means.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

from hnnbench import metrics as M
from hnnbench.api import Dataset, Model, System, Trajectories
from hnnbench.config import EvaluationConfig
from hnnbench.errors import RolloutDiverged
from hnnbench.metric import Metric

log = logging.getLogger("hnnbench")

__all__ = ["EvalContext", "Evaluation", "LinearProbe", "evaluate", "failed_metrics"]


@dataclass
class LinearProbe:
    """Affine least-squares map from model latents ``(N, k)`` to states ``(N, 2n)``."""

    weight: np.ndarray
    bias: np.ndarray

    @classmethod
    def fit(cls, latents: np.ndarray, states: np.ndarray) -> LinearProbe:
        design = np.concatenate([latents, np.ones((latents.shape[0], 1))], axis=1)
        coef, *_ = np.linalg.lstsq(design, states, rcond=None)
        return cls(weight=coef[:-1], bias=coef[-1])

    def __call__(self, latents: np.ndarray) -> np.ndarray:
        return latents @ self.weight + self.bias


@dataclass
class Evaluation:
    """Metrics (``{name: {"mean", "sem"}}``), divergence, arrays for figures, and the
    metrics whose computation raised (a plugin bug: recorded, not fatal)."""

    metrics: dict[str, dict[str, float]]
    diverged: Optional[str] = None
    arrays: dict[str, np.ndarray] = field(default_factory=dict)
    errors: dict[str, str] = field(default_factory=dict)


class EvalContext:
    """What the metrics of one trained model share, computed on first use.

    Attributes:
        system, model, data, traj, cfg: the job's objects.
        pixels: whether the model sees observations (its rollouts are latents).
    """

    def __init__(self, system: System, model: Model, data: Dataset, traj: Trajectories,
                 cfg: EvaluationConfig) -> None:
        self.system, self.model, self.data, self.traj, self.cfg = system, model, data, traj, cfg
        self.pixels = traj.observations is not None
        self._memo: dict[str, Any] = {}
        self.arrays: dict[str, np.ndarray] = {"t": traj.t, "states_true": traj.states}

    def _once(self, key: str, make: Callable[[], Any]) -> Any:
        """``make()`` cached, a raised :class:`RolloutDiverged` included (so a failed
        rollout is attempted once, whatever asks for it)."""
        if key not in self._memo:
            try:
                self._memo[key] = (True, make())
            except RolloutDiverged as err:
                self._memo[key] = (False, err)
        ok, value = self._memo[key]
        if not ok:
            raise value
        return value

    # -- losses -----------------------------------------------------------------------
    def loss_values(self, split: str) -> Any:
        """Per-point squared errors of ``time_derivative`` on a split (state systems);
        the model's own objective on pixel systems (a mean, no standard error)."""
        data = getattr(self.data, split)
        if self.system.observation == "state":
            return M.per_point_squared_error(self.model.time_derivative(data.x), data.dxdt)
        return {"mean": float(self.model.loss(data.x, data.dxdt)), "sem": math.nan}

    # -- rollouts ---------------------------------------------------------------------
    def z0(self) -> np.ndarray:
        """Initial states in the model's coordinates (latents for pixel models)."""
        def make() -> np.ndarray:
            if self.traj.observations is not None:
                return self.model.encode(self.traj.observations[:, 0])
            return self.traj.x0
        return self._once("z0", make)

    def probe(self) -> Optional[LinearProbe]:
        """The latent -> state probe of pixel models, fitted on the training set."""
        def make() -> Optional[LinearProbe]:
            if not self.pixels:
                return None
            return LinearProbe.fit(self.model.encode(self.data.train.x),
                                   self.data.train.extras["state"])
        return self._once("probe", make)

    def roll(self, z0: np.ndarray, t: np.ndarray) -> np.ndarray:
        """A rollout of the model (``(M, T, d)``); non-finite states raise."""
        out = self.model.rollout(z0, t, rtol=self.cfg.rtol, atol=self.cfg.atol)
        if not np.all(np.isfinite(out)):
            raise RolloutDiverged("rollout produced non-finite states")
        return out

    def rollout(self) -> np.ndarray:
        """The main rollout, from :meth:`z0` over the evaluation grid."""
        return self._once("rollout", lambda: self.roll(self.z0(), self.traj.t))

    def to_states(self, z: np.ndarray) -> np.ndarray:
        """Model coordinates ``(..., d)`` -> physical states ``(..., 2n)``."""
        probe = self.probe()
        if probe is None:
            return z
        shape = z.shape
        return probe(z.reshape(-1, shape[-1])).reshape(*shape[:-1], -1)

    def reverse(self, z: np.ndarray) -> np.ndarray:
        """Time reversal R in the model's coordinates: the system's (flip momenta), or
        for latents ``(z_q, z_p)`` flipping ``z_p``."""
        if not self.pixels:
            return self.system.reverse(z)
        out = np.array(z, dtype=np.float64, copy=True)
        out[..., out.shape[-1] // 2:] *= -1.0
        return out

    def states_hat(self) -> np.ndarray:
        """``(M, T, 2n)`` physical states along the main rollout."""
        def make() -> np.ndarray:
            states = self.to_states(self.rollout())
            self.arrays["states_hat"] = states
            learned = self.model.energy(self.rollout().reshape(-1, self.rollout().shape[-1]))
            if learned is not None:
                m, t_len = states.shape[:2]
                self.arrays["learned_energy"] = np.asarray(learned).reshape(m, t_len)
            return states
        return self._once("states_hat", make)

    def _energies(self, states: np.ndarray) -> np.ndarray:
        m, t, d = states.shape
        with np.errstate(all="ignore"):
            return self.system.energy(states.reshape(m * t, d)).reshape(m, t)

    def energy_true(self) -> np.ndarray:
        """``(M, T)`` true energy along the true trajectories."""
        def make() -> np.ndarray:
            self.arrays["energy_true"] = self._energies(self.traj.states)
            return self.arrays["energy_true"]
        return self._once("energy_true", make)

    def energy_hat(self) -> np.ndarray:
        """``(M, T)`` true energy along the model's rollout."""
        def make() -> np.ndarray:
            self.arrays["energy_hat"] = self._energies(self.states_hat())
            return self.arrays["energy_hat"]
        return self._once("energy_hat", make)

    def pixel_errors(self) -> Optional[np.ndarray]:
        """``(M,)`` MSE of the decoded latent rollout against the true frames; ``None``
        for a model without a decoder."""
        if self.traj.observations is None:
            return None
        z = self.rollout()
        m, t_len, d = z.shape
        decoded = self.model.decode(z.reshape(m * t_len, d))
        if decoded is None:
            return None
        obs = self.traj.observations.reshape(m * t_len, -1)
        return np.mean(((decoded - obs) ** 2).reshape(m, -1), axis=1)


def _nan() -> dict[str, float]:
    return {"mean": math.nan, "sem": math.nan}


def failed_metrics(system: System, metrics: Sequence[Metric],
                   keep: Optional[dict[str, dict[str, float]]] = None
                   ) -> dict[str, dict[str, float]]:
    """The record of a model that diverged: each applicable metric's worst value (NaN
    where it does not apply); values in ``keep`` (e.g. finite losses) stay."""
    out: dict[str, dict[str, float]] = {}
    for metric in metrics:
        if keep and metric.name in keep:
            out[metric.name] = keep[metric.name]
        elif metric.applies(system):
            out[metric.name] = {"mean": metric.worst(), "sem": math.nan}
        else:
            out[metric.name] = _nan()
    return out


def evaluate(system: System, model: Model, data: Dataset, traj: Trajectories,
             cfg: EvaluationConfig, metrics: Optional[Sequence[Metric]] = None
             ) -> Evaluation:
    """Compute every metric (default: all registered) of ``model`` on ``system``."""
    if metrics is None:
        from hnnbench.registry import metrics as registered

        metrics = registered()
    ctx = EvalContext(system, model, data, traj, cfg)
    result: dict[str, dict[str, float]] = {}
    errors: dict[str, str] = {}
    diverged: Optional[str] = None
    for metric in metrics:
        if not metric.applies(system):
            result[metric.name] = _nan()
            continue
        try:
            values = metric.compute(ctx)
        except RolloutDiverged as err:
            result[metric.name] = {"mean": metric.worst(), "sem": math.nan}
            if metric.required and diverged is None:
                diverged = f"rollout diverged ({metric.name}): {err}"
            continue
        except Exception as err:
            # A required metric is what the job is for: whatever raised (the model, e.g.
            # out of memory, or the metric) fails the job with the traceback rather than
            # leave a NaN that reads "not applicable". An optional metric's error is
            # recorded and the job goes on.
            if metric.required:
                raise
            errors[metric.name] = f"{type(err).__name__}: {err}".splitlines()[0]
            log.warning("metric %s failed: %s", metric.name, errors[metric.name])
            result[metric.name] = _nan()
            continue
        if values is None:
            result[metric.name] = _nan()
        elif isinstance(values, dict):
            result[metric.name] = {"mean": float(values["mean"]),
                                   "sem": float(values.get("sem", math.nan))}
        else:
            result[metric.name] = M.summarize(np.asarray(values, dtype=np.float64))
        mean = result[metric.name]["mean"]
        if metric.required and not math.isfinite(mean) and not math.isnan(mean) \
                and diverged is None:
            diverged = f"{metric.name} is not finite"
    return Evaluation(metrics=result, diverged=diverged, arrays=ctx.arrays, errors=errors)
