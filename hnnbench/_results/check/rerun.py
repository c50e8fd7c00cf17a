"""``--rerun SYSTEM/MODEL/SEED``: a recorded job run again from its config in a fresh
cache and compared with its record, metric by metric, both ways.
"""

from __future__ import annotations

import math
import platform
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hnnbench._contracts.errors import HnnbenchError
from hnnbench._contracts.metric import CheckRule
from hnnbench._record.tracks import track_of
from hnnbench._results import provenance
from hnnbench._results.check.compare import format_number
from hnnbench._results.check.findings import CheckError, Finding
from hnnbench._results.check.records import record_file
from hnnbench._running.config import RUN_ONLY_KEYS
from hnnbench._running.data_hashes import DATA_HASHES, KNOWN_CPUS, X86_64, CpuDispatch, hashes_on

__all__ = ["DATA_HASHES", "RERUN_HEADERS", "Rerun", "addressed", "rerun", "rerun_config"]

RERUN_HEADERS = ["metric", "record", "re-run", "apart", "allowed", ""]


@dataclass
class Rerun:
    """One ``--rerun``: its findings (regressions) and its table, record against
    re-run per metric and data hash."""

    spec: str
    findings: list[Finding] = field(default_factory=list)
    rows: list[list[str]] = field(default_factory=list)


def rerun_config(rec: dict[str, Any], cache_dir: Path) -> dict[str, Any]:
    """The config a ``--rerun`` of ``rec`` runs: the record's stored config, with every
    run-only setting (:data:`hnnbench._running.config.RUN_ONLY_KEYS`: cache and data
    directories, device, threads, pinning, saving, batching) taken from the defaults of
    its (system, model, profile) instead of the record, a fresh ``cache_dir``, and no
    weights written. Nothing the record names decides where the re-run reads or writes."""
    config = rec.get("config")
    spec = f"{rec.get('system')}/{rec.get('model')}/{rec.get('seed')}"
    if not isinstance(config, dict) or not isinstance(config.get("system"), dict):
        raise CheckError(f"--rerun {spec}: the record holds no resolved config to run again")
    try:
        defaults = provenance.default_config(
            str(rec.get("system")),
            str(rec.get("model")),
            str(rec.get("profile") or "paper"),
            track_of(rec),
        )
    except HnnbenchError as err:
        raise CheckError(f"--rerun {spec}: cannot compose its defaults: {err}") from None
    out = {k: v for k, v in config.items() if k not in RUN_ONLY_KEYS}
    out.update({k: defaults[k] for k in RUN_ONLY_KEYS if k in defaults})
    out.update(rerun=True, save_model=False, cache_dir=str(cache_dir))
    return out


def _address(rec: dict[str, Any]) -> str:
    return f"{rec.get('system')}/{rec.get('model')}/{track_of(rec)}/{rec.get('seed')}"


def addressed(recs: Sequence[dict[str, Any]], spec: str) -> dict[str, Any]:
    """The one record ``spec`` names: ``SYSTEM/MODEL/SEED``, ``SYSTEM/MODEL/TRACK/SEED``,
    or the record's directory (or its ``result.json``). No record, or several (other
    tracks, profiles, variants or directories), is a :class:`CheckError` listing the
    candidates: a re-run runs exactly what was named."""
    as_path = Path(spec)
    by_path = [
        r
        for r in recs
        if r.get("path") and as_path in (Path(r["path"]), Path(r["path"]) / "result.json")
    ]
    if by_path:
        return by_path[0]
    parts = spec.split("/")
    if len(parts) not in (3, 4) or not parts[-1].isdigit():
        raise CheckError(
            f"--rerun {spec}: expected SYSTEM/MODEL/SEED, SYSTEM/MODEL/TRACK/SEED or a "
            "record's directory, e.g. spring/hnn_jax/0"
        )
    system, model, seed = parts[0], parts[1], int(parts[-1])
    track = parts[2] if len(parts) == 4 else None
    match = [
        r
        for r in recs
        if r.get("system") == system
        and r.get("model") == model
        and r.get("seed") == seed
        and (track is None or track_of(r) == track)
    ]
    if not match:
        raise CheckError(f"--rerun {spec}: no record of that job in the checked directories")
    if len(match) > 1:
        shown = "; ".join(
            f"{_address(r)} (profile {r.get('profile')}, {record_file(r)})" for r in match[:6]
        )
        raise CheckError(
            f"--rerun {spec}: {len(match)} records match ({shown}"
            + (f"; and {len(match) - 6} more" if len(match) > 6 else "")
            + "): name one by SYSTEM/MODEL/TRACK/SEED or by its directory"
        )
    return match[0]


def _short(value: Any) -> str:
    return str(value)[:12] if value else "none"


def _dispatches_to_try(rec: dict[str, Any], here: CpuDispatch) -> list[CpuDispatch]:
    """The CPU dispatches under which to make the record's data again when this CPU's
    give other bytes: the one the record names, else (a record made before the fields)
    :data:`~hnnbench._running.data_hashes.KNOWN_CPUS` on an x86-64 machine; never this
    CPU's own."""
    named = CpuDispatch.of_record(rec.get("environment"))
    if named is not None:
        candidates: Sequence[CpuDispatch] = [named]
    else:
        candidates = KNOWN_CPUS if platform.machine() in X86_64 else []
    return [d for d in candidates if d != here]


#: The most seconds of wall time the re-made data of one ``--rerun`` may take, all
#: dispatches together.
REMAKE_BUDGET_S = 1800.0


def _data_as_its_cpu_made_them(
    rec: dict[str, Any], config: dict[str, Any], canonical: dict[str, Any]
) -> tuple[dict[str, str] | None, list[str]]:
    """Where this CPU's data differ from the record's by hash: the record's data made
    again as the CPUs of :func:`_dispatches_to_try` make them, until one gives exactly
    the record's hashes. Returns that answer (the hashes and the dispatch that made
    them) or ``None``, and a line per dispatch tried in vain."""
    mine = rec.get("data") or {}
    if rec.get("status") == "skipped" or all(mine.get(k) == canonical.get(k) for k in DATA_HASHES):
        return None, []
    tried: list[str] = []
    deadline = time.monotonic() + REMAKE_BUDGET_S
    for target in _dispatches_to_try(rec, CpuDispatch.here()):
        left = deadline - time.monotonic()
        if left <= 0:
            tried.append(f"{target.describe()}: not tried ({REMAKE_BUDGET_S:g} s spent)")
            continue
        answer = hashes_on(config, target, timeout_s=left)
        if isinstance(answer, str):
            tried.append(answer)
        elif all(answer[k] == mine.get(k) for k in DATA_HASHES):
            return answer, tried
        else:
            tried.append(f"{target.describe()}: {_short(answer['dataset_sha256'])}")
    return None, tried


def rerun(
    recs: Sequence[dict[str, Any]], spec: str, rules: tuple[CheckRule, dict[str, CheckRule]]
) -> Rerun:
    """Run the job ``spec`` names (:func:`addressed`: exactly one record) again
    (:func:`rerun_config`, in a fresh process pinned to one core where the record's job
    was, in a temporary directory with a fresh dataset cache) and
    compare: its status, its data hashes (the re-run's, generated now by the installed
    system, are the canonical ones), and each metric either side has with the record's
    by ``rules``, in both directions."""
    import tempfile

    from hnnbench._running.fresh_job import run_fresh

    rec = addressed(recs, spec)
    system, model = str(rec.get("system")), str(rec.get("model"))
    result = Rerun(spec)
    with tempfile.TemporaryDirectory(prefix="hnnbench-rerun-") as tmp:
        config = rerun_config(rec, Path(tmp) / "cache")
        # pinned to one core before JAX starts where the record was (the command's
        # jobs are), in a fresh process: XLA's thread pool, and so the last bits, as
        # the record's (_running/fresh_job.py)
        config["pin_cpu"] = rec.get("cpu_pin") is not None
        made = run_fresh(config, Path(tmp) / "job", overrides=rec.get("overrides"))
        again: dict[str, Any] = (
            made if isinstance(made, dict) else {"status": "failed", "error": made}
        )
    here = again.get("data") or {}
    forced, tried = _data_as_its_cpu_made_them(rec, config, here)
    default, by_metric = rules
    where = record_file(rec)

    def add(name: str, ref: str, cur: str, apart: str, allowed: str, ok: bool) -> None:
        result.rows.append([name, ref, cur, apart, allowed, "ok" if ok else "FAILS"])
        if not ok:
            result.findings.append(Finding("rerun", name, system, model, ref, cur, apart, allowed))

    add(
        "status",
        str(rec.get("status")),
        str(again.get("status")),
        "",
        "same status",
        again.get("status") == rec.get("status"),
    )
    if again.get("status") == "failed" and again.get("error"):
        result.rows.append(["error", "", str(again["error"]), "", "", ""])
    for key in DATA_HASHES:
        mine = (rec.get("data") or {}).get(key)
        canonical = (forced or here).get(key)
        if mine is None and canonical is None and rec.get("status") == "skipped":
            continue
        add(
            f"data.{key}",
            _short(mine),
            _short(canonical),
            "",
            "the installed system's data",
            bool(canonical) and mine == canonical,
        )
        if canonical and mine != canonical:
            also = f"; made as other CPUs make them: {'; '.join(tried)}" if tried else ""
            result.findings[
                -1
            ].current = f"canonical {_short(canonical)} ({where} names other data{also})"
    if forced is not None:
        named = CpuDispatch.of_record(rec.get("environment"))
        result.rows.append(
            [
                "cpu_dispatch",
                named.describe() if named else "not recorded",
                f"{forced['dispatch']} (forced)",
                "",
                (
                    f"this CPU's ({CpuDispatch.here().describe()}) makes "
                    f"{_short(here.get('dataset_sha256'))}: other last bits"
                    if here.get("dataset_sha256")
                    else "the re-run here made no data"
                ),
                "ok",
            ]
        )
    mine_all, theirs_all = rec.get("metrics") or {}, again.get("metrics") or {}
    # Every metric either side has: one the re-run produces and the record lacks fails.
    for name in dict.fromkeys([*mine_all, *theirs_all]):
        rule = by_metric.get(name, default)
        ref = _mean(mine_all.get(name))
        cur = _mean(theirs_all.get(name))
        if math.isnan(ref) and math.isnan(cur):
            continue
        # A re-run must agree with the record both ways, not merely be no worse.
        worst = max(rule.worsening(ref, cur), rule.worsening(cur, ref))
        ok = not (math.isnan(cur) or math.isnan(ref)) and worst <= rule.factor
        add(
            name,
            format_number(ref) if name in mine_all else "absent",
            format_number(cur),
            f"{format_number(worst)}x",
            f"within {rule.factor:g}x",
            ok,
        )
    return result


def _mean(value: Any) -> float:
    """A metric's mean as a float (NaN: absent, ``null`` or not a number)."""
    mean = value.get("mean", math.nan) if isinstance(value, dict) else math.nan
    if isinstance(mean, bool) or not isinstance(mean, (int, float)):
        return math.nan
    return float(mean)
