"""Estimate the CPU cost of the tuned track from a tiny ``hnnbench tune`` run.

A tiny run (few trials of few steps, e.g. ``trials=2 steps=100``) samples each model's
search space; its trial records give, per trial, the CPU seconds of the job and the
share of its wall time spent training (``timings``: ``fit_s`` less ``compile_s``, over
``total_s``). This script splits each trial's CPU into a training part per step and a
fixed part (data, compilation, the objective's evaluation), and extrapolates to the
real budget: ``trials`` trials of ``steps`` steps (default: each system's protocol steps
of the run's profile) and the final runs on ``seeds`` seeds (their training at the
per-step cost of the space's mean draw; their evaluation: the published protocol
records' median ``eval_s`` of the same system and model, where there are some).

It is an estimate: no pruning is assumed (successive halving stops most trials at 1/9
or 1/3 of the steps, so the tuning costs less), the per-step cost of the space's mean
draw stands for every trial, and CPU seconds are one core's.

    python scripts/analysis/tuning_costs.py results/runs/tuned_cost --trials 16 --seeds 10

Without a tiny run, ``--from-job-costs`` bounds the same budget from the published
protocol jobs' median seconds (``hnnbench/resources/job_costs.csv``, the six JAX twins
of the profile): a trial of ``--seeds-per-trial`` seeds counted as that many whole jobs,
once per study (a measured system holds one study per fold of the final seeds), plus
the final seeds, per system and per stage of ``scripts/maintainer/tune_sweep.sh``:

    python scripts/analysis/tuning_costs.py --from-job-costs --trials 16 --seeds 10
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
RECORDS = REPO / "results" / "records"
JOB_COSTS = REPO / "hnnbench" / "resources" / "job_costs.csv"
TUNE_SWEEP = REPO / "scripts" / "maintainer" / "tune_sweep.sh"
FAMILIES = ("mlp", "hnn", "dhnn", "lnn", "so_mlp", "srnn")


def stages() -> dict[int, list[str]]:
    """The systems of each stage, as ``tune_sweep.sh`` declares them (``N) systems="..."``)."""
    found = re.findall(r'^\s*(\d+)\) systems="([^"]*)"', TUNE_SWEEP.read_text("utf-8"), re.M)
    return {int(k): v.split() for k, v in found}


def protocol_steps(system: str, model: str, profile: str) -> int:
    from hnnbench._contracts.plugin import TrainSettings
    from hnnbench._running.compose import compose
    from hnnbench._running.config import prepare_job

    job = prepare_job(compose([f"system={system}", f"model={model}", f"profile={profile}"]))
    return TrainSettings.resolve(job.system_cfg, job.model_cfg).steps


def published_eval(system: str, model: str, profile: str) -> float | None:
    """The median ``eval_s`` of the published protocol records of the pair, if any."""
    values = []
    for path in (RECORDS / system / model).glob("seed*/result.json"):
        rec = json.loads(path.read_text("utf-8"))
        if rec.get("profile") == profile and rec.get("status") == "ok":
            values.append(float(rec["timings"].get("eval_s", 0.0)))
    return statistics.median(values) if values else None


def trial_parts(rec: dict) -> tuple[float, float] | None:
    """``(fixed CPU s, training CPU s per step)`` of one trial record."""
    t = rec.get("timings") or {}
    steps = rec.get("steps") or 0
    if not steps or not t.get("total_s") or "cpu_s" not in t:
        return None
    train_share = max(t.get("fit_s", 0.0) - t.get("compile_s", 0.0), 0.0) / t["total_s"]
    train_cpu = t["cpu_s"] * train_share
    return t["cpu_s"] - train_cpu, train_cpu / steps


def studies(system: str, seeds: int, profile: str) -> int:
    """How many studies one model's tuning holds on ``system`` for the final seeds
    ``0..seeds-1``: the tuner's own grouping (one, or one per fold on a measured system)."""
    from hnnbench._tuning.request import TuneRequest
    from hnnbench._tuning.tuner import Tuner

    model = f"{FAMILIES[0]}_jax"
    request = TuneRequest(
        system=system, models=[model], trials=1, seeds=list(range(seeds)), profile=profile
    )
    return len(Tuner(request).groups(model))


def from_job_costs(ns: argparse.Namespace) -> int:
    """Print the job-costs bound per system and per stage (module docstring)."""
    import csv

    with JOB_COSTS.open(encoding="utf-8") as f:
        median = {
            (row["system"], row["model"]): float(row["seconds"])
            for row in csv.DictReader(f)
            if row["profile"] == ns.profile
        }
    print("| stage | system | studies per model | trial CPU h | final CPU h | total CPU h |")
    print("|---|---|---|---|---|---|")
    for stage, systems in stages().items():
        stage_total = 0.0
        for system in systems:
            per_job = [median.get((system, f"{family}_jax")) for family in FAMILIES]
            missing = [f for f, v in zip(FAMILIES, per_job, strict=True) if v is None]
            if missing:
                print(f"| {stage} | {system} | no job costs for {', '.join(missing)} | | | |")
                continue
            # a family that cannot run on the system is recorded skipped in a few ms
            per_job = [v for v in per_job if v is not None]
            n = studies(system, ns.seeds, ns.profile)
            trials = sum(n * ns.trials * ns.seeds_per_trial * v for v in per_job) / 3600
            finals = sum(ns.seeds * v for v in per_job) / 3600
            stage_total += trials + finals
            print(
                f"| {stage} | {system} | {n} | {trials:.1f} | {finals:.1f} | "
                f"{trials + finals:.1f} |"
            )
        print(f"| {stage} | all | | | | {stage_total:.1f} |")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dir", type=Path, nargs="?", help="the tiny run's out= directory")
    p.add_argument(
        "--from-job-costs",
        action="store_true",
        help="bound the budget from hnnbench/resources/job_costs.csv instead of a tiny run",
    )
    p.add_argument("--profile", default="paper", help="job costs' profile (default paper)")
    p.add_argument("--trials", type=int, default=20, help="trials per model (default 20)")
    p.add_argument("--seeds", type=int, default=10, help="final seeds (default 10)")
    p.add_argument(
        "--seeds-per-trial",
        type=int,
        default=2,
        help="seeds each trial trains (default 2; a record is one seed of a trial's batch)",
    )
    p.add_argument(
        "--steps",
        type=int,
        default=None,
        help="steps per trial (default: each system's protocol steps)",
    )
    ns = p.parse_args(argv)
    if ns.from_job_costs:
        return from_job_costs(ns)
    if ns.dir is None:
        p.error("give the tiny run's out= directory, or --from-job-costs")
    parts: dict[tuple[str, str, str], list[tuple[float, float]]] = defaultdict(list)
    for path in sorted((ns.dir / "trials").rglob("result.json")):
        rec = json.loads(path.read_text("utf-8"))
        found = trial_parts(rec)
        if found is not None and rec.get("status") in ("ok", "diverged"):
            parts[(rec["system"], rec["model"], rec["profile"])].append(found)
    if not parts:
        print(f"no trial records under {ns.dir / 'trials'}", file=sys.stderr)
        return 1
    print(
        "| system | model | trials measured | CPU ms/step (mean draw) | fixed CPU s/trial "
        "| steps | tuning CPU h | final runs CPU h |"
    )
    print("|---|---|---|---|---|---|---|---|")
    totals: dict[str, float] = defaultdict(float)
    for (system, model, profile), values in sorted(parts.items()):
        fixed = statistics.mean(v[0] for v in values)
        per_step = statistics.mean(v[1] for v in values)
        steps = ns.steps or protocol_steps(system, model, profile)
        tuning = ns.trials * ns.seeds_per_trial * (fixed + per_step * steps)
        evaluation = published_eval(system, model, profile) or 0.0
        finals = ns.seeds * (fixed + per_step * steps + evaluation)
        totals[system] += tuning + finals
        print(
            f"| {system} | {model} | {len(values)} | {1e3 * per_step:.2f} | {fixed:.1f} | "
            f"{steps} | {tuning / 3600:.2f} | {finals / 3600:.2f} |"
        )
    print()
    for system, seconds in totals.items():
        print(
            f"{system}: about {seconds / 3600:.1f} CPU hours for {ns.trials} trials of "
            f"{ns.seeds_per_trial} seed(s) per model and {ns.seeds} final seeds, without "
            "pruning (one core; a measured system's studies per fold: times its folds)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
