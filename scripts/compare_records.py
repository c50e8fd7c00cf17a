"""Compare the metrics of two sweeps record by record.

    python scripts/compare_records.py BEFORE AFTER [--rtol 0] [--metrics a,b]

Records are matched on (system, model, seed, variant overrides). For each pair every
metric present in either record is compared: equal (bit for bit, or within ``--rtol``
relative), different (with the relative difference), or missing on one side. Exit
status 0 when every matched metric agrees, both sweeps hold the same jobs and every
record could be read, else 1.

Used to show that a refactor leaves results unchanged (``--rtol 0``: identical), and
that seeds trained as one batch agree with seeds trained alone.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

#: Overrides that do not change what a job computes (where and how it runs).
RUN_KEYS = {"system", "model", "seed", "profile", "rerun", "device", "threads", "pin_cpu",
            "save_model", "cache_dir", "data_dir", "seeds_per_job"}


def load(directory: Path) -> tuple[dict[tuple[Any, ...], dict[str, Any]], list[str]]:
    """The records below ``directory`` by job (:func:`hnnbench._records.load`), and a
    line for each file left out (unreadable or not a record)."""
    from hnnbench import _records as R

    loaded = R.load(directory)
    out = {}
    for rec in loaded.records:
        variant = tuple(sorted(
            o.lstrip("+") for o in rec.get("overrides") or []
            if o.lstrip("+~").split("=", 1)[0] not in RUN_KEYS and not o.startswith("hydra")))
        out[(rec["system"], rec["model"], rec["seed"], variant)] = rec
    return out, [str(item) for item in loaded.problems]


def value(metric: Any) -> float:
    """A metric's mean as a float (``None``: NaN)."""
    mean = metric.get("mean") if isinstance(metric, dict) else metric
    if mean is None:
        return math.nan
    return float(mean)


def same(a: float, b: float, rtol: float) -> bool:
    if math.isnan(a) and math.isnan(b):
        return True
    if a == b:
        return True
    if rtol == 0 or not (math.isfinite(a) and math.isfinite(b)):
        return False
    return abs(a - b) <= rtol * max(abs(a), abs(b))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument("--rtol", type=float, default=0.0,
                        help="relative tolerance (default 0: identical)")
    parser.add_argument("--metrics", default="", help="comma-separated subset to compare")
    args = parser.parse_args(argv)
    (before, left_before), (after, left_after) = load(args.before), load(args.after)
    wanted = {m for m in args.metrics.split(",") if m}
    bad = 0
    for item in left_before + left_after:
        print(f"LEFT OUT {item}")
        bad += 1
    n_values = 0
    for key in sorted(set(before) | set(after), key=str):
        tag = f"{key[0]} x {key[1]} seed={key[2]}" + (f" [{' '.join(key[3])}]" if key[3] else "")
        if key not in before or key not in after:
            print(f"MISSING  {tag}: only in {'after' if key in after else 'before'}")
            bad += 1
            continue
        a, b = before[key], after[key]
        if a["status"] != b["status"]:
            print(f"STATUS   {tag}: {a['status']} -> {b['status']}")
            bad += 1
        names = set(a.get("metrics") or {}) | set(b.get("metrics") or {})
        for name in sorted(names & wanted if wanted else names):
            ma, mb = (a.get("metrics") or {}).get(name), (b.get("metrics") or {}).get(name)
            if ma is None or mb is None:
                print(f"MISSING  {tag}: {name} only in {'after' if mb is not None else 'before'}")
                bad += 1
                continue
            va, vb = value(ma), value(mb)
            n_values += 1
            if not same(va, vb, args.rtol):
                rel = abs(va - vb) / max(abs(va), abs(vb), 1e-300)
                print(f"DIFFERS  {tag}: {name} {va!r} -> {vb!r} (relative {rel:.2e})")
                bad += 1
    matched = len(set(before) & set(after))
    verdict = "identical" if args.rtol == 0 else f"equal within rtol={args.rtol:g}"
    print(f"{matched} jobs matched, {n_values} metric values compared, {bad} difference(s)"
          + ("" if bad else f": all {verdict}"))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
