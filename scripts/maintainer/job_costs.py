"""Write hnnbench/resources/job_costs.csv: the wall time of one job per (profile, system,
model), from the runs this repository publishes (hnnbench._sweeping.eta reads it for the
sweep's estimate and ETA).

- paper profile: the median ``timings.total_s`` over the protocol track's records in
  results/records (every seed; variants left out). A tuned or recipe record trains other
  settings (other widths, steps, schedules: docs/TUNING.md), so its time says nothing
  of a protocol job's and is left out too;
- quick profile: ``total_s_mean`` of results/reference/quick.csv (the CI gate's seed-0
  sweep).

    python scripts/maintainer/job_costs.py            # rewrite the file
    python scripts/maintainer/job_costs.py --check    # exit 1 when the file is not what it writes

scripts/maintainer/publish_results.py and ``make ci-reference`` run it after they write results.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import sys
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
RECORDS = REPO / "results" / "records"
QUICK = REPO / "results" / "reference" / "quick.csv"


def rows(records: Path = RECORDS, quick: Path = QUICK) -> list[dict[str, object]]:
    """The table's rows: the paper profile's from ``records``, the quick profile's from
    ``quick``."""
    from hnnbench._contracts.names import DEFAULT_TRACK
    from hnnbench._record.tracks import track_of
    from hnnbench._results.leaderboard import _variant_items, variant_overrides
    from hnnbench._sweeping.eta import median_seconds

    times: dict[tuple[str, str, str], list[float]] = defaultdict(list)
    for path in sorted(records.rglob("result.json")):
        rec = json.loads(path.read_text("utf-8"))
        if (
            track_of(rec) != DEFAULT_TRACK
            or not isinstance(rec.get("timings"), dict)
            or _variant_items(variant_overrides(rec))
        ):  # another track, or a variant
            continue
        total = rec["timings"].get("total_s")
        if isinstance(total, (int, float)):
            times[(rec["profile"], rec["system"], rec["model"])].append(float(total))
    out: list[dict[str, object]] = []
    for (profile, system, model), values in sorted(times.items()):
        out.append(
            {
                "profile": profile,
                "system": system,
                "model": model,
                "seconds": f"{median_seconds(values):.3g}",
                "n_runs": len(values),
                "source": "results/records (median total_s)",
            }
        )
    if quick.exists():
        with quick.open(newline="", encoding="utf-8") as fh:
            for row in csv.DictReader(fh):
                if row.get("variant") or not row.get("total_s_mean"):
                    continue
                out.append(
                    {
                        "profile": row["profile"],
                        "system": row["system"],
                        "model": row["model"],
                        "seconds": f"{float(row['total_s_mean']):.3g}",
                        "n_runs": row.get("n_seeds", ""),
                        "source": "results/reference/quick.csv (total_s_mean)",
                    }
                )
    return out


def render() -> str:
    from hnnbench._sweeping.eta import COLUMNS

    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows())
    return buf.getvalue()


def _out() -> Path:
    from hnnbench._sweeping.eta import COSTS_FILE

    return REPO / "hnnbench" / "resources" / COSTS_FILE


def main(argv: list[str] | None = None) -> int:
    out_path = _out()
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--check",
        action="store_true",
        help="exit 1 when the committed file differs from what this writes",
    )
    args = parser.parse_args(argv)
    text = render()
    if args.check:
        if not out_path.exists() or out_path.read_text("utf-8") != text:
            print(
                f"{out_path.relative_to(REPO)} is out of date: run python "
                "scripts/maintainer/job_costs.py",
                file=sys.stderr,
            )
            return 1
        return 0
    out_path.write_text(text, encoding="utf-8")
    print(f"wrote {out_path.relative_to(REPO)} ({text.count(chr(10)) - 1} rows)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
