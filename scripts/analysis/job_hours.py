"""Job-hours of a set of records, per model family and backend: the sum of each job's
wall time (``timings.total_s``) and CPU time (``timings.cpu_s``, where the record has
it), as a Markdown table.

    python scripts/analysis/job_hours.py                  # results/records, paper profile
    python scripts/analysis/job_hours.py results/runs/<sweep> --profile quick
    python scripts/analysis/job_hours.py --track recipe   # another track's records ('any': all)

benchmarks/README.md quotes it for the paper sweeps, the old protocol's and the
re-published one (its first table, "Issue 29's figures"). A record
without timings (a job skipped before it ran) counts as a job with no time; records
of variants (``variant``) are counted apart under their family.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter, defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Optional

REPO = Path(__file__).resolve().parents[2]


def load(
    directories: Sequence[Path], profile: Optional[str], track: Optional[str] = "protocol"
) -> list[dict[str, Any]]:
    """Every readable ``result.json`` below ``directories`` of ``profile`` and ``track``
    (any when ``None``; a record without a track is the protocol's)."""
    out = []
    for directory in directories:
        for path in sorted(directory.rglob("result.json")):
            try:
                rec = json.loads(path.read_text("utf-8"))
            except (OSError, ValueError):
                print(f"job_hours.py: {path} is not readable JSON, left out", file=sys.stderr)
                continue
            if not isinstance(rec, dict):
                continue
            if (profile is None or rec.get("profile") == profile) and (
                track is None or (rec.get("track") or "protocol") == track
            ):
                out.append(rec)
    return out


def _seconds(rec: dict[str, Any], key: str) -> Optional[float]:
    timings = rec.get("timings")
    value = timings.get(key) if isinstance(timings, dict) else None
    return float(value) if isinstance(value, (int, float)) else None


def table(recs: list[dict[str, Any]]) -> str:
    """The Markdown table: one row per (family, backend), then the total."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = defaultdict(list)
    for rec in recs:
        family = str(rec.get("family") or rec.get("model") or "?")
        if rec.get("variant"):
            family += " (variants)"
        groups[(family, str(rec.get("backend") or "—"))].append(rec)
    lines = [
        "| family | backend | jobs | statuses | wall h (sum of total_s) | "
        "CPU h (sum of cpu_s) | jobs with cpu_s |",
        "|---|---|---|---|---|---|---|",
    ]

    def row(name: str, backend: str, items: list[dict[str, Any]]) -> str:
        walls = [w for w in (_seconds(r, "total_s") for r in items) if w is not None]
        cpus = [c for c in (_seconds(r, "cpu_s") for r in items) if c is not None]
        statuses = Counter(str(r.get("status")) for r in items)
        status = ", ".join(f"{n} {s}" for s, n in sorted(statuses.items()))
        return (
            f"| {name} | {backend} | {len(items)} | {status} | {sum(walls) / 3600:.2f} | "
            f"{sum(cpus) / 3600:.2f} | {len(cpus)} |"
        )

    for (family, backend), items in sorted(groups.items()):
        lines.append(row(family, backend, items))
    lines.append(row("**all**", "", recs))
    return "\n".join(lines)


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dirs", nargs="*", type=Path, default=[REPO / "results" / "records"])
    parser.add_argument(
        "--profile",
        default="paper",
        help="only records of this profile (default: paper; 'any': all)",
    )
    parser.add_argument(
        "--track",
        default="protocol",
        help="only records of this track (default: protocol; 'any': all)",
    )
    args = parser.parse_args(argv)
    recs = load(
        args.dirs,
        None if args.profile == "any" else args.profile,
        None if args.track == "any" else args.track,
    )
    if not recs:
        print("job_hours.py: no records", file=sys.stderr)
        return 1
    print(table(recs))
    return 0


if __name__ == "__main__":
    sys.exit(main())
