"""What ``hnnbench tune`` runs: its arguments, parsed into a :class:`TuneRequest`,
and its usage text (docs/TUNING.md).
"""

from __future__ import annotations

import shlex
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Optional

from hnnbench import _registry as registry
from hnnbench._contracts.errors import ConfigError, UnknownNameError

if TYPE_CHECKING:
    pass

__all__ = [
    "ARGUMENTS",
    "DEFAULT_SEEDS",
    "DEFAULT_SEEDS_PER_TRIAL",
    "PASSED_KEYS",
    "PASSED_PREFIXES",
    "PRUNERS",
    "TuneRequest",
    "USAGE",
    "parse",
]


#: ``pruner=``: successive halving on the selection criterion, or none.
PRUNERS = ("successive_halving", "none")
#: Settings the command passes on to every job (the system's, the evaluation's, and how
#: jobs run); ``model.*`` is what the tuner searches, and is refused.
PASSED_PREFIXES = ("system.", "evaluation.")
PASSED_KEYS = (
    "timeout_s",
    "cache_dir",
    "data_dir",
    "device",
    "device_share",
    "threads",
    "pin_cpu",
)
#: The tuner's own arguments, ``key=value``.
ARGUMENTS = (
    "system",
    "model",
    "trials",
    "seeds",
    "profile",
    "out",
    "steps",
    "pruner",
    "trial_seed",
    "seeds_per_trial",
    "sampler_seed",
)
#: The seeds the selected settings train on unless ``seeds=`` says otherwise: the
#: protocol track's seed plan, 0-9 (docs/STATISTICS.md), so the tuning gain is paired on
#: every protocol seed.
DEFAULT_SEEDS = tuple(range(10))
#: Seeds each trial trains (one batched job); its score is their criteria's mean.
DEFAULT_SEEDS_PER_TRIAL = 2
_SEEDS_TEXT = ",".join(map(str, DEFAULT_SEEDS))
USAGE = f"""\
usage: hnnbench tune system=NAME model=A,B,... trials=N [seeds={_SEEDS_TEXT}] [profile=paper]
                     [steps=S] [out=DIR] [pruner=successive_halving|none]
                     [trial_seed=0] [seeds_per_trial=2] [sampler_seed=0]
                     [system.KEY=VALUE ...]

Gives every model the same tuning budget on the system (N trials of S steps each on
seeds_per_trial seeds, default S: the system's protocol steps; trial 0 is the
protocol's settings), selects each model's settings on the system's selection
criterion read on validation, and trains the selection on each seed: the tuned track
(docs/TUNING.md). Re-running the same command resumes it. Records: OUT/final (report
and check it like a sweep).
"""


@dataclass
class TuneRequest:
    """What ``hnnbench tune`` runs (see the module docstring).

    Attributes:
        system: one registered system.
        models: registered models that declare a search space (``["all"]``: every one).
        trials: trials per model (the same for every model), >= 1.
        seeds: the seeds the selected settings train on.
        profile: ``paper`` or ``quick``.
        out: the tuned track's directory (default ``results/runs/tuned_<profile>``).
        steps: optimizer steps of every trial and final run (``None``: the system's
            protocol steps of the profile).
        pruner: one of :data:`PRUNERS`.
        trial_seed: the first trial seed (data, initial weights, minibatches); a trial
            trains ``seeds_per_trial`` seeds from it (on a measured system: the seeds
            of each fold, docs/TUNING.md).
        seeds_per_trial: seeds each trial trains, as one batched job; the trial's
            score is the mean of their criteria.
        sampler_seed: the seed of each study's sampler (TPE).
        overrides: settings passed to every job (``system.*``, ``evaluation.*``,
            :data:`PASSED_KEYS`).
        command: the command line stored in the records.
    """

    system: str
    models: list[str]
    trials: int
    seeds: list[int] = field(default_factory=lambda: list(DEFAULT_SEEDS))
    profile: str = "paper"
    out: Optional[Path] = None
    steps: Optional[int] = None
    pruner: str = "successive_halving"
    trial_seed: int = 0
    seeds_per_trial: int = DEFAULT_SEEDS_PER_TRIAL
    sampler_seed: int = 0
    overrides: list[str] = field(default_factory=list)
    command: Optional[str] = None

    @property
    def directory(self) -> Path:
        return (
            Path(self.out)
            if self.out is not None
            else Path("results") / "runs" / f"tuned_{self.profile}"
        )


def _int(key: str, value: str, low: int) -> int:
    try:
        number = int(value)
    except ValueError:
        number = low - 1
    if number < low:
        raise ConfigError(
            f"{key}={value} is invalid: expected an integer >= {low}, e.g. {key}={max(low, 1)}."
        )
    return number


def parse(args: Sequence[str]) -> TuneRequest:
    """The request of a command line (``key=value`` tokens); one-line
    :class:`ConfigError` for anything else."""
    values: dict[str, str] = {}
    overrides: list[str] = []
    for arg in args:
        key, sep, value = arg.partition("=")
        if arg in ("-h", "--help", "help"):
            raise ConfigError(" ".join(USAGE.split()))
        if not sep or not key:
            raise ConfigError(
                f"hnnbench tune: '{arg}' is not KEY=VALUE, e.g. trials=20 (hnnbench tune --help)"
            )
        if key in ARGUMENTS:
            values[key] = value
        elif key.startswith("model."):
            raise ConfigError(
                f"hnnbench tune: {arg}: model settings are what the tuner "
                "searches (each model's declared space) or the model's "
                "defaults; the step budget is steps=N"
            )
        elif key.startswith(PASSED_PREFIXES) or key in PASSED_KEYS:
            overrides.append(arg)
        elif key.lstrip("+~") == "track":
            raise ConfigError(
                f"hnnbench tune: {arg}: the tuner writes the tuned track "
                "(track=tuned); a paper's recipe runs as hnnbench -m ... "
                "track=recipe (docs/TUNING.md, 'Recipes')"
            )
        else:
            known = ", ".join([*ARGUMENTS, *(f"{p}*" for p in PASSED_PREFIXES), *PASSED_KEYS])
            raise ConfigError(f"hnnbench tune: unknown argument '{key}'; expected one of {known}")
    for key in ("system", "model", "trials"):
        if not values.get(key):
            raise ConfigError(
                f"hnnbench tune: {key}= is required, e.g. hnnbench tune "
                "system=pendulum model=hnn_jax,mlp_jax trials=20"
            )
    if "," in values["system"]:
        raise ConfigError(
            f"system={values['system']}: one system per tuning (its "
            "models share the budget); run one command per system"
        )
    pruner = values.get("pruner", "successive_halving")
    if pruner not in PRUNERS:
        raise ConfigError(f"pruner={pruner} is invalid: expected one of {', '.join(PRUNERS)}")
    seeds = [_int("seeds", s, 0) for s in values.get("seeds", _SEEDS_TEXT).split(",")]
    if len(set(seeds)) != len(seeds):
        raise ConfigError(f"seeds={values['seeds']} repeats a seed")
    return TuneRequest(
        system=values["system"],
        models=[m for m in values["model"].split(",") if m],
        trials=_int("trials", values["trials"], 1),
        seeds=seeds,
        profile=values.get("profile", "paper"),
        out=Path(values["out"]) if values.get("out") else None,
        steps=_int("steps", values["steps"], 1) if values.get("steps") else None,
        pruner=pruner,
        trial_seed=_int("trial_seed", values.get("trial_seed", "0"), 0),
        seeds_per_trial=_int(
            "seeds_per_trial", values.get("seeds_per_trial", str(DEFAULT_SEEDS_PER_TRIAL)), 1
        ),
        sampler_seed=_int("sampler_seed", values.get("sampler_seed", "0"), 0),
        overrides=overrides,
        command=shlex.join(["hnnbench", "tune", *args]),
    )


def resolve_models(request: TuneRequest) -> list[str]:
    """The requested models, ``all`` expanded to every model with a search space;
    each must be installed and declare a space."""
    available = registry.available("model")
    out: list[str] = []
    for name in request.models:
        if name == "all":
            names = [n for n in available if registry.discover("model")[n].search_space]
        else:
            if name not in registry.discover("model"):
                raise UnknownNameError("model", name, available)
            registry.get_class("model", name)  # unusable -> its error
            names = [name]
        for model in names:
            if not registry.discover("model")[model].search_space:
                raise ConfigError(
                    f"model {model} declares no search space, so it has no "
                    "tuned track (hnnbench list shows the spaces)"
                )
            if model not in out:
                out.append(model)
    return out
