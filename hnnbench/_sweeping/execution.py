"""Running a :class:`~hnnbench._sweeping.plan.Plan` through Hydra (any launcher) and
returning exactly its jobs' records (docs/ARCHITECTURE.md, "The path of one job"):
:func:`run_plan`, the Hydra task that runs one job (:func:`hydra_task`), and the
:class:`Execution` it returns.
"""

from __future__ import annotations

import contextlib
import os
import shlex
import socket
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hnnbench import _record as records
from hnnbench._contracts.names import DEFAULT_TRACK
from hnnbench._running import configstore, launch_context
from hnnbench._running.compose import profile_of, track_of_overrides
from hnnbench._running.config import hydra_error_line
from hnnbench._running.hydra_private import one_line_errors
from hnnbench._sweeping.loky import set_worker_growth
from hnnbench._sweeping.plan import Plan, plan

__all__ = ["Execution", "execute", "hydra_task", "run_plan"]


def hydra_task(cfg) -> list[dict[str, Any]]:  # noqa: ANN001 - Hydra passes a DictConfig
    """The Hydra task: one job (:func:`hnnbench._running.job.run_job`) in the directory
    Hydra chose. Returns its outcomes (``{"record", "kept"}`` per seed), which the
    sweeper collects from any launcher; a single run (no sweeper) hands them to the
    command's launch context itself."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from hnnbench._running.job import run_job

    set_worker_growth()
    hc = HydraConfig.get()
    multirun = hc.mode == RunMode.MULTIRUN
    context = launch_context.current()
    total = context.n_jobs if context is not None else None
    outcomes = [
        o.as_outcome()
        for o in run_job(
            cfg,
            Path(hc.runtime.output_dir),
            hc.job.num if multirun else None,
            total,
            overrides=list(hc.overrides.task),
        )
    ]
    collector = launch_context.local()
    if not multirun and collector is not None:
        for outcome in outcomes:
            collector.post(outcome)
    return outcomes


@dataclass
class Execution:
    """What a Hydra command line ran: the records of its jobs, in the order they
    finished (a resumed job's record as it was kept), which were kept, and the jobs
    that returned no outcome (``lost``: what was run and why). ``sweep``: whether jobs
    were to run as a sweep (``-m`` without ``--help`` and the like)."""

    multirun: bool
    records: list[dict[str, Any]]
    kept: list[bool] = field(default_factory=list)
    lost: list[str] = field(default_factory=list)
    sweep: bool = False

    def counts(self) -> dict[str, int]:
        """This run's records by status (kept ones left out), plus ``kept`` and ``lost``."""
        out: dict[str, int] = {}
        for record, kept in zip(self.records, self.kept, strict=False):
            if not kept:
                status = str(record.get("status"))
                out[status] = out.get(status, 0) + 1
        out["kept"] = sum(self.kept)
        out["lost"] = len(self.lost)
        return out

    def verdict(self) -> tuple[bool, str]:
        """``(failed, line)``: whether a job of this run failed, timed out or was lost
        (``diverged`` and ``skipped`` are outcomes, not failures), and one line saying
        so, with how many were kept from an earlier run."""
        counts = self.counts()
        kept = counts.pop("kept")
        lost = counts.pop("lost")
        new = sum(counts.values()) + lost
        failed = counts.get("failed", 0) + lost
        timeout = counts.get("timeout", 0)
        tail = f"; {kept} kept from an earlier run" if kept else ""
        if failed or timeout:
            parts = ([f"{failed} failed"] if failed else []) + (
                [f"{timeout} timed out"] if timeout else []
            )
            lost_text = f" ({lost} returned no record)" if lost else ""
            return True, (
                f"{' and '.join(parts)} of {new} job(s){lost_text} (see the log "
                f"and each record's error){tail}"
            )
        shown = ", ".join(f"{n} {s}" for s, n in sorted(counts.items())) or "none run"
        return False, f"{new} job(s): {shown}{tail}"


def execute(argv: list[str], command: str | None = None) -> Execution:
    """Check and run a Hydra command line (``hnnbench`` without a subcommand) in this
    process and return its jobs' records; raise :class:`HnnbenchError` (one line) for
    bad input. ``command`` is the command line stored in the records (default:
    ``hnnbench`` and ``argv``)."""
    return run_plan(plan(argv), command or shlex.join(["hnnbench", *argv]))


def run_plan(checked: Plan, command: str) -> Execution:
    """Run a :class:`Plan` (from :func:`plan` or :func:`~hnnbench._sweeping.plan.request`)
    through Hydra and return its jobs' records; ``command`` is stored in each record."""
    import hydra
    from hydra.core.plugins import Plugins

    from hydra_plugins.hnnbench_sweeper import HnnbenchSweeper

    # Hydra finds plugins by scanning the hydra_plugins namespace, which misses an
    # editable install; registering the class makes hydra/sweeper=hnnbench work in both.
    Plugins.instance().register(HnnbenchSweeper)
    shell = "--shell-completion" in checked.argv
    configstore.register(
        "paper" if shell else profile_of(checked.overrides),
        DEFAULT_TRACK if shell else track_of_overrides(checked.overrides),
    )
    if checked.multirun and checked.n_jobs:
        print(f"hnnbench: {checked.n_jobs} job(s)", file=sys.stderr)
    # The jobs see the command line, the sweep's size, and that the hnnbench command
    # started them (they then pin a core); this process's jobs also take the jobs the
    # plan validated, and every job's outcomes are collected here.
    context = launch_context.LaunchContext(
        command=command,
        n_jobs=checked.n_jobs or None,
        cli_pid=os.getpid(),
        host=socket.gethostname(),
        pinned=checked.pinned or None,
        prepared=dict(checked.validated),
    )
    saved = sys.argv
    sys.argv = [saved[0] if saved else "hnnbench", *checked.hydra_argv]
    try:
        with launch_context.launched(context), _one_line_hydra_errors():
            hydra.main(version_base="1.3", config_path="pkg://hnnbench_conf", config_name="config")(
                hydra_task
            )()
    finally:
        sys.argv = saved
    outcomes = [o for o in context.outcomes if "record" in o]
    shows_only = ("--help", "--hydra-help", "--info", "--cfg", "--shell-completion")
    return Execution(
        multirun=checked.multirun,
        records=[records.decode(o["record"]) for o in outcomes],
        kept=[bool(o.get("kept")) for o in outcomes],
        lost=[str(o["lost"]) for o in context.outcomes if "lost" in o],
        sweep=checked.multirun and not any(a in shows_only for a in checked.argv),
    )


def _one_line_hydra_errors() -> contextlib.AbstractContextManager[None]:
    """A safety net behind :func:`plan`: an error Hydra still finds (it prints several
    lines and exits) becomes a one-line :class:`HnnbenchError`."""
    return one_line_errors(hydra_error_line, enabled=os.environ.get("HYDRA_FULL_ERROR") != "1")
