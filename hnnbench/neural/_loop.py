"""The training loop of every neural model, written once for every backend.

A backend supplies a :class:`Trainer`: it owns the parameters and optimizer state of
``S`` seeds (``S = 1`` for an ordinary job) and runs one *chunk* of optimizer steps at
a time (a compiled ``lax.scan`` in JAX, a Python loop in torch). This module does the
rest, identically for every backend and family:

- the chunk plan: one chunk per loss record (``NeuralConfig.log_interval``);
- the learning rate of every step (:func:`lr_factors` of ``NeuralConfig.lr_schedule``),
  handed to the backend with each chunk;
- the minibatch indices of every seed, drawn on the host from its own
  :class:`~hnnbench.neural._init.BatchStream` (the next chunk's while the current one
  runs), so a seed trained in a batch of seeds sees exactly the minibatches it sees
  alone;
- the loss history of each seed (training loss, and validation loss after each
  chunk) and progress reports;
- checkpoint selection (docs/METRICS.md, "Checkpoint selection"): after each chunk
  the backend returns each seed's validation criterion per point or window (the
  system's criterion, :attr:`hnnbench.System.selection`, the same for every family); a
  seed whose criterion is finite and below its best so far has its weights kept
  (``Trainer.keep``). At the end the last checkpoint is scored unless the lowest one
  beats it by more than :data:`~hnnbench._contracts.plugin.SELECTION_Z` paired standard
  errors (the checkpoints share the points); :class:`~hnnbench.Selection` says which
  step it is, and what the late (80 %) checkpoint says of convergence;
- divergence: a seed whose training or validation loss becomes non-finite stops
  training at that chunk; it is *diverged* only if no checkpoint was kept before
  (its validation loss was never finite), and otherwise keeps its lowest checkpoint
  (the reason it stopped is recorded). Training ends when every seed has stopped;
- stopping early: a progress callback that returns ``True`` (a tuner's pruner) stops
  every seed after that chunk, each with its selected checkpoint and the reason
  (:data:`hnnbench._contracts.plugin.STOPPED_BY_CALLER`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Optional, Protocol

import numpy as np

from hnnbench._contracts.plugin import (
    HISTORY_STEP,
    HISTORY_TRAIN,
    HISTORY_VALID,
    LATE_FRACTION,
    SELECTION_Z,
    STOPPED_BY_CALLER,
    Progress,
    Selection,
    TrainSettings,
)
from hnnbench.neural._init import BatchStream

__all__ = [
    "ONE_CYCLE_FLOOR",
    "ONE_CYCLE_START",
    "SeedFit",
    "Trainer",
    "chunk_lengths",
    "lr_factors",
    "train",
]

#: The one-cycle schedule (:func:`lr_factors`): where on its sin² cycle it starts (a
#: fraction of the cycle) and its floor (a fraction of the peak ``lr``). The shape of the
#: schedule in the LNN paper's published double-pendulum notebook
#: (github.com/MilesCranmer/lagrangian_nns, notebooks/DoublePendulum.ipynb): starts at
#: sin²(0.2π) ≈ 0.35 of the peak, peaks at 3/8 of training, ends at 1e-4 of the peak.
ONE_CYCLE_START = 0.2
ONE_CYCLE_FLOOR = 1e-4


class Trainer(Protocol):
    """A backend's training state for ``S`` seeds."""

    def run_chunk(
        self, indices: Optional[np.ndarray], length: int, lrs: Optional[np.ndarray]
    ) -> tuple[Any, Any]:
        """Run ``length`` optimizer steps.

        Args:
            indices: ``(S, length, batch)`` minibatch row indices, or ``None`` (every
                step uses the whole training set).
            length: steps in this chunk.
            lrs: ``(length,)`` float64, the learning rate of each step (every seed's),
                or ``None``: the settings' constant ``lr`` at every step.

        Returns:
            ``(losses, criterion)``, array-likes of shape ``(S, length)`` (each step's
            training loss, taken before its update) and ``(S, V)`` (the validation
            criterion after the chunk at each of its ``V`` points or windows; ``(S,)``
            counts as one point: the paired standard errors are then undefined).
            They may be device arrays still being computed: the loop converts them
            with ``numpy.asarray`` after drawing the next chunk's indices.
        """
        ...

    def keep(self, seeds: np.ndarray) -> None:
        """Keep the current weights of the seeds where ``seeds`` (``(S,)`` bool) is
        true as their selected checkpoint; the backend's ``weights`` returns the kept
        weights of each seed (its current ones where none was kept)."""
        ...


@dataclass
class SeedFit:
    """The training log of one seed.

    Attributes:
        history: ``{"step": [...], "train_loss": [...], "val_loss": [...]}``.
        steps: optimizer steps run.
        diverged: why training diverged (``None`` if it did not).
        selection: the kept checkpoint (``None`` when none was: diverged).
    """

    history: dict[str, list[float]] = field(
        default_factory=lambda: {HISTORY_STEP: [], HISTORY_TRAIN: [], HISTORY_VALID: []}
    )
    steps: int = 0
    diverged: Optional[str] = None
    selection: Optional[Selection] = None


def chunk_lengths(steps: int, interval: int) -> list[int]:
    """``steps`` cut into chunks of ``interval`` steps (the last one shorter)."""
    lengths = [interval] * (steps // interval)
    if steps % interval:
        lengths.append(steps % interval)
    return lengths


def lr_factors(schedule: str, steps: int) -> np.ndarray:
    """The learning rate of each of ``steps`` steps as a fraction of ``lr``, ``(steps,)``.

    ``constant``: 1 at every step. ``one_cycle``: at step ``k`` (0-based, training
    fraction ``f = k / steps``), ``c + (1 - c) · sin²(π (a + (1 - a) f))`` with
    ``a`` = :data:`ONE_CYCLE_START` and ``c`` = :data:`ONE_CYCLE_FLOOR`: up from
    ``sin²(πa)`` to the peak 1 at ``f = (1/2 - a) / (1 - a)``, then down to ``c``.
    """
    if schedule == "constant":
        return np.ones(steps)
    if schedule != "one_cycle":
        raise ValueError(f"unknown learning-rate schedule '{schedule}'")
    f = np.arange(steps, dtype=np.float64) / max(steps, 1)
    a, c = ONE_CYCLE_START, ONE_CYCLE_FLOOR
    return c + (1.0 - c) * np.sin(np.pi * (a + (1.0 - a) * f)) ** 2


@dataclass
class _Track:
    """One seed's checkpoints on the criterion: the lowest so far, the late one (at or
    before ``(1 - LATE_FRACTION)`` of the steps) and the last, each ``(step, values)``
    with ``values`` the criterion per validation point."""

    best: Optional[tuple[int, np.ndarray]] = None
    late: Optional[tuple[int, np.ndarray]] = None
    last: Optional[tuple[int, np.ndarray]] = None


def paired_se(a: np.ndarray, b: np.ndarray) -> float:
    """The standard error of ``mean(a - b)`` for per-point values of two checkpoints on
    the same points (NaN for fewer than two points)."""
    diff = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    if diff.size < 2 or not np.all(np.isfinite(diff)):
        return math.nan
    return float(np.std(diff, ddof=1) / math.sqrt(diff.size))


def _selection(
    track: _Track,
    evaluations: int,
    first_step: int,
    criterion: Optional[str],
    stopped: Optional[str],
    last_available: bool,
) -> tuple[Selection, bool]:
    """The scored checkpoint of a seed (the rule of
    :data:`~hnnbench._contracts.plugin.SELECTION_RULE`) and whether it is the last one.
    ``last_available``: the trainer still holds the last checkpoint's weights (not so
    after a non-finite loss: then the lowest one is scored)."""
    assert track.best is not None and track.last is not None
    (best_step, best), (last_step, last) = track.best, track.last
    best_value, last_value = float(np.mean(best)), float(np.mean(last))
    final_se = paired_se(last, best)
    earlier = best_step != last_step and (
        not last_available
        or not math.isfinite(final_se)
        or last_value - best_value > SELECTION_Z * final_se
    )
    step, value = (best_step, best_value) if earlier else (last_step, last_value)
    late_step, late_value, late_se = None, math.nan, math.nan
    if track.late is not None:
        late_step, late_values = track.late
        late_value = float(np.mean(late_values))
        late_se = paired_se(late_values, last)
    return Selection(
        step,
        value,
        evaluations,
        first_step,
        stopped,
        criterion,
        int(np.size(last)),
        best_step,
        best_value,
        last_step,
        last_value,
        final_se,
        late_step,
        late_value,
        late_se,
    ), not earlier


def train(
    trainer: Trainer,
    n_train: int,
    settings: TrainSettings,
    seeds: Sequence[int],
    interval: int,
    progress: Progress,
    schedule: str = "constant",
    criterion: Optional[str] = None,
) -> list[SeedFit]:
    """Train every seed of ``trainer`` for ``settings.steps`` steps, the learning rate
    following ``schedule`` (:func:`lr_factors`); one :class:`SeedFit` per seed, in
    ``seeds`` order. ``criterion``: the name of the validation criterion the trainer
    returns (recorded in each :class:`~hnnbench.Selection`)."""
    rates = None if schedule == "constant" else settings.lr * lr_factors(schedule, settings.steps)
    batch = settings.batch_size
    streams = (
        None
        if batch is None or batch >= n_train
        else [BatchStream(seed, n_train, int(batch)) for seed in seeds]
    )

    def draw(length: int) -> Optional[np.ndarray]:
        if streams is None:
            return None
        return np.stack([stream.block(length) for stream in streams])

    fits = [SeedFit() for _ in seeds]
    tracks = [_Track() for _ in seeds]
    stopped: list[Optional[str]] = [None] * len(seeds)
    first_step: Optional[int] = None
    lengths = chunk_lengths(settings.steps, interval)
    late_at = settings.steps * (1.0 - LATE_FRACTION)
    step = 0
    indices = draw(lengths[0])
    for k, length in enumerate(lengths):
        lrs = None if rates is None else rates[step : step + length]
        losses_out, valid_out = trainer.run_chunk(indices, length, lrs)
        if k + 1 < len(lengths):  # drawn while an asynchronous backend computes
            indices = draw(lengths[k + 1])
        losses = np.asarray(losses_out, dtype=np.float64).reshape(len(seeds), length)
        points = np.asarray(valid_out, dtype=np.float64).reshape(len(seeds), -1)
        valids = np.mean(points, axis=1)
        step += length
        first_step = step if first_step is None else first_step
        live, improved = [], np.zeros(len(seeds), dtype=bool)
        for s, fit in enumerate(fits):
            if stopped[s] is not None:
                continue
            fit.steps = step
            train_loss, valid_loss = float(losses[s, -1]), float(valids[s])
            fit.history[HISTORY_STEP].append(step)
            fit.history[HISTORY_TRAIN].append(train_loss)
            fit.history[HISTORY_VALID].append(valid_loss)
            if np.all(np.isfinite(losses[s])) and np.isfinite(valid_loss):
                live.append(s)
                track = tracks[s]
                track.last = (step, points[s].copy())
                if step <= late_at:
                    track.late = track.last
                if track.best is None or valid_loss < float(np.mean(track.best[1])):
                    track.best, improved[s] = track.last, True
                continue
            bad = np.flatnonzero(~np.isfinite(losses[s]))
            at = step - length + 1 + int(bad[0]) if bad.size else step
            value = losses[s, bad[0]] if bad.size else valid_loss
            kind = "training" if bad.size else "validation"
            stopped[s] = f"{kind} loss became {value} at step {at}"
        if improved.any():
            trainer.keep(improved)
        shown = live or list(range(len(seeds)))
        stop = progress(
            step,
            {
                HISTORY_TRAIN: float(np.mean(losses[shown, -1])),
                HISTORY_VALID: float(np.mean(valids[shown])),
            },
        )
        if stop is True and live and k + 1 < len(lengths):
            for s in live:
                stopped[s] = f"{STOPPED_BY_CALLER} at step {step} (a tuner's pruner)"
            break
        if not live:
            break
    final = np.zeros(len(seeds), dtype=bool)
    for s, fit in enumerate(fits):
        evaluations = len(fit.history[HISTORY_STEP])
        if tracks[s].best is None:
            fit.diverged = stopped[s] or "the validation loss was never finite"
            continue
        assert first_step is not None
        # The trainer's current weights are the last checkpoint's unless a loss became
        # non-finite after it.
        why = stopped[s]
        available = why is None or why.startswith(STOPPED_BY_CALLER)
        fit.selection, final[s] = _selection(
            tracks[s], evaluations, first_step, criterion, stopped[s], available
        )
    # Keep the last checkpoint where the rule scores it and it is not kept yet.
    latest = np.array(
        [
            final[s] and tracks[s].best is not None and tracks[s].best[0] != tracks[s].last[0]  # type: ignore[index]
            for s in range(len(seeds))
        ]
    )
    if latest.any():
        trainer.keep(latest)
    return fits
