"""One sweep path: planning and execution of a Hydra command line, for the CLI and the
Python API alike.

:func:`plan` checks a command line before Hydra starts: flags are parsed by Hydra's own
parser, every override is parsed, names are validated (with a did-you-mean), ``all``
expands to every registered plugin, seeds are grouped (``seeds_per_job``), and the
first job's config and each other swept value are composed and validated, so a bad
input fails in one line before any job runs. :func:`execute` runs a planned command
line through Hydra (any launcher) and returns its jobs' records: each job's outcomes
travel back as the task's return value (collected by :class:`Sweeper`, which replaces
Hydra's basic sweeper so that a job's config is composed once) into a channel file of
this invocation. :func:`request` turns the Python API's arguments into a plan without
building a command line.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import json
import logging
import os
import re
import shlex
import socket
import sys
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn, Optional

from hnnbench import _costs as costs
from hnnbench import _launch as launch
from hnnbench import _records as records
from hnnbench import _registry as registry
from hnnbench._config import (
    check_hydra_node,
    compose,
    hydra_error_line,
    prepare_job,
    profile_of,
    register_schema,
    track_of_overrides,
)
from hnnbench._errors import ConfigError, HnnbenchError, UnknownNameError
from hnnbench._hydra import (
    HydraSweeper,
    args_parser,
    basic_sweeper_class,
    one_line_errors,
    waiting_for_every_submitit_job,
)
from hnnbench._record_schema import DEFAULT_TRACK

log = logging.getLogger("hnnbench")

__all__ = ["LOCK_NAME", "Execution", "Plan", "Sweeper", "execute", "plan", "request",
           "sweep_lock"]


@dataclass
class Plan:
    """A checked command line, ready for Hydra."""

    argv: list[str]
    multirun: bool
    n_jobs: int | None
    overrides: list[str] = field(default_factory=list)
    #: A swept group pinned to its first value in the command line Hydra composes its
    #: sweep-wide config with (``model=a`` for ``model=a,b``), because that config
    #: skips sweeps of groups: with the group empty, an override of one of its keys
    #: (``model.steps=5``) would not compose. The pinned text -> the sweep's text;
    #: :class:`Sweeper` hands Hydra's sweeper the sweep again.
    pinned: dict[str, str] = field(default_factory=dict)

    @property
    def hydra_argv(self) -> list[str]:
        """The command line given to Hydra (:attr:`argv`, swept groups pinned)."""
        back = {sweep: one for one, sweep in self.pinned.items()}
        return [back.get(arg, arg) for arg in self.argv]


@dataclass
class _Entry:
    """One override of the command line."""

    text: str
    prefix: str  # "", "+", "++" or "~"
    key: str
    values: list[Any] | None  # None: a sweep hnnbench cannot enumerate (left to Hydra)
    sweep: bool


def _parse_flags(argv: list[str]) -> argparse.Namespace:
    """Hydra's own argument parser, with flags and overrides in any order, raising a
    one-line :class:`ConfigError` instead of printing usage and exiting."""
    parser = args_parser()
    parser.prog = "hnnbench"

    def error(message: str) -> NoReturn:
        raise ConfigError(f"{message} (see hnnbench --help)")

    parser.error = error  # type: ignore[method-assign]
    ns = parser.parse_intermixed_args(argv)
    commands = [name for name, on in (
        ("--run", ns.run), ("--multirun", ns.multirun), ("--cfg", ns.cfg is not None),
        ("--info", ns.info is not None), ("--shell-completion", ns.shell_completion)) if on]
    if len(commands) > 1:
        raise ConfigError(
            f"{' and '.join(commands)} cannot be combined: give one of --run, --multirun (-m), "
            "--cfg, --info, --shell-completion"
        )
    if ns.resolve and ns.cfg is None and not ns.help:
        raise ConfigError("--resolve only works together with --cfg, e.g. --cfg job --resolve")
    if ns.package is not None and ns.cfg is None:
        raise ConfigError("--package only works together with --cfg, e.g. --cfg job -p system")
    for flag, value in (("--config-dir", ns.config_dir), ("--config-path", ns.config_path)):
        if value is None or value.startswith("pkg://"):
            continue
        path = Path(value.removeprefix("file://")).expanduser()
        if not path.is_dir():
            raise ConfigError(f"{flag} {value}: no such directory")
        # Hydra reads a relative --config-path relative to hnnbench's own source file;
        # users mean their working directory.
        resolved = str(path.resolve())
        if flag == "--config-dir":
            ns.config_dir = resolved
        else:
            ns.config_path = resolved
    if ns.experimental_rerun is not None:
        # Hydra's --experimental-rerun unpickles the file it is given: a pickle runs any
        # code it holds, so hnnbench never loads one.
        raise ConfigError(
            f"--experimental-rerun {ns.experimental_rerun} is refused: it unpickles the "
            "file, which can run any code. Re-run a sweep with its command line (a "
            "record's rerun_command; the same hydra.sweep.dir resumes it), or check it "
            "with hnnbench check DIR --rerun")
    return ns


def _flag_args(ns: argparse.Namespace) -> list[str]:
    """The parsed flags as Hydra expects them, in canonical spelling."""
    out: list[str] = []
    for name, flag in (("help", "--help"), ("hydra_help", "--hydra-help"), ("run", "--run"),
                       ("multirun", "--multirun"), ("shell_completion", "--shell-completion"),
                       ("resolve", "--resolve")):
        if getattr(ns, name):
            out.append(flag)
    for name, flag in (("cfg", "--cfg"), ("package", "--package"),
                       ("config_path", "--config-path"), ("config_name", "--config-name"),
                       ("config_dir", "--config-dir"), ("info", "--info")):
        if getattr(ns, name) is not None:
            out += [flag, getattr(ns, name)]
    return out


def _expand_names(kind: str, values: list[str]) -> list[str]:
    plugins = registry.group(kind)
    names = plugins.available()
    out: list[str] = []
    for value in values:
        for name in names if value == "all" else [value]:
            if name not in plugins.discover():
                raise UnknownNameError(kind, name, names)
            plugins.get(name)  # unusable -> error
            if name not in out:
                out.append(name)
    return out


_PREFIX = {"ADD": "+", "FORCE_ADD": "++", "DEL": "~", "CHANGE": ""}


def _parse_override(parser: Any, text: str) -> _Entry:
    from hydra.core.override_parser.types import Glob

    try:
        (ov,) = parser.parse_overrides([text])
    except Exception as err:
        raise ConfigError(f"Cannot parse override '{text}': {hydra_error_line(err)}") from None
    key = ov.key_or_group
    if not key:
        raise ConfigError(f"Cannot parse override '{text}': expected KEY=VALUE, e.g. seed=0")
    prefix = _PREFIX.get(ov.type.name, "")
    if ov.is_delete():
        return _Entry(text, prefix, key, [], False)
    if not ov.is_sweep_override():
        value = ov.get_value_element_as_str()
        if key in ("system", "model"):
            names = _expand_names(key, [value])
            if len(names) > 1:  # `all`
                return _Entry(f"{prefix}{key}={','.join(names)}", prefix, key, names, True)
            return _Entry(f"{prefix}{key}={names[0]}", prefix, key, names, False)
        return _Entry(text, prefix, key, [value], False)
    try:
        values: list[Any] | None = [str(v) for v in ov.sweep_string_iterator()]
    except Exception:  # glob(...) and interval(...): not enumerable without a config
        value = ov.value()
        values = None
        if key in ("system", "model") and isinstance(value, Glob):
            values = value.filter(registry.available(key))
            if not values:
                raise ConfigError(
                    f"{text}: the pattern matches no registered {key} "
                    f"(available: {', '.join(registry.available(key))})"
                ) from None
        elif ov.value_type is not None and ov.value_type.name == "INTERVAL_SWEEP":
            raise ConfigError(
                f"{text}: interval() needs an optimizing sweeper; the basic sweeper "
                "takes lists (a,b,c), range() and choice()"
            ) from None
    if values is not None and key in ("system", "model"):
        values = _expand_names(key, values)
        text = f"{prefix}{key}={','.join(values)}"
    return _Entry(text, prefix, key, values, True)


def _batch_seeds(entries: list[_Entry]) -> list[_Entry]:
    """With ``seeds_per_job=N`` (N > 1), a sweep ``seed=a,b,c,...`` becomes one job per
    N seeds: ``seed_batch=[a,b,c],[d,...]`` with ``seed=${seed_batch.0}``, the first of
    each batch (its records' directories stay ``seed<k>``; hnnbench._job.seed_directory)."""
    given = next((e for e in entries if e.key == "seed_batch"), None)
    if given is not None:
        raise ConfigError(f"{given.text}: seed_batch is set by seeds_per_job; give the seeds "
                          "with seed, e.g. -m seed=0,1,2 seeds_per_job=3")
    per_job = [e for e in entries if e.key == "seeds_per_job" and not e.sweep and e.values]
    if not per_job:
        return entries
    try:
        size = int(str(per_job[-1].values[0]))  # type: ignore[index]
    except ValueError:
        return entries  # validation reports the bad value
    where = [i for i, e in enumerate(entries) if e.key == "seed"]
    if size <= 1 or not where:
        return entries
    i = where[-1]
    seed = entries[i]
    if not seed.sweep or not seed.values or len(seed.values) < 2:
        return entries
    try:
        values = [int(str(v)) for v in seed.values]
    except ValueError:
        raise ConfigError(f"{seed.text}: seeds must be integers, e.g. seed=0,1,2") from None
    groups = [values[k:k + size] for k in range(0, len(values), size)]
    texts = ["[" + ",".join(map(str, g)) + "]" for g in groups]
    batch = _Entry(f"seed_batch={','.join(texts)}", "", "seed_batch", texts, len(texts) > 1)
    leader = _Entry("seed=${seed_batch.0}", "", "seed", ["${seed_batch.0}"], False)
    return [*entries[:i], leader, batch, *entries[i + 1:]]


def _trial(entries: list[_Entry], choice: dict[int, Any]) -> list[str]:
    """Overrides of one job: each sweep replaced by its chosen value (or its first)."""
    out = []
    for i, e in enumerate(entries):
        if not e.sweep:
            out.append(e.text)
        elif e.values:  # unenumerable sweeps are left to Hydra
            out.append(f"{e.prefix}{e.key}={choice.get(i, e.values[0])}")
    return out


def _is_group(key: str) -> bool:
    return key in ("system", "model", "profile") or "/" in key or key.startswith("hydra")


def plan(argv: list[str]) -> Plan:
    """Check a Hydra command line and rewrite ``all``; raise :class:`ConfigError`.

    The flags are parsed by Hydra's own parser; every override is parsed, names are
    checked, and the config of the first job and of every other swept value is
    composed (Hydra's ``hydra`` node included) and validated, so that Hydra never gets
    a command line it would reject with a multi-line error.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf, open_dict

    ns = _parse_flags(argv)
    flags = _flag_args(ns)
    multirun = bool(ns.multirun)
    if ns.shell_completion:  # its arguments (install=bash) are not config overrides
        return Plan(argv=flags + list(ns.overrides), multirun=False, n_jobs=None,
                    overrides=list(ns.overrides))
    profile_of(list(ns.overrides))
    track_of_overrides(list(ns.overrides))
    parser = OverridesParser.create()
    entries = [_parse_override(parser, text) for text in ns.overrides]
    if not (ns.help or ns.hydra_help or ns.info is not None):
        for kind in ("system", "model"):  # the shipped config names no plugin
            if not any(e.key == kind and not e.text.startswith("~") for e in entries):
                raise ConfigError(
                    f"no {kind} chosen: add {kind}=<name> to the command line (`hnnbench "
                    f"list` shows the {kind}s; {kind}=all for every one)")
    if multirun:
        entries = _batch_seeds(entries)
    rewritten = [e.text for e in entries]
    sweeps = {i: e for i, e in enumerate(entries) if e.sweep and (e.values is None
                                                                  or len(e.values) > 1)}
    if sweeps and not multirun:
        e = next(iter(sweeps.values()))
        vals = [str(v) for v in e.values or []]
        shown = f" ({', '.join(vals[:4])}{', ...' if len(vals) > 4 else ''})" if vals else ""
        if ns.cfg is not None or ns.info is not None:
            raise ConfigError(f"{e.key} has several values{shown}: --cfg and --info show one "
                              "config, so give one value per key")
        raise ConfigError(
            f"{e.key} has {len(vals) or 'several'} values{shown}: that is a sweep, so add -m, "
            f"e.g. hnnbench -m {' '.join(rewritten)}"
        )
    kwargs: dict[str, Any] = {}
    if ns.config_name is not None:
        kwargs["config_name"] = ns.config_name
    if ns.config_path is not None and not ns.config_path.startswith("pkg://"):
        kwargs["config_dir"] = ns.config_path
    extra: list[str] = []
    if ns.config_dir:  # Hydra puts it first on the search path, as these do
        if (Path(ns.config_dir) / f"{ns.config_name or 'config'}.yaml").is_file():
            kwargs.setdefault("config_dir", ns.config_dir)
            extra = ["hydra.searchpath=[pkg://hnnbench_conf]"]
        else:
            extra = [f"hydra.searchpath=[file://{ns.config_dir}]"]

    def job_config(overrides: list[str]) -> Any:
        """The job config (validated), then the hydra node it was composed with."""
        cfg = compose(overrides + extra, return_hydra_config=True, **kwargs)
        with open_dict(cfg):
            hydra_node = cfg.pop("hydra")
        prepare_job(cfg)
        with open_dict(cfg):
            cfg["hydra"] = hydra_node
        check_hydra_node(cfg)
        with open_dict(cfg):
            del cfg["hydra"]
        return cfg

    # The first job, composed with everything (the hydra node and its directories too).
    base = job_config(_trial(entries, {}))
    # Every other swept value, against the first value of the other keys: a group
    # (system, model, hydra/...) is composed again; a plain value is merged (fast).
    for i, e in sweeps.items():
        for value in (e.values or [])[1:]:
            if _is_group(e.key) or e.prefix:
                job_config(_trial(entries, {i: value}))
                continue
            cfg = copy.deepcopy(base)
            try:
                (ov,) = parser.parse_overrides([f"{e.key}={value}"])
                OmegaConf.update(cfg, e.key, ov.value(), merge=True)
            except ConfigError:
                raise
            except Exception as err:
                raise ConfigError(
                    f"Error merging override {e.key}={value}: {hydra_error_line(err)}"
                ) from None
            prepare_job(cfg)
    n_jobs: int | None = 1
    counts: dict[str, int | None] = {}
    for e in entries:
        if not e.key.startswith("hydra"):
            counts[e.key] = None if e.values is None else max(len(e.values), 1)
    for count in counts.values():
        n_jobs = None if n_jobs is None or count is None else n_jobs * count
    pinned = {}
    for e in sweeps.values():
        if (e.key in ("system", "model", "profile") and not e.prefix and e.values
                and any(o.key.startswith(f"{e.key}.") for o in entries)):
            pinned[f"{e.key}={e.values[0]}"] = e.text
    return Plan(argv=flags + rewritten, multirun=multirun, n_jobs=n_jobs, overrides=rewritten,
                pinned=pinned)


#: Memory (bytes) a joblib worker may gain over its first job before joblib's loky
#: replaces it with a new process. loky's own limit, 300 MB, is crossed within a few jobs
#: by a worker that imports its second backend and keeps each job's compiled JAX
#: programs (25-30 MB a job), and every replacement imports Hydra, torch and JAX again
#: (benchmarks/README.md, "joblib's worker replacement"). At this limit a worker is
#: replaced after some 60 JAX jobs, which still bounds its memory.
WORKER_GROWTH = 2_000_000_000

#: Environment variable: the limit in MB (10^6 bytes) instead of :data:`WORKER_GROWTH`
#: (300: loky's own).
WORKER_GROWTH_ENV = "HNNBENCH_WORKER_GROWTH_MB"
_growth_warned = False


def worker_growth() -> int:
    """The memory growth (bytes) a joblib worker is allowed: ``$HNNBENCH_WORKER_GROWTH_MB``
    or :data:`WORKER_GROWTH`; a bad value is reported in one line and the default used."""
    global _growth_warned
    text = os.environ.get(WORKER_GROWTH_ENV, "").strip()
    if not text:
        return WORKER_GROWTH
    try:
        megabytes = int(text)
    except ValueError:
        megabytes = 0
    if megabytes >= 1:
        return megabytes * 1_000_000
    if not _growth_warned:  # once per process, not once per job
        log.warning("%s=%r is invalid: expected a whole number of megabytes >= 1 (300 is "
                    "loky's own limit); using %d", WORKER_GROWTH_ENV, text,
                    WORKER_GROWTH // 1_000_000)
        _growth_warned = True
    return WORKER_GROWTH


def set_worker_growth() -> None:
    """Set loky's memory-growth limit to :func:`worker_growth` in this process, where a
    loky worker reads it after each task; nothing where loky is not loaded (any other
    launcher). loky declares no public setting for it."""
    module = sys.modules.get("joblib.externals.loky.process_executor")
    if module is not None and isinstance(getattr(module, "_MAX_MEMORY_LEAK_SIZE", None), int):
        module._MAX_MEMORY_LEAK_SIZE = worker_growth()  # type: ignore[attr-defined]


def _task(cfg) -> list[dict[str, Any]]:  # noqa: ANN001 - Hydra passes a DictConfig
    """The Hydra task: one job. Returns its outcomes (``{"record", "kept"}`` per seed),
    which :class:`Sweeper` collects from any launcher; a single run (no sweeper) writes
    them to the invocation's channel itself."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from hnnbench._job import run_seed_outcomes

    set_worker_growth()
    hc = HydraConfig.get()
    multirun = hc.mode == RunMode.MULTIRUN
    context = launch.current()
    total = context.n_jobs if context is not None else None
    outcomes = [{"record": o.record, "kept": o.kept} for o in run_seed_outcomes(
        cfg, Path(hc.runtime.output_dir), hc.job.num if multirun else None, total,
        overrides=list(hc.overrides.task))]
    if not multirun:
        _post(outcomes)
    return outcomes


def _post(outcomes: list[dict[str, Any]]) -> None:
    """Append job outcomes to this invocation's channel file (in the command's own
    process: the single run's job, or :class:`Sweeper` for a sweep's jobs)."""
    context = launch.current()
    if context is None or not context.returns:
        return
    with open(context.returns, "a", encoding="utf-8") as fh:
        for outcome in outcomes:
            fh.write(json.dumps(records.encode(outcome), allow_nan=False) + "\n")


class Sweeper(HydraSweeper):
    """Hydra's basic sweeper (same job order, batches and ``hydra.sweeper.params``),
    minus its per-job recomposition to validate each batch: :func:`plan` has composed
    and validated every swept value before Hydra starts, so each job's config is
    composed once, by the launcher. It holds the sweep directory's lock
    (:func:`sweep_lock`) while the sweep runs, and hands the jobs' outcomes (the task's
    return values, from whichever launcher ran them) to the invocation's channel after
    each batch; a job that returned none (it raised, or its worker died) is reported as
    lost, and the sweep goes on.

    It wraps a basic sweeper rather than subclassing it: Hydra's plugin scan executes
    its module again, which would leave a subclass with a stale base."""

    def __init__(self, max_batch_size: Optional[int] = None,
                 params: Optional[dict[str, str]] = None) -> None:
        self._args = (max_batch_size, params)
        self._basic: Any = None
        self._config: Any = None
        self._progress: Optional[costs.SweepProgress] = None

    def setup(self, *, hydra_context: Any, task_function: Any, config: Any) -> None:
        self._basic = basic_sweeper_class()(*self._args)
        self._basic.validate_batch_is_legal = lambda batch: None  # validated by plan()
        self._basic.setup(hydra_context=hydra_context, task_function=task_function,
                          config=config)
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
        context = launch.current()
        pinned = (context.pinned or {}) if context is not None else {}
        arguments = [pinned.get(arg, arg) for arg in arguments]  # Plan.pinned
        directory = Path(str(self._config.hydra.sweep.dir))
        # Progress lines with an ETA, for the hnnbench command and API (hnnbench._costs).
        self._progress = None if context is None else costs.SweepProgress(
            directory, default_profile=str(self._config.profile.name),
            costs=costs.load_costs(), on_new=lambda: _partial_report(directory))
        try:
            with sweep_lock(directory, context.command if context is not None else None):
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
            keys = [costs.job_key(o, self._progress.default_profile) for o in todo]
            launcher = self._config.hydra.launcher
            workers = next((int(launcher[k]) for k in ("n_jobs", "array_parallelism")
                            if isinstance(launcher.get(k), int) and launcher[k] > 0), None)
            line = costs.estimate_line(keys, self._progress.costs, workers)
            if line:
                print(f"hnnbench: {line}", file=sys.stderr, flush=True)


def _partial_report(directory: Path) -> None:
    """The sweep's leaderboard (csv, Markdown, HTML; no figures) of the records so far,
    rewritten while the sweep runs; the end of the sweep writes the whole report."""
    from hnnbench import _report as report

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
        _post_lost(reason[:500])
        job.status, job.return_value = JobStatus.COMPLETED, []
        return
    if isinstance(value, list):
        _post(value)


def _post_lost(reason: str) -> None:
    context = launch.current()
    if context is None or not context.returns:
        return
    with open(context.returns, "a", encoding="utf-8") as fh:
        fh.write(json.dumps({"lost": reason}) + "\n")


#: The lock file of a sweep directory (held while a sweep runs into it).
LOCK_NAME = ".hnnbench.lock"


@contextlib.contextmanager
def sweep_lock(directory: Path, command: Optional[str] = None) -> Iterator[None]:
    """Hold ``<directory>/.hnnbench.lock`` (``flock``) while a sweep runs into it, with
    the holder's pid, host, start time and command written in it; raise a one-line
    :class:`HnnbenchError` naming the holder when another sweep holds it. The lock is
    the open file's: it goes when its process ends, however it ends, so a lock left by
    a killed sweep never blocks the next one. (No locking where ``fcntl`` is missing.)"""
    try:
        import fcntl
    except ImportError:  # Windows: no flock
        yield
        return
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / LOCK_NAME
    fh = open(path, "a+", encoding="utf-8")  # noqa: SIM115 - held for the whole sweep
    try:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.seek(0)
            raise HnnbenchError(
                f"{directory} is in use by another sweep ({_holder(fh.read())}); wait for it "
                "to finish, or choose another hydra.sweep.dir (out= in the Python API)"
            ) from None
        fh.seek(0)
        fh.truncate()
        fh.write(json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                             "started": records.now_iso(), "command": command}) + "\n")
        fh.flush()
        try:
            yield
        finally:
            fh.seek(0)
            fh.truncate()
            fh.flush()
            fcntl.flock(fh.fileno(), fcntl.LOCK_UN)
    finally:
        fh.close()


def _holder(text: str) -> str:
    """``pid 123 on host, since <time>: <command>`` from a lock file's content."""
    try:
        info = json.loads(text)
        assert isinstance(info, dict)
    except Exception:  # noqa: BLE001 - written in the middle, or by something else
        return "holder unknown"
    shown = f"pid {info.get('pid', '?')} on {info.get('host', '?')}"
    if info.get("started"):
        shown += f", since {info['started']}"
    if info.get("command"):
        shown += f": {info['command']}"
    return shown


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
                [f"{timeout} timed out"] if timeout else [])
            lost_text = f" ({lost} returned no record)" if lost else ""
            return True, (f"{' and '.join(parts)} of {new} job(s){lost_text} (see the log "
                          f"and each record's error){tail}")
        shown = ", ".join(f"{n} {s}" for s, n in sorted(counts.items())) or "none run"
        return False, f"{new} job(s): {shown}{tail}"


def execute(argv: list[str], command: str | None = None) -> Execution:
    """Check and run a Hydra command line (``hnnbench`` without a subcommand) in this
    process and return its jobs' records; raise :class:`HnnbenchError` (one line) for
    bad input. ``command`` is the command line stored in the records (default:
    ``hnnbench`` and ``argv``)."""
    return _launch_plan(plan(argv), command or shlex.join(["hnnbench", *argv]))


def _launch_plan(checked: Plan, command: str) -> Execution:
    import hydra
    from hydra.core.plugins import Plugins

    from hydra_plugins.hnnbench_sweeper import HnnbenchSweeper

    # Hydra finds plugins by scanning the hydra_plugins namespace, which misses an
    # editable install; registering the class makes hydra/sweeper=hnnbench work in both.
    Plugins.instance().register(HnnbenchSweeper)
    shell = "--shell-completion" in checked.argv
    register_schema()
    registry.register_configs(
        "paper" if shell else profile_of(checked.overrides),
        DEFAULT_TRACK if shell else track_of_overrides(checked.overrides))
    if checked.multirun and checked.n_jobs:
        print(f"hnnbench: {checked.n_jobs} job(s)", file=sys.stderr)
    with tempfile.TemporaryDirectory(prefix="hnnbench-") as tmp:
        channel = Path(tmp) / "outcomes.jsonl"
        channel.touch()
        # Jobs (here or in launcher workers) see the command line, the sweep's size, and
        # that the hnnbench command started them (they then pin a core: _affinity).
        context = launch.LaunchContext(command=command, n_jobs=checked.n_jobs or None,
                                       cli_pid=os.getpid(), host=socket.gethostname(),
                                       returns=str(channel), pinned=checked.pinned or None)
        saved = sys.argv
        sys.argv = [saved[0] if saved else "hnnbench", *checked.hydra_argv]
        try:
            with launch.launched(context), _one_line_hydra_errors():
                hydra.main(version_base="1.3", config_path="pkg://hnnbench_conf",
                           config_name="config")(_task)()
        finally:
            sys.argv = saved
        lines = [json.loads(line) for line in channel.read_text("utf-8").splitlines()
                 if line.strip()]
    outcomes = [o for o in lines if "record" in o]
    shows_only = ("--help", "--hydra-help", "--info", "--cfg", "--shell-completion")
    return Execution(multirun=checked.multirun,
                     records=[records.decode(o["record"]) for o in outcomes],
                     kept=[bool(o.get("kept")) for o in outcomes],
                     lost=[str(o["lost"]) for o in lines if "lost" in o],
                     sweep=checked.multirun and not any(a in shows_only for a in checked.argv))


def _one_line_hydra_errors() -> contextlib.AbstractContextManager[None]:
    """A safety net behind :func:`plan`: an error Hydra still finds (it prints several
    lines and exits) becomes a one-line :class:`HnnbenchError`."""
    return one_line_errors(hydra_error_line, enabled=os.environ.get("HYDRA_FULL_ERROR") != "1")


# --------------------------------------------------------------------------- the API


def hydra_value(value: Any) -> str:
    """A Python value as a Hydra override value: booleans, ``None``, numbers and lists
    as Hydra writes them; a string quoted (``'...'``, backslash-escaped) unless it is a
    plain word, so paths with spaces, quotes, ``#``, ``~``, brackets, ``=``, ``,``,
    backslashes, ``${`` or any non-ASCII character reach the job as the same string."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(hydra_value(v) for v in value) + "]"
    text = str(value)
    if text and all(c.isascii() and (c.isalnum() or c in "_-./:") for c in text):
        return text
    # OmegaConf reads ${...} as an interpolation: \${ is a literal ${ (and backslashes
    # right before it are doubled, or they would escape it).
    text = re.sub(r"(\\*)\$\{", lambda m: m.group(1) * 2 + "\\${", text)
    # In Hydra's quoted value, backslashes are literal except right before a quote or
    # the closing quote: those are doubled, and a quote is escaped.
    text = re.sub(r"(\\*)('|\Z)",
                  lambda m: m.group(1) * 2 + ("\\'" if m.group(2) else ""), text)
    return "'" + text + "'"


def request(*, single: Mapping[str, Any], swept: Mapping[str, Sequence[Any]] = {},
            raw: Mapping[str, str] = {}, multirun: bool) -> Plan:
    """The plan of a Python API call, with no command line built by the caller:
    ``single`` settings take one value each (quoted for Hydra by :func:`hydra_value`),
    ``swept`` settings a list of values (a sweep), ``raw`` settings are Hydra override
    values as written (e.g. ``"100,200"`` to sweep). Keys use dots (``model.steps``)
    or a Hydra group (``hydra/launcher``)."""
    overrides = [f"{key}={hydra_value(value)}" for key, value in single.items()]
    overrides += [f"{key}={','.join(hydra_value(v) for v in values)}"
                  for key, values in swept.items()]
    overrides += [f"{key}={value}" for key, value in raw.items()]
    return plan((["-m"] if multirun else []) + overrides)


def launch_plan(checked: Plan, command: str) -> Execution:
    """Run a :class:`Plan` (from :func:`plan` or :func:`request`) and return its jobs'
    records; ``command`` is stored in each record."""
    return _launch_plan(checked, command)
