"""How long a sweep will take: job costs from published runs, and progress with an ETA.

``hnnbench/resources/job_costs.csv`` holds one row per ``(profile, system, model)``:
the median wall time in seconds of one job (one seed, one core) over the runs it was
taken from, and where they come from. ``scripts/maintainer/job_costs.py`` writes it from the
published records (``results/records``, the paper profile) and the quick profile's CI
reference (``results/reference/quick.csv``); nobody edits it by hand.

A sweep started by the ``hnnbench`` command prints, before its jobs start, what the
published runs of its jobs took in all, then, while it runs, a line each time jobs
finish: how many of how many, and an ETA. The ETA scales the published cost of the
jobs still to run by how fast this sweep has gone so far (its elapsed time over the
published cost of the jobs it finished), so it accounts for the number of workers and
the machine; with no published cost, it uses the mean time per finished job.
"""

from __future__ import annotations

import csv
import statistics
import sys
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Optional, TextIO

__all__ = [
    "COLUMNS",
    "COSTS_FILE",
    "JobKey",
    "SweepProgress",
    "duration_text",
    "estimate_line",
    "job_key",
    "load_costs",
]

#: The resource file of job costs (``hnnbench/resources``).
COSTS_FILE = "job_costs.csv"
#: Its columns (one declaration; scripts/maintainer/job_costs.py writes them).
COLUMNS = ("profile", "system", "model", "seconds", "n_runs", "source")

#: ``(profile, system, model)``.
JobKey = tuple[str, str, str]


def load_costs(path: Optional[Path] = None) -> dict[JobKey, float]:
    """Seconds per job by ``(profile, system, model)`` (empty when the file is missing
    or unreadable: an estimate is a convenience, never a reason to fail)."""
    try:
        if path is None:
            text = resources.files("hnnbench.resources").joinpath(COSTS_FILE).read_text("utf-8")
        else:
            text = Path(path).read_text("utf-8")
        rows = list(csv.DictReader(text.splitlines()))
        return {
            (r["profile"], r["system"], r["model"]): float(r["seconds"])
            for r in rows
            if float(r["seconds"]) >= 0
        }
    except (OSError, KeyError, ValueError, TypeError):
        return {}


def _chosen(overrides: Sequence[str]) -> dict[str, str]:
    chosen: dict[str, str] = {}
    for text in overrides:
        key, _, value = text.partition("=")
        if key.lstrip("+~") in ("system", "model", "profile", "track", "seed"):
            chosen[key.lstrip("+~")] = value
    return chosen


def job_key(overrides: Sequence[str], default_profile: str) -> Optional[JobKey]:
    """The ``(profile, system, model)`` whose published cost a job's overrides choose
    (``None`` when they choose no system or model, or a track other than the protocol:
    the published costs are the protocol's, and a recipe's network may cost many times
    more)."""
    chosen = _chosen(overrides)
    if "system" not in chosen or "model" not in chosen:
        return None
    if chosen.get("track", "protocol") != "protocol":
        return None
    return chosen.get("profile", default_profile), chosen["system"], chosen["model"]


def job_directory(overrides: Sequence[str]) -> Optional[str]:
    """``<system>/<model>/seed<k>``, the directory in a sweep of the job these overrides
    choose, whatever its track (``None`` when they choose no system or model)."""
    chosen = _chosen(overrides)
    if "system" not in chosen or "model" not in chosen:
        return None
    return f"{chosen['system']}/{chosen['model']}/seed{chosen.get('seed', '0')}"


def duration_text(seconds: float) -> str:
    """``42 s``, ``12 min``, ``3 h 05 min``."""
    seconds = max(0.0, float(seconds))
    if seconds < 90:
        return f"{seconds:.0f} s"
    minutes = round(seconds / 60)
    if minutes < 90:
        return f"{minutes} min"
    return f"{minutes // 60} h {minutes % 60:02d} min"


#: What the estimate rests on, said with it: the machines of the published runs.
ESTIMATE_BASIS = (
    "estimated from the published runs: median wall time per job, one core "
    "each, on the project's 2-core CPU machines "
    f"(hnnbench/resources/{COSTS_FILE}); yours may differ"
)


def estimate_line(
    keys: Sequence[Optional[JobKey]], costs: Mapping[JobKey, float], workers: Optional[int]
) -> Optional[str]:
    """What the published runs of these jobs took, and what that rests on
    (:data:`ESTIMATE_BASIS`), or ``None`` when none is known (or no job will run)."""
    known = [costs[k] for k in keys if k is not None and k in costs]
    if not known:
        return None
    total = sum(known)
    line = f"the published runs of these jobs took {duration_text(total)} of job time"
    if workers and workers > 1:
        line += f" (about {duration_text(total / workers)} on {workers} workers)"
    unknown = len(keys) - len(known)
    if unknown:
        line += f"; {unknown} job(s) have no published run and are not counted"
    return f"{line} ({ESTIMATE_BASIS})"


@dataclass
class SweepProgress:
    """A thread that watches a sweep directory for new records and prints progress
    lines (``done/total`` and an ETA) to ``out``. Register jobs with :meth:`add` (a
    batch, each job its overrides; the first call starts the thread) and end with
    :meth:`stop`. A job whose directory (``<system>/<model>/seed<k>``) already holds a
    record when it is registered counts as kept from an earlier run. ``on_new`` is
    called from the thread when new records have arrived, at most once every
    ``on_new_every_s`` seconds; an exception there is printed once and the sweep goes
    on."""

    directory: Path
    default_profile: str
    costs: Mapping[JobKey, float]
    every_s: float = 10.0
    out: TextIO = field(default_factory=lambda: sys.stderr)
    on_new: Optional[Callable[[], None]] = None
    on_new_every_s: float = 60.0
    _pending: bool = False
    _last_on_new: float = float("-inf")
    _on_new_failed: bool = False
    # job directory -> its published cost's key (None: no cost, e.g. another track)
    _jobs: dict[str, Optional[JobKey]] = field(default_factory=dict)
    _kept: set[str] = field(default_factory=set)
    _done: set[str] = field(default_factory=set)
    _seen: set[Path] = field(default_factory=set)
    _start: float = field(default_factory=time.monotonic)
    _stop: threading.Event = field(default_factory=threading.Event)
    _thread: Optional[threading.Thread] = None

    def kept(self, overrides: Sequence[str]) -> bool:
        """Whether the job of these overrides holds a record from an earlier run (it is
        registered by :meth:`add`): it will not run again."""
        return job_directory(overrides) in self._kept

    def add(self, batch: Iterable[Sequence[str]]) -> None:
        """Register a batch of jobs (each its overrides) and start watching."""
        existing = self._records()
        if self._thread is None:
            self._seen = set(existing)
        had = {self._job_of(p) for p in existing}
        for overrides in batch:
            job = job_directory(overrides)
            if job is None:
                continue
            self._jobs[job] = job_key(overrides, self.default_profile)
            if job in had:
                self._kept.add(job)
        if self._thread is None:
            self._start = time.monotonic()
            self._thread = threading.Thread(target=self._run, name="hnnbench-progress", daemon=True)
            self._thread.start()

    @property
    def started(self) -> bool:
        """Whether jobs have been registered (the thread runs)."""
        return self._thread is not None

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=120)  # a report rewrite in progress ends first

    def _records(self) -> list[Path]:
        try:
            return list(self.directory.rglob("result.json"))
        except OSError:
            return []

    def _job_of(self, path: Path) -> str:
        parts = path.relative_to(self.directory).parts
        return "/".join(parts[:3])

    def _run(self) -> None:
        while not self._stop.wait(self.every_s):
            new = [p for p in self._records() if p not in self._seen]
            if new:
                self._seen.update(new)
                self._done.update(j for j in map(self._job_of, new) if j not in self._kept)
                self.out.write(f"hnnbench: {self.line()}\n")
                self.out.flush()
                self._pending = True
            if (
                self._pending
                and self.on_new is not None
                and time.monotonic() - self._last_on_new >= self.on_new_every_s
            ):
                self._call_on_new()

    def _call_on_new(self) -> None:
        assert self.on_new is not None
        self._pending, self._last_on_new = False, time.monotonic()
        try:
            self.on_new()
        except Exception as err:  # noqa: BLE001 - a convenience must not stop the sweep
            if not self._on_new_failed:
                self._on_new_failed = True
                self.out.write(f"hnnbench: could not update the sweep's report: {err}\n")
                self.out.flush()

    def line(self) -> str:
        """``k/N jobs done in T; ETA ... for the M left`` (kept jobs not counted)."""
        elapsed = time.monotonic() - self._start
        jobs = dict(self._jobs)
        todo = [j for j in jobs if j not in self._kept]
        done = [j for j in todo if j in self._done]
        left = [j for j in todo if j not in self._done]
        text = f"{len(done)}/{len(todo)} jobs done in {duration_text(elapsed)}"
        if not left or not done:
            return text
        done_cost = [self.costs[k] for j in done if (k := jobs[j]) is not None and k in self.costs]
        left_cost = [self.costs[k] for j in left if (k := jobs[j]) is not None and k in self.costs]
        if len(done_cost) == len(done) and len(left_cost) == len(left) and sum(done_cost) > 0:
            # this sweep's seconds per published second, times what is left
            eta = elapsed / sum(done_cost) * sum(left_cost)
        else:  # no published cost for some: the mean time per finished job
            eta = elapsed / len(done) * len(left)
        return f"{text}; ETA {duration_text(eta)} for the {len(left)} left"


def median_seconds(values: Iterable[float]) -> float:
    """The median of the finite, non-negative values (``nan`` for none)."""
    kept = [v for v in values if v == v and 0 <= v < float("inf")]
    return statistics.median(kept) if kept else float("nan")
