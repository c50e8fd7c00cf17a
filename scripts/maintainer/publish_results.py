"""Publish paper-profile sweeps as the committed leaderboard.

    python scripts/maintainer/publish_results.py SWEEP_DIR [SWEEP_DIR ...] \
        [--figure two_body_energy]
        [--replace SYSTEM[,SYSTEM]] [--withdraw SYSTEM[/TRACK][,...]]
    python scripts/maintainer/publish_results.py --pages-only     # steps 2 and 3 alone

1. Copies every ``result.json`` of the sweeps into ``results/records/<system>/<model>/
   seed<k>/result.json``, and beside the lowest seed of each pair that has a rollout a
   small *figure rollout* (``rollout.npz``: what the per-system figures draw, 3
   trajectories, at most 200 time points, float32; ``hnnbench._results.report.figures.
   figure_arrays``), so that a report merging a new sweep with ``results/records`` draws
   every model. Weights and full rollouts stay in the sweeps. Sweeps of different
   systems, run at different times or on different machines, merge there; a record
   already present for the same job is replaced. ``--replace S`` re-publishes system
   ``S``: its published protocol records that the directories do not hold (another
   seed plan, a model gone) are removed in the same step. ``--withdraw S`` (or ``S/TRACK``)
   removes the published records of ``S`` (of that track) that the directories do not
   hold, with no replacement: records that today's code refuses (another step budget,
   another data version) until their re-publication. ``results/records`` itself may be one
   of the directories (a new model's sweep is published with it: docs/LEADERBOARD.md).
2. ``hnnbench report`` over ``results/records`` (its records and figure rollouts) into
   ``results/``: leaderboard.{csv,md,html},
   families.csv, twins.csv, aggregate.{csv,md}, improvement.csv, aggregate_scales.csv,
   paper_comparison.md, figures/; a PNG in figures/ that this report did not draw is
   removed (the page shows every figure there). The leaderboard is the one of
   ``results/records`` (tests/integration/test_published.py rebuilds it from the committed records
   and compares).
3. Replaces, in results/README.md (the results page; README.md only links to it), the
   block between ``<!-- aggregate:begin -->`` and ``<!-- aggregate:end -->`` with the
   aggregate across systems (the verdicts its intervals support and the performance
   profiles), the block between ``<!-- leaderboard:begin -->`` and
   ``<!-- leaderboard:end -->`` with the family table (and the notes of its status
   cells), its provenance, the heatmap and the twins' agreement, the block between
   ``<!-- tracks:begin -->`` and ``<!-- tracks:end -->`` with the tracks side by side
   (tracks.md), and the block between ``<!-- provenance:begin -->`` and
   ``<!-- provenance:end -->`` with the provenance and the list of systems published so
   far. Links in the blocks are relative to results/.

Records come from other machines (docs/LEADERBOARD.md, "Threat model"): a record's
directory is built from its names by ``hnnbench._contracts.paths.safe_join`` (a name that is not a
name, or a path outside results/records, is refused), every Markdown cell and line is
escaped (``hnnbench._results.report.markdown``), and a marker counts only as a whole line of its
own, exactly once, so no content can forge one.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "results"
RECORDS = RESULTS / "records"
BEGIN, END = "<!-- {name}:begin -->", "<!-- {name}:end -->"


def replace_block(text: str, name: str, body: str) -> str:
    """``text`` with the marked block ``name`` replaced by ``body``; the markers stay.

    A marker is a line of its own (nothing else on it), and each must be there exactly
    once: a marker inside a line (content quoting one) never counts, and a second one
    is refused rather than guessed at. ``body`` may hold no marker text at all."""
    begin, end = BEGIN.format(name=name), END.format(name=name)
    for marker in (begin, end, "<!--"):
        if marker in body:
            raise SystemExit(
                f"publish: the {name} block would contain {marker!r}; refusing to write it"
            )
    lines = text.split("\n")
    starts = [i for i, line in enumerate(lines) if line.strip() == begin]
    stops = [i for i, line in enumerate(lines) if line.strip() == end]
    if not starts or not stops:
        raise SystemExit(
            f"publish: marker {begin} ... {end} not found (each on a line of "
            "its own); add it where the block should go"
        )
    if len(starts) > 1 or len(stops) > 1 or stops[0] < starts[0]:
        raise SystemExit(
            f"publish: markers {begin} ... {end} must each be on one line, "
            f"once, in that order (found lines {[i + 1 for i in starts]} and "
            f"{[i + 1 for i in stops]})"
        )
    return "\n".join([*lines[: starts[0] + 1], body.strip(), *lines[stops[0] :]])


#: The line that leads the notes under the family table (its status cells' ``[n]``).
NOTES_LEAD = "Why runs did not finish"


def table_and_provenance(markdown: str) -> tuple[str, str]:
    """Split leaderboard.md into (its first table: the family table, with the notes its
    status cells point to, if any; provenance bullet lines)."""
    lines = markdown.splitlines()
    start = next((i for i, line in enumerate(lines) if line.startswith("|")), len(lines))
    stop = next((i for i in range(start, len(lines)) if not lines[i].startswith("|")), len(lines))
    rest = [line for line in lines[stop:] if line.strip()]
    notes: list[str] = []
    if rest and rest[0].startswith(NOTES_LEAD):
        notes = [rest[0], *itertools.takewhile(lambda ln: ln.split(". ", 1)[0].isdigit(), rest[1:])]
    table = "\n".join(lines[start:stop])
    if notes:
        table += "\n\n" + notes[0] + "\n\n" + "\n".join(notes[1:])
    prov = "\n".join(line for line in lines if line.startswith("- "))
    return table, prov


def sentence_after(markdown: str, heading: str) -> str:
    """The first non-empty line after ``heading`` in ``markdown``."""
    lines = markdown.splitlines()
    at = lines.index(heading) if heading in lines else len(lines)
    return next((line for line in lines[at + 1 :] if line.strip()), "")


def record_dir(rec: dict, root: Path | None = None) -> Path:
    """``results/records/<system>/<model>/seed<k>`` of a protocol record, and
    ``results/records/<system>/<model>/<track>/seed<k>`` of a tuned or recipe one (so a
    row of another track never replaces the protocol's), built by
    ``hnnbench._contracts.paths.safe_join``: a system or model that is not a name
    (``hnnbench._contracts.names.NAME_PATTERN``), a track not of ``TRACKS``, a seed that is
    not a non-negative integer, or a path outside results/records is refused
    (``SystemExit``, naming the record)."""
    from hnnbench._contracts.errors import UnsafePathError
    from hnnbench._contracts.names import DEFAULT_TRACK, TRACKS, name_problem
    from hnnbench._contracts.paths import safe_join

    where = rec.get("path", "a record")
    seed = rec.get("seed")
    track = rec.get("track", DEFAULT_TRACK)
    problem = (
        name_problem("system", rec.get("system"))
        or name_problem("model", rec.get("model"))
        or (None if track in TRACKS else f"track {track!r} is not one of {', '.join(TRACKS)}")
        or (
            None
            if isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0
            else f"seed {seed!r} is not a non-negative integer"
        )
    )
    if problem:
        raise SystemExit(f"publish: {where}: {problem}")
    parts = [
        rec["system"],
        rec["model"],
        *([track] if track != DEFAULT_TRACK else []),
        f"seed{seed}",
    ]
    try:
        return safe_join(RECORDS if root is None else root, *parts)
    except UnsafePathError as err:
        raise SystemExit(f"publish: {where}: {err}") from None


def job_of(rec: dict) -> tuple[str, str, str, int]:
    """A published job's identity: (track, system, model, seed)."""
    from hnnbench._record.tracks import track_of

    return track_of(rec), str(rec["system"]), str(rec["model"]), int(rec["seed"])


def copy_figure_rollouts(sweeps: list[Path], root: Path | None = None) -> tuple[int, int]:
    """For each published (system, model), the figure rollout of its lowest seed that has
    a ``rollout.npz`` in the sweeps, next to its record in results/records (``root``);
    any other ``rollout.npz`` there is removed. Returns (files, bytes); a rollout that
    cannot be read safely is ``SystemExit`` (one line) before anything is published."""
    import io
    import zipfile

    import numpy as np

    from hnnbench import _record as records
    from hnnbench._contracts.paths import safe_join
    from hnnbench._results.report.figures import figure_arrays

    chosen: dict[tuple[str, str, str], tuple[int, Path]] = {}
    for sweep in sweeps:
        for rec in records.load(sweep, strict=True).records:
            source = Path(rec["path"]) / records.ROLLOUT_NAME
            if rec.get("status") not in ("ok", "diverged") or not source.is_file():
                continue
            track, system, model, seed = job_of(rec)
            key = (track, system, model)
            if key not in chosen or seed < chosen[key][0]:
                chosen[key] = (seed, source)
    written = {}
    for (track, system, model), (seed, source) in sorted(chosen.items()):
        rec = {
            "system": system,
            "model": model,
            "seed": seed,
            "track": track,
            "path": str(source.parent),
        }
        target = safe_join(record_dir(rec, root), records.ROLLOUT_NAME)
        buffer = io.BytesIO()
        try:
            arrays = figure_arrays(records.load_arrays(source))
        except (records.UnsafeFile, OSError, ValueError, KeyError, zipfile.BadZipFile) as err:
            raise SystemExit(
                f"publish: {source}: the rollout cannot be read safely ({err}); re-run "
                "the job or remove the file; nothing was published"
            ) from None
        np.savez_compressed(buffer, **arrays)
        target.parent.mkdir(parents=True, exist_ok=True)
        tmp = target.with_name(f".{target.name}.tmp")
        tmp.write_bytes(buffer.getvalue())
        tmp.replace(target)
        written[target.resolve()] = len(buffer.getvalue())
    for stale in (RECORDS if root is None else root).rglob(records.ROLLOUT_NAME):
        if stale.resolve() not in written:
            stale.unlink()
    return len(written), sum(written.values())


def remove_stale_figures(made: list[Path]) -> list[Path]:
    """Remove every PNG in results/figures that is not one of ``made`` (the page shows
    every figure there); returns the removed files."""
    keep = {Path(p).resolve() for p in made}
    stale = [p for p in sorted((RESULTS / "figures").glob("*.png")) if p.resolve() not in keep]
    for path in stale:
        path.unlink()
    return stale


def given_records(sweeps: list[Path]) -> list[dict]:
    """The records of the directories given, each checked: valid against the schema (a
    strict load), the paper profile, the paper settings (its variant derived from its
    stored config), and no job twice (``SystemExit`` naming the record otherwise)."""
    from hnnbench import _record as records
    from hnnbench._results import validity
    from hnnbench._results.provenance import config_variant

    out: list[dict] = []
    seen: dict[tuple[str, str, str, int], str] = {}
    for sweep in sweeps:
        if not Path(sweep).is_dir():
            raise SystemExit(f"publish: {sweep} is not a directory of records")
        recs, bad = records.load(sweep, strict=True)
        # The one strict validation of every door: what `hnnbench check` refuses is
        # never published.
        checked = validity.validate(recs, bad)
        if checked.problems:
            first, more = checked.problems[0], len(checked.problems) - 1
            raise SystemExit(
                f"publish: {sweep}: {first.line()}"
                + (f" (and {more} more problem(s))" if more else "")
                + "; hnnbench check lists every one; nothing was published"
            )
        for rec in recs:
            if rec.get("profile") != "paper":
                raise SystemExit(
                    f"publish: {rec['path']} is profile {rec.get('profile')}, not paper"
                )
            # The published rows are the plugins' paper settings: the variant is derived
            # from the stored config against the paper defaults, not read from overrides.
            variant = config_variant(rec)
            why = (
                variant.problem
                or variant.mismatch
                or (
                    f"its config is a variant ({variant.label}), not the paper settings"
                    if variant.label
                    else None
                )
            )
            if why:
                raise SystemExit(f"publish: {rec['path']}: {why}")
            job = job_of(rec)
            if job in seen:
                raise SystemExit(
                    f"publish: {job} is in both {seen[job]} and {rec['path']}: "
                    "the report would count it twice; move the superseded "
                    "run out of its sweep"
                )
            seen[job] = str(rec["path"])
            out.append(rec)
    return out


def copy_records(
    sweeps: list[Path], recs: list[dict] | None = None, root: Path | None = None
) -> int:
    """Copy each sweep's records (:func:`given_records`, unless already given as
    ``recs``) into results/records; returns how many."""
    from hnnbench import _record as records
    from hnnbench._contracts.paths import safe_join
    from hnnbench._record.store import MAX_RECORD_BYTES

    recs = given_records(sweeps) if recs is None else recs
    for rec in recs:
        source = Path(rec["path"]) / records.RECORD_NAME
        target = record_dir(rec, root)
        text = source.read_text()
        if len(text.encode()) > MAX_RECORD_BYTES:
            raise SystemExit(f"publish: {source} grew over {MAX_RECORD_BYTES} bytes")
        target.mkdir(parents=True, exist_ok=True)
        records.atomic_write_text(safe_join(target, records.RECORD_NAME), text)
    return len(recs)


def published_jobs(root: Path | None = None) -> set[tuple[str, str, str, int]]:
    """The (track, system, model, seed) of every record under results/records
    (:func:`record_dir`'s layout); a record anywhere else there (a stray directory) is
    ``SystemExit`` naming it, before anything is written."""
    from hnnbench._contracts.names import DEFAULT_TRACK, TRACKS, name_problem

    root = RECORDS if root is None else root
    jobs: set[tuple[str, str, str, int]] = set()
    for path in sorted(root.rglob("result.json")):
        parts = path.relative_to(root).parts[:-1]
        track = parts[2] if len(parts) == 4 else DEFAULT_TRACK
        seed = parts[-1].removeprefix("seed") if parts else ""
        if (
            len(parts) not in (3, 4)
            or name_problem("system", parts[0])
            or name_problem("model", parts[1])
            or (len(parts) == 4 and (track == DEFAULT_TRACK or track not in TRACKS))
            or not parts[-1].startswith("seed")
            or not seed.isdigit()
        ):
            raise SystemExit(
                f"publish: {path} is not at records/<system>/<model>/[<track>/]seed<k>/"
                "result.json; move or remove it; nothing was published"
            )
        jobs.add((track, parts[0], parts[1], int(seed)))
    return jobs


def remove_jobs(jobs: set[tuple[str, str, str, int]], root: Path | None = None) -> int:
    """Remove the published records (and figure rollouts) of ``jobs`` ((track, system,
    model, seed)); returns how many."""
    import shutil

    for track, system, model, seed in jobs:
        directory = record_dir(
            {
                "system": system,
                "model": model,
                "seed": seed,
                "track": track,
                "path": "results/records",
            },
            root,
        )
        shutil.rmtree(directory)
    for empty in sorted(
        (RECORDS if root is None else root).rglob("*"), key=lambda p: len(p.parts), reverse=True
    ):
        if empty.is_dir() and not any(empty.iterdir()):
            empty.rmdir()
    return len(jobs)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "sweeps",
        type=Path,
        nargs="*",
        help="sweep directories with result.json records and rollouts",
    )
    parser.add_argument(
        "--figure",
        default="heatmap_energy_mse",
        help="figure shown in results/README.md (a name under results/figures/)",
    )
    parser.add_argument(
        "--replace",
        default="",
        metavar="SYSTEM[,SYSTEM]",
        help="replace every published protocol-track record of these "
        "systems by the records given (a re-publication): the "
        "published ones the directories do not hold are removed in "
        "the same step",
    )
    parser.add_argument(
        "--withdraw",
        default="",
        metavar="SYSTEM[/TRACK][,...]",
        help="remove the published records of these systems (of every track, or of "
        "TRACK) that the directories given do not hold, without a replacement: records "
        "today's code refuses, until they are re-published",
    )
    parser.add_argument(
        "--pages-only",
        action="store_true",
        help="no sweeps: rebuild the report, figures and results/README.md "
        "blocks (steps 2 and 3) from results/records as committed, "
        "after a change of the report's code",
    )
    args = parser.parse_args(argv)
    if args.pages_only:
        if args.sweeps or args.replace or args.withdraw:
            parser.error("--pages-only takes no sweeps, no --replace and no --withdraw")
        status, _ = write_pages(args.figure)
        return status
    if not args.sweeps:
        parser.error("give the sweep directories to publish (or --pages-only)")

    recs = given_records(args.sweeps)
    replaced = {s for s in args.replace.split(",") if s}
    from hnnbench._contracts.names import DEFAULT_TRACK, TRACKS, name_problem

    withdrawn: set[tuple[str, str | None]] = set()
    for item in (s for s in args.withdraw.split(",") if s):
        system, _, track = item.partition("/")
        problem = name_problem("system", system) or (
            f"unknown track {track!r} (tracks: {', '.join(TRACKS)})"
            if track and track not in TRACKS
            else None
        )
        if problem:
            print(f"publish: --withdraw {item}: {problem}", file=sys.stderr)
            return 2
        withdrawn.add((system, track or None))

    for system in sorted(replaced):
        problem = name_problem("system", system)
        if problem:
            print(f"publish: --replace {system}: {problem}", file=sys.stderr)
            return 2
        if not any(r["system"] == system and job_of(r)[0] == DEFAULT_TRACK for r in recs):
            print(
                f"publish: --replace {system}: the directories given hold no protocol "
                f"record of {system}; refusing to remove its published records",
                file=sys.stderr,
            )
            return 2
    # Every record already published must be among those given (results/records itself
    # may be given), so that the page and the records agree; the protocol records of a
    # replaced system go.
    given = {job_of(r) for r in recs}
    superseded = {
        job
        for job in published_jobs() - given
        if (job[0] == DEFAULT_TRACK and job[1] in replaced)
        or (job[1], None) in withdrawn
        or (job[1], job[0]) in withdrawn
    }
    stale = published_jobs() - given - superseded
    if stale:
        print(
            f"publish: results/records holds jobs the directories given here do not "
            f"({sorted(stale)[:5]} ...): pass every sweep that was published, or "
            "results/records itself",
            file=sys.stderr,
        )
        return 2
    copied, removed_records, rollouts, rollout_bytes = stage_and_publish(
        args.sweeps, recs, superseded
    )
    status, summary = write_pages(args.figure)
    if status:
        return status
    import job_costs  # scripts/maintainer/: the sweep's estimate reads the published job times

    job_costs.main([])
    print(
        json.dumps(
            {
                "copied_records": copied,
                "removed_records": removed_records,
                "figure_rollouts": rollouts,
                "figure_rollout_bytes": rollout_bytes,
                **summary,
            }
        )
    )
    return 0


def stage_and_publish(
    sweeps: list[Path], recs: list[dict], superseded: set[tuple[str, str, str, int]]
) -> tuple[int, int, int, int]:
    """All or nothing: the new results/records is built in a staging directory beside it
    (a copy of the published records, the given records copied in, the superseded ones
    removed, the figure rollouts written), loaded back strictly, and only then moved
    into place; any failure leaves results/records as it was. Returns (records copied,
    records removed, figure rollouts, their bytes)."""
    import os
    import shutil
    import tempfile

    from hnnbench import _record as records

    RESULTS.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".publish-", dir=RESULTS))
    try:
        stage = staging / "records"
        if RECORDS.is_dir():
            shutil.copytree(RECORDS, stage, symlinks=True)
        else:
            stage.mkdir()
        copied = copy_records(sweeps, recs, root=stage)
        removed = remove_jobs(superseded, root=stage)
        rollouts, rollout_bytes = copy_figure_rollouts(sweeps, root=stage)
        staged, bad = records.load(stage, strict=True)
        if bad:
            raise SystemExit(
                f"publish: a staged record does not load: {bad[0]}; nothing was published"
            )
        published_jobs(stage)
        old = staging / "old"
        if RECORDS.exists():
            os.replace(RECORDS, old)
        os.replace(stage, RECORDS)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return copied, removed, rollouts, rollout_bytes


def write_pages(figure_name: str) -> tuple[int, dict[str, Any]]:
    """Steps 2 and 3: the report of results/records into results/, stale figures
    removed, and the blocks of results/README.md. Returns ``(0, summary)``, or ``(2,
    {})`` with the reason on stderr."""
    from hnnbench._contracts.errors import HnnbenchError
    from hnnbench._results.report import write_report
    from hnnbench._results.report.figures import main_profile_figure
    from hnnbench._results.report.markdown import md_code
    from hnnbench._results.report.verdicts import aggregate_markdown

    published = sorted(p.parent.relative_to(RECORDS) for p in RECORDS.rglob("result.json"))
    try:
        report = write_report([RECORDS], RESULTS)
    except HnnbenchError as err:
        print(f"publish: {err}", file=sys.stderr)
        return 2, {}
    removed = remove_stale_figures([m.path for m in report.figures])
    figure = RESULTS / "figures" / f"{figure_name}.png"
    if not figure.exists():
        names = sorted(p.stem for p in (RESULTS / "figures").glob("*.png"))
        print(f"publish: no figure {figure.name}; available: {', '.join(names)}", file=sys.stderr)
        return 2, {}
    markdown = report.files["md"].read_text()
    table, prov = table_and_provenance(markdown)
    systems = sorted({p.parts[0] for p in published})
    results_readme = RESULTS / "README.md"
    body = "\n\n".join(
        [
            prov,
            table,
            "![Which family wins where: rank by energy MSE]"
            f"({figure.relative_to(RESULTS).as_posix()})",
            sentence_after(markdown, "## Twin agreement") + " The twin table, every model's "
            "row and the per-system figures: [leaderboard.html](leaderboard.html).",
        ]
    )
    text = replace_block(results_readme.read_text(), "leaderboard", body)
    assert report.verdicts is not None
    profile = main_profile_figure(report.figures)
    text = replace_block(
        text,
        "aggregate",
        aggregate_markdown(
            report.verdicts,
            profile.relative_to(RESULTS).as_posix() if profile else None,
            heading="",
        ),
    )
    text = replace_block(
        text, "tracks", report.files["tracks_md"].read_text().removeprefix("# Tracks").strip()
    )
    listing = f"- Systems published: {', '.join(md_code(s) for s in systems)}"
    for line in protocol_lines(report.records) + partial_lines(published):
        listing += "\n" + line
    results_readme.write_text(replace_block(text, "provenance", f"{prov}\n{listing}"))
    return 0, {
        "published_records": len(published),
        "systems": systems,
        "figures": len(report.figures),
        "stale_figures_removed": [p.name for p in removed],
    }


def protocol_lines(recs: list[dict[str, Any]]) -> list[str]:
    """Which protocol each published system's protocol-track records were made under
    (their record schema and hnnbench versions: a leaderboard re-published in parts
    mixes them), and the installed systems with no published record."""
    from hnnbench._contracts.names import DEFAULT_TRACK
    from hnnbench._record.tracks import track_of
    from hnnbench._registry.groups import available
    from hnnbench._results.report.markdown import md_code

    # schema -> the systems with records of it, and the hnnbench versions that wrote them
    made: dict[int, tuple[set[str], set[str]]] = {}
    for rec in recs:
        if track_of(rec) != DEFAULT_TRACK:
            continue
        version = str((rec.get("environment") or {}).get("hnnbench") or "?")
        systems, versions = made.setdefault(int(rec.get("schema_version") or 0), (set(), set()))
        systems.add(rec["system"])
        versions.add(version)
    lines = []
    newest = max(made, default=0)
    for schema, (systems, versions) in sorted(made.items(), reverse=True):
        when = "the current protocol" if schema == newest else "an earlier protocol"
        lines.append(
            f"- Under {when} (record schema {schema}, hnnbench {', '.join(sorted(versions))}): "
            + ", ".join(md_code(s) for s in sorted(systems))
        )
    published = {s for systems, _ in made.values() for s in systems}
    absent = [s for s in available("system") if s not in published]
    if absent:
        lines.append(
            f"- Not published: {', '.join(md_code(s) for s in absent)} (withdrawn until "
            "re-published under the current protocol, or not run)"
        )
    return lines


def partial_lines(published: set[Path] | list[Path]) -> list[str]:
    """One line per published system that lacks some installed models, naming them
    (``records/<system>/<model>/...`` paths)."""
    from hnnbench._registry.groups import available
    from hnnbench._results.report.markdown import md_code

    models: dict[str, set[str]] = {}
    for path in published:
        models.setdefault(path.parts[0], set()).add(path.parts[1])
    lines = []
    for system in sorted(models):
        missing = [m for m in available("model") if m not in models[system]]
        if missing:
            lines.append(
                f"- Partly published: {md_code(system)} lacks {', '.join(missing)} "
                "(not run yet at the paper profile)"
            )
    return lines


if __name__ == "__main__":
    sys.exit(main())
