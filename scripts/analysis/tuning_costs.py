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
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
RECORDS = REPO / "results" / "records"


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


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dir", type=Path, help="the tiny run's out= directory")
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
