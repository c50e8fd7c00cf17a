"""Progress display for training runs and their evaluation.

On a terminal: a tqdm bar per run with the current losses, then one over the metrics of
its evaluation. Elsewhere (CI logs, Slurm output files): a log line at every quarter of
the run, then one per metric evaluated, with its seconds (:class:`EvaluationProgress`).
``HNNBENCH_PROGRESS=bar|log|off`` forces a mode. Every few seconds an update also checks
that the ``hnnbench`` command which started the job still exists
(:func:`hnnbench._running.launch_context.abandoned`).

An observer (:func:`observing`, this process's jobs only) sees every update and may ask
training to stop: ``hnnbench tune`` reports each validation loss to its pruner this way
(:mod:`hnnbench._tuning`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from types import TracebackType
from typing import Any, Optional

from hnnbench._running import launch_context

log = logging.getLogger("hnnbench")
#: Seconds between two checks for an abandoned job.
CHECK_EVERY_S = 5.0
#: A metric that takes at least this many seconds gets a log line of its own (the
#: quick ones stay silent: a sweep's log is not a list of every metric of every job).
LOG_METRIC_S = 1.0

__all__ = ["EvaluationProgress", "Observer", "TrainingProgress", "observing"]

#: ``observer(step, losses) -> stop``: sees every training update of this process's
#: jobs; ``True`` asks the model to stop training (:data:`hnnbench.Progress`).
Observer = Callable[[int, Mapping[str, float]], Optional[bool]]
_observer: Optional[Observer] = None


@contextlib.contextmanager
def observing(observer: Observer) -> Iterator[None]:
    """Hand every training update of the jobs run in this process (in this block) to
    ``observer``, whose answer is the progress callback's (``True``: stop)."""
    global _observer
    previous, _observer = _observer, observer
    try:
        yield
    finally:
        _observer = previous


def _mode() -> str:
    """``bar``, ``log`` or ``off``: ``$HNNBENCH_PROGRESS``, else a bar on a terminal."""
    mode = os.environ.get("HNNBENCH_PROGRESS", "")
    if mode not in ("bar", "log", "off"):
        mode = "bar" if sys.stderr.isatty() else "log"
    return mode


def _exit_if_abandoned(label: str) -> None:
    """A launcher worker whose command was killed alone: nothing waits for this job or
    this process. Exit now; no record, so a re-run redoes it."""
    if launch_context.abandoned():
        log.warning(
            "%s: the hnnbench command that started this job has gone; "
            "exiting (re-run the command to resume the sweep)",
            label,
        )
        logging.shutdown()
        os._exit(130)


class TrainingProgress:
    """Context manager; pass :meth:`update` to ``Model.fit`` as its ``progress``."""

    def __init__(self, label: str, total: int) -> None:
        self.label = label
        self.total = max(int(total), 1)
        self.mode = _mode()
        self._bar = None
        self._last = 0
        self._next_log = self.total // 4
        self._next_check = time.monotonic() + CHECK_EVERY_S

    def __enter__(self) -> TrainingProgress:
        if self.mode == "bar":
            from tqdm.auto import tqdm

            self._bar = tqdm(
                total=self.total, desc=self.label, leave=False, dynamic_ncols=True, unit="step"
            )
        return self

    def update(self, step: int, losses: Mapping[str, float]) -> Optional[bool]:
        """Show the update; return the observer's answer (``True``: stop training)."""
        if time.monotonic() >= self._next_check:
            self._next_check = time.monotonic() + CHECK_EVERY_S
            _exit_if_abandoned(self.label)
        if self._bar is not None:
            self._bar.update(step - self._last)
            self._bar.set_postfix({k: f"{v:.3g}" for k, v in losses.items()}, refresh=False)
        elif self.mode == "log" and step >= self._next_log and step < self.total:
            text = "  ".join(f"{k}={v:.3g}" for k, v in losses.items())
            log.info("  %s step %d/%d  %s", self.label, step, self.total, text)
            self._next_log += max(self.total // 4, 1)
        self._last = step
        return None if _observer is None else _observer(step, losses)

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._bar is not None:
            self._bar.close()


class EvaluationProgress:
    """Context manager; pass :meth:`update` to :func:`hnnbench._running.evaluation.evaluate` as its
    ``progress``: called with ``(metric, index, total, None)`` when a metric that applies
    starts and ``(metric, index, total, seconds)`` when it is done. A bar shows the metric
    being computed; a log says when the evaluation starts (``spring/hnn_jax s0
    evaluation: 10 metrics``) and gives each metric that took :data:`LOG_METRIC_S` or more
    a line (``spring/hnn_jax s0 evaluation 4/10 energy_mse 4.2 s``), so a long
    evaluation (rollouts of many trajectories) is never silent."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.mode = _mode()
        self._bar: Optional[object] = None
        self._next_check = time.monotonic() + CHECK_EVERY_S

    def __enter__(self) -> EvaluationProgress:
        return self

    def update(self, metric: str, index: int, total: int, seconds: Optional[float]) -> None:
        """Show that ``metric`` (the ``index``-th of ``total`` that apply) started
        (``seconds`` None) or is done."""
        if time.monotonic() >= self._next_check:
            self._next_check = time.monotonic() + CHECK_EVERY_S
            _exit_if_abandoned(self.label)
        if self.mode == "bar":
            from tqdm.auto import tqdm

            if self._bar is None:
                self._bar = tqdm(
                    total=total,
                    desc=f"{self.label} evaluation",
                    leave=False,
                    dynamic_ncols=True,
                    unit="metric",
                )
            bar: Any = self._bar
            if seconds is None:
                bar.set_postfix_str(metric, refresh=True)
            else:
                bar.update(1)
        elif self.mode == "log":
            if seconds is None and index == 1:
                log.info("  %s evaluation: %d metrics", self.label, total)
            elif seconds is not None and seconds >= LOG_METRIC_S:
                log.info(
                    "  %s evaluation %d/%d %s %.1f s", self.label, index, total, metric, seconds
                )

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._bar is not None:
            bar: Any = self._bar
            bar.close()
