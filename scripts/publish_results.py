"""Publish a paper-profile sweep as the committed leaderboard.

    python scripts/publish_results.py SWEEP_DIR [--figure two_body_energy]

1. ``hnnbench report SWEEP_DIR --out results/``: leaderboard.{csv,md,html},
   paper_comparison.md and figures/ (all written by code).
2. Replaces the block between ``<!-- leaderboard:begin -->`` and
   ``<!-- leaderboard:end -->`` in README.md with the Markdown table, its provenance
   (command, commit, device) and one figure, and the block between
   ``<!-- provenance:begin -->`` and ``<!-- provenance:end -->`` in results/README.md
   with the provenance.

``tests/test_published.py`` checks that README.md and results/ agree, so the README
table cannot drift from the committed records.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "results"
BEGIN, END = "<!-- {name}:begin -->", "<!-- {name}:end -->"


def replace_block(text: str, name: str, body: str) -> str:
    """``text`` with the marked block ``name`` replaced by ``body``; the markers stay."""
    begin, end = BEGIN.format(name=name), END.format(name=name)
    pattern = re.compile(re.escape(begin) + r".*?" + re.escape(end), flags=re.S)
    if not pattern.search(text):
        raise SystemExit(f"publish: marker {begin} ... {end} not found; add it where the "
                         "block should go")
    return pattern.sub(lambda _: f"{begin}\n{body.strip()}\n{end}", text, count=1)


def table_and_provenance(markdown: str) -> tuple[str, str]:
    """Split leaderboard.md into (table lines, provenance bullet lines)."""
    lines = markdown.splitlines()
    table = "\n".join(line for line in lines if line.startswith("|"))
    prov = "\n".join(line for line in lines if line.startswith("- "))
    return table, prov


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sweep", type=Path, help="sweep directory with result.json records")
    parser.add_argument("--figure", default="two_body_energy",
                        help="figure embedded in README.md (a name under results/figures/)")
    args = parser.parse_args(argv)

    from hnnbench.errors import HnnbenchError
    from hnnbench.report import write_report

    try:
        report = write_report(args.sweep, RESULTS)
    except HnnbenchError as err:
        print(f"publish: {err}", file=sys.stderr)
        return 2
    figure = RESULTS / "figures" / f"{args.figure}.png"
    if not figure.exists():
        names = sorted(p.stem for p in (RESULTS / "figures").glob("*.png"))
        print(f"publish: no figure {figure.name}; available: {', '.join(names)}",
              file=sys.stderr)
        return 2
    table, prov = table_and_provenance(report.files["md"].read_text())
    readme = ROOT / "README.md"
    body = "\n\n".join([
        prov, table,
        f"![True energy along rollouts]({figure.relative_to(ROOT).as_posix()})",
    ])
    readme.write_text(replace_block(readme.read_text(), "leaderboard", body))
    results_readme = RESULTS / "README.md"
    results_readme.write_text(replace_block(results_readme.read_text(), "provenance", prov))
    print(f"published {report.out}: {len(report.figures)} figures; README.md and "
          "results/README.md updated")
    return 0


if __name__ == "__main__":
    sys.exit(main())
