"""Typed config schema of a job, composition, and validation.

The top-level config is :class:`RunConfig` (registered in Hydra's ConfigStore as
``hnnbench_schema`` and extended by conf/config.yaml); ``system`` and ``model`` are the
plugins' own config dataclasses. Validation happens before any job starts (in the CLI)
and again at the start of each job, never deep inside training.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Optional

from omegaconf import MISSING, DictConfig, OmegaConf

from hnnbench import registry
from hnnbench.api import Model, ModelConfig, System, SystemConfig
from hnnbench.errors import ConfigError

__all__ = [
    "EvaluationConfig",
    "Job",
    "ProfileConfig",
    "RunConfig",
    "compose",
    "hydra_error_line",
    "prepare_job",
    "register_schema",
]

DEVICE_RE = re.compile(r"^(auto|cpu|cuda(:\d+)?)$")


@dataclass
class EvaluationConfig:
    """Evaluation protocol shared by all systems (docs/METRICS.md).

    Attributes:
        rtol, atol: tolerances of the adaptive Dormand-Prince rollouts of every model.
        vpt_threshold: relative state error that ends the valid prediction time.
    """

    rtol: float = 1e-9
    atol: float = 1e-9
    vpt_threshold: float = 0.1


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
        rerun: redo jobs that already have a finished record in their directory.
        threads: CPU threads per job for torch/BLAS/XLA (0: the library default). One
            thread is fastest for the paper-sized networks and keeps parallel workers
            from oversubscribing the cores.
        save_model: write the trained weights next to the record.
        cache_dir: dataset cache (default ``$HNNBENCH_CACHE_DIR`` or the user cache).
        data_dir: where measured data files are looked up before ``$HNNBENCH_DATA_DIR``.
    """

    system: Any = MISSING
    model: Any = MISSING
    profile: ProfileConfig = field(default_factory=ProfileConfig)
    seed: int = 0
    device: str = "auto"
    rerun: bool = False
    threads: int = 1
    save_model: bool = True
    cache_dir: Optional[str] = None
    data_dir: Optional[str] = None
    evaluation: EvaluationConfig = field(default_factory=EvaluationConfig)


def register_schema() -> None:
    from hydra.core.config_store import ConfigStore

    ConfigStore.instance().store(name="hnnbench_schema", node=RunConfig, provider="hnnbench")


def validate_run(cfg: Any) -> None:
    """Check the run-level fields of a composed config."""
    seed = cfg.seed
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(f"seed={seed} is invalid: expected an integer >= 0, e.g. seed=0.")
    if not DEVICE_RE.match(str(cfg.device)):
        raise ConfigError(
            f"device={cfg.device} is invalid: expected auto, cpu, cuda or cuda:N."
        )
    if cfg.threads < 0:
        raise ConfigError(f"threads={cfg.threads} is invalid: expected an integer >= 0.")
    ev = cfg.evaluation
    for key in ("rtol", "atol", "vpt_threshold"):
        if not getattr(ev, key) > 0:
            raise ConfigError(
                f"evaluation.{key}={getattr(ev, key)} is invalid: expected a number > 0."
            )


def _instantiate_config(kind: str, node: Any) -> Any:
    """The plugin config dataclass for a composed ``system`` / ``model`` node."""
    name = node.name
    cls = registry.get_class(kind, name)  # type: ignore[arg-type]
    values = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node
    assert isinstance(values, dict)
    try:
        return cls.Config(**values)
    except TypeError as err:
        raise ConfigError(f"{kind} '{name}': {err}") from None


@dataclass
class Job:
    """A validated job: plugin classes and typed configs."""

    run: Any
    system_cls: type[System]
    system_cfg: SystemConfig
    model_cls: type[Model]
    model_cfg: ModelConfig


def prepare_job(cfg: DictConfig) -> Job:
    """Validate a composed config and resolve its plugins.

    Raises:
        ConfigError: with a one-line message naming the bad value.
    """
    validate_run(cfg)
    system_cls = registry.get_class("system", cfg.system.name)
    model_cls = registry.get_class("model", cfg.model.name)
    system_cfg = _instantiate_config("system", cfg.system)
    model_cfg = _instantiate_config("model", cfg.model)
    system_cfg.validate()
    model_cfg.validate()
    return Job(cfg, system_cls, system_cfg, model_cls, model_cfg)


def profile_of(overrides: list[str]) -> str:
    """The profile named by ``profile=...`` in ``overrides`` (default ``paper``)."""
    profile = "paper"
    for item in overrides:
        key, sep, value = item.partition("=")
        if sep and key.lstrip("+~") == "profile":
            profile = value
    if "," in profile or profile.startswith(("glob(", "choice(", "range(")):
        raise ConfigError(
            f"profile={profile}: a sweep runs one profile; start one sweep per profile."
        )
    registry.validate_profile(profile)
    return profile


def compose(overrides: list[str] | None = None) -> DictConfig:
    """Compose the job config for ``overrides`` as the CLI would (for tests, notebooks).

    Raises:
        ConfigError: a bad override (one line).
    """
    from hydra import compose as hydra_compose
    from hydra import initialize_config_module
    from hydra.core.global_hydra import GlobalHydra

    overrides = list(overrides or [])
    register_schema()
    registry.register_configs(profile_of(overrides))
    GlobalHydra.instance().clear()
    try:
        with initialize_config_module("hnnbench_conf", version_base="1.3"):
            return hydra_compose("config", overrides=overrides)
    except ConfigError:
        raise
    except Exception as err:
        raise ConfigError(hydra_error_line(err)) from None


def hydra_error_line(err: BaseException) -> str:
    """Condense a Hydra/OmegaConf composition error into one line."""
    parts: list[str] = []
    seen: set[int] = set()
    cur: BaseException | None = err
    while cur is not None and id(cur) not in seen:
        seen.add(id(cur))
        text = str(cur).strip()
        if text:
            first = text.splitlines()[0].strip()
            full_key = re.search(r"full_key:\s*(\S+)", text)
            if full_key and full_key.group(1) not in first:
                first = f"{first} (key: {full_key.group(1)})"
            if first not in parts:
                parts.append(first)
        cur = cur.__cause__ or cur.__context__
    line = ": ".join(parts) or type(err).__name__
    line = line.replace("\n", " ")
    if "Could not find" in line or "not in" in line:
        line += ". Run `hnnbench list` for the names, or `hnnbench --cfg job` for the keys."
    return line
