"""Would the tuned track's verdicts differ if its rows read the trial seeds too?

    python scripts/analysis/trial_seed_leaders.py results/records [--system double_pendulum]

A simulated system's tuned rows leave out the final runs on their study's trial seeds
(docs/TUNING.md, "Which seeds a tuned row reads"). This script builds the tracks table
(``tracks.csv``'s verdict cells) twice from the same records: as published, and with
every tuned record's ``tuning.trial_seeds`` emptied in memory, so those runs are read
in. It prints one line per (system, metric) tuned cell, the two verdicts side by side,
and marks a cell whose set of leading families differs; then the count of such cells.
Nothing is written.
"""

from __future__ import annotations

import argparse
import copy
import sys
from pathlib import Path
from typing import Any


def _tuned_cells(recs: list[dict[str, Any]]) -> dict[tuple[str, str], str]:
    from hnnbench._results.leaderboard import leaderboard
    from hnnbench._results.report.verdicts import build_verdicts, tracks_frame

    verdicts = build_verdicts(recs, leaderboard(recs), with_aggregate=False)
    frame = tracks_frame(verdicts.families)
    if frame.empty or "tuned" not in frame:
        return {}
    return {
        (str(row.system), str(row.metric)): str(row.tuned)
        for row in frame.itertuples()
        if isinstance(row.tuned, str) and row.tuned not in ("", "—")
    }


def main(argv: list[str] | None = None) -> int:
    from hnnbench._results.report.inputs import load_sweeps
    from hnnbench._results.report.verdicts import _leader_set

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dirs", nargs="+", type=Path, help="record directories (merged)")
    p.add_argument("--system", action="append", default=None, help="only these systems")
    ns = p.parse_args(argv)
    recs, _ = load_sweeps(ns.dirs)
    if ns.system:
        recs = [r for r in recs if r.get("system") in ns.system]
    with_trials = copy.deepcopy(recs)
    for rec in with_trials:
        if isinstance(rec.get("tuning"), dict):
            rec["tuning"]["trial_seeds"] = []
    published, read_in = _tuned_cells(recs), _tuned_cells(with_trials)
    if not published:
        print("no tuned cell in these records", file=sys.stderr)
        return 1
    changed = 0
    for key in sorted(published):
        a, b = published[key], read_in.get(key, "—")
        differs = _leader_set(a) != _leader_set(b)
        changed += differs
        mark = "  <- other leaders" if differs else ""
        print(f"{key[0]:18s} {key[1]:14s} {a:28s} | with trial seeds: {b}{mark}")
    print(f"{changed} of {len(published)} tuned cells have other leaders with the trial seeds")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
