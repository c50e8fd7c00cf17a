"""The tuned track of one system: one Optuna study per model with the same budget,
each trial a job on the sweep's job path, the selection on validation, and the
final runs on each seed (docs/TUNING.md).
"""

from __future__ import annotations

import json
import logging
import math
import os
import socket
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional

from omegaconf import OmegaConf, open_dict

from hnnbench import _record as records
from hnnbench import _registry as registry
from hnnbench._contracts.errors import BackendMissingError, ConfigError, UnknownNameError
from hnnbench._contracts.metric import Metric
from hnnbench._contracts.plugin import HISTORY_VALID, STOPPED_BY_CALLER, TrainSettings
from hnnbench._contracts.space import (
    Categorical,
    Distribution,
    IntRange,
    LogUniform,
    SearchSpace,
    Uniform,
    describe,
    space_json,
)
from hnnbench._record.tracks import SELECTED_ON, STEPS_SETTING
from hnnbench._running import launch_context, progress
from hnnbench._running.compose import compose, profile_of
from hnnbench._running.config import prepare_job
from hnnbench._running.job import run_job
from hnnbench._sweeping.lock import sweep_lock
from hnnbench._tuning.request import PASSED_KEYS, TuneRequest, resolve_models

if TYPE_CHECKING:
    import optuna

log = logging.getLogger("hnnbench")

__all__ = ["FIRST_RUNG", "REDUCTION", "Study", "Tuner", "objective_metric", "run_tuning"]


#: Successive halving: the first rung at this fraction of the step budget, each next one
#: this many times later; at a rung the best ``1 / REDUCTION`` of the trials go on.
REDUCTION = 3
FIRST_RUNG = 1 / 9


@dataclass
class Study:
    """One model's tuning: its summary (:meth:`summary`) and final records."""

    model: str
    space: SearchSpace
    budget_trials: int
    steps: int
    objective: Metric
    pruner: str
    trials: list[dict[str, Any]] = field(default_factory=list)
    selected: Optional[dict[str, Any]] = None
    finals: list[dict[str, Any]] = field(default_factory=list)

    @property
    def cpu_s(self) -> float:
        """CPU seconds of every trial's job (pruned and failed ones included)."""
        return float(sum(t.get("cpu_s") or 0.0 for t in self.trials))

    def tuning(self, study_name: str) -> dict[str, Any]:
        """The ``tuning`` block of the final records (``hnnbench._record.fields``)."""
        assert self.selected is not None
        states = [t["state"] for t in self.trials]
        return {
            "selected_on": SELECTED_ON,
            "objective": self.objective.name,
            "trials": self.budget_trials,
            "steps": self.steps,
            "space": space_json(self.space),
            "selected": dict(self.selected["settings"]),
            "selected_trial": self.selected["number"],
            # "inf" where every trial diverged (strict JSON, as the record stores it)
            "selected_value": records.encode(self.selected["value"]),
            "completed": states.count("complete"),
            "pruned": states.count("pruned"),
            "pruner": self.pruner,
            "sampler": "TPE",
            "cpu_s": round(self.cpu_s, 3),
            "study": study_name,
        }


def objective_metric() -> Metric:
    """The registered metric declared to select on (:attr:`Metric.selects`)."""
    found = [m for m in registry.metrics() if m.selects]
    if len(found) != 1:
        raise ConfigError(
            "hnnbench tune selects on the one registered metric that declares "
            f"selects=True, but {len(found)} do"
            + (f" ({', '.join(m.name for m in found)})" if found else "")
            + ": check the installed metric plugins (hnnbench list)"
        )
    return found[0]


def _rounded(value: float, low: float, high: float) -> float:
    """``value`` to 3 significant digits (settings read as written), kept in bounds."""
    return min(max(float(f"{value:.3g}"), low), high)


def _override_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return value
    return json.dumps(value)


def _distribution(dist: Distribution) -> Any:
    import optuna

    if isinstance(dist, LogUniform):
        return optuna.distributions.FloatDistribution(dist.low, dist.high, log=True)
    if isinstance(dist, Uniform):
        return optuna.distributions.FloatDistribution(dist.low, dist.high)
    if isinstance(dist, IntRange):
        return optuna.distributions.IntDistribution(dist.low, dist.high, log=dist.log)
    assert isinstance(dist, Categorical)
    return optuna.distributions.CategoricalDistribution(dist.choices)


def _settings(space: SearchSpace, params: Mapping[str, Any]) -> dict[str, Any]:
    """A trial's parameters as settings ``{"model.lr": 0.00312, ...}`` (floats to 3
    significant digits)."""
    out: dict[str, Any] = {}
    for name, dist in space.items():
        value = params[name]
        if isinstance(dist, (LogUniform, Uniform)):
            value = _rounded(float(value), dist.low, dist.high)
        elif isinstance(dist, IntRange):
            value = int(value)
        out[f"model.{name}"] = value
    return out


def _pruned(record: Mapping[str, Any]) -> bool:
    stopped = (record.get("selection") or {}).get("stopped") or ""
    return str(stopped).startswith(STOPPED_BY_CALLER)


def _value(record: Mapping[str, Any], objective: Metric) -> float:
    """The trial's objective: its metric's mean where it is ``ok``, else the metric's
    worst value (a diverged, failed or timed-out trial is a result of its settings)."""
    if record.get("status") != "ok":
        return objective.worst()
    mean: Any = ((record.get("metrics") or {}).get(objective.name) or {}).get("mean")
    try:
        value = float(mean)
    except (TypeError, ValueError):
        return objective.worst()
    return objective.worst() if math.isnan(value) else value


class Tuner:
    """Runs a :class:`TuneRequest` (:func:`run_tuning`)."""

    def __init__(self, request: TuneRequest) -> None:
        self.request = request
        self.root = request.directory.resolve()
        self.system = request.system
        self.objective = objective_metric()

    # -- jobs ------------------------------------------------------------------------
    def _overrides(
        self, model: str, seed: int, settings: Mapping[str, Any], steps: int
    ) -> list[str]:
        return [
            f"system={self.system}",
            f"model={model}",
            f"seed={seed}",
            f"profile={self.request.profile}",
            f"{STEPS_SETTING}={steps}",
            *(f"{k}={_override_value(v)}" for k, v in settings.items()),
            "track=tuned",
            *self.request.overrides,
        ]

    def _job(
        self,
        overrides: list[str],
        directory: Path,
        tuning: dict[str, Any],
        extra: Sequence[str] = (),
        rerun: bool = False,
    ) -> dict[str, Any]:
        """Run one job, as a sweep's Hydra task does (its config composed by
        :func:`~hnnbench._running.compose.compose`, run by the one job entry
        :func:`~hnnbench._running.job.run_job` in this command's launch context), and
        return its record; ``extra``: overrides not stored as the job's."""
        cfg = compose([*overrides, *extra])
        with open_dict(cfg):
            cfg.tuning = OmegaConf.create(tuning)
            if rerun:
                cfg.rerun = True
        (outcome,) = run_job(cfg, directory, overrides=[*overrides, *extra])
        return outcome.record

    def protocol_steps(self, model: str) -> int:
        """The system's protocol steps of the profile (the default step budget)."""
        cfg = compose(
            [
                f"system={self.system}",
                f"model={model}",
                f"profile={self.request.profile}",
                *self.request.overrides,
            ]
        )
        job = prepare_job(cfg)
        return TrainSettings.resolve(job.system_cfg, job.model_cfg).steps

    # -- one study -------------------------------------------------------------------
    def study_name(self, model: str) -> str:
        return f"{self.system}/{model}"

    def _storage(self) -> Any:
        import optuna

        path = self.root / "tuning" / f"{self.system}.db"
        path.parent.mkdir(parents=True, exist_ok=True)
        return optuna.storages.RDBStorage(
            f"sqlite:///{path}", engine_kwargs={"connect_args": {"timeout": 60}}
        )

    def _identity(self, model: str, space: SearchSpace, steps: int) -> dict[str, Any]:
        """What a study is of: resuming with anything else is refused."""
        return {
            "steps": steps,
            "profile": self.request.profile,
            "objective": self.objective.name,
            "space": space_json(space),
            "trial_seed": self.request.trial_seed,
            # what the jobs compute, not how they run
            "overrides": sorted(
                o for o in self.request.overrides if o.split("=", 1)[0] not in PASSED_KEYS
            ),
            "pruner": self._pruner_name(space),
        }

    def _pruner_name(self, space: SearchSpace) -> str:
        loss_knobs = [n for n, d in space.items() if d.changes_training_loss]
        if self.request.pruner == "none":
            return "none"
        if loss_knobs:
            return f"none ({', '.join(loss_knobs)} changes the training loss)"
        return f"successive_halving (rungs at 1/9 and 1/3 of the steps, best 1/{REDUCTION} on)"

    def _open(self, model: str, space: SearchSpace, steps: int) -> optuna.Study:
        import optuna

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        identity = self._identity(model, space, steps)
        pruning = identity["pruner"].startswith("successive_halving")
        pruner = (
            optuna.pruners.SuccessiveHalvingPruner(
                min_resource=max(1, math.ceil(steps * FIRST_RUNG)), reduction_factor=REDUCTION
            )
            if pruning
            else optuna.pruners.NopPruner()
        )
        storage = self._storage()
        name = self.study_name(model)
        study = optuna.create_study(
            storage=storage,
            study_name=name,
            direction="minimize" if self.objective.better == "lower" else "maximize",
            load_if_exists=True,
            pruner=pruner,
        )
        stored = study.user_attrs.get("identity")
        if stored is None:
            study.set_user_attr("identity", identity)
        elif stored != identity:
            differs = sorted(k for k in identity if identity[k] != stored.get(k))
            raise ConfigError(
                f"{self.root} holds the study {name} made with other settings "
                f"({', '.join(f'{k}: {stored.get(k)!r} -> {identity[k]!r}' for k in differs)})"
                "; resume with the settings it was made with, or choose another out="
            )
        # Reseeded on each start by the trials so far (interrupted ones included), so a
        # resumed study does not repeat its first draws.
        study.sampler = optuna.samplers.TPESampler(
            seed=self.request.sampler_seed + len(study.trials),
            n_startup_trials=min(10, max(1, math.ceil(self.request.trials / 2))),
        )
        return study

    def _trial_dir(self, model: str, number: int) -> Path:
        return self.root / "trials" / self.system / model / f"trial{number:03d}"

    def _recover(self, study: optuna.Study, model: str, space: SearchSpace) -> None:
        """Trials an interruption left running: told from their record where it was
        written, else failed and their settings queued again (they are not counted)."""
        import optuna

        for trial in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
            record = records.read_record(self._trial_dir(model, trial.number) / records.RECORD_NAME)
            if record is not None and record.get("status") in (
                *records.FINISHED,
                "failed",
                "timeout",
            ):
                state = optuna.trial.TrialState.PRUNED if _pruned(record) else None
                study.tell(
                    trial.number, None if state else _value(record, self.objective), state=state
                )
                log.info(
                    "%s trial %d: recovered from its record", self.study_name(model), trial.number
                )
                continue
            study.tell(trial.number, state=optuna.trial.TrialState.FAIL)
            study.enqueue_trial(dict(trial.params), user_attrs={"replays": trial.number})
            log.info(
                "%s trial %d: interrupted; its settings run again",
                self.study_name(model),
                trial.number,
            )

    def _run_trial(
        self, study: optuna.Study, model: str, space: SearchSpace, steps: int, k: int
    ) -> None:
        import optuna

        distributions = {n: _distribution(d) for n, d in space.items()}
        trial = study.ask(distributions)
        settings = _settings(space, trial.params)
        pruning = not isinstance(study.pruner, optuna.pruners.NopPruner)
        best = [math.inf]  # the training loop's validation loss: lower is better
        asked = [False]

        def observe(step: int, losses: Mapping[str, float]) -> Optional[bool]:
            # The training loop's own validation loss (the family's objective on the
            # validation split), best so far: what the pruner compares at its rungs.
            value = losses.get(HISTORY_VALID)
            if value is None or not math.isfinite(value):
                return None
            best[0] = min(best[0], value)
            trial.report(best[0], step)
            if pruning and step < steps and trial.should_prune():
                asked[0] = True
                return True
            return None

        directory = self._trial_dir(model, trial.number)
        tuning = {
            "selected_on": SELECTED_ON,
            "objective": self.objective.name,
            "trial": trial.number,
            "study": self.study_name(model),
        }
        start = time.perf_counter()
        with progress.observing(observe):
            record = self._job(
                self._overrides(model, self.request.trial_seed, settings, steps),
                directory,
                tuning,
                extra=[f"evaluation.metrics=[{self.objective.name}]", "save_model=false"],
            )
        cpu = float((record.get("timings") or {}).get("cpu_s") or 0.0)
        trial.set_user_attr("settings", settings)
        trial.set_user_attr("status", record.get("status"))
        trial.set_user_attr("cpu_s", cpu)
        if record.get("status") == "skipped":
            study.tell(trial, state=optuna.trial.TrialState.FAIL)
            raise _Skipped(str(record.get("error")))
        if asked[0] or _pruned(record):
            study.tell(trial, state=optuna.trial.TrialState.PRUNED)
            outcome = f"pruned at step {record.get('steps')}"
        else:
            value = _value(record, self.objective)
            study.tell(trial, value)
            outcome = f"{record.get('status')}, {self.objective.name}={value:.3g}"
        spent = [
            float(t.user_attrs.get("cpu_s") or 0.0)
            for t in study.get_trials(deepcopy=False)
            if "cpu_s" in t.user_attrs
        ]
        left = (self.request.trials - k) * sum(spent) / max(len(spent), 1)
        log.info(
            "%s trial %d/%d (#%d): %s; %.1f s CPU, %.1f s wall; %s; this study so "
            "far %.0f s CPU, about %.0f s CPU to go (at its mean per trial)",
            self.study_name(model),
            k,
            self.request.trials,
            trial.number,
            outcome,
            cpu,
            time.perf_counter() - start,
            " ".join(f"{key}={_override_value(v)}" for key, v in settings.items()),
            sum(spent),
            left,
        )

    def tune_model(self, model: str) -> Study:
        """Tune ``model`` to the budget (resuming its study), then train its selected
        settings on each seed."""
        import optuna

        space = registry.discover("model")[model].search_space
        assert space is not None
        steps = self.request.steps or self.protocol_steps(model)
        optuna_study = self._open(model, space, steps)
        name = self.study_name(model)
        result = Study(
            model, space, self.request.trials, steps, self.objective, self._pruner_name(space)
        )
        self._recover(optuna_study, model, space)
        counted = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)

        def done() -> int:
            return len(optuna_study.get_trials(deepcopy=False, states=counted))

        log.info(
            "%s: %d/%d trials done; space: %s; %d steps per trial; pruner: %s",
            name,
            done(),
            self.request.trials,
            describe(space),
            steps,
            result.pruner,
        )
        skipped: Optional[str] = None
        while done() < self.request.trials:
            try:
                self._run_trial(optuna_study, model, space, steps, done() + 1)
            except _Skipped as err:
                skipped = str(err)
                log.warning("%s: skipped (%s); no tuning", name, skipped)
                break
        result.trials = [
            _trial_summary(t)
            for t in optuna_study.get_trials(deepcopy=False)
            if t.state in (*counted, optuna.trial.TrialState.FAIL)
            and t.user_attrs.get("status") is not None
        ]
        if skipped is None:
            result.selected = _select(optuna_study, self.objective)
        self._write_summary(result)
        if result.selected is None:
            return result
        log.info(
            "%s: selected trial %d (%s=%.3g) of %d; tuning CPU %.0f s: %s",
            name,
            result.selected["number"],
            self.objective.name,
            result.selected["value"],
            len(result.trials),
            result.cpu_s,
            " ".join(f"{k}={_override_value(v)}" for k, v in result.selected["settings"].items()),
        )
        tuning = result.tuning(name)
        for seed in self.request.seeds:
            directory = self.root / "final" / self.system / model / f"seed{seed}"
            existing = records.read_record(directory / records.RECORD_NAME)
            stale = existing is not None and existing.get("tuning") != tuning
            overrides = self._overrides(model, seed, result.selected["settings"], steps)
            record = self._job(overrides, directory, tuning, rerun=stale)
            result.finals.append(record)
        return result

    def _write_summary(self, study: Study) -> None:
        path = self.root / "tuning" / self.system / f"{study.model}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        summary = {
            "system": self.system,
            "model": study.model,
            "profile": self.request.profile,
            "trials_budget": study.budget_trials,
            "steps": study.steps,
            "objective": study.objective.name,
            "selected_on": SELECTED_ON,
            "space": space_json(study.space),
            "pruner": study.pruner,
            "cpu_s": round(study.cpu_s, 3),
            "selected": study.selected,
            "trials": study.trials,
        }
        records.atomic_write_text(path, json.dumps(records.encode(summary), indent=2) + "\n")

    def run(self) -> list[Study]:
        models = resolve_models(self.request)
        log.info(
            "hnnbench tune: %s, %d model(s) x %d trial(s), seeds %s, profile %s, into %s",
            self.system,
            len(models),
            self.request.trials,
            ",".join(map(str, self.request.seeds)),
            self.request.profile,
            self.root,
        )
        out = []
        with sweep_lock(self.root / "trials" / self.system, self.request.command):
            for model in models:
                out.append(self.tune_model(model))
        return out


class _Skipped(Exception):
    """The model cannot run on the system (its trial was recorded ``skipped``)."""


def _trial_summary(trial: Any) -> dict[str, Any]:
    return {
        "number": trial.number,
        "state": trial.state.name.lower(),
        "value": trial.value,
        "status": trial.user_attrs.get("status"),
        "settings": trial.user_attrs.get("settings"),
        "cpu_s": trial.user_attrs.get("cpu_s"),
        "last_step": trial.last_step,
    }


def _select(study: Any, objective: Metric) -> Optional[dict[str, Any]]:
    """The best completed trial by the objective (ties: the earliest); pruned trials
    are never selected. With every trial at the objective's worst value (all diverged),
    the earliest."""
    import optuna

    complete = [
        t
        for t in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
        if t.value is not None and t.user_attrs.get("settings") is not None
    ]
    if not complete:
        return None
    sign = 1.0 if objective.better == "lower" else -1.0
    best = min(complete, key=lambda t: (sign * float(t.value), t.number))
    return {
        "number": best.number,
        "value": float(best.value),
        "settings": dict(best.user_attrs["settings"]),
    }


def run_tuning(request: TuneRequest) -> list[Study]:
    """Run (or resume) a tuning in this process; one :class:`Study` per model."""
    try:
        import optuna  # noqa: F401
    except ImportError:
        raise BackendMissingError(
            "hnnbench tune needs optuna, which is not installed: pip install 'hnnbench[tune]'"
        ) from None
    profile_of([f"profile={request.profile}"])  # an unknown profile: one line
    if request.system not in registry.discover("system"):
        raise UnknownNameError("system", request.system, registry.available("system"))
    registry.get_class("system", request.system)
    context = launch_context.LaunchContext(
        command=request.command, cli_pid=os.getpid(), host=socket.gethostname()
    )
    # Its jobs run in this process, one after the other (a trial's settings depend on
    # the trials before it), and pin it to one core as the command's jobs do.
    with launch_context.launched(context):
        return Tuner(request).run()
