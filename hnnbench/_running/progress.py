"""Progress display for training runs.

On a terminal: a tqdm bar per run with the current losses. Elsewhere (CI logs, Slurm
output files): a log line at every quarter of the run. ``HNNBENCH_PROGRESS=bar|log|off``
forces a mode. Every few seconds an update also checks that the ``hnnbench`` command
which started the job still exists (:func:`hnnbench._running.launch_context.abandoned`).

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
from typing import Optional

from hnnbench._running import launch_context

log = logging.getLogger("hnnbench")
#: Seconds between two checks for an abandoned job.
CHECK_EVERY_S = 5.0

__all__ = ["Observer", "TrainingProgress", "observing"]

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


class TrainingProgress:
    """Context manager; pass :meth:`update` to ``Model.fit`` as its ``progress``."""

    def __init__(self, label: str, total: int) -> None:
        self.label = label
        self.total = max(int(total), 1)
        mode = os.environ.get("HNNBENCH_PROGRESS", "")
        if mode not in ("bar", "log", "off"):
            mode = "bar" if sys.stderr.isatty() else "log"
        self.mode = mode
        self._bar = None
        self._last = 0
        self._next_log = self.total // 4
        self._next_check = time.monotonic() + CHECK_EVERY_S

    def __enter__(self) -> TrainingProgress:
        if self.mode == "bar":
            from tqdm.auto import tqdm

            self._bar = tqdm(total=self.total, desc=self.label, leave=False, dynamic_ncols=True,
                             unit="step")
        return self

    def update(self, step: int, losses: Mapping[str, float]) -> Optional[bool]:
        """Show the update; return the observer's answer (``True``: stop training)."""
        if time.monotonic() >= self._next_check:
            self._next_check = time.monotonic() + CHECK_EVERY_S
            if launch_context.abandoned():
                # A launcher worker whose command was killed alone: nothing waits for
                # this job or this process. Exit now; no record, so a re-run redoes it.
                log.warning("%s: the hnnbench command that started this job has gone; "
                            "exiting (re-run the command to resume the sweep)", self.label)
                logging.shutdown()
                os._exit(130)
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
        self, exc_type: type[BaseException] | None, exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self._bar is not None:
            self._bar.close()
