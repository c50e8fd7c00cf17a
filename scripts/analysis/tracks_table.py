"""The tracks side by side: one Markdown table per metric, a row per (system, family),
a column per track, and a line per system saying whether the family with the lowest
(or highest) mean changes between the tracks.

    python scripts/analysis/tracks_table.py results/records results/runs/tuned_paper/final \\
        --metric test_loss --metric energy_mse

Reads the records with ``hnnbench.load`` (several directories merge; the protocol's and
the tuned track's records are told apart by their ``track``) and takes each family's
model of one backend (``--backend``, default ``jax``: one family is one competitor).
Cells are mean ± std over seeds of the leaderboard (its ``ok`` runs); the winner of a
track is the family with the best mean among the pairs whose every seed is ``ok``:
a statement about means, not a test of separation (say "best" only where intervals
over paired seeds separate it).
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

TRACK_ORDER = ("protocol", "tuned", "recipe")


def main(argv: list[str] | None = None) -> int:
    import hnnbench
    from hnnbench._registry.groups import metrics as registered
    from hnnbench._results.leaderboard import format_value

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dirs", nargs="+", type=Path, help="record directories (merged)")
    p.add_argument(
        "--metric", action="append", default=None, help="a metric (repeatable; default test_loss)"
    )
    p.add_argument("--backend", default="jax", help="the backend of each family's model")
    ns = p.parse_args(argv)
    declared = {m.name: m for m in registered()}
    board = hnnbench.leaderboard(hnnbench.load(*ns.dirs))
    if "track" not in board:
        board["track"] = "protocol"
    if "variant" in board:
        board = board[board["variant"].fillna("") == ""]
    board = board[(board["backend"] == ns.backend) & board["ranked"].astype(bool)]
    tracks = [t for t in TRACK_ORDER if t in set(board["track"])]
    for name in ns.metric or ["test_loss"]:
        metric = declared.get(name)
        if metric is None or f"{name}_mean" not in board:
            print(f"unknown metric {name}", file=sys.stderr)
            return 2
        sign = 1.0 if metric.better == "lower" else -1.0
        print(f"### {name} ({metric.better} is better)\n")
        print("| system | family | " + " | ".join(tracks) + " |")
        print("|---|---|" + "---|" * len(tracks))
        lines = []
        for system, rows in board.groupby("system", sort=False):
            winners = {}
            for track in tracks:
                ranked = rows[(rows["track"] == track) & (rows["n_ok"] == rows["n_seeds"])]
                values = ranked[f"{name}_mean"].astype(float)
                values = values[values.apply(math.isfinite)]
                if len(values) >= 2:
                    winners[track] = ranked.loc[(sign * values).idxmin(), "family"]
            for family, frows in rows.groupby("family", sort=False):
                cells = []
                for track in tracks:
                    r = frows[frows["track"] == track]
                    text = (
                        "—"
                        if r.empty
                        else format_value(
                            float(r[f"{name}_mean"].iloc[0]), float(r[f"{name}_std"].iloc[0])
                        )
                    )
                    cells.append(f"**{text}**" if winners.get(track) == family else text)
                print(f"| {system} | {family} | " + " | ".join(cells) + " |")
            found = [f"{t}: {w}" for t, w in winners.items()]
            changed = len(set(winners.values())) > 1
            lines.append(
                f"- {system}: the lowest-mean family "
                if sign > 0
                else f"- {system}: the highest-mean family "
            )
            lines[-1] += (
                f"changes between tracks ({'; '.join(found)})."
                if changed
                else f"is the same on every track ({'; '.join(found) or 'none'})."
            )
        print()
        print("\n".join(lines))
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
