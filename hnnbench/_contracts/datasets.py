"""Dataset scaffolding shared by systems: seed streams (:func:`seed_stream`, one generator
per purpose: :data:`DATA_STREAM`, :data:`EVAL_STREAM`, :data:`SPLIT_STREAM`,
:data:`VALID_STREAM`), the train/test split of whole trajectories
(:class:`TrajectorySplit`, :func:`trajectory_dataset`), and the validation split carved
from training data by one rule (:func:`with_validation`; docs/PLUGINS.md, "2. Write a
system"; docs/METRICS.md, "Validation and the scored checkpoint").
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal, Optional

import numpy as np

from hnnbench._contracts.errors import ConfigError
from hnnbench._contracts.plugin import Dataset, Split

__all__ = [
    "DATA_STREAM",
    "EVAL_STREAM",
    "SPLIT_STREAM",
    "TrajectoryIndices",
    "TrajectorySplit",
    "MIN_VALID_TRAJECTORIES",
    "VALID_FRACTION",
    "VALID_STREAM",
    "seed_stream",
    "trajectory_dataset",
    "validation_rule",
    "with_validation",
]

#: Stream tag of the training/test data (initial states, then input noise).
DATA_STREAM = 0
#: Stream tag of the evaluation trajectories.
EVAL_STREAM = 1
#: Stream tag of the shuffled train/test assignment (``test_from="shuffled"``).
SPLIT_STREAM = 3

#: Stream tag of the validation trajectories (:func:`with_validation`).
VALID_STREAM = 4
#: The share of the training data held out for validation.
VALID_FRACTION = 0.1
#: Fewest training trajectories from which whole trajectories are held out; below it,
#: the tail of each trajectory is.
MIN_VALID_TRAJECTORIES = 10

#: Where the test trajectories come from (:attr:`TrajectorySplit.test_from`).
TestFrom = Literal["first", "last", "shuffled"]
#: Which of the two counts :func:`round` gives (:attr:`TrajectorySplit.rounding`).
Rounding = Literal["test", "train"]
_TEST_FROM: tuple[str, ...] = ("first", "last", "shuffled")
_ROUNDING: tuple[str, ...] = ("test", "train")


def seed_stream(seed: int, stream: int) -> np.random.Generator:
    """The generator of stream ``stream`` of job seed ``seed``:
    ``np.random.default_rng((seed, stream))``.

    Args:
        seed: the job's seed (an integer >= 0).
        stream: the stream tag, :data:`DATA_STREAM`, :data:`EVAL_STREAM`,
            :data:`SPLIT_STREAM` or a system's own tag.

    Returns:
        A fresh generator; two calls with the same arguments draw the same numbers.
    """
    return np.random.default_rng((seed, int(stream)))


@dataclass(frozen=True)
class TrajectoryIndices:
    """Which trajectories each split holds.

    Attributes:
        train: ``(n_train,)`` trajectory indices, ascending.
        test: ``(n_test,)`` trajectory indices, ascending, disjoint from ``train``.
    """

    train: np.ndarray
    test: np.ndarray


@dataclass(frozen=True)
class TrajectorySplit:
    """The rule that assigns whole trajectories to train and test.

    Attributes:
        test_fraction: the share of the trajectories that test, strictly between 0 and 1
            (a system's ``test_split`` setting).
        test_from: which trajectories test. ``"first"``: indices ``0 .. n_test - 1``;
            ``"last"``: the last ``n_test``; ``"shuffled"``: ``n_test`` indices drawn
            without replacement from :data:`SPLIT_STREAM` of the seed
            (``seed_stream(seed, SPLIT_STREAM).permutation(n_traj)[:n_test]``). Either way
            the rest train, and both keep the trajectories in ascending order.
        rounding: which count :func:`round` (Python's, half to even) gives. ``"test"``:
            ``n_test = round(n_traj * test_fraction)``, ``n_train = n_traj - n_test``;
            ``"train"``: ``n_train = round(n_traj * (1 - test_fraction))``,
            ``n_test = n_traj - n_train``. The two differ only when the product falls on
            (or, in floating point, next to) a half: e.g. 5 trajectories at 0.3 test 2
            with ``"test"`` and 1 with ``"train"``.
    """

    test_fraction: float
    test_from: TestFrom
    rounding: Rounding = "test"

    def __post_init__(self) -> None:
        if self.test_from not in _TEST_FROM:
            raise ValueError(
                f"TrajectorySplit.test_from={self.test_from!r} is invalid: expected one of "
                f"{', '.join(map(repr, _TEST_FROM))}."
            )
        if self.rounding not in _ROUNDING:
            raise ValueError(
                f"TrajectorySplit.rounding={self.rounding!r} is invalid: expected one of "
                f"{', '.join(map(repr, _ROUNDING))}."
            )

    def sizes(self, n_traj: int) -> tuple[int, int]:
        """``(n_train, n_test)`` for ``n_traj`` trajectories (not checked for emptiness)."""
        if self.rounding == "train":
            n_train = round(n_traj * (1 - self.test_fraction))
            return n_train, n_traj - n_train
        n_test = round(n_traj * self.test_fraction)
        return n_traj - n_test, n_test

    def check(
        self,
        n_traj: int,
        *,
        fraction_key: str = "test_split",
        count_key: str = "n_traj",
        unit: str = "trajectories",
        owner: str = "system",
    ) -> None:
        """Raise a one-line :class:`ConfigError` if train or test would be empty.

        For a config's ``validate``: the message names the settings,
        ``{owner}.{fraction_key}`` (this rule's fraction) and ``{owner}.{count_key}``
        (``n_traj``), and says to use more ``unit`` or another split.
        """
        if not 0 < self.sizes(n_traj)[1] < n_traj:
            raise ConfigError(
                f"{owner}.{fraction_key}={self.test_fraction} with {owner}.{count_key}="
                f"{n_traj} leaves an empty train or test set: use more {unit} or another "
                "split."
            )

    def indices(self, n_traj: int, seed: Optional[int] = None) -> TrajectoryIndices:
        """The trajectory indices of each split.

        Args:
            n_traj: number of trajectories (``>= 2``).
            seed: the job's seed; required for ``test_from="shuffled"``, unused otherwise.

        Raises:
            ConfigError: train or test would be empty (too few trajectories for the
                fraction), or ``"shuffled"`` without a seed.
        """
        n_train, n_test = self.sizes(n_traj)
        if not 0 < n_test < n_traj:
            raise ConfigError(
                f"A test fraction of {self.test_fraction} (rounding the {self.rounding} "
                f"count) of {n_traj} trajectories leaves an empty train or test set "
                f"({n_train} train, {n_test} test): use more trajectories or another "
                "test fraction."
            )
        order = np.arange(n_traj)
        if self.test_from == "shuffled":
            if seed is None:
                raise ConfigError(
                    'TrajectorySplit(test_from="shuffled") draws the test trajectories from '
                    "the job's seed: pass seed=<the seed of dataset()>."
                )
            test = np.sort(seed_stream(seed, SPLIT_STREAM).permutation(n_traj)[:n_test])
            train = np.setdiff1d(order, test, assume_unique=True)
        elif self.test_from == "first":
            test, train = order[:n_test], order[n_test:]
        else:
            train, test = order[:n_train], order[n_train:]
        return TrajectoryIndices(train=train, test=test)


def trajectory_dataset(
    x: np.ndarray,
    dxdt: np.ndarray,
    t: np.ndarray,
    split: TrajectorySplit,
    *,
    seed: Optional[int] = None,
    extras: Optional[Mapping[str, np.ndarray]] = None,
    meta: Optional[Mapping[str, Any]] = None,
) -> Dataset:
    """A :class:`Dataset` of whole trajectories, split into train and test by ``split``.

    Each split's points are its trajectories in ascending index order, each trajectory's
    points in time order: point ``k * n_points + j`` of a split is sample ``j`` of its
    ``k``-th trajectory. Every array is copied (C-contiguous) and keeps its dtype.

    Args:
        x: ``(n_traj, n_points, D)`` model inputs (states ``D = 2n`` in the system's
            units, or flattened observations), noise included.
        dxdt: ``(n_traj, n_points, D)`` targets, the time derivative of ``x`` (state
            units per time unit).
        t: ``(n_points,)`` sample times shared by all trajectories, or
            ``(n_traj, n_points)`` per trajectory (the system's time units).
        split: which trajectories test (:class:`TrajectorySplit`).
        seed: the job's seed; needed only by ``split.test_from == "shuffled"``.
        extras: further per-point arrays, each ``(n_traj, n_points, ...)`` (e.g. the
            true states behind pixel observations); split like ``x``.
        meta: ``Dataset.meta``, stored as given (JSON-serialisable).

    Returns:
        The dataset: ``Split.x`` and ``Split.dxdt`` ``(n * n_points, D)``, ``Split.traj``
        ``(n * n_points,)`` the trajectory's index in ``x`` (0 .. n_traj - 1),
        ``Split.t`` ``(n * n_points,)``, extras ``(n * n_points, ...)``, with ``n`` the
        split's number of trajectories (:meth:`TrajectorySplit.sizes`).

    Raises:
        ValueError: the arrays' leading shapes disagree.
        ConfigError: train or test would be empty (see :meth:`TrajectorySplit.indices`).
    """
    if x.ndim < 2:
        raise ValueError(f"x must be shaped (n_traj, n_points, ...), got shape {x.shape}.")
    n_traj, n_points = x.shape[:2]
    extras = dict(extras or {})
    for name, value in {"dxdt": dxdt, **{f"extras[{k!r}]": v for k, v in extras.items()}}.items():
        if value.shape[:2] != (n_traj, n_points):
            raise ValueError(
                f"{name} must be shaped ({n_traj}, {n_points}, ...) like x, got shape "
                f"{value.shape}."
            )
    times = np.broadcast_to(t, (n_traj, n_points))
    ids = np.broadcast_to(np.arange(n_traj)[:, None], (n_traj, n_points))
    chosen = split.indices(n_traj, seed)

    def take(a: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """``a[rows]`` with the trajectory and time axes merged (a fresh C array)."""
        picked = np.ascontiguousarray(a[rows])
        return picked.reshape(len(rows) * n_points, *a.shape[2:])

    def make(rows: np.ndarray) -> Split:
        return Split(
            x=take(x, rows),
            dxdt=take(dxdt, rows),
            traj=take(ids, rows),
            t=take(times, rows),
            extras={key: take(value, rows) for key, value in extras.items()},
        )

    return Dataset(train=make(chosen.train), test=make(chosen.test), meta=dict(meta or {}))


def validation_rule(data: Dataset) -> str:
    """The rule :func:`with_validation` applies to ``data``, in words (for records)."""
    n = len(np.unique(data.train.traj))
    if n >= MIN_VALID_TRAJECTORIES:
        return (
            f"{VALID_FRACTION:g} of the {n} training trajectories, whole, drawn from "
            f"seed stream {VALID_STREAM}"
        )
    return (
        f"the last {VALID_FRACTION:g} of the points of each of the {n} training "
        "trajectories (time order)"
    )


def _subset(split: Split, rows: np.ndarray) -> Split:
    return Split(
        x=split.x[rows],
        dxdt=split.dxdt[rows],
        traj=split.traj[rows],
        t=split.t[rows],
        extras={k: v[rows] for k, v in split.extras.items()},
    )


def with_validation(data: Dataset, seed: int) -> Dataset:
    """``data`` with a validation split carved from its training split (the rule of
    the module docstring); ``test`` and ``meta`` are unchanged, and the points of each
    part keep their order.

    Args:
        data: a system's dataset (``data.valid`` must be ``None``).
        seed: the job's seed (the draw of the validation trajectories).

    Raises:
        ValueError: ``data`` already has a validation split, or its training split has
            fewer than two points.
    """
    if data.valid is not None:
        raise ValueError("the dataset already has a validation split")
    train = data.train
    ids = np.asarray(train.traj)
    unique = np.unique(ids)
    if len(unique) >= MIN_VALID_TRAJECTORIES:
        n_valid = max(1, round(VALID_FRACTION * len(unique)))
        chosen = np.sort(seed_stream(seed, VALID_STREAM).permutation(unique)[:n_valid])
        held = np.isin(ids, chosen)
    else:
        if len(train) < 2:
            raise ValueError(
                f"a training split of {len(train)} point(s) leaves no "
                "validation: a system needs at least 2 training points"
            )
        held = np.zeros(len(train), dtype=bool)
        times = np.asarray(train.t)
        for traj in unique:
            rows = np.flatnonzero(ids == traj)
            rows = rows[np.argsort(times[rows], kind="stable")]
            k = min(max(1, round(VALID_FRACTION * len(rows))), len(rows) - 1)
            if k > 0:
                held[rows[len(rows) - k :]] = True
        if held.all() or not held.any():  # one single-point trajectory, or none held
            held[:] = False
            held[-1] = True
    return dataclasses.replace(
        data,
        train=_subset(train, np.flatnonzero(~held)),
        valid=_subset(train, np.flatnonzero(held)),
    )
