"""One job: dataset -> fit -> evaluate -> record.

A job is self-contained: it reads its composed config and writes ``result.json`` (and
``rollout.npz``, the trained weights) into its own directory, so any Hydra launcher can
run it. It never raises for a problem of its own run: a diverging model is recorded as
``diverged``, an exception as ``failed``, an unsupported (system, model) pair as
``skipped``, and the sweep goes on.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from hnnbench import cache, records
from hnnbench.api import Dataset, Trajectories, TrainSettings
from hnnbench.config import EvaluationConfig, Job, prepare_job
from hnnbench.errors import HnnbenchError, RolloutDiverged
from hnnbench.evaluate import ROLLOUT_METRICS, evaluate
from hnnbench.progress import TrainingProgress

log = logging.getLogger("hnnbench")

__all__ = ["run_job"]


def _set_threads(threads: int) -> None:
    if threads <= 0:
        return
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[var] = str(threads)
    if "torch" in sys.modules:
        import torch

        torch.set_num_threads(threads)


def _base_record(cfg: DictConfig) -> dict[str, Any]:
    return {
        "schema_version": records.SCHEMA_VERSION,
        "system": cfg.system.name,
        "system_version": None,
        "model": cfg.model.name,
        "model_version": None,
        "backend": None,
        "seed": cfg.seed,
        "profile": cfg.profile.name,
        "status": "failed",
        "error": None,
        "metrics": {},
        "timings": {},
        "steps": 0,
        "device": None,
        "data": {},
        "config": OmegaConf.to_container(cfg, resolve=True),
        "environment": records.environment(),
        "created_at": records.now_iso(),
    }


def _save_arrays(directory: Path, arrays: dict[str, np.ndarray], history: dict) -> None:
    payload = {k: np.asarray(v) for k, v in arrays.items()}
    payload.update({f"history.{k}": np.asarray(v, dtype=np.float64) for k, v in history.items()})
    tmp = directory / f".rollout.{os.getpid()}.tmp.npz"
    np.savez_compressed(tmp, **payload)
    os.replace(tmp, directory / "rollout.npz")


def run_job(
    cfg: DictConfig, directory: Path, index: int | None = None, total: int | None = None
) -> dict[str, Any]:
    """Run one job and write its record into ``directory``; return the record."""
    directory = Path(directory)
    tag = f"{cfg.system.name} x {cfg.model.name} seed={cfg.seed}"
    count = f"[{index + 1}/{total}] " if index is not None and total else ""
    existing = records.read_record(directory / records.RECORD_NAME)
    if existing and existing.get("status") in records.FINISHED and not cfg.rerun:
        log.info("%s%s: already finished (%s), skipped; rerun=true redoes it",
                 count, tag, existing["status"])
        return existing

    record = _base_record(cfg)
    timings: dict[str, float] = record["timings"]
    start = time.perf_counter()
    log.info("%s%s: start", count, tag)
    try:
        job = prepare_job(cfg)
        _execute(job, cfg, directory, record, timings)
    except HnnbenchError as err:
        record.update(status="failed", error=str(err))
    except Exception as err:  # isolate the failure; the sweep goes on
        record.update(status="failed", error=f"{type(err).__name__}: {err}".splitlines()[0])
        record["traceback"] = traceback.format_exc()
    timings["total_s"] = time.perf_counter() - start
    records.write_record(directory, record)
    _log_outcome(count, tag, record)
    return record


def _execute(
    job: Job, cfg: DictConfig, directory: Path, record: dict[str, Any],
    timings: dict[str, float],
) -> None:
    system = job.system_cls(job.system_cfg)
    record.update(system_version=system.version, model_version=job.model_cls.version,
                  backend=job.model_cls.backend)
    reason = job.model_cls.unsupported_reason(system)
    if reason is not None:
        record.update(status="skipped", error=f"{cfg.model.name} on {cfg.system.name}: {reason}")
        return
    _set_threads(int(cfg.threads))
    root = cache.cache_root(cfg.cache_dir)
    seed = int(cfg.seed)

    t0 = time.perf_counter()
    data, data_path, data_hit = cache.cached(system, seed, "dataset", lambda: system.dataset(seed),
                                             Dataset.load, root)
    traj, traj_path, _ = cache.cached(system, seed, "evaluation",
                                      lambda: system.evaluation(seed), Trajectories.load, root)
    timings["data_s"] = time.perf_counter() - t0
    record["data"] = {
        "cache_hit": data_hit,
        "dataset_sha256": cache.file_sha256(data_path),
        "evaluation_sha256": cache.file_sha256(traj_path),
        "n_train": len(data.train),
        "n_test": len(data.test),
        "n_eval_traj": int(traj.states.shape[0]),
        "meta": data.meta,
        "evaluation_meta": traj.meta,
    }

    model = job.model_cls(job.model_cfg, system, str(cfg.device))
    record["device"] = model.device
    train = TrainSettings.resolve(job.system_cfg, job.model_cfg)
    record["train"] = dataclasses.asdict(train)
    t0 = time.perf_counter()
    history: dict = {}
    try:
        with TrainingProgress(f"{cfg.system.name}/{cfg.model.name} s{seed}", train.steps) as bar:
            fit = model.fit(data, train, seed, bar.update)
        history = fit.history
        record["steps"] = fit.steps
    except RolloutDiverged as err:
        timings["fit_s"] = time.perf_counter() - t0
        timings.update(model.timings)
        inf = {"mean": float("inf"), "sem": float("nan")}
        record["metrics"] = {k: dict(inf) for k in ("train_loss", "test_loss", *ROLLOUT_METRICS)}
        record.update(status="diverged", error=f"training diverged: {err}")
        return
    timings["fit_s"] = time.perf_counter() - t0
    if cfg.save_model:
        try:
            model.save(directory / "weights.safetensors")
        except NotImplementedError:
            pass

    t0 = time.perf_counter()
    ev = EvaluationConfig(**OmegaConf.to_container(cfg.evaluation, resolve=True))  # type: ignore[arg-type]
    result = evaluate(system, model, data, traj, ev)
    timings["eval_s"] = time.perf_counter() - t0
    timings.update(model.timings)
    record["metrics"] = result.metrics
    record["history"] = history
    _save_arrays(directory, result.arrays, history)
    if result.diverged:
        record.update(status="diverged", error=result.diverged)
    else:
        record["status"] = "ok"


def _log_outcome(count: str, tag: str, record: dict[str, Any]) -> None:
    status = record["status"]
    secs = record["timings"].get("total_s", 0.0)
    if status == "ok":
        m = record["metrics"]
        log.info("%s%s: ok in %.1f s  test_loss=%.3g  energy_mse=%.3g", count, tag, secs,
                 m["test_loss"]["mean"], m["energy_mse"]["mean"])
    else:
        log.warning("%s%s: %s in %.1f s: %s", count, tag, status, secs, record.get("error"))
