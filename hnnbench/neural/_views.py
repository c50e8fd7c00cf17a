"""How a neural model sees a system: the coordinates it works in and its training data.

A :class:`View` is chosen once per model, from the system's observation and the
family's declared coordinates, and composes with any family:

- :class:`CanonicalView`: the family works on the system's states ``(q, p)``;
- :class:`VelocityView`: the family works on ``(q, q̇)``; the system's
  :class:`~hnnbench._contracts.kinematics.Kinematics` maps states, targets and predicted rates;
- :class:`PixelView`: the family is the latent dynamics of an autoencoder on
  observations (the 2019 pixel-pendulum model); latents ``z = (z_q, z_p)``, time in
  frames.

A view turns a :class:`~hnnbench._contracts.plugin.Dataset` into a :class:`Problem` (numpy arrays
the backend trains on) and converts between the model API's arrays and the family's
working coordinates. It is pure numpy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal, Optional

import numpy as np

from hnnbench._contracts.errors import ConfigError, UnsupportedPair
from hnnbench._contracts.kinematics import Kinematics
from hnnbench._contracts.plugin import CLEAN_INPUTS, Dataset, Split, System
from hnnbench.neural._family import Family

__all__ = [
    "CC_WEIGHT",
    "DYNAMICS_WEIGHT",
    "VALID_POINTS",
    "CanonicalView",
    "PixelView",
    "Problem",
    "VelocityView",
    "View",
    "trajectory_windows",
    "view_for",
]

#: The pixel test loss logged during training is taken on this many evenly spaced test
#: points (the whole test set costs as much as ~10 training steps).
VALID_POINTS = 1024
#: Weights of the pixel objective's canonical-coordinates and latent-dynamics terms
#: (the 2019 paper's; :class:`PixelView`), read by both backends' ``pixel_objective``.
CC_WEIGHT = 1.0
DYNAMICS_WEIGHT = 0.1
#: A time step outside [median / F, median * F] of its trajectory is a gap.
WINDOW_GAP_FACTOR = 1.5
#: Classical Runge-Kutta steps per observed interval when the rollout criterion
#: (:attr:`hnnbench.System.selection` ``"rollout"``) integrates a family's field.
CRITERION_RK4_SUBSTEPS = 4

Kind = Literal["derivatives", "windows", "pixels"]
#: How a backend scores the validation arrays of a :class:`Problem`, per point (or
#: window): ``field`` (squared error of the field against the targets, mean over
#: coordinates), ``field:weighted`` (the same after mapping the error to the system's
#: coordinates by each point's matrix: second-order families), ``windows:rk4`` /
#: ``windows:map`` (squared position error of rollouts over each window, by RK4 on the
#: field or by the family's own map ``step``), ``pixels`` (the pixel objective per row).
Criterion = Literal["field", "field:weighted", "windows:rk4", "windows:map", "pixels"]


@dataclass(frozen=True)
class Problem:
    """What a backend trains on: arrays with a common leading dimension (rows are
    drawn together into minibatches) and the loss that consumes them.

    Attributes:
        kind: ``"derivatives"``: ``(z, ż)``, loss ``mean((field(z) - ż)^2)``;
            ``"windows"``: ``(windows (W, L, d), dts (W, L - 1))``, the family's
            ``window_loss``; ``"pixels"``: ``(x, x_next)``, the autoencoder objective.
        train, valid: the arrays of the training split and of the validation split
            the training loop selects its checkpoint on (for pixels, at most
            :data:`VALID_POINTS` validation rows).
        options: keyword arguments of the family's ``window_loss`` (hashable, e.g.
            ``(("substeps", 1),)``).
        criterion: how the validation arrays are scored (:data:`Criterion`): the
            selection criterion of the system (docs/METRICS.md, "Checkpoint
            selection"), the same for every family.
        criterion_name: its name in records (``selection.criterion``).
        criterion_options: its keyword options (``(("substeps", k),)`` for windows).
        stacked: the arrays carry a leading seed axis (:meth:`stack`): each seed of a
            batch trains on its own data.
    """

    kind: Kind
    train: tuple[np.ndarray, ...]
    valid: tuple[np.ndarray, ...]
    options: tuple[tuple[str, Any], ...] = ()
    criterion: Criterion = "field"
    criterion_name: str = "field_mse"
    criterion_options: tuple[tuple[str, Any], ...] = ()

    #: Whether the arrays hold one leading axis per seed (``S`` problems stacked).
    stacked: bool = False

    @property
    def n(self) -> int:
        """Training rows (of each seed)."""
        return int(self.train[0].shape[1 if self.stacked else 0])

    @staticmethod
    def stackable(problems: Sequence[Problem]) -> bool:
        """Whether the problems of several seeds can train as one batch: the same kind
        and options, and arrays of the same shapes."""
        first = problems[0]
        return all(
            (other.kind, other.options, other.criterion, other.criterion_options)
            == (first.kind, first.options, first.criterion, first.criterion_options)
            and len(other.train + other.valid) == len(first.train + first.valid)
            and all(
                a.shape == b.shape
                for a, b in zip(other.train + other.valid, first.train + first.valid, strict=True)
            )
            for other in problems[1:]
        )

    @staticmethod
    def stack(problems: Sequence[Problem]) -> Problem:
        """The problems of several seeds as one, each array with a leading seed axis.

        Raises:
            ValueError: the problems differ in kind, options or array shapes (they
                cannot be trained as one batch).
        """
        if not Problem.stackable(problems):
            raise ValueError(
                "the seeds' training data differ in kind, options or shape; "
                "check Problem.stackable first"
            )
        first = problems[0]
        return Problem(
            first.kind,
            tuple(np.stack(arrays) for arrays in zip(*(p.train for p in problems), strict=True)),
            tuple(np.stack(arrays) for arrays in zip(*(p.valid for p in problems), strict=True)),
            first.options,
            first.criterion,
            first.criterion_name,
            first.criterion_options,
            stacked=True,
        )


def trajectory_windows(
    split: Split, states: np.ndarray, length: int, wrapped: tuple[int, ...] = (), stride: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Windows of ``length`` consecutive samples of each trajectory.

    Rows of ``states`` (``(N, d)``, aligned with ``split``) are grouped by
    ``split.traj`` and ordered by ``split.t``; every run of ``length`` rows whose time
    steps all lie within :data:`WINDOW_GAP_FACTOR` of the trajectory's median step (so
    no window spans a gap in measured data) is a window, one starting every ``stride``
    rows (1: overlapping windows; ``length - 1``: windows that share only their ends).
    Columns ``wrapped`` hold angles wrapped into ``[-π, π)``
    (:attr:`hnnbench.System.wrapped_angles`): within each window they are unwrapped
    (whole turns added from the second sample on), so that a window never asks for a
    2π jump. The window's first state keeps its wrapped value.

    Returns:
        ``(windows (W, length, d), dts (W, length - 1))``: the states and each
        interval's own time step (measured data is not exactly equally spaced). ``W``
        may be 0.
    """
    windows: list[np.ndarray] = []
    dts: list[np.ndarray] = []
    traj, t = np.asarray(split.traj), np.asarray(split.t, dtype=np.float64)
    for tid in np.unique(traj):
        rows = np.flatnonzero(traj == tid)
        rows = rows[np.argsort(t[rows], kind="stable")]
        steps = np.diff(t[rows])
        if steps.size < length - 1:
            continue
        median = float(np.median(steps))
        good = (steps > median / WINDOW_GAP_FACTOR) & (steps < median * WINDOW_GAP_FACTOR)
        for start in range(0, len(rows) - length + 1, stride):
            if np.all(good[start : start + length - 1]):
                window = np.array(states[rows[start : start + length]], dtype=np.float64)
                if wrapped:
                    cols = list(wrapped)
                    window[:, cols] = np.unwrap(window[:, cols], axis=0)
                windows.append(window)
                dts.append(steps[start : start + length - 1])
    if not windows:
        return np.zeros((0, length, states.shape[1])), np.zeros((0, length - 1))
    return np.stack(windows), np.stack(dts)


class View:
    """Base: the family works on the system's own states (identity maps)."""

    #: Time of one model time unit, in system time (pixels: the frame interval).
    time_unit: float = 1.0

    def __init__(self, family: Family, system: System) -> None:
        self.family = family
        self.system = system

    @property
    def dim(self) -> int:
        """Dimension ``d`` of the family's working coordinates."""
        return 2 * self.system.dof

    @property
    def angles(self) -> tuple[int, ...]:
        """The working coordinates that are angles (:attr:`hnnbench.System.angles`:
        positions, the same in ``(q, p)`` and ``(q, q̇)``), which the networks embed."""
        return tuple(self.system.angles)

    def to_model(self, x: np.ndarray) -> np.ndarray:
        """Model-API inputs ``(..., D)`` -> working coordinates ``(..., d)``."""
        return np.asarray(x, dtype=np.float64)

    def from_model(self, z: np.ndarray) -> np.ndarray:
        """Working coordinates -> what :meth:`~hnnbench.Model.rollout` returns."""
        return z

    def rate_out(self, z: np.ndarray, zdot: np.ndarray) -> np.ndarray:
        """A rate in working coordinates (per model time unit) -> the model API's
        ``dx/dt`` (per system time unit)."""
        return zdot / self.time_unit

    def _pairs(self, split: Split) -> tuple[np.ndarray, np.ndarray]:
        return self._pairs_at(split.x, split.dxdt)

    def _pairs_at(self, x: np.ndarray, dxdt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(z, ż)`` in working coordinates of states ``x`` and their rates ``dxdt``."""
        return np.asarray(x, dtype=np.float64), np.asarray(dxdt, dtype=np.float64)

    def error_weights(self, z: np.ndarray) -> Optional[np.ndarray]:
        """``(N, 2n, d)`` matrices taking an error of a working-coordinate rate at ``z``
        to the error of the system's ``dx/dt`` (the tangent of :meth:`rate_out`, which
        is affine in the rate); ``None`` where the working coordinates are the
        system's."""
        return None

    def problem(
        self,
        data: Dataset,
        window: int = 0,
        options: tuple[tuple[str, Any], ...] = (),
        integrator: Literal["rk4", "map"] = "rk4",
    ) -> Problem:
        """The training problem of ``data`` for this family (``window``: states per
        training window, 0 for the family's; ``options``: the family's loss options;
        ``integrator``: how the family rolls out, for the rollout criterion: RK4 on its
        field, or its own map ``step`` with ``options``' substeps). ``data`` must hold
        a validation split (:func:`hnnbench._contracts.datasets.with_validation`). The validation
        arrays are those of the system's selection criterion (:meth:`criterion`), the
        same for every family."""
        valid = _validation(data)
        arrays, kind, name, criterion_options = self.criterion(valid, integrator, options)
        if self.family.data == "windows":
            wrapped = tuple(self.system.wrapped_angles)
            length = window or self.family.window
            z, _ = self._pairs(data.train)
            train = trajectory_windows(data.train, z, length, wrapped)
            if train[0].shape[0] == 0:
                raise UnsupportedPair(
                    f"the {self.system.name} training data has no {length} consecutive, "
                    "equally spaced samples of one trajectory, which the "
                    f"{self.family.name} family trains on (model.window={length}: a "
                    "shorter window may fit)"
                )
            return Problem("windows", train, arrays, options, kind, name, criterion_options)
        return Problem(
            "derivatives", self._pairs(data.train), arrays, options, kind, name, criterion_options
        )

    def criterion(
        self,
        valid: Split,
        integrator: Literal["rk4", "map"] = "rk4",
        options: tuple[tuple[str, Any], ...] = (),
    ) -> tuple[tuple[np.ndarray, ...], Criterion, str, tuple[tuple[str, Any], ...]]:
        """``(arrays, criterion, name, criterion options)``: the validation arrays of the
        system's selection criterion (:attr:`hnnbench.System.selection`; docs/METRICS.md,
        "Checkpoint selection").

        ``field``: the inputs (the clean ones where the system adds noise) and targets
        in working coordinates, and for second-order families each point's
        :meth:`error_weights`, so every family's error is measured in the system's
        ``dx/dt``. ``rollout``: windows of ``selection_steps + 1`` consecutive
        validation states sharing only their ends, and their intervals; the error is
        taken on the positions, which every family's coordinates share."""
        if self.system.selection == "rollout":
            steps = int(self.system.selection_steps)
            z = self.to_model(valid.x)
            wrapped = tuple(self.system.wrapped_angles)
            for length in range(steps + 1, 1, -1):  # a short split: its longest windows
                windows = trajectory_windows(valid, z, length, wrapped, stride=length - 1)
                if windows[0].shape[0]:
                    break
            else:
                raise UnsupportedPair(
                    f"the {self.system.name} validation data has no 2 consecutive, equally "
                    "spaced samples of one trajectory, which its rollout criterion needs"
                )
            if integrator == "map":
                return windows, "windows:map", f"rollout_q_mse_{steps}", tuple(options)
            return (
                windows,
                "windows:rk4",
                f"rollout_q_mse_{steps}",
                (("substeps", CRITERION_RK4_SUBSTEPS),),
            )
        clean = CLEAN_INPUTS in valid.extras
        x = valid.extras[CLEAN_INPUTS] if clean else valid.x
        z, zdot = self._pairs_at(x, valid.dxdt)
        name = "field_mse_clean" if clean else "field_mse"
        weights = self.error_weights(z)
        if weights is None:
            return (z, zdot), "field", name, ()
        return (z, zdot, weights), "field:weighted", name, ()


def _validation(data: Dataset) -> Split:
    if data.valid is None:
        raise ValueError(
            "the dataset has no validation split: carve one with "
            "hnnbench.with_validation(data, seed)"
        )
    return data.valid


class CanonicalView(View):
    """The family works on ``(q, p)``."""


class VelocityView(View):
    """The family works on ``(q, q̇)``: states, targets and rates go through the system's
    kinematics."""

    def __init__(self, family: Family, system: System, kinematics: Kinematics) -> None:
        super().__init__(family, system)
        self.kinematics = kinematics

    def to_model(self, x: np.ndarray) -> np.ndarray:
        return self.kinematics.to_velocity(x)

    def from_model(self, z: np.ndarray) -> np.ndarray:
        return self.kinematics.to_canonical(z)

    def rate_out(self, z: np.ndarray, zdot: np.ndarray) -> np.ndarray:
        return self.kinematics.canonical_rate(z, zdot)

    def _pairs_at(self, x: np.ndarray, dxdt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.kinematics.to_velocity(x), self.kinematics.velocity_rate(x, dxdt)

    def error_weights(self, z: np.ndarray) -> Optional[np.ndarray]:
        z = np.asarray(z, dtype=np.float64)
        base = self.kinematics.canonical_rate(z, np.zeros_like(z))
        columns = []
        for j in range(z.shape[-1]):
            unit = np.zeros_like(z)
            unit[..., j] = 1.0
            columns.append(self.kinematics.canonical_rate(z, unit) - base)
        return np.stack(columns, axis=-1)


class PixelView(View):
    """The family is the latent dynamics of an autoencoder on observations.

    Inputs are flattened pairs of consecutive frames ``x``; the next input ``x'`` is
    ``extras["x_next"]`` (else ``x + dt * dxdt``). The autoencoder maps ``x`` to
    ``2n`` latents ``z = (z_q, z_p)``; the family's field ``f`` is trained per frame
    (``dt = 1``), so the model API reports ``f(z) / dt_frame`` and rolls out over
    ``t / dt_frame``. ``time_derivative``, ``rollout`` and ``energy`` act on latents;
    ``encode`` / ``decode`` map observations ``(N, D)`` to latents ``(N, 2n)`` and
    back. Training and reported losses are the 2019 objective (reconstruction +
    canonical-coordinates + 0.1 x one Euler step of the latent dynamics).
    """

    def __init__(self, family: Family, system: System) -> None:
        super().__init__(family, system)
        self.time_unit = 1.0

    @property
    def angles(self) -> tuple[int, ...]:
        """Latents are no angles."""
        return ()

    def set_frame_dt(self, data: Dataset) -> None:
        if "dt" not in data.meta:
            raise ConfigError(f"{self.system.name}: pixel datasets must record meta['dt']")
        self.time_unit = float(data.meta["dt"])

    def pairs(
        self, x: np.ndarray, dxdt: np.ndarray, extras: dict[str, np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(x, x_next)``: ``extras["x_next"]`` if present, else ``x + dt * dxdt``."""
        x_next = extras.get("x_next")
        if x_next is None:
            x_next = np.asarray(x) + self.time_unit * np.asarray(dxdt)
        return np.asarray(x), np.asarray(x_next)

    def problem(
        self,
        data: Dataset,
        window: int = 0,
        options: tuple[tuple[str, Any], ...] = (),
        integrator: Literal["rk4", "map"] = "rk4",
    ) -> Problem:
        """The 2019 objective's pairs; the validation criterion is the same objective
        per row (pixel frames are rendered, not measured: there is no input noise to
        average out) on at most :data:`VALID_POINTS` validation rows."""
        self.set_frame_dt(data)
        train = self.pairs(data.train.x, data.train.dxdt, data.train.extras)
        valid = _validation(data)
        sub = np.unique(np.linspace(0, len(valid) - 1, min(len(valid), VALID_POINTS)).astype(int))
        valid_pairs = self.pairs(
            valid.x[sub], valid.dxdt[sub], {k: v[sub] for k, v in valid.extras.items()}
        )
        return Problem("pixels", train, valid_pairs, (), "pixels", "pixel_objective")


def view_for(family: Family, system: System) -> View:
    """The view of ``family`` on ``system``; raises :class:`UnsupportedPair` where the
    system lacks what the family needs (callers check
    :func:`unsupported_reason` first)."""
    reason = unsupported_reason(family, system)
    if reason is not None:
        raise UnsupportedPair(reason)
    if system.observation == "pixels":
        return PixelView(family, system)
    if family.coordinates == "velocity":
        kinematics = system.kinematics()
        assert kinematics is not None
        return VelocityView(family, system, kinematics)
    return CanonicalView(family, system)


def unsupported_reason(family: Family, system: System) -> str | None:
    """Why ``family`` cannot run on ``system`` (``None`` if it can)."""
    observations: Sequence[str] = family.observations
    if system.observation not in observations:
        return (
            f"{system.observation} observations are not supported by the {family.name} "
            f"family (it runs on: {', '.join(observations)})"
        )
    if family.coordinates == "velocity" and system.kinematics() is None:
        return (
            f"the {family.name} family works in velocity coordinates (q, q̇) and "
            f"{system.name} declares no kinematics (System.kinematics)"
        )
    return None
