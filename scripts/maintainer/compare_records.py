"""Compare two sweeps record by record: every field that says what a job computed, and
the arrays and weights beside each record.

    python scripts/maintainer/compare_records.py BEFORE AFTER [--rtol 0] [--metrics a,b]
        [--metrics-only] [--ignore FIELD]

Records are matched on (track, system, model, seed, tuner trial, variant overrides).
For each pair it compares, and prints every difference it finds:

- the whole record, field by field (metrics, statuses, errors, histories, selection,
  config, steps, training protocol, data hashes and sizes, identity, tuning, overrides,
  command lines), with these left out: what says when, where and with which hnnbench it
  ran (``environment``: versions, host, git commit; ``created_at``; ``timings``;
  ``tuning.cpu_s``, also in the config a tuned job ran with; ``cpu_pin``, the core a
  job was given; ``data.cache_hit``, whether the dataset was in the cache already; each
  plugin's ``distribution_version``), and the run-only settings (:data:`RUN_ONLY_KEYS`,
  which say how a job runs, not what it computes) in ``config``, ``overrides`` and
  ``rerun_command``. Each sweep's own directory, written into paths and command
  lines, reads as ``<sweep>``;
- ``rollout.npz`` beside the record: the same arrays, equal element by element (NaN
  equal to NaN);
- the weights file the record names: the same bytes.

Metric means and standard errors are equal bit for bit, or within ``--rtol`` relative;
every other value exactly. Exit status 0 when nothing differs, both sweeps hold the
same jobs and every record could be read, else 1.

Used to show that a refactor leaves results unchanged (identical, in all but version
fields), and with ``--metrics-only --rtol R`` that seeds trained as one batch agree
with seeds trained alone.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hnnbench._record.loader import load as load_records
from hnnbench._running.config import RUN_ONLY_KEYS

#: Top-level record fields that say when, where and with which hnnbench a job ran.
IGNORED = {"environment", "created_at", "timings", "cpu_pin"}
#: Fields below the top level, likewise (``*``: any key).
IGNORED_PATHS = frozenset(
    {
        ("tuning", "cpu_s"),
        ("config", "tuning", "cpu_s"),
        ("data", "cache_hit"),
        ("plugins", "*", "distribution_version"),
    }
)
#: Overrides that do not say which job a record is (its identity's keys, the run-only
#: settings, Hydra's own).
NOT_VARIANT = {"system", "model", "seed", "profile", "track", "tuning"} | set(RUN_ONLY_KEYS)

Key = tuple[Any, ...]


def job_key(record: dict[str, Any]) -> Key:
    """Which job a record is: track, system, model, seed, tuner trial, and the overrides
    of other settings (sorted)."""
    variant = tuple(
        sorted(
            o.lstrip("+")
            for o in record.get("overrides") or []
            if o.lstrip("+~").split("=", 1)[0] not in NOT_VARIANT and not o.startswith("hydra")
        )
    )
    tuning = record.get("tuning") if isinstance(record.get("tuning"), dict) else {}
    return (
        record.get("track") or "protocol",
        record["system"],
        record["model"],
        record["seed"],
        tuning.get("trial"),
        variant,
    )


def describe(key: Key) -> str:
    track, system, model, seed, trial, variant = key
    tag = f"{system} x {model} seed={seed}"
    if track != "protocol":
        tag += f" track={track}"
    if trial is not None:
        tag += f" trial={trial}"
    return tag + (f" [{' '.join(variant)}]" if variant else "")


def _run_only(override: str) -> bool:
    return override.lstrip("+~").split("=", 1)[0] in RUN_ONLY_KEYS


def comparable(record: dict[str, Any]) -> dict[str, Any]:
    """``record`` with the run-only settings left out of its ``overrides`` and its
    ``rerun_command`` (its ``config``'s are left out by :func:`diff`)."""
    out = dict(record)
    if isinstance(out.get("overrides"), list):
        out["overrides"] = [o for o in out["overrides"] if not _run_only(str(o))]
    if isinstance(out.get("rerun_command"), str):
        out["rerun_command"] = shlex.join(
            t for t in shlex.split(out["rerun_command"]) if not _run_only(t)
        )
    return out


def load(directory: Path) -> tuple[dict[Key, tuple[dict[str, Any], Path]], list[str]]:
    """The records below ``directory`` by job, each as its raw JSON (strict JSON: no
    decoding, so values compare as written) with its directory, and a line for each
    file left out (unreadable, not a record, or a second record of one job)."""
    loaded = load_records(directory)
    problems = [str(item) for item in loaded.problems]
    out: dict[Key, tuple[dict[str, Any], Path]] = {}
    for rec in loaded.records:
        path = Path(rec["path"])
        raw = comparable(json.loads((path / "result.json").read_text("utf-8")))
        key = job_key(raw)
        if key in out:
            problems.append(
                f"{path}: a second record of {describe(key)} (the first: {out[key][1]})"
            )
            continue
        out[key] = (raw, path)
    return out, problems


def _ignored(path: tuple[str, ...]) -> bool:
    if len(path) == 1 and path[0] in IGNORED:
        return True
    if len(path) == 2 and path[0] == "config" and path[1] in RUN_ONLY_KEYS:
        return True
    return any(
        len(path) == len(pattern) and all(p in ("*", q) for p, q in zip(pattern, path, strict=True))
        for pattern in IGNORED_PATHS
    )


def _normal(value: Any, root: str) -> Any:
    """A string with the sweep's own directory written as ``<sweep>``."""
    return value.replace(root, "<sweep>") if isinstance(value, str) and root else value


def _number(value: Any) -> float:
    """A metric value as a float (``None``: NaN; ``"inf"``: inf)."""
    return math.nan if value is None else float(value)


def same_number(a: Any, b: Any, rtol: float) -> bool:
    if a == b:
        return True
    try:
        x, y = _number(a), _number(b)
    except (TypeError, ValueError):
        return False
    if math.isnan(x) and math.isnan(y):
        return True
    if rtol == 0 or not (math.isfinite(x) and math.isfinite(y)):
        return False
    return abs(x - y) <= rtol * max(abs(x), abs(y))


def diff(
    a: Any, b: Any, roots: tuple[str, str], rtol: float = 0.0, path: tuple[str, ...] = ()
) -> Iterator[str]:
    """Every difference between two JSON values, as ``field: before -> after`` lines
    (fields in :data:`IGNORED` and :data:`IGNORED_PATHS` left out)."""
    if _ignored(path):
        return
    name = ".".join(path) or "(record)"
    if isinstance(a, dict) and isinstance(b, dict):
        for key in sorted(set(a) | set(b), key=str):
            sub = (*path, str(key))
            if _ignored(sub):
                continue
            if key not in b:
                yield f"{'.'.join(sub)}: only before ({_short(a[key])})"
            elif key not in a:
                yield f"{'.'.join(sub)}: only after ({_short(b[key])})"
            else:
                yield from diff(a[key], b[key], roots, rtol, sub)
        return
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            yield f"{name}: {len(a)} -> {len(b)} items"
            return
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            yield from diff(x, y, roots, rtol, (*path, str(i)))
        return
    metric_value = len(path) == 3 and path[0] == "metrics" and path[2] in ("mean", "sem")
    if metric_value and same_number(a, b, rtol):
        return
    if _normal(a, roots[0]) != _normal(b, roots[1]) or type(a) is not type(b):
        yield f"{name}: {_short(a)} -> {_short(b)}"


def _short(value: Any, limit: int = 160) -> str:
    text = json.dumps(value, sort_keys=True)
    return text if len(text) <= limit else text[:limit] + "..."


def compare_arrays(a: Path, b: Path) -> list[str]:
    """Differences between two ``.npz`` files: arrays only on one side, or whose
    shape, dtype or any element differs (NaN equal to NaN)."""
    import numpy as np

    out = []
    with np.load(a, allow_pickle=False) as fa, np.load(b, allow_pickle=False) as fb:
        for name in sorted(set(fa.files) | set(fb.files)):
            if name not in fb.files or name not in fa.files:
                out.append(f"{a.name}:{name}: only {'before' if name in fa.files else 'after'}")
                continue
            x, y = fa[name], fb[name]
            if x.shape != y.shape or x.dtype != y.dtype:
                out.append(f"{a.name}:{name}: {x.dtype}{x.shape} -> {y.dtype}{y.shape}")
            elif not np.array_equal(x, y, equal_nan=x.dtype.kind in "fc"):
                bad = (
                    int(np.sum(~((x == y) | (np.isnan(x) & np.isnan(y)))))
                    if x.dtype.kind in "fc"
                    else int(np.sum(x != y))
                )
                out.append(f"{a.name}:{name}: {bad} of {x.size} elements differ")
    return out


def compare_files(
    ra: dict[str, Any], da: Path, rb: dict[str, Any], db: Path
) -> tuple[list[str], int]:
    """Differences between the files beside two records (the rollout arrays and the
    weights file), and how many files were compared."""
    out: list[str] = []
    n = 0
    for name, kind in (("rollout.npz", "arrays"), (ra.get("weights_file"), "bytes")):
        if not name:
            continue
        fa, fb = da / name, db / name
        if not fa.is_file() and not fb.is_file():
            continue
        if not (fa.is_file() and fb.is_file()):
            out.append(f"{name}: only {'before' if fa.is_file() else 'after'}")
            continue
        n += 1
        if kind == "arrays":
            out += compare_arrays(fa, fb)
        elif fa.read_bytes() != fb.read_bytes():
            out.append(
                f"{name}: the bytes differ ({fa.stat().st_size} -> {fb.stat().st_size} bytes)"
            )
    return out, n


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    parser.add_argument(
        "--rtol",
        type=float,
        default=0.0,
        help="relative tolerance of metric values (default 0: identical)",
    )
    parser.add_argument("--metrics", default="", help="comma-separated subset to compare")
    parser.add_argument(
        "--metrics-only", action="store_true", help="compare statuses and metric values only"
    )
    parser.add_argument(
        "--ignore",
        action="append",
        default=[],
        metavar="FIELD",
        help="a top-level field not to compare, e.g. command (repeatable)",
    )
    args = parser.parse_args(argv)
    IGNORED.update(args.ignore)
    (before, left_before), (after, left_after) = load(args.before), load(args.after)
    roots = (str(args.before.resolve()), str(args.after.resolve()))
    wanted = {m for m in args.metrics.split(",") if m}
    bad = 0
    for item in left_before + left_after:
        print(f"LEFT OUT {item}")
        bad += 1
    n_values = n_files = 0
    for key in sorted(set(before) | set(after), key=str):
        tag = describe(key)
        if key not in before or key not in after:
            print(f"MISSING  {tag}: only in {'after' if key in after else 'before'}")
            bad += 1
            continue
        (a, da), (b, db) = before[key], after[key]
        if args.metrics_only or wanted:
            fields = {"status": a.get("status")}, {"status": b.get("status")}
            ma, mb = a.get("metrics") or {}, b.get("metrics") or {}
            names = set(ma) | set(mb)
            names = names & wanted if wanted else names
            lines = list(
                diff(
                    {**fields[0], "metrics": {k: ma.get(k) for k in names}},
                    {**fields[1], "metrics": {k: mb.get(k) for k in names}},
                    roots,
                    args.rtol,
                )
            )
            n_values += len(names)
        else:
            lines = list(diff(a, b, roots, args.rtol))
            n_values += len(a.get("metrics") or {})
            files, n = compare_files(a, da, b, db)
            lines += files
            n_files += n
        for line in lines:
            print(f"DIFFERS  {tag}: {line}")
        bad += len(lines)
    matched = len(set(before) & set(after))
    verdict = "identical" if args.rtol == 0 else f"equal within rtol={args.rtol:g}"
    what = (
        f"{n_values} metric values compared"
        if args.metrics_only or wanted
        else f"records compared field by field ({n_values} metric values), "
        f"{n_files} files beside them"
    )
    print(
        f"{matched} jobs matched, {what}, {bad} difference(s)" + ("" if bad else f": all {verdict}")
    )
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
