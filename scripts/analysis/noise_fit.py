"""Where do the families go on the noisy systems? The training loss at the noisy inputs
against the true field's, and how the clean-input criterion moves meanwhile (issue 46's
selection).

On a system with input noise (docs/METRICS.md: ``train_loss`` takes the model's field at
the *noisy* training inputs, the targets are clean), the true field is not the field
that minimises ``train_loss``: the clean targets' expectation given the noisy input (the
field averaged over the noise) scores lower, and so does a network that fits the noise
of its training inputs. A model below the true field's ``train_loss`` has moved towards
either, away from the true field at the clean inputs, which the criterion (``val_loss``)
measures; these records cannot tell the two apart (a held-out split at noisy inputs
would). Reads the protocol records of one backend's twins beside the oracle's (same
profile, system, variant and seed) under the directories given, and prints per system
and family (medians over the seeds with an oracle row):

- ``train/true at scored``: the model's ``train_loss`` at the scored checkpoint over the
  oracle's on the same seed's training inputs (below 1: below the noise floor);
- ``at final``: the same at the last checkpoint, from the training history; only for a
  family whose history logs ``train_loss`` itself (its logged value at the scored step
  equals the metric within 1 %; so_mlp, the LNN and the SRNN log their own objectives,
  shown ``-``);
- ``crit final/best``: the criterion at the final checkpoint over its lowest value;
- ``at``: the scored checkpoint's step over the steps trained.

    python scripts/analysis/noise_fit.py results/records \\
        --systems spring,damped_spring,pendulum,damped_pendulum
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

#: How close a history's logged training loss must be to the metric to be read as it.
SAME_QUANTITY_RTOL = 0.01


def _mean(rec: dict, metric: str) -> float:
    try:
        return float(rec["metrics"][metric]["mean"])
    except (KeyError, TypeError, ValueError):
        return math.nan


def _ratios(rec: dict, floor: float) -> dict[str, float]:
    """One seed's ratios (NaN where the record lacks what a ratio needs)."""
    sel = rec.get("selection") or {}
    hist = rec.get("history") or {}
    steps, train = hist.get("step") or [], hist.get("train_loss") or []
    scored = _mean(rec, "train_loss")
    out = {
        "scored": scored / floor,
        "final": math.nan,
        "crit": math.nan,
        "at": math.nan,
    }
    if sel.get("step") in steps and train:
        logged = float(train[steps.index(sel["step"])])
        if math.isclose(logged, scored, rel_tol=SAME_QUANTITY_RTOL):
            out["final"] = float(train[-1]) / floor
    best, final = sel.get("best_value"), sel.get("final_value")
    if isinstance(best, (int, float)) and isinstance(final, (int, float)) and best > 0:
        out["crit"] = final / best
    if isinstance(sel.get("step"), int) and rec.get("steps"):
        out["at"] = sel["step"] / int(rec["steps"])
    return out


def table(directories: list[Path], systems: list[str], backend: str) -> list[str]:
    """The printed lines: a header, then one line per (system, family)."""
    from hnnbench import _record as records
    from hnnbench._record.tracks import track_of
    from hnnbench._results.leaderboard import variant_labels, variant_overrides

    recs = records.load(*directories).records
    recs = [r for r in recs if track_of(r) == "protocol" and r.get("status") == "ok"]
    profiles = sorted({str(r.get("profile")) for r in recs})
    if len(profiles) > 1:
        return [f"records of several profiles ({', '.join(profiles)}): give one profile's"]
    labels = variant_labels([variant_overrides(r) for r in recs])
    recs = [r for r, label in zip(recs, labels, strict=True) if not label]  # no variant
    lines = [
        f"{'system':16s} {'model':12s} {'seeds':>5s} {'train/true at scored':>21s} "
        f"{'at final':>9s} {'crit final/best':>16s} {'at':>5s}"
    ]
    for system in systems:
        floors = {
            int(r["seed"]): _mean(r, "train_loss")
            for r in recs
            if r["system"] == system and r["model"] == "oracle"
        }
        models = sorted(
            {
                str(r["model"])
                for r in recs
                if r["system"] == system and r.get("backend") == backend and not r.get("reference")
            }
        )
        if not floors:
            lines.append(f"{system:16s} no oracle record: no noise floor to compare with")
            continue
        if not all(math.isfinite(v) and v > 0 for v in floors.values()):
            lines.append(f"{system:16s} the true field scores 0 on train_loss: no input noise")
            continue
        for model in models:
            seeds = [
                _ratios(r, floors[int(r["seed"])])
                for r in recs
                if r["system"] == system and r["model"] == model and int(r["seed"]) in floors
            ]

            def med(key: str, seeds: list[dict[str, float]] = seeds) -> str:
                vals = [s[key] for s in seeds if math.isfinite(s[key])]
                return f"{statistics.median(vals):.3g}" if vals else "-"

            lines.append(
                f"{system:16s} {model:12s} {len(seeds):5d} {med('scored'):>21s} "
                f"{med('final'):>9s} {med('crit'):>16s} {med('at'):>5s}"
            )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directories", nargs="+", type=Path)
    parser.add_argument("--systems", default="spring,damped_spring,pendulum,damped_pendulum")
    parser.add_argument("--backend", default="jax")
    ns = parser.parse_args(argv)
    missing = [str(d) for d in ns.directories if not d.is_dir()]
    if missing:
        print(
            f"noise_fit: not a directory: {', '.join(missing)}; give folders of records "
            "(results/records)",
            file=sys.stderr,
        )
        return 2
    print("\n".join(table(ns.directories, ns.systems.split(","), ns.backend)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
