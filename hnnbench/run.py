"""One job: dataset -> fit -> evaluate -> record.

A job is self-contained: it reads its composed config and writes ``result.json`` (and
``rollout.npz``, the trained weights) into its own directory, so any Hydra launcher can
run it. It never raises for a problem of its own run: a diverging model is recorded as
``diverged``, an exception as ``failed``, an unsupported (system, model) pair as
``skipped``, and the sweep goes on.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import shlex
import shutil
import sys
import time
import traceback
import uuid
from pathlib import Path
from typing import Any, Optional

import numpy as np
import threadpoolctl
from omegaconf import DictConfig, OmegaConf

from hnnbench import affinity, cache, launch, paths, records, registry
from hnnbench.api import Dataset, TrainSettings, Trajectories
from hnnbench.config import EvaluationConfig, Job, prepare_job
from hnnbench.errors import HnnbenchError, RolloutDiverged, UnsupportedPair
from hnnbench.evaluate import evaluate, failed_metrics
from hnnbench.progress import TrainingProgress

log = logging.getLogger("hnnbench")

__all__ = ["run_job"]


def _set_threads(threads: int) -> None:
    """Cap every CPU thread pool the job computes with at ``threads`` (0: leave them).

    BLAS and OpenMP libraries read ``OMP_NUM_THREADS`` and the like only when they load,
    and numpy's OpenBLAS is loaded long before a job starts, so the environment alone
    leaves it at one thread per core. threadpoolctl caps the pools already loaded
    (numpy's OpenBLAS, torch's OpenMP) and the environment those loaded later. Left at
    two threads, OpenBLAS on a job pinned to one core (:mod:`hnnbench.affinity`) spends
    its time in two threads waiting on each other: a QR of 1568 x 200 took 0.8 s instead
    of 0.02 s, half the time of a quick pixel-pendulum job.
    """
    if threads <= 0:
        return
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = str(threads)
    threadpoolctl.threadpool_limits(limits=threads)
    if "torch" in sys.modules:
        import torch

        torch.set_num_threads(threads)


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


def _base_record(cfg: DictConfig, overrides: list[str] | None) -> dict[str, Any]:
    context = launch.current()
    command = context.command if context is not None else None
    job_overrides = [o for o in overrides or [] if not o.startswith(("hydra.", "hydra/"))]
    return {
        "schema_version": records.SCHEMA_VERSION,
        "system": _select(cfg, "system.name"),
        "system_version": None,
        "model": _select(cfg, "model.name"),
        "model_version": None,
        "backend": None,
        "seed": _select(cfg, "seed"),
        "profile": _select(cfg, "profile.name"),
        "status": "failed",
        "error": None,
        "metrics": {},
        "timings": {},
        "steps": 0,
        "device": None,
        "data": {},
        "config": _config_container(cfg),
        # How to run exactly this job again (the resolved config above is the truth;
        # these are the command lines that produced it).
        "overrides": list(overrides) if overrides is not None else None,
        "command": command,
        "rerun_command": shlex.join(["hnnbench", *job_overrides])
        if overrides is not None else None,
        "environment": records.environment(),
        "created_at": records.now_iso(),
    }


def _save_arrays(directory: Path, arrays: dict[str, np.ndarray], history: dict) -> None:
    payload = {k: np.asarray(v) for k, v in arrays.items()}
    payload.update({f"history.{k}": np.asarray(v, dtype=np.float64) for k, v in history.items()})
    with records.atomic_path(directory / "rollout.npz") as tmp, open(tmp, "wb") as fh:
        np.savez_compressed(fh, **payload)


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


def _check_finite(record: dict[str, Any]) -> None:
    """A finished job whose train/test loss is NaN/inf is ``diverged``, with inf
    losses, whatever the model and the rollouts said."""
    means = {k: record["metrics"].get(k, {}).get("mean") for k in ("train_loss", "test_loss")}
    bad = [k for k, v in means.items() if isinstance(v, (int, float)) and not np.isfinite(v)]
    if not bad:
        return
    for key in bad:
        record["metrics"][key]["mean"] = float("inf")
    if record["status"] == "ok":
        record.update(status="diverged", error=f"non-finite {' and '.join(bad)}")


def run_job(
    cfg: DictConfig, directory: Path, index: int | None = None, total: int | None = None,
    overrides: list[str] | None = None,
) -> dict[str, Any]:
    """Run one job and write its record into ``directory``; return the record.

    Never raises for a problem of the job itself (bad config, data, model, NaNs): the
    record says ``failed`` or ``diverged``. ``overrides`` (Hydra's task overrides) are
    stored in the record so the job can be re-run exactly.
    """
    directory = Path(directory)
    system, model, seed = (_select(cfg, k) for k in ("system.name", "model.name", "seed"))
    tag = f"{system} x {model} seed={seed}"
    count = f"[{index + 1}/{total}] " if index is not None and total else ""
    existing = records.read_record(directory / records.RECORD_NAME)
    if existing and existing.get("status") in records.FINISHED and not _select(cfg, "rerun"):
        log.info("%s%s: already finished (%s), skipped; rerun=true redoes it",
                 count, tag, existing["status"])
        return existing

    _clean_stale(directory)
    record = _base_record(cfg, overrides)
    timings: dict[str, float] = record["timings"]
    start = time.perf_counter()
    log.info("%s%s: start", count, tag)
    try:
        job = prepare_job(cfg)
        # The job's cache_dir and data_dir settings hold for all it does: the dataset
        # cache, measured data files (data.locate) and the JAX compilation cache.
        with paths.overrides(cache_dir=cfg.cache_dir, data_dir=cfg.data_dir):
            _execute(job, cfg, directory, record, timings)
    except HnnbenchError as err:
        record.update(status="failed", error=str(err))
    except Exception as err:  # isolate the failure; the sweep goes on
        record.update(status="failed", error=f"{type(err).__name__}: {err}".splitlines()[0])
        record["traceback"] = traceback.format_exc()
    timings["total_s"] = time.perf_counter() - start
    try:
        records.write_record(directory, record)
    except Exception as err:  # e.g. a full disk: say so, and let the sweep go on
        log.error("%s%s: could not write %s: %s", count, tag,
                  directory / records.RECORD_NAME, err)
    _log_outcome(count, tag, record)
    return record


def _execute(
    job: Job, cfg: DictConfig, directory: Path, record: dict[str, Any],
    timings: dict[str, float],
) -> None:
    system = job.system_cls(job.system_cfg)
    family = getattr(job.model_cls, "family", None)
    record.update(system_version=system.version, model_version=job.model_cls.version,
                  backend=job.model_cls.backend, family=getattr(family, "name", None),
                  ranked=bool(getattr(job.model_cls, "ranked", True)))
    reason = job.model_cls.unsupported_reason(system)
    if reason is not None:
        record.update(status="skipped", error=f"{cfg.model.name} on {cfg.system.name}: {reason}")
        return
    _set_threads(int(cfg.threads))
    pin = cfg.get("pin_cpu")
    if pin or (pin is None and int(cfg.threads) == 1 and affinity.started_by_cli()):
        record["cpu_pin"] = affinity.claim_core()
    seed = int(cfg.seed)

    t0 = time.perf_counter()
    data, data_path, data_hit = cache.cached(system, seed, "dataset", lambda: system.dataset(seed),
                                             Dataset.load)
    traj, traj_path, _ = cache.cached(system, seed, "evaluation",
                                      lambda: system.evaluation(seed), Trajectories.load)
    timings["data_s"] = time.perf_counter() - t0
    record["data"] = {
        "cache_hit": data_hit,
        "dataset_sha256": paths.sha256_file(data_path),
        "evaluation_sha256": paths.sha256_file(traj_path),
        "n_train": len(data.train),
        "n_test": len(data.test),
        "n_eval_traj": int(traj.states.shape[0]),
        "meta": data.meta,
        "evaluation_meta": traj.meta,
    }

    train = TrainSettings.resolve(job.system_cfg, job.model_cfg)
    record["train"] = dataclasses.asdict(train)
    t0 = time.perf_counter()
    history: dict = {}
    try:
        model = job.model_cls(job.model_cfg, system, str(cfg.device))
        record["device"] = model.device
        with TrainingProgress(f"{cfg.system.name}/{cfg.model.name} s{seed}", train.steps) as bar:
            fit = model.fit(data, train, seed, bar.update)
        history = fit.history
        record["steps"] = fit.steps
        if fit.steps == 0:  # no training loop (closed form, oracle): no protocol used
            record["train"] = None
    except UnsupportedPair as err:
        record.update(status="skipped", error=f"{cfg.model.name} on {cfg.system.name}: {err}")
        return
    except RolloutDiverged as err:
        timings["fit_s"] = time.perf_counter() - t0
        timings.update(model.timings)
        _diverged(record, system, f"training diverged: {err}")
        return
    timings["fit_s"] = time.perf_counter() - t0
    if _history_diverged(history):
        timings.update(model.timings)
        record["history"] = history
        _diverged(record, system, f"training diverged: {_history_diverged(history)}")
        return
    if cfg.save_model:
        record["weights_file"] = _save_model(model, directory)

    t0 = time.perf_counter()
    ev = EvaluationConfig(**OmegaConf.to_container(cfg.evaluation, resolve=True))  # type: ignore[arg-type]
    result = evaluate(system, model, data, traj, ev)
    timings["eval_s"] = time.perf_counter() - t0
    timings.update(model.timings)
    record["metrics"] = result.metrics
    if result.errors:
        record["metric_errors"] = result.errors
    record["history"] = history
    _save_arrays(directory, result.arrays, history)
    if result.diverged:
        record.update(status="diverged", error=result.diverged)
    else:
        record["status"] = "ok"
    _check_finite(record)


def _history_diverged(history: dict) -> str | None:
    """Why the training log shows divergence (a non-finite loss), or ``None``."""
    for key in ("train_loss", "test_loss"):
        values = np.asarray(history.get(key, []), dtype=np.float64)
        if values.size and not np.all(np.isfinite(values)):
            step = int(np.argmax(~np.isfinite(values)))
            steps = history.get("step") or []
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
        log.info("%s%s: ok in %.1f s  test_loss=%.3g  energy_mse=%.3g", count, tag, secs,
                 m["test_loss"]["mean"], m["energy_mse"]["mean"])
    else:
        log.warning("%s%s: %s in %.1f s: %s", count, tag, status, secs, record.get("error"))
