"""Published results and claims next to ours: every registered claim set
(:mod:`hnnbench._contracts.claims`), its published values cell by cell, and its claims evaluated
per backend."""

from __future__ import annotations

import math
from typing import Any, Optional

import pandas as pd

from hnnbench import _registry as registry
from hnnbench._contracts import claims
from hnnbench._contracts.names import DEFAULT_TRACK
from hnnbench._results.leaderboard import format_value, text_column
from hnnbench._results.report.markdown import md_code, md_text
from hnnbench._results.report.tables import md_table, seed_line

__all__ = [
    "board_lookup",
    "claim_results",
    "claims_frame",
    "comparison_frame",
    "comparison_markdown",
    "main_profile",
    "ours_cell",
    "paper_claim_ratios",
    "paper_table",
    "plain_rows",
]


def plain_rows(board: pd.DataFrame) -> pd.DataFrame:
    """The rows without a variant, of the protocol track: comparisons with published
    results use those only (a variant row is a setting the sweep varied away from the
    others; the tuned and recipe tracks are other budgets)."""
    board = board[text_column(board, "track", DEFAULT_TRACK) == DEFAULT_TRACK]
    return board[text_column(board, "variant") == ""]


def main_profile(board: pd.DataFrame) -> Optional[str]:
    """The profile the comparison with published results reads: ``paper`` where the
    protocol track has rows of it, else the first profile of the protocol's rows."""
    board = plain_rows(board) if not board.empty else board
    profiles = list(dict.fromkeys(str(p) for p in board["profile"])) if not board.empty else []
    if not profiles:
        return None
    return "paper" if "paper" in profiles else profiles[0]


def board_lookup(board: pd.DataFrame, profile: Optional[str] = None) -> claims.Lookup:
    """A :data:`hnnbench._contracts.claims.Lookup` on a leaderboard (one profile), over the rows
    without a variant."""
    if profile is not None and "profile" in board:
        board = board[board["profile"].astype(str) == str(profile)]
    index = {(r["system"], r["model"]): r for _, r in plain_rows(board).iterrows()}

    def lookup(system: str, model: str, metric: str) -> Optional[float]:
        row = index.get((system, model))
        if row is None:
            return None
        value = row.get(f"{metric}_mean", math.nan)
        return math.nan if value is None or pd.isna(value) else float(value)

    return lookup


def board_untrained(board: pd.DataFrame, profile: Optional[str] = None) -> claims.Untrained:
    """A :data:`hnnbench._contracts.claims.Untrained` on a leaderboard: a pair "did not train" when
    more than half of its seeds kept their first evaluation's weights
    (``n_untrained``, from the records' ``selection.trained``)."""
    if profile is not None and "profile" in board:
        board = board[board["profile"].astype(str) == str(profile)]
    index = {(r["system"], r["model"]): r for _, r in plain_rows(board).iterrows()}

    def untrained(system: str, model: str) -> Optional[str]:
        row = index.get((system, model))
        if row is None or "n_untrained" not in row:
            return None
        bad, seeds = int(row.get("n_untrained") or 0), int(row.get("n_seeds") or 0)
        if seeds and 2 * bad > seeds:
            return (
                f"{model} did not train on {bad} of {seeds} seeds (its best validation "
                "loss was its first evaluation): not tested"
            )
        return None

    return untrained


def claim_results(board: pd.DataFrame, profile: Optional[str] = None) -> list[claims.ClaimResult]:
    """Every registered claim evaluated on a leaderboard, per backend."""
    profile = profile if profile is not None else main_profile(board)
    return claims.evaluate_claims(
        board_lookup(board, profile),
        registry.all_claims(),
        registry.family_models(),
        board_untrained(board, profile),
    )


def paper_claim_ratios() -> dict[str, claims.ClaimResult]:
    """Each claim of a set with published values, evaluated on those values."""
    out = {}
    for claim_set in registry.claim_sets():
        for res in claims.published_results(claim_set):
            out[res.claim.id] = res
    return out


def paper_table(name: str) -> pd.DataFrame:
    """The published values of claim set ``name`` (natural units), one row per value,
    with its role (``model``: the paper's name for it) and family."""
    for claim_set in registry.claim_sets():
        if claim_set.name == name:
            return pd.DataFrame(
                [
                    {
                        "system": p.system,
                        "task": p.task,
                        "model": p.role,
                        "family": p.family,
                        "metric": p.metric,
                        "value": p.value,
                        "pm": p.pm,
                        "printed_value": p.printed_value,
                        "printed_pm": p.printed_pm,
                        "printed_scale": p.printed_scale,
                        "source": p.source,
                    }
                    for p in claim_set.published
                ]
            )
    raise KeyError(f"no claim set '{name}' is registered")


def _pow10(scale: str) -> str:
    exp = int(round(math.log10(float(scale))))
    sup = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")
    return f"10{str(exp).translate(sup)}"


def _published_cell(p: claims.Published) -> str:
    value = f"{p.value:.2e}"
    return value if math.isnan(p.pm) else f"{value} ± {p.pm:.1e}"


def ours_cell(
    board: pd.DataFrame, profile: Optional[str], system: str, model: Optional[str], metric: str
) -> str:
    if model is None:
        return "—"
    sel = plain_rows(board)
    sel = sel[(sel["system"] == system) & (sel["model"] == model)]
    if profile is not None:
        sel = sel[sel["profile"].astype(str) == profile]
    if sel.empty or f"{metric}_mean" not in sel:
        return "—"
    row = sel.iloc[0]
    return format_value(row[f"{metric}_mean"], row[f"{metric}_std"])


def comparison_frame(
    board: pd.DataFrame, claim_set: Optional[claims.ClaimSet] = None
) -> pd.DataFrame:
    """Every published cell of ``claim_set`` (default: the first set that has some)
    next to ours, per backend that has a model of the cell's family."""
    if claim_set is None:
        claim_set = next((cs for cs in registry.claim_sets() if cs.published), None)
    if claim_set is None:
        return pd.DataFrame()
    profile = main_profile(board)
    pairs = registry.family_models()
    backends = [
        b for b, models in pairs.items() if board["model"].isin(list(models.values())).any()
    ]
    roles = list(dict.fromkeys(p.role for p in claim_set.published))
    family_of = {p.role: p.family for p in claim_set.published}
    systems = registry.ordered("system", [p.system for p in claim_set.published])
    rows = []
    for system in systems:
        for metric in dict.fromkeys(p.metric for p in claim_set.published if p.system == system):
            cells = {
                p.role: p for p in claim_set.published if p.system == system and p.metric == metric
            }
            first = next(iter(cells.values()))
            row: dict[str, Any] = {"task": f"{first.task} ({system})", "metric": metric}
            for role in roles:
                row[f"paper {role}"] = _published_cell(cells[role]) if role in cells else "—"
            printed = " / ".join(cells[r].printed_value for r in roles if r in cells)
            scale = first.printed_scale
            row["paper printed"] = printed + ("" if scale in ("1", "1.0") else f" ×{_pow10(scale)}")
            for backend in backends:
                for role in roles:
                    model = pairs[backend].get(family_of[role])
                    row[f"ours {role} ({backend})"] = ours_cell(
                        board, profile, system, model, metric
                    )
            row["source"] = first.source.split(" (")[0]
            row["ours differs"] = claim_set.definition(system, metric) or "—"
            rows.append(row)
    return pd.DataFrame(rows)


def claims_frame(board: pd.DataFrame) -> pd.DataFrame:
    results = claim_results(board)
    published = paper_claim_ratios()
    rows = []
    for res in results:
        p = published.get(res.claim.id)
        rows.append(
            {
                "claim": res.claim.text,
                "backend": res.backend,
                "result": res.outcome,
                "our numbers": res.numbers(),
                "published": f"{claims.fmt_ratio(p.ratio)}" if p else "—",
                "source": res.claim.source.split(" (")[0],
            }
        )
    return pd.DataFrame(rows)


def comparison_markdown(board: pd.DataFrame) -> str:
    profile = main_profile(board)
    rows = plain_rows(board)
    rows = rows[rows["profile"].astype(str) == str(profile)] if profile is not None else rows
    lines = ["# Comparison with published results", ""]
    if rows.empty:
        lines += [
            "No protocol-track rows: the comparison with published results reads the "
            "protocol track only (the tuned and recipe tracks are other budgets).",
            "",
        ]
    else:
        lines += [seed_line(rows), ""]
    if profile is not None and profile != "paper":
        lines += [
            f"Note: profile {md_code(profile)} is not the paper settings (profile `paper`); "
            "this comparison is indicative only.",
            "",
        ]
    for claim_set in registry.claim_sets():
        if not claim_set.published:
            continue
        lines += [
            f"## {md_text(claim_set.title)}",
            "",
            md_text(claim_set.note),
            "",
            md_table(comparison_frame(board, claim_set)),
            "",
        ]
    claims = claims_frame(board)
    counts = claims["result"].value_counts().to_dict() if not claims.empty else {}
    lines += [
        "## Qualitative claims",
        "",
        "Declared by the claim sets of the `hnnbench.claims` entry points; evaluated per "
        "backend on the means above. Column *published* is the same ratio on the "
        "published numbers, where a source published them.",
        "",
        *(
            f"{md_text(claim_set.title)}: {md_text(claim_set.note)}\n"
            for claim_set in registry.claim_sets()
            if claim_set.note and not claim_set.published
        ),
        md_table(claims),
        "",
        ", ".join(f"{n} {k}" for k, n in sorted(counts.items())) + ".",
        "",
    ]
    return "\n".join(lines)
