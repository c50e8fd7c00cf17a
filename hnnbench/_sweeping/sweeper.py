"""hnnbench's Hydra sweeper: Hydra's basic sweeper without its per-job recomposition,
holding the sweep's lock, printing progress, and collecting every job's outcomes
from any launcher.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Optional

from hnnbench._running import launch_context
from hnnbench._running.hydra_private import (
    HydraSweeper,
    basic_sweeper_class,
    runs_in_process,
    waiting_for_every_submitit_job,
)
from hnnbench._sweeping import eta
from hnnbench._sweeping.lock import sweep_lock

log = logging.getLogger("hnnbench")

__all__ = ["Sweeper"]


class Sweeper(HydraSweeper):
    """Hydra's basic sweeper (same job order, batches and ``hydra.sweeper.params``),
    minus its per-job recomposition to validate each batch: :func:`plan` has composed
    and validated every swept value before Hydra starts, so each job's config is
    composed once, by the launcher. It holds the sweep directory's lock
    (:func:`sweep_lock`) while the sweep runs, and hands the jobs' outcomes (the task's
    return values, from whichever launcher ran them) to the command's launch context
    after each batch; a job that returned none (it raised, or its worker died) is
    reported as lost, and the sweep goes on. Under a launcher that runs jobs in other
    processes it also exports the launch context to them
    (:func:`hnnbench._running.launch_context.exported`).

    It wraps a basic sweeper rather than subclassing it: Hydra's plugin scan executes
    its module again, which would leave a subclass with a stale base."""

    def __init__(
        self, max_batch_size: Optional[int] = None, params: Optional[dict[str, str]] = None
    ) -> None:
        self._args = (max_batch_size, params)
        self._basic: Any = None
        self._config: Any = None
        self._progress: Optional[eta.SweepProgress] = None

    def setup(self, *, hydra_context: Any, task_function: Any, config: Any) -> None:
        self._basic = basic_sweeper_class()(*self._args)
        self._basic.validate_batch_is_legal = lambda batch: None  # validated by plan()
        self._basic.setup(hydra_context=hydra_context, task_function=task_function, config=config)
        self._config = config
        launcher = self._basic.launcher
        launch_batch = launcher.launch

        def launch_and_collect(job_overrides: Any, initial_job_idx: int) -> Any:
            if self._progress is not None:
                self._started(job_overrides)
            with waiting_for_every_submitit_job(launcher):
                results = launch_batch(job_overrides, initial_job_idx=initial_job_idx)
            for overrides, job in zip(job_overrides, results, strict=False):
                _collect(job, overrides)
            return results

        launcher.launch = launch_and_collect

    def __getstate__(self) -> dict[str, Any]:
        # A submitit launcher pickles itself for its tasks, with this sweeper (its
        # launch method is wrapped here); the progress thread stays in the command.
        return {**self.__dict__, "_progress": None}

    def sweep(self, arguments: list[str]) -> Any:
        context = launch_context.current()
        pinned = (context.pinned or {}) if context is not None else {}
        arguments = [pinned.get(arg, arg) for arg in arguments]  # Plan.pinned
        directory = Path(str(self._config.hydra.sweep.dir))
        # Progress lines with an ETA, for the hnnbench command and API (hnnbench._sweeping.eta).
        self._progress = (
            None
            if context is None
            else eta.SweepProgress(
                directory,
                default_profile=str(self._config.profile.name),
                costs=eta.load_costs(),
                on_new=lambda: _partial_report(directory),
            )
        )
        # Jobs in this process read the context set here; a launcher's other processes
        # read it from the environment.
        exported = None if runs_in_process(self._basic.launcher) else context
        try:
            with (
                sweep_lock(directory, context.command if context is not None else None),
                launch_context.exported(exported),
            ):
                return self._basic.sweep(arguments)
        finally:
            if self._progress is not None:
                self._progress.stop()

    def _started(self, batch: Sequence[Sequence[str]]) -> None:
        """A batch is about to launch: watch for its jobs' records, and on the first
        batch say what the jobs that will run (not those kept from an earlier run) took
        when published, and what that estimate rests on; nothing when none will run."""
        assert self._progress is not None
        first = not self._progress.started
        self._progress.add([list(o) for o in batch])
        todo = [list(o) for o in batch if not self._progress.kept(list(o))]
        if first and todo:
            keys = [eta.job_key(o, self._progress.default_profile) for o in todo]
            launcher = self._config.hydra.launcher
            workers = next(
                (
                    int(launcher[k])
                    for k in ("n_jobs", "array_parallelism")
                    if isinstance(launcher.get(k), int) and launcher[k] > 0
                ),
                None,
            )
            line = eta.estimate_line(keys, self._progress.costs, workers)
            if line:
                print(f"hnnbench: {line}", file=sys.stderr, flush=True)


def _partial_report(directory: Path) -> None:
    """The sweep's leaderboard (csv, Markdown, HTML; no figures) of the records so far,
    rewritten while the sweep runs; the end of the sweep writes the whole report."""
    from hnnbench._results import report

    report.write_report(directory, figures=False, aggregate=False)


def _collect(job: Any, overrides: Sequence[str]) -> None:
    """Post one finished job's outcomes; a job that raised (it returned none) is posted
    as lost, with the reason, and marked done so that the sweep goes on."""
    from hydra.core.utils import JobStatus

    try:
        value = job.return_value
    except BaseException as err:  # noqa: BLE001 - whatever the job raised, SystemExit too
        if isinstance(err, KeyboardInterrupt):
            raise
        shown = " ".join(str(err).split())
        reason = f"{' '.join(overrides)}: {type(err).__name__}" + (f": {shown}" if shown else "")
        log.error("job returned no record: %s", reason[:500])
        _post({"lost": reason[:500]})
        job.status, job.return_value = JobStatus.COMPLETED, []
        return
    if isinstance(value, list):
        for outcome in value:
            _post(outcome)


def _post(outcome: dict[str, Any]) -> None:
    """Hand one outcome to the command's launch context (none: a sweep started by
    Hydra itself, not by the hnnbench command or API)."""
    context = launch_context.local()
    if context is not None:
        context.post(outcome)
