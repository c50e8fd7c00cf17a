"""Synthetic sweep directories for the report and check tests: real ``result.json``
records (via :func:`hnnbench._record.store.write_record`) and ``rollout.npz`` arrays in the
layout that :mod:`hnnbench._running.job` writes."""

from __future__ import annotations

import copy
import functools
import json
from pathlib import Path
from typing import Any

import numpy as np

from hnnbench import _record as records
from hnnbench import _registry as registry
from hnnbench._running.job import plugin_provenance

INF = float("inf")
NAN = float("nan")

#: (system, model) -> metric means of seed 0; seed s multiplies errors by (1 + 0.1 s).
BASE: dict[tuple[str, str], dict[str, float]] = {
    ("spring", "mlp_torch"): {
        "train_loss": 3.7e-2,
        "test_loss": 3.8e-2,
        "energy_mse": 4e-3,
        "rollout_mse": 0.2,
        "reversibility_error": 1e-8,
        "time_reversal_error": 3e-2,
        "valid_prediction_time": 1.2,
    },
    ("spring", "hnn_torch"): {
        "train_loss": 3.6e-2,
        "test_loss": 3.7e-2,
        "energy_mse": 2e-5,
        "rollout_mse": 0.1,
        "reversibility_error": 4e-8,
        "time_reversal_error": 3e-4,
        "valid_prediction_time": 4.0,
    },
    ("spring", "oracle"): {
        "train_loss": 4e-2,
        "test_loss": 4e-2,
        "energy_mse": 2e-16,
        "rollout_mse": 4e-17,
        "reversibility_error": 1e-8,
        "time_reversal_error": 1e-15,
        "valid_prediction_time": 20.0,
    },
    ("spring", "dhnn_torch"): {
        "train_loss": 3.6e-2,
        "test_loss": 3.8e-2,
        "energy_mse": 4e-4,
        "rollout_mse": 0.15,
        "reversibility_error": 4e-6,
        "time_reversal_error": 3e-3,
        "valid_prediction_time": 2.0,
    },
    ("pendulum", "mlp_torch"): {
        "train_loss": 5e-2,
        "test_loss": 5e-2,
        "energy_mse": 5e-2,
        "rollout_mse": 1.0,
        "reversibility_error": 2e-6,
        "time_reversal_error": 4.0,
        "valid_prediction_time": 3.7,
    },
    ("pendulum", "hnn_torch"): {
        "train_loss": 3.4e-2,
        "test_loss": 3.4e-2,
        "energy_mse": 1e-3,
        "rollout_mse": 8e-2,
        "reversibility_error": 2e-6,
        "time_reversal_error": 0.14,
        "valid_prediction_time": 3.9,
    },
}
BACKEND = {
    "mlp_torch": "torch",
    "hnn_torch": "torch",
    "mlp_jax": "jax",
    "hnn_jax": "jax",
    "oracle": "numpy",
}
HIGHER_BETTER = {"valid_prediction_time"}


def seed_metrics(system: str, model: str, seed: int) -> dict[str, float]:
    base = BASE.get((system, model)) or BASE[("spring", model.replace("jax", "torch"))]
    out = {}
    for name, value in base.items():
        f = 1.0 + 0.1 * seed
        out[name] = value / f if name in HIGHER_BETTER else value * f
    return out


def _arrays(
    system: str, model: str, seed: int, n_traj: int = 3, n_t: int = 25, steps: int = 20
) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 5.0, n_t)
    r = 0.2 + 0.8 * rng.random(n_traj)
    phase = rng.random(n_traj) * 2 * np.pi
    q = r[:, None] * np.cos(t[None] + phase[:, None])
    p = -r[:, None] * np.sin(t[None] + phase[:, None])
    true = np.stack([q, p], axis=-1)
    drift = 0.0 if model == "oracle" else (0.02 if model.startswith("hnn") else 0.1)
    hat = true * (1.0 + drift * t[None, :, None] / t[-1])
    arrays: dict[str, np.ndarray] = {
        "t": t,
        "states_true": true,
        "states_hat": hat,
        "energy_true": np.sum(true**2, axis=-1),
        "energy_hat": np.sum(hat**2, axis=-1),
    }
    if model.startswith("hnn") or model == "oracle":
        arrays["learned_energy"] = np.sum(hat**2, axis=-1) + 0.3
    if model != "oracle":
        step = np.arange(1, steps + 1, dtype=np.float64)
        arrays["history.step"] = step
        arrays["history.train_loss"] = 1.0 / step
        arrays["history.test_loss"] = 1.1 / step
    return arrays


def _installed_version(kind: str, name: str) -> str:
    """The installed plugin's version (records of other versions fail hnnbench check)."""
    info = registry.discover(kind).get(name)  # type: ignore[arg-type]
    return info.version if info is not None and info.ok else "1"


def _declared(model: str) -> dict[str, Any]:
    """``family``, ``backend``, ``ranked`` (and ``reference`` where it has one) as the
    installed model's class declares them (what a strict load compares a record's fields
    with); for a model not installed, guessed from its name."""
    info = registry.discover("model").get(model)
    if info is not None and info.ok:
        cls = info.cls
        out = {
            "backend": getattr(cls, "backend", None),
            "family": getattr(getattr(cls, "family", None), "name", None),
            "ranked": bool(getattr(cls, "ranked", True)),
        }
        if getattr(cls, "reference", None) is not None:
            out["reference"] = cls.reference
        return out
    return {
        "backend": BACKEND.get(model, model.rsplit("_", 1)[-1]),
        "family": model.rsplit("_", 1)[0] if model != "oracle" else None,
        "ranked": model != "oracle",
    }


@functools.cache
def _config_text(system: str, model: str, profile: str, overrides: tuple[str, ...]) -> str:
    from omegaconf import OmegaConf

    from hnnbench._running.compose import compose

    cfg = compose([f"system={system}", f"model={model}", f"profile={profile}", *overrides])
    return json.dumps(records.encode(OmegaConf.to_container(cfg, resolve=True)))


def job_config(
    system: str, model: str, seed: int, profile: str = "quick", overrides: tuple[str, ...] = ()
) -> dict[str, Any]:
    """The resolved config a job of these settings stores in its record."""
    config = json.loads(_config_text(system, model, profile, tuple(overrides)))
    config["seed"] = seed
    return config


def write_run(
    root: Path,
    system: str,
    model: str,
    seed: int,
    status: str = "ok",
    metrics: dict[str, float] | None = None,
    profile: str = "quick",
    rollout: bool = True,
    overrides: tuple[str, ...] = (),
) -> Path:
    """One job directory like ``run.py`` writes it; returns the directory. ``overrides``
    are the job's extra command-line overrides (its variant)."""
    directory = Path(root) / system / model / f"seed{seed}"
    if overrides:
        directory = directory / ",".join(sorted(overrides))
    directory.mkdir(parents=True, exist_ok=True)
    values = seed_metrics(system, model, seed) if metrics is None else metrics
    if status == "diverged" and metrics is None:
        # what a diverged job records: each rollout metric's worst value (Metric.worst)
        values = {
            k: (v if k.endswith("_loss") else 0.0 if k in HIGHER_BETTER else INF)
            for k, v in values.items()
        }
    if status in ("failed", "skipped"):
        values = {}
    record: dict[str, Any] = {
        "schema_version": records.SCHEMA_VERSION,
        "system": system,
        "system_version": _installed_version("system", system),
        "model": model,
        "model_version": _installed_version("model", model),
        **_declared(model),
        "seed": seed,
        "profile": profile,
        "status": status,
        "error": None if status == "ok" else f"synthetic {status}",
        "metrics": {k: {"mean": v, "sem": 0.1 * v} for k, v in values.items()},
        "timings": {
            "data_s": 0.1,
            "fit_s": 2.0 + seed,
            "eval_s": 1.0,
            "total_s": 3.1 + seed,
            "cpu_s": 2.1 + seed,
        },
        "steps": 20,
        "device": "cpu",
        "data": {},
        "command": f"hnnbench -m system={system} seed={seed}",
        "overrides": [f"system={system}", f"model={model}", f"seed={seed}", *overrides],
        "config": job_config(system, model, seed, profile, overrides),
        "plugins": {
            "system": plugin_provenance("system", system),
            "model": plugin_provenance("model", model),
        },
        "environment": records.environment(),
        "created_at": records.now_iso(),
    }
    records.write_record(directory, record)
    if rollout and status in ("ok", "diverged"):
        arrays = _arrays(system, model, seed)
        if status == "diverged":
            arrays = {
                k: v
                for k, v in arrays.items()
                if k in ("t", "states_true") or k.startswith("history.")
            }
        np.savez_compressed(directory / "rollout.npz", **arrays)
    return directory


PAIRS = (
    ("spring", "mlp_torch"),
    ("spring", "hnn_torch"),
    ("spring", "oracle"),
    ("pendulum", "mlp_torch"),
    ("pendulum", "hnn_torch"),
)


def make_sweep(root: Path, pairs=PAIRS, seeds=(0, 1), **kwargs: Any) -> Path:
    root = Path(root)
    for system, model in pairs:
        for seed in seeds:
            write_run(root, system, model, seed, **kwargs)
    return root


def scale_metric(root: Path, system: str, model: str, metric: str, factor: float) -> None:
    """Multiply ``metric`` of every record of (system, model) under ``root``."""
    for path in Path(root).rglob(records.RECORD_NAME):
        rec = records.read_record(path)
        assert rec is not None
        if rec["system"] == system and rec["model"] == model:
            rec = copy.deepcopy(rec)
            rec["metrics"][metric]["mean"] *= factor
            records.write_record(path.parent, rec)


def set_status(root: Path, system: str, model: str, seed: int, status: str) -> None:
    """Rewrite one run as ``status`` (diverged: infinite rollout metrics)."""
    import shutil

    directory = Path(root) / system / model / f"seed{seed}"
    profile = (records.read_record(directory / records.RECORD_NAME) or {}).get("profile", "quick")
    shutil.rmtree(directory)
    write_run(root, system, model, seed, status=status, profile=profile)


def tuned_rows_problems(
    tuned: list[dict[str, Any]], protocol: list[dict[str, Any]], least_seeds: int
) -> list[str]:
    """What breaks docs/TUNING.md's promise about tuned rows, read from their records
    (``tuned``) beside the protocol track's (``protocol``): on each system with tuned
    rows, every family the protocol ran there (skipped ones aside) is tuned; every
    study states its criterion (the one its runs were selected on), at least 2 seeds
    per trial and the protocol's settings as trial 0; families on one system had equal
    budgets (``budget_findings``); each family holds seeds 0..n-1, n at least
    ``least_seeds``; and the runs of one study (one per fold on a measured system)
    share its one selected configuration. Empty: nothing breaks it."""
    from hnnbench._record.tracks import track_problem
    from hnnbench._results.check.records import budget_findings

    problems = [
        f"{f.system}/{f.model}: unequal {f.metric}: {f.reference} against {f.current}"
        for f in budget_findings(tuned)
    ]
    ran: dict[str, set[str]] = {}
    for r in protocol:
        if r.get("ranked", True) and r["model"] != "oracle" and r.get("status") != "skipped":
            ran.setdefault(r["system"], set()).add(str(r["family"]))
    pairs: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in tuned:
        where = f"{r['system']}/{r['model']}/seed{r['seed']}"
        tuning = r["tuning"]
        problem = track_problem(r)
        if problem is not None:
            problems.append(f"{where}: {problem}")
        if tuning.get("criterion") != (r.get("selection") or {}).get("criterion"):
            problems.append(f"{where}: tuned on {tuning.get('criterion')}, selected on another")
        if not (tuning.get("seeds_per_trial") or 0) >= 2:
            problems.append(f"{where}: {tuning.get('seeds_per_trial')} seed(s) per trial")
        if tuning.get("protocol_trial") != 0:
            problems.append(f"{where}: the protocol's settings are not trial 0")
        pairs.setdefault((r["system"], str(r["family"])), []).append(r)
    for system in sorted({s for s, _ in pairs}):
        fams = {f for s, f in pairs if s == system}
        if fams != ran.get(system, set()):
            problems.append(
                f"{system}: tuned {sorted(fams)}, protocol {sorted(ran.get(system, []))}"
            )
    for (system, family), runs in sorted(pairs.items()):
        seeds = sorted(r["seed"] for r in runs)
        if len(seeds) < least_seeds or seeds != list(range(len(seeds))):
            problems.append(f"{system}/{family}: tuned seeds {seeds}")
        by_study: dict[str, set[str]] = {}
        for r in runs:
            chosen = json.dumps(r["tuning"]["selected"], sort_keys=True)
            by_study.setdefault(str(r["tuning"].get("study")), set()).add(chosen)
        problems += [
            f"{system}/{family}: study {study} selected {len(chosen)} configurations"
            for study, chosen in sorted(by_study.items())
            if len(chosen) != 1
        ]
    return problems
