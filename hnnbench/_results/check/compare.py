"""A leaderboard against the reference, row by row: metrics by their rules, statuses,
coverage and claims; ``same``: two-sided (docs/LEADERBOARD.md).
"""

from __future__ import annotations

import math
from typing import Any, Optional

import pandas as pd

from hnnbench import _registry as registry
from hnnbench._contracts import claims
from hnnbench._contracts.metric import CheckRule
from hnnbench._contracts.names import STATUSES
from hnnbench._results.check.findings import CheckError, CheckResult, Finding
from hnnbench._results.check.reference import model_text, row_key
from hnnbench._results.check.rules import load_rules

__all__ = ["compare"]


def format_number(x: float) -> str:
    if x is None or pd.isna(x):
        return "—"
    if math.isinf(x):
        return "inf"
    return f"{x:.3g}"


def _seeds(row: Any) -> Optional[frozenset[str]]:
    value = row.get("seeds")
    if value is None or pd.isna(value):
        return None
    return frozenset(s.strip() for s in str(value).split(";") if s.strip())


def _seed_text(seeds: Optional[frozenset[str]]) -> str:
    return "?" if seeds is None else "seeds " + ",".join(sorted(seeds, key=lambda s: (len(s), s)))


def _ok_share(row: Any) -> float:
    n = int(row["n_seeds"])
    return int(row["n_ok"]) / n if n else 0.0


def _status_text(row: Any) -> str:
    parts = [f"{int(row[f'n_{s}'])} {s}" for s in STATUSES if int(row.get(f"n_{s}", 0))]
    return ", ".join(parts) or "no runs"


def _claims_by_key(board: pd.DataFrame) -> dict[tuple[str, str, str], claims.ClaimResult]:
    from hnnbench._results.report.published import board_lookup, board_untrained

    out = {}
    every_claim = registry.all_claims()
    for profile in dict.fromkeys(board["profile"].astype(str)):
        for res in claims.evaluate_claims(
            board_lookup(board, profile),
            every_claim,
            registry.family_models(),
            board_untrained(board, profile),
        ):
            out[(profile, res.claim.id, res.backend)] = res
    return out


def compare(
    reference: pd.DataFrame,
    current: pd.DataFrame,
    rules: Optional[tuple[CheckRule, dict[str, CheckRule]]] = None,
    allow_missing: bool = False,
    same: Optional[float] = None,
) -> CheckResult:
    """Compare two leaderboards; see the module docstring (``same``: ``--same RTOL``)."""
    default, by_metric = rules if rules is not None else load_rules()
    result = CheckResult()
    ref = reference.copy()
    cur = current.copy()
    ref_keys = {row_key(r): r for _, r in ref.iterrows()}
    cur_keys = {row_key(r): r for _, r in cur.iterrows()}
    if ref_keys and cur_keys and not set(ref_keys) & set(cur_keys):
        ref_prof = sorted({k[0] for k in ref_keys})
        cur_prof = sorted({k[0] for k in cur_keys})
        if ref_prof != cur_prof:
            raise CheckError(
                f"The reference is for profile {', '.join(ref_prof)} but the sweep "
                f"ran profile {', '.join(cur_prof)}; compare like with like"
            )
    metrics = [c[: -len("_mean")] for c in ref.columns if c.endswith("_mean")]

    for key, r in ref_keys.items():
        system, model = key[1], model_text(key[2], key[3], key[4])
        c = cur_keys.get(key)
        if c is None:
            finding = Finding("missing", "-", system, model, _status_text(r), "no runs")
            (result.info if allow_missing else result.regressions).append(finding)
            continue
        result.n_pairs += 1
        ref_seeds, cur_seeds = _seeds(r), _seeds(c)
        if ref_seeds != cur_seeds:
            result.info.append(
                Finding(
                    "seeds",
                    "-",
                    system,
                    model,
                    _seed_text(ref_seeds),
                    _seed_text(cur_seeds),
                    "",
                    "same seeds expected",
                )
            )
        changed = same is not None and (int(c["n_ok"]), int(c["n_seeds"])) != (
            int(r["n_ok"]),
            int(r["n_seeds"]),
        )
        if changed or _ok_share(c) < _ok_share(r):
            result.regressions.append(
                Finding(
                    "status",
                    "status",
                    system,
                    model,
                    _status_text(r),
                    _status_text(c),
                    f"ok {int(c['n_ok'])}/{int(c['n_seeds'])}",
                    f"ok >= {int(r['n_ok'])}/{int(r['n_seeds'])}",
                )
            )
        for metric in metrics:
            rule = by_metric.get(metric, default)
            ref_value = float(r[f"{metric}_mean"])
            if math.isnan(ref_value):
                continue  # not applicable, or no result in the reference
            cur_value = c.get(f"{metric}_mean", math.nan)
            cur_value = math.nan if cur_value is None or pd.isna(cur_value) else float(cur_value)
            result.n_metrics += rule.gate
            if rule.gate:
                result.gated.append((system, model, metric))
            if math.isnan(cur_value):
                finding = Finding(
                    "metric",
                    metric,
                    system,
                    model,
                    format_number(ref_value),
                    "no value",
                    "",
                    rule.limit_text(),
                )
                (result.regressions if rule.gate else result.info).append(finding)
                continue
            if same is not None:
                if not rule.gate:
                    continue
                diff = rule.difference(ref_value, cur_value)
                if diff > same:
                    result.regressions.append(
                        Finding(
                            "changed",
                            metric,
                            system,
                            model,
                            format_number(ref_value),
                            format_number(cur_value),
                            f"{format_number(diff)} rel",
                            f"within {same:g} rel",
                        )
                    )
                continue
            factor = rule.worsening(ref_value, cur_value)
            if factor > rule.factor:
                finding = Finding(
                    "metric" if rule.gate else "info",
                    metric,
                    system,
                    model,
                    format_number(ref_value),
                    format_number(cur_value),
                    "inf worse" if math.isinf(factor) else f"{format_number(factor)}x worse",
                    rule.limit_text(),
                )
                (result.regressions if rule.gate else result.info).append(finding)
    for key, c in cur_keys.items():
        if key not in ref_keys:
            result.info.append(
                Finding(
                    "new",
                    "-",
                    key[1],
                    model_text(key[2], key[3], key[4]),
                    "not in reference",
                    _status_text(c),
                )
            )

    ref_claims, cur_claims = _claims_by_key(ref), _claims_by_key(cur)
    for (profile, claim_id, backend), rc in ref_claims.items():
        cc = cur_claims.get((profile, claim_id, backend))
        claim = rc.claim
        pair = f"{backend} pair" if backend != "-" else "-"
        now = cc.outcome if cc is not None else claims.NOT_RUN
        finding = Finding(
            "claim",
            claim.metric,
            claim.system,
            pair,
            f"{rc.outcome} ({claims.fmt_ratio(rc.ratio)})",
            f"{now} ({claims.fmt_ratio(cc.ratio) if cc is not None else 'n/a'})",
            "",
            claim.requirement(),
        )
        if rc.outcome == claims.REPRODUCED:
            result.n_claims += 1
            if now == claims.NOT_RUN and allow_missing:
                result.info.append(finding)
            elif now != claims.REPRODUCED:
                result.regressions.append(finding)
        elif not (rc.outcome == claims.NOT_RUN and now == claims.NOT_RUN):
            result.info.append(finding)
    return result
