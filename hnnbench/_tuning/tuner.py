"""The tuned track of one system: one Optuna study per model (per fold of a measured
system) with the same budget, each trial one batched job of ``seeds_per_trial`` seeds on
the sweep's job path, trial 0 the protocol's settings, trials scored, pruned and
selected on the system's selection criterion read on validation, and the final runs on
each seed (docs/TUNING.md).
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
from hnnbench._record.tracks import SELECTED_ON, STEPS_SETTING, study_summary_name
from hnnbench._running import launch_context, progress
from hnnbench._running.compose import compose, profile_of
from hnnbench._running.config import prepare_job
from hnnbench._running.job import run_job
from hnnbench._sweeping.lock import sweep_lock
from hnnbench._tuning.request import PASSED_KEYS, TuneRequest, resolve_models

if TYPE_CHECKING:
    import optuna

log = logging.getLogger("hnnbench")

__all__ = [
    "CRITERION",
    "FIRST_RUNG",
    "PROTOCOL_TRIAL",
    "REDUCTION",
    "SCORE",
    "FoldGroup",
    "Study",
    "Tuner",
    "objective_metric",
    "run_tuning",
    "trial_score",
]


#: Successive halving: the first rung at this fraction of the step budget, each next one
#: this many times later; at a rung the best ``1 / REDUCTION`` of the trials go on.
REDUCTION = 3
FIRST_RUNG = 1 / 9
#: What a trial is scored on: each seed's selection criterion at its scored checkpoint
#: (the record's ``selection.validation_loss``, named by ``selection.criterion``), the
#: same value the protocol track's checkpoint selection reads (docs/METRICS.md).
CRITERION = "selection.validation_loss"
#: How a trial's seeds are combined into its score.
SCORE = "mean over the trial's seeds (the worst value if any seed is not ok)"
#: The trial number of the protocol's settings in every study (enqueued first).
PROTOCOL_TRIAL = 0


@dataclass(frozen=True)
class FoldGroup:
    """One study's data: the seeds its trials train and the final seeds its selection
    trains on. ``fold``: the measured series' fold they share (``None``: a simulated
    system, one study for every final seed)."""

    fold: Optional[int]
    trial_seeds: tuple[int, ...]
    final_seeds: tuple[int, ...]


@dataclass
class Study:
    """One model's tuning: its summary (:meth:`summary`) and final records."""

    model: str
    space: SearchSpace
    budget_trials: int
    steps: int
    objective: Metric
    pruner: str
    group: FoldGroup = FoldGroup(None, (0,), ())
    criterion: Optional[str] = None
    trials: list[dict[str, Any]] = field(default_factory=list)
    selected: Optional[dict[str, Any]] = None
    finals: list[dict[str, Any]] = field(default_factory=list)

    @property
    def cpu_s(self) -> float:
        """CPU seconds of every trial's job (pruned and failed ones included)."""
        return float(sum(t.get("cpu_s") or 0.0 for t in self.trials))

    @property
    def cpu_s_per_trial(self) -> float:
        """The mean CPU seconds of a counted trial (0 without trials)."""
        return self.cpu_s / len(self.trials) if self.trials else 0.0

    @property
    def protocol_value(self) -> Optional[float]:
        """The protocol trial's score (``None``: not run)."""
        for trial in self.trials:
            if trial.get("protocol") and trial.get("value") is not None:
                return float(trial["value"])
        return None

    def tuning(self, study_name: str) -> dict[str, Any]:
        """The ``tuning`` block of the final records (``hnnbench._record.fields``)."""
        assert self.selected is not None
        states = [t["state"] for t in self.trials]
        return {
            "selected_on": SELECTED_ON,
            "objective": CRITERION,
            "criterion": self.criterion or self.objective.name,
            "score": SCORE,
            "seeds_per_trial": len(self.group.trial_seeds),
            "trial_seeds": list(self.group.trial_seeds),
            "fold": self.group.fold,
            "protocol_trial": PROTOCOL_TRIAL,
            "protocol_value": records.encode(self.protocol_value)
            if self.protocol_value is not None
            else None,
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
            "cpu_s_per_trial": round(self.cpu_s_per_trial, 3),
            "study": study_name,
        }


def objective_metric() -> Metric:
    """The registered metric declared to select on (:attr:`Metric.selects`): what a
    trial of a model without a selection criterion (a plugin that keeps its last
    iterate) is scored on, and the worst value and direction of every score."""
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


def _number(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _criterion(record: Mapping[str, Any], objective: Metric) -> tuple[float, str]:
    """One seed's ``(criterion value, criterion name)``: its selection criterion at the
    scored checkpoint (:data:`CRITERION`), or, for a model that records no selection,
    the fallback metric's mean; the worst value where the seed is not ``ok`` (a
    diverged, failed or timed-out seed is a result of its settings)."""
    selection = record.get("selection")
    if isinstance(selection, Mapping) and "validation_loss" in selection:
        name = str(selection.get("criterion") or "validation_loss")
        value = _number(selection.get("validation_loss"))
    else:
        name = objective.name
        value = _number(((record.get("metrics") or {}).get(objective.name) or {}).get("mean"))
    if record.get("status") != "ok" or math.isnan(value):
        return objective.worst(), name
    return value, name


def trial_score(recs: Sequence[Mapping[str, Any]], objective: Metric) -> tuple[float, str]:
    """A trial's ``(score, criterion name)``: the mean of its seeds' criteria
    (:func:`_criterion`; :data:`SCORE`), the worst value if any seed has none."""
    if not recs:
        return objective.worst(), objective.name
    values, names = zip(*(_criterion(r, objective) for r in recs), strict=True)
    worst = objective.worst()
    if any(v == worst or not math.isfinite(v) for v in values):
        return worst, names[0]
    return float(sum(values) / len(values)), names[0]


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
    ) -> list[dict[str, Any]]:
        """Run one job, as a sweep's Hydra task does (its config composed by
        :func:`~hnnbench._running.compose.compose`, run by the one job entry
        :func:`~hnnbench._running.job.run_job` in this command's launch context), and
        return its records (one per seed of a ``seed_batch``); ``extra``: overrides
        not stored as the job's."""
        cfg = compose([*overrides, *extra])
        with open_dict(cfg):
            cfg.tuning = OmegaConf.create(tuning)
            if rerun:
                cfg.rerun = True
        return [o.record for o in run_job(cfg, directory, overrides=[*overrides, *extra])]

    def _prepared(self, model: str) -> Any:
        cfg = compose(
            [
                f"system={self.system}",
                f"model={model}",
                f"profile={self.request.profile}",
                *self.request.overrides,
            ]
        )
        return prepare_job(cfg)

    def protocol_steps(self, model: str) -> int:
        """The system's protocol steps of the profile (the default step budget)."""
        job = self._prepared(model)
        return TrainSettings.resolve(job.system_cfg, job.model_cfg).steps

    def protocol_settings(self, model: str, space: SearchSpace) -> dict[str, Any]:
        """The protocol's value of every setting of ``space`` (``{"model.lr": 0.001,
        ...}``): the model's config under the profile, its training fields resolved
        against the system's protocol as a protocol job resolves them."""
        job = self._prepared(model)
        train = TrainSettings.resolve(job.system_cfg, job.model_cfg)
        out: dict[str, Any] = {}
        for name in space:
            value = getattr(train, name) if hasattr(train, name) else getattr(job.model_cfg, name)
            out[f"model.{name}"] = value
        return out

    def groups(self, model: str) -> list[FoldGroup]:
        """The studies of ``model``: one over every final seed on a simulated system;
        on a measured one (a system whose seeds choose folds, ``System.fold``), one per
        fold of the final seeds, whose trials train seeds of that fold only, so no
        study's selection ever read the test block its final seeds are scored on. A
        measured system's trial seeds are the first of the fold from ``trial_seed`` on
        that are not final seeds (the defaults: ``s + 10`` and ``s + 15`` for the final
        seeds ``s`` and ``s + 5`` of a five-fold system): the same data, other
        initialisations, so every final seed is one no trial trained."""
        first, count = self.request.trial_seed, self.request.seeds_per_trial
        job = self._prepared(model)
        fold = getattr(job.system_cls(job.system_cfg), "fold", None)
        if not callable(fold):
            trial_seeds = tuple(range(first, first + count))
            return [FoldGroup(None, trial_seeds, tuple(self.request.seeds))]
        finals_all = set(self.request.seeds)
        by_fold: dict[int, list[int]] = {}
        for seed in self.request.seeds:
            by_fold.setdefault(int(fold(seed)), []).append(seed)
        out = []
        # a bounded search: a fold rule that gives fold k too few seeds in this range
        # (a periodic rule gives it thousands) is refused rather than searched forever
        last = max([first, *finals_all]) + 10_000 * count
        for k, finals in by_fold.items():
            seeds: list[int] = []
            for candidate in range(first, last):
                if len(seeds) == count:
                    break
                if candidate not in finals_all and int(fold(candidate)) == k:
                    seeds.append(candidate)
            if len(seeds) < count:
                raise ConfigError(
                    f"{self.system}: fold {k} has {len(seeds)} seed(s) from trial_seed={first} "
                    f"to {last - 1} that are not final seeds, and a trial needs "
                    f"seeds_per_trial={count}. Use fewer seeds per trial, or check the "
                    "system's fold rule (System.fold)."
                )
            out.append(FoldGroup(k, tuple(seeds), tuple(finals)))
        return out

    # -- one study -------------------------------------------------------------------
    def study_name(self, model: str, group: Optional[FoldGroup] = None) -> str:
        fold = "" if group is None or group.fold is None else f"/fold{group.fold}"
        return f"{self.system}/{model}{fold}"

    def _storage(self) -> Any:
        import optuna

        path = self.root / "tuning" / f"{self.system}.db"
        path.parent.mkdir(parents=True, exist_ok=True)
        return optuna.storages.RDBStorage(
            f"sqlite:///{path}", engine_kwargs={"connect_args": {"timeout": 60}}
        )

    def _identity(
        self, model: str, space: SearchSpace, steps: int, group: FoldGroup
    ) -> dict[str, Any]:
        """What a study is of: resuming with anything else is refused."""
        return {
            "steps": steps,
            "profile": self.request.profile,
            "objective": CRITERION,
            "score": SCORE,
            "space": space_json(space),
            "trial_seeds": list(group.trial_seeds),
            "protocol_trial": PROTOCOL_TRIAL,
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
        return (
            "successive_halving on the criterion (rungs at 1/9 and 1/3 of the steps, "
            f"best 1/{REDUCTION} on; the protocol trial never pruned)"
        )

    def _open(
        self, model: str, space: SearchSpace, steps: int, group: Optional[FoldGroup] = None
    ) -> optuna.Study:
        import optuna

        group = group or self.groups(model)[0]
        optuna.logging.set_verbosity(optuna.logging.WARNING)
        identity = self._identity(model, space, steps, group)
        pruning = identity["pruner"].startswith("successive_halving")
        pruner = (
            optuna.pruners.SuccessiveHalvingPruner(
                min_resource=max(1, math.ceil(steps * FIRST_RUNG)), reduction_factor=REDUCTION
            )
            if pruning
            else optuna.pruners.NopPruner()
        )
        storage = self._storage()
        name = self.study_name(model, group)
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
        if not study.trials:  # trial 0: the protocol's settings, before any draw
            settings = self.protocol_settings(model, space)
            params = {
                n: settings[f"model.{n}"]
                for n, d in space.items()
                if _admissible(d, settings[f"model.{n}"])
            }
            study.enqueue_trial(params, user_attrs={"protocol": True, "settings": settings})
        # Reseeded on each start by the trials so far (interrupted ones included), so a
        # resumed study does not repeat its first draws.
        study.sampler = optuna.samplers.TPESampler(
            seed=self.request.sampler_seed + len(study.trials),
            n_startup_trials=min(10, max(1, math.ceil(self.request.trials / 2))),
        )
        return study

    def _trial_dir(self, model: str, number: int, group: Optional[FoldGroup] = None) -> Path:
        fold = () if group is None or group.fold is None else (f"fold{group.fold}",)
        return self.root / "trials" / self.system / model / Path(*fold) / f"trial{number:03d}"

    def _trial_records(self, model: str, number: int, group: FoldGroup) -> list[dict[str, Any]]:
        """The records of trial ``number`` that were written (one per trial seed)."""
        directory = self._trial_dir(model, number, group)
        found = [
            records.read_record(directory / f"seed{s}" / records.RECORD_NAME)
            for s in group.trial_seeds
        ]
        return [r for r in found if r is not None]

    def _recover(
        self, study: optuna.Study, model: str, space: SearchSpace, group: FoldGroup
    ) -> None:
        """Trials an interruption left running: told from their records where every
        seed's was written, else failed and their settings queued again (they are not
        counted)."""
        import optuna

        for trial in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
            recs = self._trial_records(model, trial.number, group)
            finished = (*records.FINISHED, "failed", "timeout")
            if len(recs) == len(group.trial_seeds) and all(
                r.get("status") in finished for r in recs
            ):
                state = optuna.trial.TrialState.PRUNED if any(map(_pruned, recs)) else None
                value = None if state else trial_score(recs, self.objective)[0]
                study.tell(trial.number, value, state=state)
                log.info(
                    "%s trial %d: recovered from its records",
                    self.study_name(model, group),
                    trial.number,
                )
                continue
            study.tell(trial.number, state=optuna.trial.TrialState.FAIL)
            attrs: dict[str, Any] = {"replays": trial.number}
            if trial.user_attrs.get("protocol"):
                attrs.update(protocol=True, settings=trial.user_attrs.get("settings"))
            study.enqueue_trial(dict(trial.params), user_attrs=attrs)
            log.info(
                "%s trial %d: interrupted; its settings run again",
                self.study_name(model, group),
                trial.number,
            )

    def _run_trial(
        self,
        study: optuna.Study,
        model: str,
        space: SearchSpace,
        steps: int,
        k: int,
        group: Optional[FoldGroup] = None,
    ) -> None:
        import optuna

        group = group or self.groups(model)[0]
        distributions = {n: _distribution(d) for n, d in space.items()}
        trial = study.ask(distributions)
        protocol = bool(trial.user_attrs.get("protocol"))
        settings = (
            dict(trial.user_attrs["settings"])
            if protocol and trial.user_attrs.get("settings")
            else _settings(space, trial.params)
        )
        pruning = not isinstance(study.pruner, optuna.pruners.NopPruner) and not protocol
        best = [math.inf]  # the criterion: lower is better

        def observe(step: int, losses: Mapping[str, float]) -> Optional[bool]:
            # The training loop's validation criterion after each chunk (the mean over
            # the batch's seeds; the system's selection criterion, the same for every
            # family), best so far: what the pruner compares at its rungs.
            value = losses.get(HISTORY_VALID)
            if value is None or not math.isfinite(value):
                return None
            best[0] = min(best[0], value)
            trial.report(best[0], step)
            if pruning and step < steps and trial.should_prune():
                return True
            return None

        directory = self._trial_dir(model, trial.number, group)
        seeds = list(group.trial_seeds)
        tuning = {
            "selected_on": SELECTED_ON,
            "objective": CRITERION,
            "trial": trial.number,
            "study": self.study_name(model, group),
            "seeds_per_trial": len(seeds),
            "trial_seeds": seeds,
            "protocol_trial": PROTOCOL_TRIAL if protocol else None,
        }
        batch = [f"seed_batch=[{','.join(map(str, seeds))}]"] if len(seeds) > 1 else []
        start = time.perf_counter()
        with progress.observing(observe):
            recs = self._job(
                [*self._overrides(model, seeds[0], settings, steps), *batch],
                directory / f"seed{seeds[0]}",
                tuning,
                extra=[f"evaluation.metrics=[{self.objective.name}]", "save_model=false"],
            )
        cpu = float(sum(float((r.get("timings") or {}).get("cpu_s") or 0.0) for r in recs))
        statuses = [str(r.get("status")) for r in recs]
        trial.set_user_attr("settings", settings)
        trial.set_user_attr("status", statuses[0] if len(set(statuses)) == 1 else statuses)
        trial.set_user_attr("cpu_s", cpu)
        if "skipped" in statuses:
            study.tell(trial, state=optuna.trial.TrialState.FAIL)
            raise _Skipped(str(recs[statuses.index("skipped")].get("error")))
        score, criterion = trial_score(recs, self.objective)
        trial.set_user_attr("criterion", criterion)
        trial.set_user_attr("seed_values", [_criterion(r, self.objective)[0] for r in recs])
        if any(map(_pruned, recs)):
            study.tell(trial, state=optuna.trial.TrialState.PRUNED)
            outcome = f"pruned at step {max(int(r.get('steps') or 0) for r in recs)}"
        else:
            study.tell(trial, score)
            outcome = f"{', '.join(sorted(set(statuses)))}, {criterion}={score:.3g}"
        spent = [
            float(t.user_attrs.get("cpu_s") or 0.0)
            for t in study.get_trials(deepcopy=False)
            if "cpu_s" in t.user_attrs
        ]
        left = (self.request.trials - k) * sum(spent) / max(len(spent), 1)
        log.info(
            "%s trial %d/%d (#%d%s, seeds %s): %s; %.1f s CPU, %.1f s wall; %s; this study "
            "so far %.0f s CPU, about %.0f s CPU to go (at its mean per trial)",
            self.study_name(model, group),
            k,
            self.request.trials,
            trial.number,
            ", the protocol's settings" if protocol else "",
            ",".join(map(str, seeds)),
            outcome,
            cpu,
            time.perf_counter() - start,
            " ".join(f"{key}={_override_value(v)}" for key, v in settings.items()),
            sum(spent),
            left,
        )

    def tune_model(self, model: str) -> list[Study]:
        """Tune ``model`` to the budget (resuming its studies: one, or one per fold of
        a measured system), then train each study's selected settings on its final
        seeds."""
        return [self._tune_group(model, group) for group in self.groups(model)]

    def _tune_group(self, model: str, group: FoldGroup) -> Study:
        import optuna

        space = registry.discover("model")[model].search_space
        assert space is not None
        steps = self.request.steps or self.protocol_steps(model)
        optuna_study = self._open(model, space, steps, group)
        name = self.study_name(model, group)
        result = Study(
            model,
            space,
            self.request.trials,
            steps,
            self.objective,
            self._pruner_name(space),
            group=group,
        )
        self._recover(optuna_study, model, space, group)
        counted = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)

        def done() -> int:
            return len(optuna_study.get_trials(deepcopy=False, states=counted))

        log.info(
            "%s: %d/%d trials done; space: %s; %d steps per trial on seeds %s; pruner: %s",
            name,
            done(),
            self.request.trials,
            describe(space),
            steps,
            ",".join(map(str, group.trial_seeds)),
            result.pruner,
        )
        skipped: Optional[str] = None
        while done() < self.request.trials:
            try:
                self._run_trial(optuna_study, model, space, steps, done() + 1, group)
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
        criteria = [t["criterion"] for t in result.trials if t.get("criterion")]
        result.criterion = criteria[0] if criteria else None
        if skipped is None:
            result.selected = _select(optuna_study, self.objective)
        self._write_summary(result, name)
        if result.selected is None:
            return result
        log.info(
            "%s: selected trial %d (%s=%.3g; the protocol's %s) of %d; tuning CPU %.0f s: %s",
            name,
            result.selected["number"],
            result.criterion,
            result.selected["value"],
            "not run" if result.protocol_value is None else f"{result.protocol_value:.3g}",
            len(result.trials),
            result.cpu_s,
            " ".join(f"{k}={_override_value(v)}" for k, v in result.selected["settings"].items()),
        )
        tuning = result.tuning(name)
        for seed in group.final_seeds:
            directory = self.root / "final" / self.system / model / f"seed{seed}"
            existing = records.read_record(directory / records.RECORD_NAME)
            stale = existing is not None and existing.get("tuning") != tuning
            overrides = self._overrides(model, seed, result.selected["settings"], steps)
            result.finals.extend(self._job(overrides, directory, tuning, rerun=stale))
        return result

    def _summary_path(self, model: str, group: FoldGroup) -> Path:
        return self.root / "tuning" / self.system / study_summary_name(model, group.fold)

    def _write_summary(self, study: Study, name: str) -> None:
        path = self._summary_path(study.model, study.group)
        path.parent.mkdir(parents=True, exist_ok=True)
        summary = {
            "system": self.system,
            "model": study.model,
            "study": name,
            "profile": self.request.profile,
            "trials_budget": study.budget_trials,
            "steps": study.steps,
            "objective": CRITERION,
            "criterion": study.criterion,
            "score": SCORE,
            "seeds_per_trial": len(study.group.trial_seeds),
            "trial_seeds": list(study.group.trial_seeds),
            "fold": study.group.fold,
            "final_seeds": list(study.group.final_seeds),
            "protocol_trial": PROTOCOL_TRIAL,
            "protocol_value": study.protocol_value,
            "selected_on": SELECTED_ON,
            "space": space_json(study.space),
            "pruner": study.pruner,
            "cpu_s": round(study.cpu_s, 3),
            "cpu_s_per_trial": round(study.cpu_s_per_trial, 3),
            "selected": study.selected,
            "trials": study.trials,
        }
        records.atomic_write_text(path, json.dumps(records.encode(summary), indent=2) + "\n")

    def run(self) -> list[Study]:
        models = resolve_models(self.request)
        log.info(
            "hnnbench tune: %s, %d model(s) x %d trial(s) of %d seed(s), final seeds %s, "
            "profile %s, into %s",
            self.system,
            len(models),
            self.request.trials,
            self.request.seeds_per_trial,
            ",".join(map(str, self.request.seeds)),
            self.request.profile,
            self.root,
        )
        out = []
        with sweep_lock(self.root / "trials" / self.system, self.request.command):
            for model in models:
                out.extend(self.tune_model(model))
        return out


def _admissible(dist: Distribution, value: Any) -> bool:
    """Whether ``value`` lies in ``dist`` (the protocol's value can lie outside a
    space, e.g. the quick profile's narrow network)."""
    if isinstance(dist, Categorical):
        return any(value == c and type(value) is type(c) for c in dist.choices)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    if isinstance(dist, IntRange) and value != int(value):
        return False
    low, high = dist.low, dist.high
    return bool(low <= value <= high)


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
        "protocol": bool(trial.user_attrs.get("protocol")),
        "criterion": trial.user_attrs.get("criterion"),
        "seed_values": trial.user_attrs.get("seed_values"),
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
