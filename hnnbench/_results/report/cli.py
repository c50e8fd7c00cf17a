"""``hnnbench report DIR [DIR ...] [--out OUT] [--no-figures] [--embed-figures]``."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from hnnbench._contracts.errors import OneLineArgumentParser
from hnnbench._results.report.build import write_report
from hnnbench._results.report.tables import families_markdown

__all__ = ["main"]


def _parser() -> OneLineArgumentParser:
    p = OneLineArgumentParser(
        prog="hnnbench report",
        description="Tables (CSV, Markdown, HTML) and figures from run records; "
        "several directories merge into one leaderboard.",
    )
    p.add_argument(
        "dirs",
        metavar="DIR",
        nargs="+",
        help="sweep or record directories (searched for result.json)",
    )
    p.add_argument(
        "--out",
        metavar="OUT",
        default=None,
        help="output directory (default: DIR, when there is one)",
    )
    p.add_argument("--no-figures", action="store_true", help="tables only (faster)")
    p.add_argument(
        "--embed-figures",
        action="store_true",
        help="put the figures inside leaderboard.html (one self-contained file, "
        "many MB) instead of linking them from figures/",
    )
    p.add_argument(
        "--strict",
        action="store_true",
        help="every record must pass the strict validation of hnnbench check; an "
        "unreadable or invalid one is an error (default: left out with a warning)",
    )
    p.add_argument(
        "--tuning",
        metavar="DIR",
        nargs="+",
        default=None,
        help="folders of tuned studies' summaries (the tuning/ folder of each "
        "`hnnbench tune` out=, or results/tuning): the tracks page shows how each "
        "study's best criterion converged (put it last: it takes every DIR after it)",
    )
    p.add_argument(
        "--allow-unverified",
        action="store_true",
        help="with --strict: records whose plugins cannot be verified here pass (said)",
    )
    return p


def main(args: Sequence[str]) -> int:
    ns = _parser().parse_args(list(args))
    report = write_report(
        [Path(d) for d in ns.dirs],
        ns.out,
        figures=not ns.no_figures,
        strict=ns.strict,
        embed_figures=ns.embed_figures,
        allow_unverified=ns.allow_unverified,
        tuning=ns.tuning,
    )
    if ns.strict and ns.allow_unverified:
        print(
            "report --strict --allow-unverified: records whose plugins cannot be "
            "verified were accepted"
        )
    assert report.verdicts is not None
    print(families_markdown(report.verdicts.families))
    print()
    for item in report.unreadable:
        print(f"warning: record left out: {item}")
    others = ", ".join(
        path.name for key, path in report.files.items() if key not in ("csv", "html")
    )
    print(
        f"wrote {report.files['csv']}, {others}, {report.files['html'].name} and "
        f"{len(report.figures)} figure(s) in {report.out / 'figures'} from "
        f"{len(report.records)} record(s)"
    )
    return 0
