"""A metric, declared once: what it computes and how every consumer treats it.

A :class:`Metric` holds everything about one metric: its name and definition, the
function that computes it from an evaluation, which direction is better, how tables
and figures display it, the tolerance of the regression gate, the systems it applies
to, and what a diverged rollout records for it. The evaluation, the leaderboard, the
report and ``hnnbench check`` all read these declarations; none names a metric.

Metrics are plugins of the entry-point group ``hnnbench.metrics``: each entry point
names a :class:`Metric` instance. hnnbench's own (:mod:`hnnbench_plugins.metrics`) are declared
there the same way, so a third-party package adds a metric to every leaderboard and
to ``hnnbench check`` with no change here (docs/PLUGINS.md).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, Optional

import numpy as np

from hnnbench._contracts.errors import RolloutDiverged
from hnnbench._contracts.outputs import checked, checked_scalar
from hnnbench._contracts.plugin import CLEAN_INPUTS, Dataset, Model, System, Trajectories

__all__ = [
    "CheckRule",
    "EvalContext",
    "EvaluationConfig",
    "LinearProbe",
    "Metric",
    "STATE_BOUND",
    "always",
    "per_point_squared_error",
    "sem",
    "summarize",
]


def always(system: System) -> bool:
    """The default :attr:`Metric.applies`: every system."""
    return True


@dataclass(frozen=True)
class CheckRule:
    """The rule ``hnnbench check`` applies to a metric (or a timing): the one class for
    it. A :class:`Metric` declares it; ``--rules FILE`` overrides it.

    Attributes:
        factor: how much worse is tolerated, as a ratio compared in log space: a
            lower-is-better value fails above ``reference * factor``, a higher-is-better
            one below ``reference / factor``.
        floor: values below it count as it: a numerical noise floor (so that 1e-16 vs
            1e-14 from an exact model on two machines is no regression), or a metric's
            resolution (a share of 15 trajectories moves in steps of 1/15).
        gate: ``False``: differences are reported as information, never a failure.
        better: ``"lower"`` or ``"higher"``; a :class:`Metric` sets it to its own
            :attr:`Metric.better`.
    """

    factor: float = 10.0
    floor: float = 0.0
    gate: bool = True
    better: Literal["lower", "higher"] = "lower"

    def worsening(self, reference: float, current: float) -> float:
        """How many times worse ``current`` is than ``reference`` (< 1: better)."""
        ref, cur = max(reference, self.floor), max(current, self.floor)
        worse, base = (cur, ref) if self.better == "lower" else (ref, cur)
        if math.isinf(worse) and math.isinf(base):
            return 1.0
        if base <= 0:
            return 1.0 if worse <= 0 else math.inf
        return worse / base

    def limit_text(self) -> str:
        op = "<=" if self.better == "lower" else ">="
        side = f"ref x {self.factor:g}" if self.better == "lower" else f"ref / {self.factor:g}"
        return f"{op} {side}"

    def difference(self, reference: float, current: float) -> float:
        """``|current - reference|`` relative to the larger magnitude (0 when both are at
        or below the noise floor, ``inf`` when exactly one is non-finite)."""
        if max(abs(reference), abs(current)) <= self.floor:
            return 0.0
        if math.isinf(reference) or math.isinf(current):
            return 0.0 if reference == current else math.inf
        return abs(current - reference) / max(abs(reference), abs(current))


@dataclass(frozen=True)
class Metric:
    """One metric (see the module docstring).

    Attributes:
        name: the record's key and the leaderboard's column (``<name>_mean``).
        description: one line: what it measures (``hnnbench list``, docs, page tooltips).
        compute: ``EvalContext -> values``: an array of per-trajectory (or per-point)
            values, summarised as their mean and standard error; a ``{"mean", "sem"}``
            dict; or ``None`` when it does not apply to this model (recorded as NaN).
            It may raise :class:`~hnnbench._contracts.errors.RolloutDiverged` (the metric then
            records :meth:`worst`).
        better: ``"lower"`` or ``"higher"``.
        scale: ``"log"`` (errors spanning decades) or ``"linear"``, for tables/figures.
        check: the regression gate's tolerance.
        applies: ``System -> bool``; elsewhere the metric is NaN ("not applicable").
        required: a non-finite value makes the job ``diverged``; ``False`` for metrics
            that probe failure modes on purpose (e.g. a long-horizon rollout). Only a
            ranked metric is ever required (:attr:`decides_status`): a diagnostic whose
            rollout fails records :meth:`worst` and the reason in the record's
            ``metric_errors``, and the run keeps its status.
        summary: shown in the end-of-sweep summary table.
        order: position in tables (lower first; then by name).
        reference: where its definition is documented.
        figures: the report's board figures that plot it: ``"heatmap"`` (a rank
            heatmap of models by system), ``"data_efficiency"`` (the metric against a
            swept training-set size).
        log: shown in the one-line outcome a job logs when it finishes.
        errors_fail_job: an exception while computing it fails the job (with the
            traceback); ``False`` (default): its message is recorded in the record's
            ``metric_errors``, the value is NaN and the job goes on.
        ranked: whether the leaderboard marks its best value; ``False`` for a
            diagnostic that a broken model can win (the reversibility of a flow says
            nothing of its accuracy: the zero field is exactly reversible), shown but
            never marked best.
        domain: ``(low, high)``, the values its mean can take (an error or a time is
            ``(0, inf)``). A strict load of records (``hnnbench check``, publishing)
            refuses a mean outside it; ``nan`` (not applicable) and :meth:`worst` (a
            diverged model's ``inf``) are always allowed (:meth:`value_problem`).
        best_requires: ``(metric, threshold)``: a row is eligible to be marked best on
            this metric only where its mean of ``metric`` (a higher-is-better metric)
            exceeds ``threshold``. For a metric a degenerate model would win, e.g. the
            energy error of a model that does not move (0 on a conservative system),
            eligible only where the rollout beats standing still.
        beat_reference: a cell of this metric is marked (best or tied) only where its
            leader's mean beats the standing-still reference's mean on it (the zero field,
            :data:`~hnnbench.STANDING_STILL`, whose row must be on the board); where no
            family does, the reference's cell says so (docs/STATISTICS.md, "The trivial
            references"). For metrics on which standing still is a fair opponent
            (rollout errors, skill, valid prediction time); an energy error, where it
            scores 0 by construction, uses :attr:`best_requires` instead.
        evidence: metrics computed from one and the same evidence share a name here
            (the rollout metrics: ``"rollout"``); a report counts their agreeing verdicts
            on one system as one finding, not several (docs/STATISTICS.md). ``""``: its
            own.
        headline: a headline verdict (ranked metrics only): the aggregate across systems
            on the README and the report page, its performance profile, and the ranks
            ``hnnbench check`` prints for a new model lead with it
            (docs/STATISTICS.md).
        within_horizon: its mean is a time along the evaluation rollout, at most the
            evaluation horizon the record's data states (``data.evaluation_meta.
            horizon``); a strict load refuses a larger one.
        selects: the metric ``hnnbench tune`` selects on (in its direction), computed
            on the validation split only, never on test: one registered metric at most
            declares it (docs/TUNING.md). A trial of the tuner computes it alone.
    """

    name: str
    description: str
    compute: Callable[[EvalContext], Any]
    better: Literal["lower", "higher"] = "lower"
    scale: Literal["log", "linear"] = "log"
    check: CheckRule = field(default_factory=CheckRule)
    applies: Callable[[System], bool] = always
    required: bool = True
    ranked: bool = True
    summary: bool = True
    order: int = 1000
    reference: str = "docs/METRICS.md"
    figures: tuple[str, ...] = ()
    log: bool = False
    errors_fail_job: bool = False
    domain: tuple[float, float] = (-math.inf, math.inf)
    best_requires: Optional[tuple[str, float]] = None
    beat_reference: bool = False
    evidence: str = ""
    headline: bool = False
    selects: bool = False
    within_horizon: bool = False

    def __post_init__(self) -> None:
        low, high = self.domain
        if not (isinstance(low, (int, float)) and isinstance(high, (int, float)) and low <= high):
            raise ValueError(
                f"metric {self.name!r}: domain must be (low, high) numbers "
                f"with low <= high, not {self.domain!r}"
            )
        if self.headline and not self.ranked:
            raise ValueError(
                f"metric {self.name!r}: a headline metric must be ranked "
                "(ranked=True); a diagnostic is never a verdict"
            )
        if self.check.better != self.better:  # the metric's direction is the rule's
            object.__setattr__(self, "check", dataclasses.replace(self.check, better=self.better))

    @property
    def decides_status(self) -> bool:
        """Whether a non-finite value of this metric makes the run ``diverged``: a
        required, ranked metric (a diagnostic never sets a run's status)."""
        return self.required and self.ranked

    def worst(self) -> float:
        """The value recorded when the model failed (diverged): the bad end of its
        :attr:`domain` (``inf`` for errors; ``0`` for a time or a share, where higher is
        better: a diverged model predicts nothing; ``-inf`` for an unbounded score)."""
        low, high = self.domain
        return low if self.better == "higher" else high

    def value_problem(self, mean: Any, sem: Any = math.nan) -> Optional[str]:
        """Why ``mean`` / ``sem`` (floats, decoded) cannot be this metric's summary, or
        ``None``: a mean is NaN (not applicable), :meth:`worst`, or a finite number in
        :attr:`domain`; a standard error is NaN or ``>= 0`` (``inf`` where a value is)."""
        low, high = self.domain
        if not isinstance(mean, (int, float)) or isinstance(mean, bool):
            return f"mean {mean!r} is not a number"
        if not (
            math.isnan(mean)
            or mean == self.worst()
            or (math.isfinite(mean) and low <= mean <= high)
        ):
            return f"mean {mean!r} is outside the domain [{low:g}, {high:g}] of {self.name}" + (
                "" if math.isfinite(mean) else f" (a diverged run records {self.worst():g})"
            )
        if (
            not isinstance(sem, (int, float))
            or isinstance(sem, bool)
            or not (math.isnan(sem) or sem >= 0)
        ):
            return f"sem {sem!r} is not a standard error (>= 0)"
        return None


# --------------------------------------------------------------- summaries


def per_point_squared_error(pred: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``(N,)`` squared error of each point, averaged over its coordinates."""
    diff = np.asarray(pred, dtype=np.float64) - np.asarray(target, dtype=np.float64)
    return np.mean(diff.reshape(diff.shape[0], -1) ** 2, axis=1)


def sem(values: np.ndarray) -> float:
    """Standard error of the mean (``nan`` for fewer than two values)."""
    values = np.asarray(values, dtype=np.float64)
    if values.size < 2 or not np.all(np.isfinite(values)):
        return float("nan") if values.size < 2 else float("inf")
    return float(np.std(values, ddof=1) / np.sqrt(values.size))


def summarize(values: np.ndarray) -> dict[str, float]:
    """``{"mean": ..., "sem": ...}`` over evaluation trajectories (or points)."""
    values = np.asarray(values, dtype=np.float64)
    mean = float(np.mean(values)) if np.all(np.isfinite(values)) else float("inf")
    return {"mean": mean, "sem": sem(values)}


# ------------------------------------------------------------- the evaluation


@dataclass
class EvaluationConfig:
    """Evaluation protocol shared by all systems (docs/METRICS.md).

    Attributes:
        rtol, atol: tolerances of the adaptive Dormand-Prince rollouts of every model.
        vpt_threshold: relative state error that ends the valid prediction time.
        metrics: the names of the metrics to compute (``None``: every registered
            metric). A tuner's trial computes only the metric it selects on, so it
            never computes a test metric (docs/TUNING.md); the record then holds only
            those.
    """

    rtol: float = 1e-9
    atol: float = 1e-9
    vpt_threshold: float = 0.1
    metrics: Optional[list[str]] = None


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


#: The state bound of every rollout (docs/METRICS.md, "Diverged"): a rollout whose
#: state norm exceeds this multiple of the largest norm in the data has left the
#: system's domain and is ``diverged``, the same for every model and backend.
STATE_BOUND = 100.0


class EvalContext:
    """What the metrics of one trained model share, computed on first use.

    Attributes:
        system, model, data, traj, cfg: the job's objects.
        pixels: whether the model sees observations (its rollouts are latents).
    """

    def __init__(
        self, system: System, model: Model, data: Dataset, traj: Trajectories, cfg: EvaluationConfig
    ) -> None:
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
    def loss_values(self, split: str, clean: bool = False) -> Any:
        """Per-point squared errors of ``time_derivative`` on a split (state systems);
        the model's own objective on pixel systems (a mean, no standard error).
        ``clean``: where the system added noise to the inputs, take the field at the
        clean inputs (``Split.extras[CLEAN_INPUTS]``), so the loss measures the model
        against its (clean) targets and not the noise."""
        data = getattr(self.data, split)
        if self.system.observation == "state":
            x = data.extras.get(CLEAN_INPUTS, data.x) if clean else data.x
            pred = checked(
                self.model,
                "time_derivative",
                self.model.time_derivative(x),
                np.shape(data.dxdt),
                "(N, D) like its targets",
            )
            return per_point_squared_error(pred, data.dxdt)
        loss = checked_scalar(self.model, "loss", self.model.loss(data.x, data.dxdt))
        return {"mean": loss, "sem": math.nan}

    # -- rollouts ---------------------------------------------------------------------
    def z0(self) -> np.ndarray:
        """Initial states in the model's coordinates (latents for pixel models)."""

        def make() -> np.ndarray:
            obs = self.traj.observations
            if obs is not None:
                return checked(
                    self.model,
                    "encode",
                    self.model.encode(obs[:, 0]),
                    (obs.shape[0], None),
                    "(N, k)",
                    float64=False,
                )
            return self.traj.x0

        return self._once("z0", make)

    def probe(self) -> Optional[LinearProbe]:
        """The latent -> state probe of pixel models, fitted on the training set."""

        def make() -> Optional[LinearProbe]:
            if not self.pixels:
                return None
            x = self.data.train.x
            latents = checked(
                self.model,
                "encode",
                self.model.encode(x),
                (len(x), np.shape(self.z0())[-1]),
                "(N, k) like the rollout's",
                float64=False,
            )
            return LinearProbe.fit(latents, self.data.train.extras["state"])

        return self._once("probe", make)

    def roll(self, z0: np.ndarray, t: np.ndarray) -> np.ndarray:
        """A rollout of the model (``(M, T, d)``); non-finite states, or states beyond
        the bound (:meth:`state_bound`), raise :class:`RolloutDiverged`."""
        out = checked(
            self.model,
            "rollout",
            self.model.rollout(z0, t, rtol=self.cfg.rtol, atol=self.cfg.atol),
            (len(z0), len(t), np.shape(z0)[-1]),
            "(M, T, d): M initial states, T times, d their width",
        )
        if not np.all(np.isfinite(out)):
            raise RolloutDiverged("rollout produced non-finite states")
        bound = self.state_bound()
        if bound is not None:
            norms = np.linalg.norm(self._bounded(out), axis=-1)
            if float(norms.max()) > bound:
                i, k = np.unravel_index(int(np.argmax(norms > bound)), norms.shape)
                raise RolloutDiverged(
                    f"the rollout left the state bound at t={float(t[k]):g}: |x| = "
                    f"{float(norms[i, k]):.3g} > {bound:.3g} ({STATE_BOUND:g} x the largest "
                    "|x| of the training inputs and the true evaluation states, angles "
                    "left out)"
                )
        return out

    def _bounded(self, x: np.ndarray) -> np.ndarray:
        """The columns of states ``(..., 2n)`` the bound applies to (angles left out)."""
        angles = set(getattr(self.system, "angles", ()))
        keep = [c for c in range(np.shape(x)[-1]) if c not in angles]
        return np.asarray(x)[..., keep]

    def state_bound(self) -> Optional[float]:
        """The largest state norm a rollout may reach before it is ``diverged``:
        :data:`STATE_BOUND` times the largest norm among the training inputs and the
        true evaluation states (angle columns left out: a turning rod is no blow-up).
        ``None`` for models rolled out in latents (pixels)."""
        if self.pixels:
            return None

        def make() -> float:
            scale = max(
                float(np.linalg.norm(self._bounded(self.data.train.x), axis=-1).max()),
                float(np.linalg.norm(self._bounded(self.traj.states), axis=-1).max()),
            )
            return STATE_BOUND * scale

        return float(self._once("state_bound", make))

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
        out[..., out.shape[-1] // 2 :] *= -1.0
        return out

    def states_hat(self) -> np.ndarray:
        """``(M, T, 2n)`` physical states along the main rollout."""

        def make() -> np.ndarray:
            states = self.to_states(self.rollout())
            self.arrays["states_hat"] = states
            flat = self.rollout().reshape(-1, self.rollout().shape[-1])
            learned = checked(
                self.model,
                "energy",
                self.model.energy(flat),
                (len(flat),),
                "(N,) or None",
                optional=True,
            )
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
        obs = self.traj.observations.reshape(m * t_len, -1)
        decoded = checked(
            self.model,
            "decode",
            self.model.decode(z.reshape(m * t_len, d)),
            obs.shape,
            "(N, D_obs) like the frames",
            float64=False,
            optional=True,
        )
        if decoded is None:
            return None
        return np.mean(((decoded - obs) ** 2).reshape(m, -1), axis=1)
