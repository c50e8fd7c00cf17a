"""The job's config: its typed schema (:class:`RunConfig`), the settings that say how a
job runs rather than what it computes (:data:`RUN_ONLY_KEYS`, declared once), and
validation into a :class:`Job` (plugin classes and typed configs) with one-line errors.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field, fields
from typing import Any, Optional

from omegaconf import MISSING, DictConfig, OmegaConf

from hnnbench import _registry as registry
from hnnbench._contracts.device import device_request
from hnnbench._contracts.errors import ConfigError, HnnbenchError, UnknownNameError
from hnnbench._contracts.metric import EvaluationConfig
from hnnbench._contracts.names import DEFAULT_TRACK, TRACKS
from hnnbench._contracts.plugin import Model, ModelConfig, System, SystemConfig
from hnnbench._running import tracking
from hnnbench._running.device_share import MAX_SHARE

__all__ = [
    "Job",
    "MAX_SEED",
    "ProfileConfig",
    "RUN_ONLY_KEYS",
    "RunConfig",
    "SweeperConfig",
    "fingerprint",
    "hydra_error_line",
    "prepare_job",
    "validate_run",
]


#: Top-level config keys that say where and how a job runs, not what it computes: a
#: finished record is reused on resume whatever they are, they define no leaderboard
#: variant, and they are left out of a sweep job's directory name (conf/config.yaml's
#: ``override_dirname.exclude_keys``, which tests/unit/test_config.py holds to this list).
RUN_ONLY_KEYS = frozenset(
    {
        "rerun",
        "device",
        "device_share",
        "threads",
        "pin_cpu",
        "save_model",
        "cache_dir",
        "data_dir",
        "seeds_per_job",
        "seed_batch",
        "timeout_s",
        "log_to",
        "mlflow_uri",
    }
)
#: Seeds must fit every backend's generator (torch, numpy, JAX keys): 0 <= seed < 2**32.
MAX_SEED = 2**32 - 1


@dataclass
class ProfileConfig:
    name: str = "paper"
    description: str = ""


@dataclass
class RunConfig:
    """One job: a system, a model and how to run them.

    Attributes:
        seed: seeds data generation, evaluation trajectories and model init (int >= 0).
        device: ``auto`` (GPU if present), ``cpu``, ``cuda`` or ``cuda:N``.
        device_share: job processes that share one GPU (1 to 64; run ``N × GPUs`` of
            them with a launcher): each takes a slot of the least-held GPU, sees only
            it, and lets JAX take ``0.9 / N`` of its memory
            (:mod:`hnnbench._running.device_share`). 1: one job per GPU; no effect on
            the CPU.
        rerun: redo jobs that already have a finished record in their directory.
        threads: CPU threads per job for torch/BLAS/XLA (0: the library default). One
            thread is fastest for the paper-sized networks and keeps parallel workers
            from oversubscribing the cores.
        pin_cpu: pin the job's process to one free core (:mod:`hnnbench._running.affinity`), so
            that XLA runs one thread too and results do not depend on the launcher.
            ``null`` (default): pin when ``threads=1`` and the ``hnnbench`` command
            started the job (not when a notebook calls ``run_job``).
        save_model: write the trained weights next to the record.
        cache_dir: every cache: datasets, measured data, JAX's compiled executables
            (default ``$HNNBENCH_CACHE_DIR`` or the user cache; :mod:`hnnbench._contracts.paths`).
        data_dir: where measured data files are looked up before ``$HNNBENCH_DATA_DIR``.
        seeds_per_job: a sweep over ``seed`` trains this many seeds of a (system, model)
            pair as one batch, in one job (the CLI groups the seeds into
            ``seed_batch``); each seed still gets its own record. 1: one seed per job.
        seed_batch: the seeds this job trains as one batch (set by the CLI from
            ``seeds_per_job``; ``seed`` is its first); ``null``: just ``seed``.
        timeout_s: the job's wall-clock limit in seconds, per seed (a batch of N seeds
            gets N times it); past it the job stops and is recorded ``timeout``
            (:func:`hnnbench._running.job.time_limit`). Set per profile (paper: 6 h, quick:
            20 min); ``0`` or ``null``: no limit.
        track: the benchmark track the job belongs to (:data:`TRACKS`): ``protocol``
            (each system's shared protocol, the default), ``tuned`` (the settings an
            equal-budget tuning selected on validation: ``hnnbench tune``) or ``recipe``
            (a family paper's own recipe, another budget). Tracks are never ranked
            together (docs/TUNING.md).
        tuning: how a ``tuned`` job's settings were chosen (trials, step budget,
            space, selected settings, CPU seconds; set by ``hnnbench tune``), copied into
            the record; ``null`` for every other track.
        log_to: experiment trackers each finished job is exported to
            (:mod:`hnnbench._running.tracking`): ``[mlflow, tensorboard]``, ``mlflow`` or
            ``tensorboard``; ``[]`` (default): none.
        mlflow_uri: the MLflow tracking store (``null``: ``sqlite:///<sweep
            dir>/mlflow.db``).
    """

    system: Any = MISSING
    model: Any = MISSING
    profile: ProfileConfig = field(default_factory=ProfileConfig)
    seed: int = 0
    device: str = "auto"
    device_share: int = 1
    rerun: bool = False
    threads: int = 1
    pin_cpu: Optional[bool] = None
    save_model: bool = True
    cache_dir: Optional[str] = None
    data_dir: Optional[str] = None
    seeds_per_job: int = 1
    seed_batch: Optional[list[int]] = None
    timeout_s: Optional[float] = 21600.0
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)
    track: str = DEFAULT_TRACK
    tuning: Optional[Any] = None
    log_to: Any = field(default_factory=list)
    mlflow_uri: Optional[str] = None


@dataclass
class SweeperConfig:
    """``hydra/sweeper=hnnbench`` (the default): Hydra's basic sweeper's settings, for
    :class:`hnnbench._sweeping.sweeper.Sweeper`."""

    _target_: str = "hydra_plugins.hnnbench_sweeper.HnnbenchSweeper"
    max_batch_size: Optional[int] = None
    params: Optional[dict[str, str]] = None


def not_a_setting(what: str, key: Any, known: list[str]) -> ConfigError:
    """``<what>. Did you mean '<closest>'? Settings: <known>``."""
    close = difflib.get_close_matches(str(key), known, n=1)
    hint = f" Did you mean '{close[0]}'?" if close else ""
    return ConfigError(f"{what}.{hint} Settings: {', '.join(known)}")


def validate_run(cfg: Any) -> None:
    """Check the run-level fields of a composed config."""
    from omegaconf.errors import MissingMandatoryValue, OmegaConfBaseException

    known = [f.name for f in fields(RunConfig)]
    for key in cfg:
        if key not in known and key != "hydra":
            raise not_a_setting(f"{key} is not an hnnbench setting", key, known)
    for key in ("system", "model"):  # the shipped config names no plugin
        if key not in cfg or cfg.get(key) is None:
            raise ConfigError(
                f"no {key} chosen: add {key}=<name> to the command line "
                f"(`hnnbench list` shows the {key}s; {key}=all for every one)"
            )
    for key in known:
        if key not in cfg:
            raise ConfigError(f"{key} is missing (removed with ~{key}?): hnnbench needs it.")
    try:  # without resolving: ${hydra:...} only resolves in a running job
        OmegaConf.to_container(cfg, resolve=False, throw_on_missing=True)
    except MissingMandatoryValue as err:
        key = getattr(err, "full_key", None) or "a setting"
        raise ConfigError(
            f"{key} has no value: set it, e.g. {key}=<value> "
            "(`hnnbench --cfg job` shows the config)."
        ) from None
    for key in cfg:  # every interpolation resolves (except those needing a running job)
        if key == "hydra":
            continue
        try:
            node = cfg[key]
            if isinstance(node, DictConfig):
                OmegaConf.to_container(node, resolve=True)
        except OmegaConfBaseException as err:
            if not needs_running_hydra(err):
                raise
    for key in ("system", "model"):
        node = cfg.get(key)
        if not isinstance(node, DictConfig) or not isinstance(node.get("name"), str):
            raise ConfigError(
                f"{key} is not a {key} config: choose one with {key}=<name> "
                "(`hnnbench list` shows the names)."
            )
    seed = cfg.seed
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise ConfigError(
            f"seed={seed} is invalid: expected an integer from 0 to {MAX_SEED}, e.g. seed=0."
        )
    spj = cfg.seeds_per_job
    if isinstance(spj, bool) or not isinstance(spj, int) or spj < 1:
        raise ConfigError(
            f"seeds_per_job={spj} is invalid: expected an integer >= 1, e.g. seeds_per_job=3."
        )
    batch = cfg.get("seed_batch")
    if batch is not None:
        values = list(batch)
        if not values or any(
            isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= MAX_SEED for v in values
        ):
            raise ConfigError(
                f"seed_batch={values} is invalid: expected a list of seeds, "
                "e.g. seed_batch=[0,1,2] (normally set by seeds_per_job)."
            )
        if len(set(values)) != len(values) or values[0] != seed:
            raise ConfigError(
                f"seed_batch={values} must hold distinct seeds starting with "
                f"seed={seed}; let seeds_per_job set it."
            )
    device_request(str(cfg.device))  # a ConfigError saying what is accepted
    share = cfg.device_share
    if isinstance(share, bool) or not isinstance(share, int) or not 1 <= share <= MAX_SHARE:
        raise ConfigError(
            f"device_share={share} is invalid: expected the number of jobs that share one "
            f"GPU, an integer from 1 to {MAX_SHARE}, e.g. device_share=4."
        )
    limit = cfg.get("timeout_s")
    if limit is not None and (
        isinstance(limit, bool)
        or not isinstance(limit, (int, float))
        or not (limit >= 0 and math.isfinite(limit))
    ):
        raise ConfigError(
            f"timeout_s={limit} is invalid: expected seconds >= 0 (0 or null: no limit), "
            "e.g. timeout_s=3600."
        )
    if cfg.threads < 0:
        raise ConfigError(f"threads={cfg.threads} is invalid: expected an integer >= 0.")
    ev = cfg.evaluation
    for key in ("rtol", "atol", "vpt_threshold"):
        value = getattr(ev, key)
        if not (value > 0 and math.isfinite(value)):
            raise ConfigError(f"evaluation.{key}={value} is invalid: expected a finite number > 0.")
    chosen = ev.get("metrics")
    if chosen is not None:
        names = registry.available("metric")
        for name in list(chosen):
            if name not in names:
                raise UnknownNameError("metric", str(name), names)
    track = cfg.get("track")
    if track not in TRACKS:
        raise ConfigError(
            f"track={track} is invalid: expected one of {', '.join(TRACKS)} "
            "(protocol: the shared protocol, the default)."
        )
    tuning = cfg.get("tuning")
    if tuning is not None and (track != "tuned" or not isinstance(tuning, DictConfig)):
        raise ConfigError(
            "tuning is set by hnnbench tune for track=tuned only (a mapping); "
            "remove it from the command line."
        )
    tracking.check(cfg.get("log_to"), cfg.get("mlflow_uri"))


def _instantiate_config(kind: str, node: Any) -> Any:
    """The plugin config dataclass for a composed ``system`` / ``model`` node."""
    name = str(node.name)
    cls = registry.group(kind).get(name)
    values = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node
    assert isinstance(values, dict)
    known = [f.name for f in fields(cls.Config)]
    for raw_key, value in values.items():
        key = str(raw_key)
        if key not in known:
            raise not_a_setting(f"{kind}.{key} is not a setting of {kind} '{name}'", key, known)
        # No plugin setting means anything with NaN or an infinity (a finite bound
        # works where "no bound" is meant); plugins check their own ranges.
        if isinstance(value, float) and not math.isfinite(value):
            raise ConfigError(
                f"{kind}.{key}={value} is invalid: expected a finite number. "
                f"Fix it with {kind}.{key}=<finite value>."
            )
    try:
        return cls.Config(**{str(k): v for k, v in values.items()})
    except TypeError as err:
        raise ConfigError(f"{kind} '{name}': {err}") from None
    except (KeyboardInterrupt, HnnbenchError):
        raise
    except BaseException as err:  # noqa: BLE001 - the plugin's __post_init__, sys.exit too
        raise ConfigError(_plugin_raised(kind, name, "config", err)) from None


def _plugin_raised(kind: str, name: str, where: str, err: BaseException) -> str:
    """One line: the plugin's config code raised (a bug of the plugin, named)."""
    text = " ".join(str(err).split())
    return (
        f"{kind} '{name}': its {where} raised {type(err).__name__}"
        + (f": {text}" if text else "")
        + " (a bug of the plugin: check its settings or "
        "report it to its authors)"
    )


@dataclass
class Job:
    """A validated job: plugin classes and typed configs."""

    run: Any
    system_cls: type[System]
    system_cfg: SystemConfig
    model_cls: type[Model]
    model_cfg: ModelConfig


def fingerprint(cfg: DictConfig) -> Optional[str]:
    """What a job's config says, as one string (its resolved settings, the ``hydra`` node
    left out): equal for two compositions of the same job. ``None`` where it does not
    resolve outside a running job (``${hydra:...}``)."""
    import json

    try:
        values = OmegaConf.to_container(cfg, resolve=True)
    except Exception:  # noqa: BLE001 - resolution needs a running job: no fingerprint
        return None
    if isinstance(values, dict):
        values.pop("hydra", None)
    return json.dumps(values, sort_keys=True, default=repr)


def prepare_job(cfg: DictConfig) -> Job:
    """Validate a composed config and resolve its plugins.

    Raises:
        ConfigError: with a one-line message naming the bad value.
    """
    from omegaconf.errors import OmegaConfBaseException

    try:
        validate_run(cfg)
        system_cls = registry.get_class("system", cfg.system.name)
        model_cls = registry.get_class("model", cfg.model.name)
        system_cfg = _instantiate_config("system", cfg.system)
        model_cfg = _instantiate_config("model", cfg.model)
    except OmegaConfBaseException as err:  # interpolation, missing or mistyped values
        raise ConfigError(hydra_error_line(err)) from None
    for kind, typed in (("system", system_cfg), ("model", model_cfg)):
        try:
            typed.validate()
        except (HnnbenchError, KeyboardInterrupt):
            raise
        except (TypeError, ValueError, ArithmeticError) as err:  # a value validate() chokes on
            raise ConfigError(
                f"{kind} '{typed.name}': invalid config ({type(err).__name__}: {err})".replace(
                    "\n", " "
                )
            ) from None
        except BaseException as err:  # noqa: BLE001 - any other: the plugin's bug, named
            raise ConfigError(_plugin_raised(kind, str(typed.name), "validate()", err)) from None
    return Job(cfg, system_cls, system_cfg, model_cls, model_cfg)


def needs_running_hydra(err: BaseException) -> bool:
    """An interpolation like ``${hydra:runtime.output_dir}`` only resolves in a job."""
    return "HydraConfig was not set" in str(err)


def hydra_error_line(err: BaseException) -> str:
    """Condense a Hydra/OmegaConf composition error into one line."""
    parts: list[str] = []
    seen: set[int] = set()
    cur: BaseException | None = err
    while cur is not None and id(cur) not in seen:
        seen.add(id(cur))
        text = str(cur).strip()
        # OmegaConf chains an unformatted copy of its message ('$VALUE'); Hydra's parser
        # chains a 'None'. Neither says anything.
        if text and "$VALUE" not in text and text != "None":
            first = text.splitlines()[0].strip()
            full_key = re.search(r"full_key:\s*(\S+)", text)
            if full_key and full_key.group(1) not in first:
                first = f"{first} (key: {full_key.group(1)})"
            if not any(first.split(" (key: ")[0] in part for part in parts):
                parts.append(first)
        cur = cur.__cause__ or cur.__context__
    line = ": ".join(p.rstrip(".:") if i < len(parts) - 1 else p for i, p in enumerate(parts))
    line = " ".join((line or type(err).__name__).split())
    if "Could not find" in line or "not in" in line:
        line += ". Run `hnnbench list` for the names, or `hnnbench --cfg job` for the keys."
    return line
