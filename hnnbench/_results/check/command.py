"""``hnnbench check DIR [DIR ...] --reference CSV``: the command: validate the records,
compare their leaderboard with the reference (or ``--update`` it), print what it found
(docs/LEADERBOARD.md, "3. Validate").
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from hnnbench import _record as records
from hnnbench._contracts import claims
from hnnbench._contracts.errors import OneLineArgumentParser
from hnnbench._contracts.text import csv_text
from hnnbench._results.check.compare import compare
from hnnbench._results.check.findings import (
    HEADERS,
    CheckError,
    CheckResult,
    Finding,
    missing_line,
    published_reference,
    update_hint,
)
from hnnbench._results.check.output import FORMATS, CheckReport, emit
from hnnbench._results.check.ranks import ranking
from hnnbench._results.check.records import findings, record_variants
from hnnbench._results.check.reference import read_reference, row_key
from hnnbench._results.check.rerun import RERUN_HEADERS, Rerun, rerun
from hnnbench._results.check.rules import load_rules
from hnnbench._results.leaderboard import leaderboard_frame, records_frame
from hnnbench._results.validity import ALLOW_UNVERIFIED, Validation, validate

__all__ = ["main"]


class _Parser(OneLineArgumentParser):
    error_type = CheckError


def _parser() -> _Parser:
    p = _Parser(
        prog="hnnbench check",
        description="Validate run records and compare their leaderboard with a "
        "reference leaderboard.csv; exit 1 on a regression.",
    )
    p.add_argument(
        "dirs", metavar="DIR", nargs="+", help="sweep or record directories (their records merge)"
    )
    p.add_argument(
        "--reference",
        metavar="CSV",
        required=True,
        help="reference leaderboard.csv (e.g. results/reference/quick.csv)",
    )
    p.add_argument(
        "--update", action="store_true", help="rewrite the reference from DIR instead of checking"
    )
    p.add_argument(
        "--rules",
        metavar="FILE",
        default=None,
        help="YAML tolerances overriding the metrics' declared rules",
    )
    p.add_argument(
        "--allow-missing",
        action="store_true",
        help="a reference pair with no run in DIR is information, not a "
        "regression (for a sweep of only some systems or models)",
    )
    p.add_argument(
        "--rerun",
        metavar="SYSTEM/MODEL/SEED",
        action="append",
        default=[],
        help="run this job again from its record and compare (repeatable)",
    )
    p.add_argument(
        "--same",
        metavar="RTOL",
        type=float,
        default=None,
        help="two-sided: every gated metric within RTOL relative of the "
        "reference and the same statuses (a reproduction check)",
    )
    p.add_argument(
        "--format",
        choices=FORMATS,
        default="text",
        help="text (default), json, junit (JUnit XML) or markdown (docs/CI.md)",
    )
    p.add_argument(
        "--output",
        metavar="FILE",
        default=None,
        help="write the --format report to FILE (the text still goes to stdout)",
    )
    p.add_argument(
        ALLOW_UNVERIFIED,
        action="store_true",
        help="records whose plugins cannot be verified here (not installed, unusable, "
        "no 'plugins' field) are information, not failures (the output says so)",
    )
    p.add_argument(
        "--overwrite-published",
        action="store_true",
        help="with --update: allow rewriting a published leaderboard.csv (one next to "
        "a records/ directory), which publishing rebuilds",
    )
    return p


def main(args: Sequence[str]) -> int:
    """Run ``hnnbench check``; 0 when nothing regressed (or the reference was written),
    1 on a regression. Bad input raises :class:`CheckError` (one line)."""
    from hnnbench._results.report.inputs import load_sweeps

    ns = _parser().parse_args(list(args))
    recs, bad = load_sweeps([Path(d) for d in ns.dirs], strict=True, refuse=False)
    rules = load_rules(ns.rules)
    reference = Path(ns.reference)
    ref_board = None if ns.update else read_reference(reference)
    if ns.same is not None and not ns.same >= 0:
        raise CheckError(f"--same {ns.same}: expected a relative tolerance >= 0, e.g. 1e-3")
    # Each record's variant is derived from its stored config, never read from its
    # overrides (hnnbench._results.provenance).
    variants = record_variants(recs)
    checked = validate(recs, bad, variants=variants, allow_unverified=ns.allow_unverified)
    frame = records_frame(recs, [v.label for v in variants])
    board = leaderboard_frame(frame)
    where = " ".join(ns.dirs)
    if ns.update:
        if ns.format != "text" or ns.output:
            raise CheckError("--format and --output report a check; --update writes a reference")
        return _update(reference, board, checked, where, ns.overwrite_published)
    assert ref_board is not None
    result = compare(ref_board, board, rules, allow_missing=ns.allow_missing, same=ns.same)
    result.regressions[:0] = findings(checked.problems)
    result.info += findings(checked.information)
    reruns = [rerun(recs, spec, rules) for spec in ns.rerun]
    for done in reruns:
        result.regressions += done.findings
    ranks = ranking(ref_board, board, frame=frame)
    text = io.StringIO()
    with contextlib.redirect_stdout(text) if ns.format != "text" or ns.output else _as_is():
        status = _print_text(ns, recs, bad, checked, result, reruns, ranks.lines, reference)
    report = CheckReport(
        ns.dirs,
        str(reference),
        ns.rules,
        ns.same,
        ns.allow_missing,
        len(recs) + len(bad),
        len(ns.rerun),
        result,
        reruns,
        ranks,
        status,
    )
    emit(report, ns.format, ns.output, text.getvalue())
    return status


@contextlib.contextmanager
def _as_is() -> Any:
    yield


def _print_text(
    ns: Any,
    recs: Sequence[dict[str, Any]],
    bad: Sequence[records.Unreadable],
    checked: Validation,
    result: CheckResult,
    reruns: Sequence[Rerun],
    ranks: Sequence[str],
    reference: Path,
) -> int:
    """The text report (today's output); the exit status."""
    where = " ".join(ns.dirs)
    print(
        f"hnnbench check: {where} vs {reference}"
        + (
            f" (two-sided, within {ns.same:g} relative)"
            if ns.same is not None
            else f" (rules: declared + {ns.rules})"
            if ns.rules
            else " (rules: declared)"
        )
    )
    print(
        f"validated {len(recs) + len(bad)} record(s); compared {result.n_pairs} pair(s), "
        f"{result.n_metrics} gated metric value(s), {result.n_claims} claim(s) reproduced "
        f"in the reference" + (f"; re-ran {len(ns.rerun)} job(s)" if ns.rerun else "")
    )
    if checked.unverified and ns.allow_unverified:
        print(
            f"UNVERIFIED ({ALLOW_UNVERIFIED}): {len(checked.unverified)} record plugin(s) "
            f"could not be verified and were accepted, e.g. {checked.unverified[0].line()}"
        )
    _print_reruns(reruns)
    _print_ranks(ranks)
    _print_information(result, failing=not ns.allow_missing)
    return _print_verdict(result, reference)


def _update(
    reference: Path, board: pd.DataFrame, checked: Validation, where: str, overwrite: bool
) -> int:
    """``--update``: write the reference from the checked records, only when every one
    passed the strict validation, saying how many pairs of the old reference it drops;
    a published leaderboard.csv is rewritten only with ``--overwrite-published``."""
    if checked.problems:
        first, more = checked.problems[0], len(checked.problems) - 1
        raise CheckError(
            f"not writing a reference from records that fail validation: {first.line()}"
            + (f" (and {more} more)" if more else "")
            + "; fix or remove them (hnnbench check without --update lists each)"
        )
    if reference.is_dir():
        raise CheckError(f"Reference {reference} is a directory; give a CSV file path")
    if published_reference(reference) and reference.exists() and not overwrite:
        raise CheckError(
            f"{reference} is a published leaderboard (next to records/): publishing "
            "rebuilds it (scripts/maintainer/publish_results.py); write the reference "
            "elsewhere, or pass --overwrite-published"
        )
    dropped = 0
    if reference.is_file():
        try:
            old = read_reference(reference)
            have = {row_key(r) for _, r in board.iterrows()}
            dropped = sum(row_key(r) not in have for _, r in old.iterrows())
        except CheckError:
            dropped = 0
    try:
        records.atomic_write_text(reference, csv_text(board))
    except OSError as err:
        raise CheckError(f"Cannot write reference {reference}: {err.strerror}") from None
    print(
        f"hnnbench check: wrote reference {reference} from {where} "
        f"({len(board)} system x model pairs)"
        + (f"; {dropped} pair(s) of the old reference are not in it" if dropped else "")
    )
    return 0


def _table(rows: list[list[Any]], headers: list[str]) -> str:
    from tabulate import tabulate

    return str(tabulate(rows, headers=headers, tablefmt="simple", disable_numparse=True))


def _print_reruns(reruns: Sequence[Rerun]) -> None:
    for done in reruns:
        print()
        print(
            f"--rerun {done.spec} (fresh cache; the record's run-only settings ignored): "
            "record vs re-run"
        )
        print(_table(done.rows, RERUN_HEADERS))


def _print_ranks(ranks: Sequence[str]) -> None:
    if ranks:
        print()
        print(
            "ranks of the families new to the reference (headline metrics; 95% intervals "
            "over seeds; among the reference's families unless said):"
        )
        for line in ranks:
            print(f"  {line}")


def _print_information(result: CheckResult, failing: bool) -> None:
    """What is information, not failing: new pairs, missing pairs and unevaluated claims
    (failing unless ``--allow-missing``), and every other finding of that kind."""
    missing = [f for f in result.info + result.regressions if f.check == "missing"]
    unrun = [f for f in result.info if f.check == "claim" and f.current.startswith(claims.NOT_RUN)]
    new = [f for f in result.info if f.check == "new"]
    shown: list[Finding] = [
        f for f in result.info if f not in missing and f not in unrun and f not in new
    ]
    if missing or unrun or new:
        print()
    if new:
        models = list(dict.fromkeys(f.model for f in new))
        print(
            f"new: {len(new)} pair(s) not in the reference ({', '.join(models[:4])}"
            + (f" and {len(models) - 4} more" if len(models) > 4 else "")
            + ")"
        )
    if missing or unrun:
        print(missing_line(missing, unrun, failing=failing))
    if shown:
        print()
        print("information (not failing):")
        print(_table([f.row() for f in shown], HEADERS))


def _print_verdict(result: CheckResult, reference: Path) -> int:
    """The regressions, with what to do about them, or OK; the exit status."""
    if not result.regressions:
        print()
        print("hnnbench check: OK, no regressions")
        return 0
    listed = [f for f in result.regressions if f.check != "missing"]
    print()
    print(
        f"REGRESSIONS ({len(result.regressions)}"
        + (
            f", {len(result.regressions) - len(listed)} of them missing pairs, above"
            if len(listed) < len(result.regressions)
            else ""
        )
        + "):"
    )
    if listed:
        print(_table([f.row() for f in listed], HEADERS))
    print()
    print(
        f"hnnbench check: FAILED, {len(result.regressions)} regression(s)."
        f"{update_hint(result, reference)}"
    )
    return 1
