"""Runs you can watch: each finished job exported to experiment trackers, MLflow and
TensorBoard, when the ``log_to`` setting asks for them (off by default).

The job hands each record to :func:`export` right after writing it
(:func:`hnnbench._running.job.run_job`; a record kept from an earlier run is not sent
again), which sends

- to **MLflow** (``log_to=mlflow``): one run per record, named
  ``<system>/<model>/seed<k>``, in the experiment ``hnnbench`` of the tracking store
  ``mlflow_uri`` (default: ``sqlite:///<sweep dir>/mlflow.db``; a single run's, in its
  own directory): the resolved config as parameters (dotted keys), every metric's mean
  (and its standard error as ``<metric>_sem``) and the timings (``timings/<name>``) as
  metrics, the training history as metric series over the steps
  (``history/<column>``), and the job's identity, status and record path as tags
  (``hnnbench.*``);
- to **TensorBoard** (``log_to=tensorboard``): event files in ``<job dir>/tensorboard/``
  with the same history, metrics and timings as scalars, and the config as text.

Non-finite values (``NaN``: not applicable; ``inf``: a diverged rollout) are left out of
both; the record keeps them. The trackers are optional (``pip install
'hnnbench[track]'``: mlflow-skinny and tensorboardX); asking for one that is not
installed is a one-line error before any job runs (:func:`check`). An export never fails
its job: a failure is logged as a warning, and the record stands as written.
"""

from __future__ import annotations

import contextlib
import difflib
import json
import logging
import math
import time
from collections.abc import Iterator, Mapping, Sequence
from importlib.util import find_spec
from pathlib import Path
from typing import Any, Optional

from hnnbench._contracts.errors import ConfigError

__all__ = ["INSTALL_HINT", "TRACKERS", "check", "default_mlflow_uri", "export", "parse_log_to"]

log = logging.getLogger("hnnbench")

#: The trackers ``log_to`` may name, and the module each needs.
TRACKERS: dict[str, str] = {"mlflow": "mlflow", "tensorboard": "tensorboardX"}
#: How to install them.
INSTALL_HINT = "pip install 'hnnbench[track]'"
#: The MLflow experiment every run goes to.
EXPERIMENT = "hnnbench"
#: The TensorBoard event files' folder in a job's directory.
TENSORBOARD_DIR = "tensorboard"
#: MLflow's limits per call of ``log_batch`` (params, metrics) and per param value.
_MAX_PARAMS, _MAX_METRICS, _MAX_VALUE = 100, 1000, 500


def parse_log_to(value: Any) -> tuple[str, ...]:
    """The trackers a ``log_to`` value names: ``None``, ``""`` or ``[]`` (none),
    ``"mlflow"``, ``"mlflow,tensorboard"`` or ``[mlflow, tensorboard]``; raises a
    one-line ConfigError with a did-you-mean for an unknown name."""
    if value is None:
        return ()
    if isinstance(value, str):
        items: list[Any] = value.split(",")
    elif isinstance(value, Sequence):  # a list, or Hydra's ListConfig
        items = list(value)
    else:
        items = [value]
    names: list[str] = []
    for item in items:
        if not isinstance(item, str):
            raise ConfigError(
                f"log_to={value} is invalid: expected tracker names, e.g. "
                f"log_to=[{','.join(TRACKERS)}]."
            )
        name = item.strip()
        if not name:
            continue
        if name not in TRACKERS:
            close = difflib.get_close_matches(name, list(TRACKERS), n=1)
            hint = f" Did you mean '{close[0]}'?" if close else ""
            raise ConfigError(
                f"log_to: unknown tracker '{name}'.{hint} Available: "
                f"{', '.join(TRACKERS)} (e.g. log_to=[mlflow,tensorboard])."
            )
        if name not in names:
            names.append(name)
    return tuple(names)


def check(log_to: Any, mlflow_uri: Any) -> tuple[str, ...]:
    """Validate the ``log_to`` and ``mlflow_uri`` settings and that the trackers named
    are installed (one-line ConfigError with the install hint); return the trackers."""
    trackers = parse_log_to(log_to)
    missing = [
        f"{name} needs {TRACKERS[name]}" for name in trackers if find_spec(TRACKERS[name]) is None
    ]
    if missing:
        raise ConfigError(
            f"log_to={','.join(trackers)}: {'; '.join(missing)}, which is not "
            f"installed: {INSTALL_HINT}"
        )
    if mlflow_uri is not None and (not isinstance(mlflow_uri, str) or not mlflow_uri.strip()):
        raise ConfigError(
            f"mlflow_uri={mlflow_uri} is invalid: expected an MLflow tracking "
            "URI, e.g. mlflow_uri=sqlite:////path/to/mlflow.db, or null for "
            "<sweep dir>/mlflow.db."
        )
    return trackers


def default_mlflow_uri(job_dir: Path) -> str:
    """``sqlite:///<dir>/mlflow.db`` where ``<dir>`` is the sweep directory of a
    multirun, else the job's own directory."""
    where = Path(job_dir)
    with contextlib.suppress(Exception):  # not inside a Hydra job: its own directory
        from hydra.core.hydra_config import HydraConfig
        from hydra.types import RunMode

        hydra = HydraConfig.get()
        if hydra.mode == RunMode.MULTIRUN:
            where = Path(str(hydra.sweep.dir))
    return f"sqlite:///{(where.resolve() / 'mlflow.db').as_posix()}"


def export(
    record: Mapping[str, Any], directory: Path, log_to: Any, mlflow_uri: Optional[str] = None
) -> list[str]:
    """Send a finished job's ``record`` (written in ``directory``) to the trackers of
    ``log_to``; never raises. Returns the warnings (each also logged)."""
    warnings: list[str] = []
    try:
        trackers = parse_log_to(log_to)
    except ConfigError as err:
        trackers, warnings = (), [str(err)]
    for name in trackers:
        try:
            if name == "mlflow":
                _to_mlflow(
                    record, Path(directory), mlflow_uri or default_mlflow_uri(Path(directory))
                )
            else:
                _to_tensorboard(record, Path(directory) / TENSORBOARD_DIR)
        except Exception as err:  # noqa: BLE001 - an exporter must not fail the job
            reason = " ".join(f"{type(err).__name__}: {err}".split())[:300]
            hint = f" ({INSTALL_HINT})" if isinstance(err, ImportError) else ""
            warnings.append(
                f"could not export {_label(record)} to {name}: {reason}{hint}; "
                "the record is unaffected"
            )
    for text in warnings:
        log.warning("%s", text)
    return warnings


# --------------------------------------------------------------------------- content


def _label(record: Mapping[str, Any]) -> str:
    return f"{record.get('system')}/{record.get('model')}/seed{record.get('seed')}"


def _flat(config: Any, prefix: str = "") -> dict[str, str]:
    """A nested config as ``{"system.n_traj": "20", ...}`` (values as JSON text, cut to
    MLflow's limit)."""
    out: dict[str, str] = {}
    if isinstance(config, Mapping):
        for key, value in config.items():
            out.update(_flat(value, f"{prefix}{key}."))
    elif prefix:
        text = config if isinstance(config, str) else json.dumps(config, default=str)
        out[prefix.rstrip(".")] = text[:_MAX_VALUE]
    return out


def _finite(value: Any) -> Optional[float]:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


#: A metric's values over the training steps: ``[(step, value), ...]``.
Series = list[tuple[int, float]]


def scalars(record: Mapping[str, Any]) -> tuple[dict[str, float], dict[str, Series]]:
    """``(final, series)``: the finite metric means, standard errors (``<metric>_sem``)
    and timings (``timings/<name>``) of ``record``, and its training history as
    ``{"history/<column>": [(step, value), ...]}``."""
    final: dict[str, float] = {}
    for name, summary in (record.get("metrics") or {}).items():
        if isinstance(summary, Mapping):
            for key, suffix in (("mean", ""), ("sem", "_sem")):
                value = _finite(summary.get(key))
                if value is not None:
                    final[f"{name}{suffix}"] = value
    for name, seconds in (record.get("timings") or {}).items():
        value = _finite(seconds)
        if value is not None:
            final[f"timings/{name}"] = value
    history = record.get("history") or {}
    steps = list(history.get("step") or [])
    series: dict[str, Series] = {}
    for column, values in history.items():
        if column == "step" or not isinstance(values, list) or len(values) != len(steps):
            continue
        points = [
            (int(s), v)
            for s, raw in zip(steps, values, strict=True)
            if (v := _finite(raw)) is not None
        ]
        if points:
            series[f"history/{column}"] = points
    return final, series


def _tags(record: Mapping[str, Any], directory: Path) -> dict[str, str]:
    env = record.get("environment") or {}
    tags = {
        f"hnnbench.{k}": str(record.get(k))
        for k in ("system", "model", "seed", "profile", "track", "status", "backend", "family")
        if record.get(k) is not None
    }
    tags["hnnbench.record"] = str(Path(directory).resolve() / "result.json")
    tags["hnnbench.version"] = str(env.get("hnnbench", ""))
    if record.get("error"):
        tags["hnnbench.error"] = str(record["error"])[:_MAX_VALUE]
    return tags


# --------------------------------------------------------------------------- MLflow


@contextlib.contextmanager
def _store_lock(uri: str) -> Iterator[None]:
    """Hold an exclusive lock beside a SQLite store while this process writes to it:
    parallel jobs of a sweep would otherwise race to create its tables."""
    path = uri.removeprefix("sqlite:///") if uri.startswith("sqlite:///") else None
    try:
        import fcntl
    except ImportError:  # not POSIX: SQLite's own locking only
        fcntl = None  # type: ignore[assignment]
    if path is None or fcntl is None:
        yield
        return
    lock = Path(f"{path}.lock")
    lock.parent.mkdir(parents=True, exist_ok=True)
    with open(lock, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _to_mlflow(record: Mapping[str, Any], directory: Path, uri: str) -> None:
    from mlflow.entities import Metric, Param, RunTag
    from mlflow.tracking import MlflowClient

    final, series = scalars(record)
    now = int(time.time() * 1000)
    last = max(
        [int(s) for s in (record.get("history") or {}).get("step") or []]
        or [int(record.get("steps") or 0)]
    )
    metrics = [Metric(key, value, now, last) for key, value in final.items()]
    metrics += [
        Metric(key, value, now, step) for key, points in series.items() for step, value in points
    ]
    params = [Param(k, v) for k, v in _flat(record.get("config") or {}).items()]
    failed = record.get("status") in ("failed", "timeout")
    with _store_lock(uri):
        client = MlflowClient(tracking_uri=uri)
        experiment = client.get_experiment_by_name(EXPERIMENT)
        if experiment is not None:
            experiment_id = experiment.experiment_id
        else:
            artifacts = None
            if uri.startswith("sqlite:///"):
                artifacts = (Path(uri.removeprefix("sqlite:///")).parent / "mlartifacts").as_uri()
            experiment_id = client.create_experiment(EXPERIMENT, artifact_location=artifacts)
        run = client.create_run(
            experiment_id, run_name=_label(record), tags=_tags(record, directory)
        )
        run_id = run.info.run_id
        for i in range(0, len(params), _MAX_PARAMS):
            client.log_batch(run_id, params=params[i : i + _MAX_PARAMS])
        for i in range(0, len(metrics), _MAX_METRICS):
            client.log_batch(run_id, metrics=metrics[i : i + _MAX_METRICS])
        client.log_batch(run_id, tags=[RunTag("hnnbench.exported_at", str(now))])
        client.set_terminated(run_id, status="FAILED" if failed else "FINISHED")


# --------------------------------------------------------------------------- TensorBoard


def _to_tensorboard(record: Mapping[str, Any], logdir: Path) -> None:
    from tensorboardX import SummaryWriter

    final, series = scalars(record)
    last = max(
        [step for points in series.values() for step, _ in points]
        or [int(record.get("steps") or 0)]
    )
    writer = SummaryWriter(logdir=str(logdir))
    try:
        for key, points in series.items():
            for step, value in points:
                writer.add_scalar(key, value, step)
        for key, value in final.items():
            writer.add_scalar(key if "/" in key else f"metrics/{key}", value, last)
        config = json.dumps(record.get("config") or {}, indent=1, sort_keys=True, default=str)
        writer.add_text("config", "```\n" + config + "\n```", 0)
        tags = "\n".join(f"- {k}: {v}" for k, v in _tags(record, logdir.parent).items())
        writer.add_text("record", tags, 0)
    finally:
        writer.close()
