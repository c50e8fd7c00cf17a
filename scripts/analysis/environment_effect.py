"""How much of the tuning gain is the change of environment? (issue 50)

The published protocol rows and tuned rows were made by different installs (commits) on
different classes of CPU (docs/TUNING.md, "Tuning gain"), so the tuning gain (protocol /
tuned, paired by seed) holds that change as well as the change of settings. This script
reads protocol runs made again in the tuned rows' environment (the tuned records'
commit, on a CPU of their class) beside the published protocol and tuned records, and
prints per system, family and metric, paired by seed, with each median's
order-statistic interval (``hnnbench._results.stats.paired_effect``) and the seeds:

- ``environment``: published protocol / protocol re-run (above ×1: the re-run scores
  lower; ×1: the environment alone moves nothing);
- ``gain, published``: published protocol / tuned, the tuning gain the pages show (on
  the seeds re-run);
- ``gain, one environment``: protocol re-run / tuned, the tuning gain with the
  environment held fixed.

Metrics: the selection criterion (``criterion``: each run's ``selection.validation_loss``)
and ``--metrics`` (default ``test_loss``). Make the re-run with the tuned records'
install, on the seeds no trial trained, e.g. for spring:

    <tuned install>/bin/hnnbench -m system=spring \\
        model=mlp_jax,hnn_jax,dhnn_jax,lnn_jax,so_mlp_jax,srnn_jax \\
        seed=2,3,4,5,6,7,8,9 profile=paper hydra.sweep.dir=RERUN
    python scripts/analysis/environment_effect.py RERUN
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

#: The criterion's row name (as the tuning gain names it).
CRITERION = "criterion"


def _value(rec: Mapping[str, Any], metric: str) -> float:
    """``metric``'s seed value of ``rec`` (the criterion: ``selection.validation_loss``);
    NaN where the record lacks it."""
    try:
        if metric == CRITERION:
            return float((rec.get("selection") or {})["validation_loss"])
        return float(rec["metrics"][metric]["mean"])
    except (KeyError, TypeError, ValueError):
        return math.nan


def _text(value: float, scale: str) -> str:
    """A paired effect to four digits (a factor, or a difference): an environment's
    effect is near ×1, where two digits tell nothing."""
    if scale == "log":
        return f"×{10.0**value:.4g}" if math.isfinite(value) else f"×{10.0**value}"
    return f"{value:+.4g}"


def _effect(mine: dict[int, float], theirs: dict[int, float], better: str, scale: str) -> str:
    """``mine`` against ``theirs`` paired by seed: the median with its interval and the
    number of seeds."""
    from hnnbench._results import stats

    seeds = sorted(s for s in set(mine) & set(theirs) if math.isfinite(mine[s] + theirs[s]))
    if not seeds:
        return "—"
    gain, low, high, _ = stats.paired_effect(
        [mine[s] for s in seeds], [theirs[s] for s in seeds], better, scale
    )
    return f"{_text(gain, scale)} [{_text(low, scale)}, {_text(high, scale)}] ({len(seeds)})"


def table(rerun: Path, published: Path, metrics: list[str]) -> list[str]:
    """The printed lines: a header, then one line per (system, family, metric) the
    re-run holds; ``SystemExit`` (one line) where a re-run record is not a protocol run
    of the paper profile."""
    from hnnbench import _record as records
    from hnnbench._record.tracks import track_of
    from hnnbench._results.leaderboard import metric_declarations

    declared = metric_declarations()
    unknown = [m for m in metrics if m not in declared]
    if unknown:
        raise SystemExit(
            f"environment_effect: unknown metric(s) {', '.join(unknown)}; "
            f"declared: {', '.join(declared)}"
        )
    again = records.load(rerun).records
    if not again:
        raise SystemExit(f"environment_effect: {rerun}: no records; give a re-run's sweep folder")
    bad = next((r for r in again if track_of(r) != "protocol" or r.get("profile") != "paper"), None)
    if bad is not None:
        raise SystemExit(
            f"environment_effect: {bad.get('path')}: track {track_of(bad)}, profile "
            f"{bad.get('profile')}; a re-run is of the protocol track and the paper profile"
        )
    runs = [r for r in records.load(published).records if r.get("profile") == "paper"]
    seeds_of: dict[tuple[str, str, str], dict[int, Mapping[str, Any]]] = {}
    for side, rec in [*((track_of(r), r) for r in runs), *(("rerun", r) for r in again)]:
        seeds_of.setdefault((side, rec["system"], rec["model"]), {})[int(rec["seed"])] = rec
    lines = [
        f"{'system':<16} {'family':<8} {'metric':<10} {'environment':<32} "
        f"{'gain, published':<32} {'gain, one environment':<32}"
    ]
    pairs = sorted({(r["system"], r["model"]) for r in again})
    for system, model in pairs:
        mine = seeds_of[("rerun", system, model)]
        protocol = seeds_of.get(("protocol", system, model), {})
        tuned = seeds_of.get(("tuned", system, model), {})
        family = str(next(iter(mine.values())).get("family") or model)
        for metric in [CRITERION, *metrics]:
            better, scale = (
                ("lower", "log")
                if metric == CRITERION
                else (declared[metric].better, declared[metric].scale)
            )
            again_v, protocol_v, tuned_v = (
                {s: _value(r, metric) for s, r in recs.items() if s in mine}
                for recs in (mine, protocol, tuned)
            )
            lines.append(
                f"{system:<16} {family:<8} {metric:<10} "
                f"{_effect(again_v, protocol_v, better, scale):<32} "
                f"{_effect(tuned_v, protocol_v, better, scale):<32} "
                f"{_effect(tuned_v, again_v, better, scale):<32}"
            )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rerun", type=Path, help="the re-run's sweep folder (protocol runs)")
    parser.add_argument(
        "--records", type=Path, default=REPO / "results" / "records", help="published records"
    )
    parser.add_argument("--metrics", default="test_loss", help="comma-separated metrics")
    args = parser.parse_args(argv)
    metrics = [m for m in args.metrics.split(",") if m]
    print("\n".join(table(args.rerun, args.records, metrics)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
