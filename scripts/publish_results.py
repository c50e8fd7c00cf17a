"""Publish paper-profile sweeps as the committed leaderboard.

    python scripts/publish_results.py SWEEP_DIR [SWEEP_DIR ...] [--figure two_body_energy]

1. Copies every ``result.json`` of the sweeps into ``results/records/<system>/<model>/
   seed<k>/result.json`` (records only: they are small; rollouts and weights stay in the
   sweeps). Sweeps of different systems, run at different times or on different
   machines, merge there; a record already present for the same job is replaced.
2. ``hnnbench report`` over the sweeps (their rollouts draw the figures) into
   ``results/``: leaderboard.{csv,md,html}, paper_comparison.md, figures/. The
   leaderboard is the one of ``results/records`` (tests/test_published.py rebuilds it
   from the committed records and compares).
3. Replaces the block between ``<!-- leaderboard:begin -->`` and
   ``<!-- leaderboard:end -->`` in README.md with the Markdown table, its provenance and
   the heatmap, and the block between ``<!-- provenance:begin -->`` and
   ``<!-- provenance:end -->`` in results/README.md with the provenance and the list of
   systems published so far.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "results"
RECORDS = RESULTS / "records"
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


def copy_records(sweeps: list[Path]) -> int:
    """Copy each sweep's records into results/records; returns how many."""
    from hnnbench import _records as R
    from hnnbench._provenance import config_variant

    count = 0
    seen: dict[tuple[str, str, int], str] = {}
    for sweep in sweeps:
        recs, bad = R.load(sweep, strict=True)
        if bad:
            raise SystemExit(f"publish: {len(bad)} unreadable or invalid record(s) in "
                             f"{sweep}, e.g. {bad[0]}")
        for rec in recs:
            if rec.get("profile") != "paper":
                raise SystemExit(f"publish: {rec['path']} is profile {rec.get('profile')}, "
                                 "not paper")
            # The published rows are the plugins' paper settings: the variant is derived
            # from the stored config against the paper defaults, not read from overrides.
            variant = config_variant(rec)
            why = variant.problem or variant.mismatch or (
                f"its config is a variant ({variant.label}), not the paper settings"
                if variant.label else None)
            if why:
                raise SystemExit(f"publish: {rec['path']}: {why}")
            job = (str(rec["system"]), str(rec["model"]), int(rec["seed"]))
            if job in seen:
                raise SystemExit(f"publish: {job} is in both {seen[job]} and {rec['path']}: "
                                 "the report would count it twice; move the superseded "
                                 "run out of its sweep")
            seen[job] = str(rec["path"])
            source = Path(rec["path"]) / R.RECORD_NAME
            target = RECORDS / str(rec["system"]) / str(rec["model"]) / f"seed{rec['seed']}"
            target.mkdir(parents=True, exist_ok=True)
            R.atomic_write_text(target / R.RECORD_NAME, source.read_text())
            count += 1
    return count


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("sweeps", type=Path, nargs="+",
                        help="sweep directories with result.json records and rollouts")
    parser.add_argument("--figure", default="heatmap_energy_mse",
                        help="figure embedded in README.md (a name under results/figures/)")
    args = parser.parse_args(argv)

    from hnnbench._errors import HnnbenchError
    from hnnbench._report import write_report

    copied = copy_records(args.sweeps)
    # Figures need the rollouts, which only the sweeps keep; every published record
    # must be in one of them so that the page and the records agree.
    published = sorted(p.parent.relative_to(RECORDS) for p in RECORDS.rglob("result.json"))
    try:
        report = write_report(args.sweeps, RESULTS)
    except HnnbenchError as err:
        print(f"publish: {err}", file=sys.stderr)
        return 2
    in_sweeps = {(r["system"], r["model"], int(r["seed"])) for r in report.records}
    on_record = {(p.parts[0], p.parts[1], int(p.parts[2].removeprefix("seed")))
                 for p in published}
    if in_sweeps != on_record:
        print(f"publish: results/records holds jobs the sweeps given here do not "
              f"({sorted(on_record - in_sweeps)[:5]} ...): pass every sweep that was "
              "published", file=sys.stderr)
        return 2
    figure = RESULTS / "figures" / f"{args.figure}.png"
    if not figure.exists():
        names = sorted(p.stem for p in (RESULTS / "figures").glob("*.png"))
        print(f"publish: no figure {figure.name}; available: {', '.join(names)}",
              file=sys.stderr)
        return 2
    table, prov = table_and_provenance(report.files["md"].read_text())
    systems = sorted({p.parts[0] for p in published})
    readme = ROOT / "README.md"
    body = "\n\n".join([
        prov, table,
        f"![Which model wins where: rank by energy MSE]({figure.relative_to(ROOT).as_posix()})",
    ])
    readme.write_text(replace_block(readme.read_text(), "leaderboard", body))
    results_readme = RESULTS / "README.md"
    listing = f"- Systems published: {', '.join(f'`{s}`' for s in systems)}"
    for line in partial_lines(published):
        listing += "\n" + line
    results_readme.write_text(replace_block(results_readme.read_text(), "provenance",
                                            f"{prov}\n{listing}"))
    print(json.dumps({"copied_records": copied, "published_records": len(published),
                      "systems": systems, "figures": len(report.figures)}))
    return 0


def partial_lines(published: set[Path] | list[Path]) -> list[str]:
    """One line per published system that lacks some installed models, naming them
    (``records/<system>/<model>/...`` paths)."""
    from hnnbench._registry import available

    models: dict[str, set[str]] = {}
    for path in published:
        models.setdefault(path.parts[0], set()).add(path.parts[1])
    lines = []
    for system in sorted(models):
        missing = [m for m in available("model") if m not in models[system]]
        if missing:
            lines.append(f"- Partly published: `{system}` lacks {', '.join(missing)} "
                         "(not run yet at the paper profile)")
    return lines


if __name__ == "__main__":
    sys.exit(main())
