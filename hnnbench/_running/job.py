"""One job: dataset -> fit -> evaluate -> one record per seed (:func:`run_job`, the one
job entry of a sweep's Hydra task, the tuner and ``hnnbench check --rerun``).

A job is self-contained: it reads its composed config and writes ``result.json`` (and
``rollout.npz``, the trained weights) into its own directory, so any Hydra launcher can
run it. It never raises for a problem of its own run: a diverging model is recorded as
``diverged``, an exception as ``failed``, an unsupported (system, model) pair as
``skipped``, and the sweep goes on (docs/ARCHITECTURE.md, "The path of one job").
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import logging
import os
import shlex
import shutil
import signal
import sys
import threading
import time
import traceback
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal, Optional

import numpy as np
import threadpoolctl
from omegaconf import DictConfig, OmegaConf, open_dict

from hnnbench import _record as records
from hnnbench import _registry as registry
from hnnbench._contracts import datasets, paths
from hnnbench._contracts.errors import HnnbenchError, JobTimeout, RolloutDiverged, UnsupportedPair
from hnnbench._contracts.metric import EvaluationConfig
from hnnbench._contracts.names import DEFAULT_TRACK, TRACKS
from hnnbench._contracts.plugin import HISTORY_STEP, Dataset, FitResult, TrainSettings, Trajectories
from hnnbench._record.fields import new_record
from hnnbench._running import (
    affinity,
    dataset_cache,
    device_share,
    isolation,
    launch_context,
    tracking,
)
from hnnbench._running.config import RUN_ONLY_KEYS, Job, fingerprint, prepare_job
from hnnbench._running.evaluation import evaluate, failed_metrics
from hnnbench._running.progress import EvaluationProgress, TrainingProgress

log = logging.getLogger("hnnbench")

__all__ = [
    "SeedOutcome",
    "config_change",
    "plugin_provenance",
    "run_job",
    "seed_directory",
    "time_limit",
]


def _set_threads(threads: int) -> None:
    """Cap every CPU thread pool the job computes with at ``threads`` (0: leave them).

    BLAS and OpenMP libraries read ``OMP_NUM_THREADS`` and the like only when they load,
    and numpy's OpenBLAS is loaded long before a job starts, so the environment alone
    leaves it at one thread per core. threadpoolctl caps the pools already loaded
    (numpy's OpenBLAS, torch's OpenMP) and the environment those loaded later. Left at
    two threads, OpenBLAS on a job pinned to one core (:mod:`hnnbench._running.affinity`) spends
    its time in two threads waiting on each other: a QR of 1568 x 200 took 0.8 s instead
    of 0.02 s, half the time of a quick pixel-pendulum job.
    """
    if threads <= 0:
        return
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = str(threads)
    threadpoolctl.threadpool_limits(limits=threads)
    if sys.modules.get("torch") is not None:  # loaded (None: blocked)
        import torch

        torch.set_num_threads(threads)


_pinned_once = False


def _warn_if_xla_started() -> None:
    """At the first pin of this process, warn when JAX's backends had already started:
    XLA sized its CPU thread pool from the cores it saw then (later jobs of a serial
    sweep reuse the pool of a pinned first job, so only the first pin matters), and
    this process's JAX results may differ in the last bits from the ``hnnbench``
    command's, which pins every job before JAX starts (docs/SYSTEMS_PIXEL.md). Silent
    when JAX's private backend table is not there (:func:`device_share.jax_started`)."""
    global _pinned_once
    if _pinned_once:
        return
    _pinned_once = True
    if not device_share.jax_started():
        return
    log.warning(
        "JAX was started in this process before the job pinned it to one core: "
        "its JAX results may differ in the last bits from the hnnbench command's; "
        "for records comparable bit for bit, run from a fresh process or the CLI"
    )


def _select(cfg: DictConfig, key: str) -> Any:
    try:
        return OmegaConf.select(cfg, key, default=None)
    except Exception:  # an unresolvable interpolation: the job fails with the reason
        return None


def _config_container(cfg: DictConfig) -> Any:
    try:
        return OmegaConf.to_container(cfg, resolve=True)
    except Exception:
        return OmegaConf.to_container(cfg, resolve=False)


def config_change(old: Any, new: Any, prefix: str = "") -> str | None:
    """The first setting whose value differs between a finished record's resolved
    config ``old`` and a job's ``new`` (``"key: old -> new"``), or ``None``.

    Keys that only one side has are not compared (a setting added to hnnbench or a
    plugin since the record was made keeps its default), nor are
    :data:`hnnbench._running.config.RUN_ONLY_KEYS`, which do not change what a job computes.
    """
    if isinstance(old, dict) and isinstance(new, dict):
        # A profile changes many settings at once: name it rather than the first of them.
        for key in sorted(old, key=lambda k: (prefix, k) != ("", "profile")):
            if key in new and not (not prefix and key in RUN_ONLY_KEYS):
                change = config_change(old[key], new[key], f"{prefix}{key}.")
                if change is not None:
                    return change
        return None
    return None if old == new else f"{prefix.rstrip('.')}: {old!r} -> {new!r}"


def plugin_provenance(kind: Literal["system", "model"], name: str) -> dict[str, Any]:
    """The record's ``plugins.<kind>``: the plugin's name and ``version`` (its class
    attribute), and the distribution (pip package) that installed it, with that
    package's version (``null`` for a plugin registered in this process, which no
    package provides)."""
    info = registry.discover(kind).get(name)
    cls = getattr(info, "cls", None)
    version = getattr(cls, "version", None)
    return {
        "name": name,
        "version": None if version is None else str(version),
        "distribution": getattr(info, "distribution", None),
        "distribution_version": getattr(info, "dist_version", None),
    }


def _base_record(cfg: DictConfig, overrides: list[str] | None) -> dict[str, Any]:
    """A new record of the job (:func:`hnnbench._record.fields.new_record`: every field
    a job writes, in order; a field without a value here starts with its declared
    initial value: status ``failed``, no metrics, ...)."""
    context = launch_context.current()
    command = context.command if context is not None else None
    job_overrides = [o for o in overrides or [] if not o.startswith(("hydra.", "hydra/"))]
    track = _select(cfg, "track")
    record = new_record(
        system=_select(cfg, "system.name"),
        model=_select(cfg, "model.name"),
        seed=_select(cfg, "seed"),
        profile=_select(cfg, "profile.name"),
        config=_config_container(cfg),
        # How to run exactly this job again (the resolved config above is the truth;
        # these are the command lines that produced it).
        overrides=list(overrides) if overrides is not None else None,
        command=command,
        rerun_command=shlex.join(["hnnbench", *job_overrides]) if overrides is not None else None,
        environment=records.environment(),
        created_at=records.now_iso(),
        # A bad value fails the job (prepare_job); its record stays valid meanwhile.
        track=track if track in TRACKS else DEFAULT_TRACK,
    )
    tuning = _select(cfg, "tuning")
    if isinstance(tuning, DictConfig):  # how a tuned job's settings were chosen
        record["tuning"] = OmegaConf.to_container(tuning, resolve=True)
    return record


def _save_arrays(directory: Path, arrays: dict[str, np.ndarray], history: dict) -> None:
    payload = {k: np.asarray(v) for k, v in arrays.items()}
    payload.update({f"history.{k}": np.asarray(v, dtype=np.float64) for k, v in history.items()})
    savez: Any = np.savez_compressed  # numpy's stub reads **payload as allow_pickle
    with records.atomic_path(directory / records.ROLLOUT_NAME) as tmp, open(tmp, "wb") as fh:
        savez(fh, **payload)


def _save_model(model: Any, directory: Path) -> Optional[str]:
    """Save the trained weights as ``directory / model.weights_file`` (nothing if the
    model names no file): ``model.save`` writes into a private temporary folder, then the
    file is renamed into place, so a killed job never leaves torn weights behind.
    Returns the file name, or ``None``."""
    name = getattr(model, "weights_file", None)
    if not name:
        return None
    tmpdir = directory / f".weights.{os.getpid()}.{uuid.uuid4().hex}.tmp"
    tmpdir.mkdir(parents=True)
    try:
        model.save(tmpdir / name)
        written = tmpdir / name
        if not written.is_file():
            raise HnnbenchError(
                f"{type(model).__name__}.save() did not write {name}: a model's save(path) "
                "must write exactly the path it is given (see Model.weights_file)"
            )
        with records.atomic_path(directory / name) as tmp:
            os.replace(written, tmp)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
    return name


def _clean_stale(directory: Path) -> None:
    """Remove temporary files a killed earlier attempt of this job left behind."""
    if not directory.is_dir():
        return
    for path in directory.glob(".*.tmp*"):
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            with contextlib.suppress(OSError):
                path.unlink()


def seed_directory(directory: Path, leader: int, seed: int) -> Path:
    """Where the record of ``seed`` goes when a job trains a batch led by ``leader``
    (whose directory Hydra chose): the same path with its ``seed<leader>`` component
    replaced, so every seed's record sits where a job of its own would put it."""
    directory = Path(directory)
    if seed == leader:
        return directory
    parts = list(directory.parts)
    for i in range(len(parts) - 1, -1, -1):
        if parts[i] == f"seed{leader}":
            parts[i] = f"seed{seed}"
            return Path(*parts)
    return directory / f"seed{seed}"


def _seed_config(cfg: DictConfig, seed: int) -> DictConfig:
    """The config of one seed of a batch: as if it had run alone."""
    one = copy.deepcopy(cfg)
    with open_dict(one):
        one.seed = seed
        if "seed_batch" in one:
            one.seed_batch = None
    return one


def _seed_overrides(overrides: list[str] | None, seed: int) -> list[str] | None:
    if overrides is None:
        return None
    keep = [o for o in overrides if o.lstrip("+~").split("=", 1)[0] not in ("seed", "seed_batch")]
    return [*keep, f"seed={seed}"]


_unlimited_warned = False


@contextlib.contextmanager
def time_limit(seconds: Optional[float]) -> Iterator[bool]:
    """Raise :class:`~hnnbench._contracts.errors.JobTimeout` in this thread once ``seconds`` of
    wall-clock time have passed inside the block (``None`` or ``0``: no limit); yields
    whether a limit is in force. After the first, the alarm repeats every second until
    the block is left, so a plugin that swallows one (``except BaseException``) gets
    another. An outer ``SIGALRM`` timer (its handler and what is left of its delay) is
    restored afterwards. See the module docstring for what it can interrupt."""
    global _unlimited_warned
    if not seconds or seconds <= 0:
        yield False
        return
    if (
        not hasattr(signal, "setitimer")
        or threading.current_thread() is not threading.main_thread()
    ):
        if not _unlimited_warned:
            _unlimited_warned = True
            log.warning(
                "timeout_s=%g is not enforced here: the time limit needs a job "
                "run in a process's main thread on Unix, and this one is not",
                seconds,
            )
        yield False
        return
    armed = [True]

    def on_alarm(signum: int, frame: Any) -> None:
        if armed[0]:
            raise JobTimeout(seconds)

    previous = signal.signal(signal.SIGALRM, on_alarm)
    outer_delay, outer_interval = signal.setitimer(signal.ITIMER_REAL, seconds, 1.0)
    start = time.monotonic()
    try:
        yield True
    finally:
        while True:  # an alarm in the middle of disarming is ignored, never leaks out
            try:
                armed[0] = False
                signal.setitimer(signal.ITIMER_REAL, 0)
                signal.signal(signal.SIGALRM, previous)
                if outer_delay > 0:
                    left = outer_delay - (time.monotonic() - start)
                    signal.setitimer(signal.ITIMER_REAL, max(left, 1e-3), outer_interval)
                break
            except JobTimeout:
                continue


def _failure_text(err: BaseException) -> str:
    """``Type: first line of the message`` (``SystemExit: 3``; the type alone when the
    message is empty)."""
    text = str(err).strip()
    return f"{type(err).__name__}: {text}".splitlines()[0] if text else type(err).__name__


@dataclasses.dataclass
class SeedOutcome:
    """One seed's record from :func:`run_job`; ``kept``: a finished record of an earlier
    run, reused (resume), not this run's work."""

    record: dict[str, Any]
    kept: bool

    def as_outcome(self) -> dict[str, Any]:
        """``{"record", "kept"}``: what the Hydra task returns for the sweeper."""
        return {"record": self.record, "kept": self.kept}


def run_job(
    cfg: DictConfig,
    directory: Path,
    index: int | None = None,
    total: int | None = None,
    overrides: list[str] | None = None,
) -> list[SeedOutcome]:
    """Run the job's seed, or its batch of seeds (``seed_batch``, from
    ``seeds_per_job``), and write one record per seed into ``directory``; return them in
    seed order. Never raises for a problem of the job itself (bad config, data, model,
    NaNs): its records say ``failed`` or ``diverged``. ``overrides`` (Hydra's task
    overrides) are stored in the records so that the job can be re-run exactly;
    ``index`` and ``total`` number its log lines (``[k/N]``).

    A batch trains all its seeds in one program (:meth:`hnnbench._contracts.plugin.Model.fit_seeds`)
    and writes each seed's record where a job of its own would (:func:`seed_directory`),
    as if it had run alone (``seed_batch`` records the batch). Seeds already finished
    are not run again (resume); one seed that diverges or fails leaves the others'
    records unaffected.
    """
    directory = Path(directory)
    batch = _select(cfg, "seed_batch")
    seeds = [int(s) for s in batch] if batch else [int(_select(cfg, "seed") or 0)]
    system, model = (_select(cfg, k) for k in ("system.name", "model.name"))
    count = f"[{index + 1}/{total}] " if index is not None and total else ""
    dirs = {seed: seed_directory(directory, seeds[0], seed) for seed in seeds}
    done: dict[int, dict[str, Any]] = {}
    kept: set[int] = set()
    for seed in seeds:
        existing = records.read_record(dirs[seed] / records.RECORD_NAME)
        if not existing or existing.get("status") not in records.FINISHED or _select(cfg, "rerun"):
            continue
        change = config_change(
            existing.get("config"), _config_container(_seed_config(cfg, seed) if batch else cfg)
        )
        if change is None:
            log.info(
                "%s%s x %s seed=%s: already finished (%s), skipped; rerun=true redoes it",
                count,
                system,
                model,
                seed,
                existing["status"],
            )
            done[seed] = existing
            kept.add(seed)
            continue
        # A record of other settings is not this job's result, and is not overwritten.
        message = (
            f"{dirs[seed]} holds a finished record of other settings ({change}): "
            "resume with the settings it was run with, choose another "
            "hydra.sweep.dir, or add rerun=true to replace it"
        )
        log.error("%s%s x %s seed=%s: not run: %s", count, system, model, seed, message)
        done[seed] = {**_base_record(cfg, overrides), "seed": seed, "error": message}
    pending = [s for s in seeds if s not in done]
    if not pending:
        return [SeedOutcome(done[s], s in kept) for s in seeds]

    batch_text = f" (seeds {','.join(map(str, pending))} as one batch)" if len(pending) > 1 else ""
    tags = {s: f"{system} x {model} seed={s}" for s in pending}
    runs: dict[int, dict[str, Any]] = {}
    for seed in pending:
        _clean_stale(dirs[seed])
        one_cfg = _seed_config(cfg, seed) if batch else cfg
        runs[seed] = _base_record(one_cfg, _seed_overrides(overrides, seed) if batch else overrides)
        if len(seeds) > 1:
            runs[seed]["seed_batch"] = seeds
    start, cpu_start = time.perf_counter(), time.process_time()
    log.info(
        "%s%s x %s seed=%s: start%s", count, system, model, ",".join(map(str, pending)), batch_text
    )
    limit = _timeout_seconds(cfg)
    limit = limit * len(pending) if limit else None  # per seed: a batch gets N times it
    try:
        with time_limit(limit):
            job = _prepared(cfg) or prepare_job(cfg)
            # The job's cache_dir and data_dir settings hold for all it does: the dataset
            # cache, measured data files (data.locate) and the JAX compilation cache.
            # A plugin's changes to the process (environment, working directory,
            # global settings) end with its job (_running/isolation.py).
            with (
                isolation.isolated(),
                paths.overrides(cache_dir=cfg.cache_dir, data_dir=cfg.data_dir),
            ):
                _execute(job, cfg, pending, dirs, runs)
    except KeyboardInterrupt:
        raise
    except JobTimeout as err:
        # Every seed not finished when the limit struck: its record says so, with where
        # the job was (the last lines of the traceback).
        for record in runs.values():
            if record["status"] == "failed" and not record.get("error"):
                record.update(status="timeout", error=str(err))
                record["traceback"] = traceback.format_exc()
    except HnnbenchError as err:
        for record in runs.values():
            if record["status"] == "failed" and not record.get("error"):
                record.update(status="failed", error=str(err))
    except BaseException as err:  # noqa: BLE001 - sys.exit() in a plugin too; the sweep goes on
        for record in runs.values():
            if record["status"] == "failed" and not record.get("error"):
                record.update(status="failed", error=_failure_text(err))
                record["traceback"] = traceback.format_exc()
    elapsed = time.perf_counter() - start
    # CPU seconds of the job's process, all threads: unlike total_s (wall time), it does
    # not count time the process spent waiting, e.g. paused or crowded out on a shared host.
    cpu = time.process_time() - cpu_start
    for seed, record in runs.items():
        record["timings"]["total_s"] = elapsed / len(pending)
        record["timings"]["cpu_s"] = cpu / len(pending)
        if len(pending) > 1:
            record["timings"]["batch_total_s"] = elapsed
        try:
            records.write_record(dirs[seed], record)
        except Exception as err:  # e.g. a full disk: say so, and let the sweep go on
            log.error(
                "%s%s: could not write %s: %s",
                count,
                tags[seed],
                dirs[seed] / records.RECORD_NAME,
                err,
            )
        else:  # the record is written: hand it to the trackers asked for (never raises)
            if _select(cfg, "log_to"):
                tracking.export(
                    record, dirs[seed], _select(cfg, "log_to"), _select(cfg, "mlflow_uri")
                )
        _log_outcome(count, tags[seed], record)
    return [
        SeedOutcome(done[s], s in kept) if s in done else SeedOutcome(runs[s], False) for s in seeds
    ]


def _prepared(cfg: DictConfig) -> Optional[Job]:
    """The job the command's plan validated for exactly this config, in the command's
    own process (:attr:`~hnnbench._running.launch_context.LaunchContext.prepared`), so
    that it is not validated twice; ``None`` elsewhere (a launcher's worker validates
    its job's config itself)."""
    context = launch_context.local()
    if context is None or not context.prepared:
        return None
    key = fingerprint(cfg)
    job = context.prepared.pop(key, None) if key is not None else None
    return copy.deepcopy(job) if job is not None else None


def _timeout_seconds(cfg: DictConfig) -> Optional[float]:
    """The job's ``timeout_s`` (``None``: no limit; a bad value is left to
    :func:`~hnnbench._running.config.prepare_job`, which fails the job with the reason)."""
    value = _select(cfg, "timeout_s")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if value > 0 and value < float("inf") else None


def _execute(
    job: Job,
    cfg: DictConfig,
    seeds: list[int],
    dirs: dict[int, Path],
    runs: dict[int, dict[str, Any]],
) -> None:
    system = job.system_cls(job.system_cfg)
    family = getattr(job.model_cls, "family", None)
    for record in runs.values():
        record.update(
            system_version=system.version,
            model_version=job.model_cls.version,
            backend=job.model_cls.backend,
            family=getattr(family, "name", None),
            ranked=bool(getattr(job.model_cls, "ranked", True)),
            reference=getattr(job.model_cls, "reference", None),
            plugins={
                "system": plugin_provenance("system", str(cfg.system.name)),
                "model": plugin_provenance("model", str(cfg.model.name)),
            },
        )
    reason = job.model_cls.unsupported_reason(system)
    if (
        reason is None
        and cfg.get("track") == "recipe"
        and not getattr(job.model_cls, "recipe", None)
    ):
        reason = (
            "it declares no published recipe, so it has no recipe-track row "
            "(docs/TUNING.md, 'Recipes'; hnnbench list shows the models with one)"
        )
    if reason is not None:
        for record in runs.values():
            record.update(
                status="skipped", error=f"{cfg.model.name} on {cfg.system.name}: {reason}"
            )
        return
    _set_threads(int(cfg.threads))
    pin = cfg.get("pin_cpu")
    if pin or (pin is None and int(cfg.threads) == 1 and affinity.started_by_cli()):
        core = affinity.claim_core()
        for record in runs.values():
            record["cpu_pin"] = core
        if core is not None:
            _warn_if_xla_started()
    device_share.apply_device_share(str(cfg.device), int(cfg.get("device_share", 1)))

    datas, trajs = {}, {}
    for seed in seeds:
        t0 = time.perf_counter()
        (data, data_path, data_hit), (traj, traj_path, _) = dataset_cache.system_data(system, seed)
        if data.valid is None:
            rule = datasets.validation_rule(data)
            data = datasets.with_validation(data, seed)  # carved from train, not test
        else:  # the system's own (a measured series' fold)
            rule = str(data.meta.get("validation", "the system's own validation split"))
        assert data.valid is not None
        runs[seed]["timings"]["data_s"] = time.perf_counter() - t0
        runs[seed]["data"] = {
            "cache_hit": data_hit,
            "dataset_sha256": paths.sha256_file(data_path),
            "evaluation_sha256": paths.sha256_file(traj_path),
            "n_train": len(data.train),
            "n_valid": len(data.valid),
            "validation": rule,
            "n_test": len(data.test),
            "n_eval_traj": int(traj.states.shape[0]),
            "meta": data.meta,
            "evaluation_meta": traj.meta,
        }
        datas[seed], trajs[seed] = data, traj

    train = TrainSettings.resolve(job.system_cfg, job.model_cfg)
    for record in runs.values():
        record["train"] = dataclasses.asdict(train)
    label = f"{cfg.system.name}/{cfg.model.name} s{','.join(map(str, seeds))}"
    t0 = time.perf_counter()
    try:
        model = job.model_cls(job.model_cfg, system, str(cfg.device))
        with TrainingProgress(label, train.steps) as bar:
            if len(seeds) == 1:
                fits = [(model, model.fit(datas[seeds[0]], train, seeds[0], bar.update))]
            else:
                fits = model.fit_seeds([datas[s] for s in seeds], train, seeds, bar.update)
    except UnsupportedPair as err:
        for record in runs.values():
            record.update(status="skipped", error=f"{cfg.model.name} on {cfg.system.name}: {err}")
        return
    except RolloutDiverged as err:  # the contract: divergence comes back in FitResult
        raise HnnbenchError(
            f"{cfg.model.name}.fit raised RolloutDiverged ({err}); a model reports training "
            "divergence as FitResult(diverged=...) instead (docs/PLUGINS.md)"
        ) from None
    fit_s = (time.perf_counter() - t0) / len(seeds)
    for seed, (trained, fit) in zip(seeds, fits, strict=True):
        record = runs[seed]
        record["device"] = model.device
        record["timings"]["fit_s"] = fit_s
        if len(seeds) > 1:
            record["timings"]["batch_fit_s"] = fit_s * len(seeds)
        _finish(record, system, trained, fit, datas[seed], trajs[seed], cfg, dirs[seed])


def _finish(
    record: dict[str, Any],
    system: Any,
    model: Any,
    fit: FitResult,
    data: Dataset,
    traj: Trajectories,
    cfg: DictConfig,
    directory: Path,
) -> None:
    """Record one trained seed: its training log, weights, evaluation and status."""
    timings: dict[str, float] = record["timings"]
    if fit.diverged is not None:
        timings.update(model.timings)
        _diverged(record, system, f"training diverged: {fit.diverged}")
        return
    history = fit.history
    record["steps"] = fit.steps
    if fit.steps == 0:  # no training loop (closed form, oracle): no protocol used
        record["train"] = None
    if fit.selection is not None:
        record["selection"] = fit.selection.as_record()
    elif _history_diverged(history):  # a model that keeps its last iterate
        timings.update(model.timings)
        record["history"] = history
        _diverged(record, system, f"training diverged: {_history_diverged(history)}")
        return
    if cfg.save_model:
        record["weights_file"] = _save_model(model, directory)

    t0 = time.perf_counter()
    ev = EvaluationConfig(**OmegaConf.to_container(cfg.evaluation, resolve=True))  # type: ignore[arg-type]
    # evaluation.metrics: only those (a tuner's trial: the metric it selects on alone).
    chosen = (
        None if ev.metrics is None else [m for m in registry.metrics() if m.name in set(ev.metrics)]
    )
    label = f"{cfg.system.name}/{cfg.model.name} s{record.get('seed')}"
    with EvaluationProgress(label) as shown:
        result = evaluate(system, model, data, traj, ev, chosen, progress=shown.update)
    timings["eval_s"] = time.perf_counter() - t0
    timings.update({k: v for k, v in model.timings.items() if k not in timings})
    record["metrics"] = result.metrics
    if result.errors:
        record["metric_errors"] = result.errors
    record["history"] = history
    _save_arrays(directory, result.arrays, history)
    if result.diverged:
        record.update(status="diverged", error=result.diverged)
    else:
        record["status"] = "ok"


def _history_diverged(history: dict) -> str | None:
    """Why the training log shows divergence (a non-finite value in a loss column: any
    column but the step), or ``None``."""
    for key in [k for k in history if k != HISTORY_STEP]:
        try:
            values = np.asarray(history.get(key, []), dtype=np.float64)
        except (TypeError, ValueError):
            continue
        if values.size and not np.all(np.isfinite(values)):
            step = int(np.argmax(~np.isfinite(values)))
            steps = history.get(HISTORY_STEP) or []
            at = f" at step {steps[step]}" if step < len(steps) else ""
            return f"{key} became {values[step]}{at}"
    return None


def _diverged(record: dict[str, Any], system: Any, error: str) -> None:
    record["metrics"] = failed_metrics(system, registry.metrics())
    record.update(status="diverged", error=error)


def _log_outcome(count: str, tag: str, record: dict[str, Any]) -> None:
    status = record["status"]
    secs = record["timings"].get("total_s", 0.0)
    if status == "ok":
        m = record["metrics"]
        shown = "  ".join(
            f"{metric.name}={m[metric.name]['mean']:.3g}"
            for metric in registry.metrics()
            if metric.log and metric.name in m
        )
        log.info("%s%s: ok in %.1f s  %s", count, tag, secs, shown)
    else:
        log.warning("%s%s: %s in %.1f s: %s", count, tag, status, secs, record.get("error"))
