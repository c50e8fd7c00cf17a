"""Publish paper-profile sweeps as the committed leaderboard.

    python scripts/maintainer/publish_results.py SWEEP_DIR [SWEEP_DIR ...] \
        [--figure two_body_energy]
        [--replace SYSTEM[,SYSTEM]] [--withdraw SYSTEM[/TRACK][,...]]
    python scripts/maintainer/publish_results.py --pages-only     # steps 2 and 3 alone
    python scripts/maintainer/publish_results.py --tuned OUT [OUT ...]

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

``--tuned OUT`` publishes the tuned track in parts (docs/TUNING.md, "Publishing in
parts"): each finished study of a tuner's ``out=`` folder is staged (its final records,
figure rollout and summary in ``results/staged/``); a system moves into
``results/records`` (steps 1-3), its summaries into ``results/tuning/``, once its staged
studies cover every family its protocol ran. The sweep door takes no tuned record that
is not published already.

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
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "results"
RECORDS = RESULTS / "records"
#: The tuned track's finished studies of systems not yet complete (records/ layout).
STAGED = RESULTS / "staged"
#: Every staged or published study's summary: tuning/<system>/<model>[.fold<k>].json.
STUDIES = RESULTS / "tuning"
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


def copy_figure_rollouts(recs: list[dict], root: Path | None = None) -> tuple[int, int]:
    """For each (system, model) of ``recs`` (the records being published), the figure
    rollout of its lowest seed that has a ``rollout.npz`` beside its record (of a tuned
    pair, the lowest seed that is not a trial seed, where one has it), next to its
    record in results/records (``root``); any other ``rollout.npz`` there is removed.
    Returns (files, bytes); a rollout that cannot be read safely is ``SystemExit`` (one
    line) before anything is published."""
    import io
    import zipfile

    import numpy as np

    from hnnbench import _record as records
    from hnnbench._contracts.paths import safe_join
    from hnnbench._record.tracks import on_trial_seed
    from hnnbench._results.report.figures import figure_arrays

    chosen: dict[tuple[str, str, str], tuple[tuple[bool, int], Path]] = {}
    for rec in recs:
        source = Path(rec["path"]) / records.ROLLOUT_NAME
        if rec.get("status") not in ("ok", "diverged") or not source.is_file():
            continue
        track, system, model, seed = job_of(rec)
        key = (track, system, model)
        # a tuned run on a trial seed (no row reads it) only where no other seed has one
        rank = (bool(on_trial_seed(rec)), seed)
        if key not in chosen or rank < chosen[key][0]:
            chosen[key] = (rank, source)
    written = {}
    for (track, system, model), ((_, seed), source) in sorted(chosen.items()):
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
                track, system, model, seed = job
                raise SystemExit(
                    f"publish: the {track} run {system}/{model} seed {seed} is in both "
                    f"{seen[job]} and {rec['path']}: "
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


# ----------------------------------------------------------------- the tuned track's parts
#
# A tuned system is published once every family the protocol runs there has a finished
# study (docs/TUNING.md, "Publishing in parts"). A study of one (system, family) fits in a
# session; a system's six do not. So each finished study is *staged* as it ends: its
# final records (and figure rollout) and its summaries into results/staged/ (records/'s
# layout, the summaries beside the model's records). When a system's staged studies
# cover every family, its records move into results/records in one publication and its
# summaries into results/tuning/. Each step can be run again after a crash.

#: The fields of a study summary (``hnnbench._tuning.tuner.Tuner._write_summary``) that
#: staging reads, with the JSON types each may hold.
STUDY_FIELDS: dict[str, tuple[type, ...]] = {
    "system": (str,),
    "model": (str,),
    "study": (str,),
    "profile": (str,),
    "trials_budget": (int,),
    "steps": (int,),
    "seeds_per_trial": (int,),
    "fold": (int, type(None)),
    "final_seeds": (list,),
    "protocol_trial": (int,),
    "selected": (dict, type(None)),
    "trials": (list,),
}
#: The trial states a study's budget counts (the tuner's ``done()``).
COUNTED = ("complete", "pruned")


def summary_name(model: str, fold: int | None) -> str:
    """A study summary's file name, as the tuner names it: ``<model>[.fold<k>].json``
    (:func:`hnnbench._record.tracks.study_summary_name`)."""
    from hnnbench._record.tracks import study_summary_name

    return study_summary_name(model, fold)


def study_problem(summary: dict[str, Any], system: str, model: str) -> str | None:
    """Why ``summary`` (a study summary read from a tuner's ``out=``) cannot be staged as
    a study of ``system`` x ``model``, or ``None``: each field of :data:`STUDY_FIELDS` of
    its type, the paper profile, the names of its path, the protocol's settings as its
    trial 0, and its seeds non-negative integers."""
    from hnnbench._results.report.convergence import field_problem

    problem = field_problem(summary, STUDY_FIELDS)
    if problem:
        return problem
    if summary["profile"] != "paper":
        return f"profile {summary['profile']}, not paper"
    if (summary["system"], summary["model"]) != (system, model):
        return f"it is a study of {summary['system']}/{summary['model']}, filed as {system}/{model}"
    seeds = summary["final_seeds"]
    if not seeds or not all(type(s) is int and s >= 0 for s in seeds):
        return f"final_seeds: {seeds!r} is not a list of non-negative integers"
    trials = summary["trials"]
    if not all(isinstance(t, dict) and type(t.get("number")) is int for t in trials):
        return "trials: each must be an object with an integer number"
    first = _protocol_trial(summary)
    if summary["protocol_trial"] != 0 or first is None:
        return "its trial 0 is not the protocol's settings"
    if (
        first.get("state") == "complete"
        and "protocol_value" in summary
        and not _same_value(summary["protocol_value"], first.get("value"))
    ):
        return (
            f"protocol_value {summary['protocol_value']!r} is not its trial 0's value "
            f"{first.get('value')!r}"
        )
    counted = sum(t.get("state") in COUNTED for t in trials)
    if counted > summary["trials_budget"]:
        return f"it counts {counted} trials, more than its budget of {summary['trials_budget']}"
    selected = summary["selected"]
    if selected is None:
        return None
    if not isinstance(selected.get("settings"), dict):
        return "selected: it holds no settings"
    return _selection_problem(selected, trials)


def _protocol_trial(summary: dict[str, Any]) -> dict[str, Any] | None:
    """The study's protocol trial: the one trial flagged ``protocol``, and its first
    (the lowest number: trial 0, or the run that replayed an interrupted trial 0, which
    the summary leaves out); ``None`` where there is no such trial."""
    trials = summary["trials"]
    flagged = [t for t in trials if t.get("protocol") is True]
    if len(flagged) != 1 or flagged[0]["number"] != min(t["number"] for t in trials):
        return None
    return flagged[0]


def _value(value: Any) -> float | None:
    """A criterion value as a summary writes it (a number, or the codec's ``"inf"``) as
    a float; ``None`` where it is neither."""
    from hnnbench._record.codec import decode_number

    value = decode_number(value)
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else None


def _same_value(a: Any, b: Any) -> bool:
    """Whether two criterion values as a summary writes them are the same number."""
    x, y = _value(a), _value(b)
    return x is not None and x == y


def _selection_problem(selected: dict[str, Any], trials: list[dict[str, Any]]) -> str | None:
    """Why ``selected`` is not the best completed trial of ``trials`` by the tuner's
    objective (its number, value and settings), or ``None``."""
    from hnnbench._tuning.tuner import objective_metric

    done = [t for t in trials if t.get("state") == "complete"]
    bad = next((t for t in done if _value(t.get("value")) is None), None)
    if bad is not None:
        return f"trial {bad['number']}: value {bad.get('value')!r} is not a number"
    chosen = next((t for t in done if t["number"] == selected.get("number")), None)
    if chosen is None:
        return f"selected: trial {selected.get('number')!r} is not a completed trial"
    if chosen.get("settings") != selected["settings"] or not _same_value(
        chosen.get("value"), selected.get("value")
    ):
        return f"selected: its settings or value are not those of its trial {chosen['number']}"
    sign = 1.0 if objective_metric().better == "lower" else -1.0
    best = min(done, key=lambda t: sign * (_value(t["value"]) or 0.0))
    if sign * (_value(chosen["value"]) or 0.0) > sign * (_value(best["value"]) or 0.0):
        return (
            f"selected: trial {chosen['number']} ({chosen['value']!r}) is not the best "
            f"completed trial (trial {best['number']}: {best['value']!r})"
        )
    return None


def protocol_settings_problem(summary: dict[str, Any], configs: list[dict[str, Any]]) -> str | None:
    """Why a (checked) study's trial 0 is not the settings of the published protocol
    records ``configs`` (their ``config``), or ``None``. A setting ``model.X`` is read
    from each config as the protocol job resolved it: the model's value, else, for a
    training field (``TrainSettings``), the system's. The configs must agree with one
    another on every setting first."""
    from hnnbench._contracts.plugin import SystemConfig

    first = _protocol_trial(summary)
    if first is None:
        return "its trial 0 is not the protocol's settings"
    settings = first.get("settings")
    if not isinstance(settings, dict):
        return "its trial 0 holds no settings"

    missing = object()

    def resolved(config: dict[str, Any], name: str) -> Any:
        model, system = config.get("model") or {}, config.get("system") or {}
        if model.get(name) is None and name in SystemConfig.TRAINING_FIELDS:
            return system.get(name, missing)
        return model.get(name, missing)

    def same(a: Any, b: Any) -> bool:
        numbers = (int, float)
        if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool):
            return float(a) == float(b)
        return bool(a == b)

    for key, value in settings.items():
        name = key.split(".", 1)[-1]
        values = [resolved(c, name) for c in configs]
        if any(v is missing for v in values):
            return (
                f"the published protocol records do not state {key}, so trial 0 cannot be "
                "checked against them"
            )
        if any(not same(v, values[0]) for v in values):
            shown = ", ".join(sorted({repr(v) for v in values}))
            return (
                f"the published protocol records disagree on {key} ({shown}), so trial 0 "
                "cannot be checked against them; re-publish the protocol rows"
            )
        if values and not same(values[0], value):
            return (
                f"its trial 0 sets {key}={value!r}, the published protocol records "
                f"{values[0]!r}: trial 0 must be the protocol's settings (tune with the "
                "protocol's config)"
            )
    return None


def study_finished(summary: dict[str, Any]) -> bool:
    """Whether a (checked) study ran its budget and selected a trial."""
    counted = sum(t.get("state") in COUNTED for t in summary["trials"])
    return summary["selected"] is not None and counted == summary["trials_budget"]


def _read_summaries(roots: list[Path]) -> tuple[dict[tuple[str, str], list[dict]], list[str]]:
    """Every study summary under the roots' ``tuning/``, checked, per (system, model);
    and a line per root with none yet. A summary that cannot be read or checked
    (:func:`study_problem`), or a study given twice, is ``SystemExit`` naming it."""
    from hnnbench._contracts.names import name_problem
    from hnnbench._record.store import parse_file
    from hnnbench._results.report.convergence import summary_problem

    found: dict[tuple[str, str], list[dict]] = {}
    waiting = []
    for root in roots:
        if not (root / "tuning").is_dir():
            waiting.append(f"{root}: no study summary yet (no tuning/ folder); not staged")
            continue
        for path in sorted((root / "tuning").glob("*/*.json")):
            system, model = path.parent.name, path.name.split(".")[0]
            data = parse_file(path)
            problem = (
                data
                if isinstance(data, str)
                else name_problem("system", system)
                or name_problem("model", model)
                or study_problem(data, system, model)
                or summary_problem(data)  # what the pages read of it
            )
            if problem:
                raise SystemExit(f"publish: {path}: {problem}; nothing was staged")
            assert isinstance(data, dict)
            data["path"] = str(path)
            data["final"] = str(root / "final" / system / model)
            pair = found.setdefault((system, model), [])
            twin = next((d["path"] for d in pair if d["study"] == data["study"]), None)
            if twin is not None:
                raise SystemExit(
                    f"publish: {path}: study {data['study']} is also in {twin}; give one "
                    "out= folder per study; nothing was staged"
                )
            pair.append(data)
    return found, waiting


def tuned_parts(
    roots: list[Path],
    protocol_seeds: dict[tuple[str, str], set[int]],
    protocol_configs: dict[tuple[str, str], list[dict[str, Any]]] | None = None,
) -> tuple[list[tuple[str, str, list[dict], list[Path]]], list[str]]:
    """The finished pairs under the tuners' ``out=`` roots: one ``(system, model,
    summaries, final directories)`` per pair (a directory per ``out=`` root its studies
    sit in) whose studies (one per fold on a measured
    system) all ran their budget, together cover the final seeds of the pair's published
    protocol records (``protocol_seeds``), and whose final runs are all written; and one
    line per pair (or root) left waiting, saying why. A study whose trial 0 is not the
    settings of the pair's published protocol records (``protocol_configs``, where
    given) is ``SystemExit``."""
    found, waiting = _read_summaries(roots)
    parts = []
    for (system, model), summaries in sorted(found.items()):
        where = f"{system}/{model}"
        for summary in summaries:
            problem = protocol_settings_problem(
                summary, (protocol_configs or {}).get((system, model), [])
            )
            if problem:
                raise SystemExit(f"publish: {summary['path']}: {problem}; nothing was staged")
        # A measured system's fold studies may run side by side, each in an out= folder
        # of its own (a folder takes one tuner at a time): each study's final runs are
        # read from its own folder.
        finals = sorted({Path(s["final"]) for s in summaries})
        covered = {seed for s in summaries for seed in s["final_seeds"]}
        wanted = protocol_seeds.get((system, model), set())
        unfinished = [s for s in summaries if not study_finished(s)]
        written = {
            seed
            for s in summaries
            for seed in s["final_seeds"]
            if (Path(s["final"]) / f"seed{seed}" / "result.json").is_file()
        }
        if any(t.get("status") == "skipped" for s in unfinished for t in s["trials"]):
            waiting.append(
                f"{where}: skipped by the tuner (it does not run there); nothing to stage"
            )
        elif unfinished:
            s = unfinished[0]
            done = sum(t.get("state") in COUNTED for t in s["trials"])
            waiting.append(
                f"{where}: study {s['study']} has {done} of {s['trials_budget']} trials; not staged"
            )
        elif not wanted:
            waiting.append(f"{where}: no published protocol record to pair it with; not staged")
        elif not wanted <= covered:
            waiting.append(
                f"{where}: its studies cover final seeds {sorted(covered)} of the "
                f"protocol's {sorted(wanted)} (a measured system's fold studies end one by "
                "one); not staged"
            )
        elif written != covered:
            waiting.append(
                f"{where}: the final runs of seeds {sorted(covered - written)} are not "
                f"written yet (in {', '.join(map(str, finals))}); not staged"
            )
        else:
            parts.append((system, model, summaries, finals))
    return parts, waiting


def part_records(system: str, model: str, summaries: list[dict], finals: list[Path]) -> list[dict]:
    """The final records of one finished pair (:func:`given_records`: strict, paper,
    no variant, in its studies' ``finals`` folders; a job in two of them is refused), each
    a tuned record of one of its studies, with that study's selected settings, on exactly
    the studies' final seeds; ``SystemExit`` naming what differs."""
    from hnnbench._record.tracks import track_of

    recs = given_records(finals)
    by_study = {s["study"]: s for s in summaries}
    for rec in recs:
        study = by_study.get(str((rec.get("tuning") or {}).get("study")))
        why = (
            f"it is {rec['system']}/{rec['model']}"
            if (rec["system"], rec["model"]) != (system, model)
            else f"its track is {track_of(rec)}, not tuned"
            if track_of(rec) != "tuned"
            else "it names no study of the summaries given"
            if study is None
            else "its settings are not its study's selection"
            if rec["tuning"].get("selected") != study["selected"]["settings"]
            else f"seed {rec['seed']} is not a final seed of its study"
            if rec["seed"] not in study["final_seeds"]
            else None
        )
        if why:
            raise SystemExit(f"publish: {rec['path']}: {why}; nothing was staged")
    return recs


def _published() -> list[dict]:
    from hnnbench import _record as records

    return records.load(RECORDS).records if RECORDS.is_dir() else []


def _refuse_unequal_budgets(recs: list[dict], what: str) -> None:
    """``SystemExit`` (one line) where ``recs`` (a system's tuned records, staged and
    published together) hold unequal budgets (``validity.budget_problems``)."""
    from hnnbench._results import validity

    problems = validity.budget_problems(recs)
    if problems:
        raise SystemExit(
            f"publish: {problems[0].line()}; a system's studies share one budget: tune the "
            f"pair again with the others' trials, steps and seeds per trial; nothing was {what}"
        )


def stage_tuned(roots: list[Path]) -> tuple[list[str], list[str]]:
    """Stage every finished pair under ``roots`` (:func:`tuned_parts`): its final
    records, figure rollout and summaries into results/staged, in one all-or-nothing
    step (a pair staged again replaces its staged records and summaries); refused where
    its budget differs from its system's other staged or published studies. Returns the
    pairs staged (``system/model``) and the lines of those left waiting."""
    from hnnbench import _record as records
    from hnnbench._contracts.paths import safe_join
    from hnnbench._record.tracks import track_of

    published = _published()
    seeds: dict[tuple[str, str], set[int]] = {}
    configs: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in published:
        if track_of(r) == "protocol":
            seeds.setdefault((r["system"], r["model"]), set()).add(r["seed"])
            configs.setdefault((r["system"], r["model"]), []).append(r.get("config") or {})
    parts, waiting = tuned_parts(roots, seeds, configs)
    if not parts:
        return [], waiting
    recs = [r for system, model, s, dirs in parts for r in part_records(system, model, s, dirs)]
    pairs = {(system, model) for system, model, _, _ in parts}
    before = given_records([STAGED]) if STAGED.is_dir() else []
    kept = [r for r in before if (r["system"], r["model"]) not in pairs]
    systems = {system for system, _ in pairs}
    others = [
        r
        for r in published
        if track_of(r) == "tuned"
        and r["system"] in systems
        and (r["system"], r["model"]) not in pairs
    ]
    _refuse_unequal_budgets([*recs, *kept, *others], "staged")
    given = {job_of(r) for r in recs}
    superseded = {
        job_of(r) for r in before if (r["system"], r["model"]) in pairs and job_of(r) not in given
    }

    def summaries(stage: Path) -> None:
        for system, model, studies, _ in parts:
            folder = safe_join(stage, system, model)
            for old in folder.glob("*.json"):
                old.unlink()
            for study in studies:
                body = {k: v for k, v in study.items() if k not in ("path", "final")}
                text = json.dumps(body, indent=2) + "\n"
                records.atomic_write_text(
                    safe_join(folder, summary_name(model, study["fold"])), text
                )

    finals = sorted({final for _, _, _, dirs in parts for final in dirs})
    stage_and_publish([*finals, STAGED], [*recs, *kept], superseded, STAGED, summaries)
    return sorted(f"{s}/{m}" for s, m in pairs), waiting


def protocol_families(recs: list[dict]) -> dict[str, dict[str, set[str]]]:
    """Per system, each family the protocol track ran there (ranked, not the oracle,
    not skipped) with its models: what a tuned system must hold."""
    from hnnbench._record.tracks import track_of

    ran: dict[str, dict[str, set[str]]] = {}
    for r in recs:
        if (
            track_of(r) == "protocol"
            and r.get("ranked", True)
            and r["model"] != "oracle"
            and r.get("status") != "skipped"
        ):
            ran.setdefault(r["system"], {}).setdefault(str(r["family"]), set()).add(r["model"])
    return ran


def tuned_families(recs: list[dict]) -> dict[str, set[str]]:
    """Per system, the families of its tuned records among ``recs``."""
    from hnnbench._record.tracks import track_of

    out: dict[str, set[str]] = {}
    for r in recs:
        if track_of(r) == "tuned":
            out.setdefault(r["system"], set()).add(str(r["family"]))
    return out


def incomplete_tuned(recs: list[dict]) -> list[str]:
    """One line per system of ``recs`` whose tuned records lack a family its protocol
    records ran (:func:`protocol_families`)."""
    ran = protocol_families(recs)
    return [
        f"{system}: tuned {', '.join(sorted(fams))}; its protocol ran "
        f"{', '.join(sorted(ran.get(system, {})))}"
        for system, fams in sorted(tuned_families(recs).items())
        if not set(ran.get(system, {})) <= fams
    ]


def staged_families() -> dict[str, set[str]]:
    """Per system in results/staged, the families of its staged studies."""
    from hnnbench import _record as records

    return tuned_families(records.load(STAGED).records if STAGED.is_dir() else [])


def publish_complete_systems() -> list[str]:
    """Publish every staged system whose staged studies, with its published tuned ones,
    cover every family its protocol ran: its staged records into results/records
    (replacing its published tuned ones of the same models) in one all-or-nothing
    publication, then its summaries into results/tuning, then its staged folder
    removed. Run again after a crash between these steps, it publishes the same records
    again and finishes. Returns those systems."""
    import os
    import shutil
    import tempfile

    from hnnbench import _record as records
    from hnnbench._contracts.paths import safe_join

    published = _published()
    ran = protocol_families(published)
    tuned = tuned_families(published)
    complete = [
        system
        for system, families in sorted(staged_families().items())
        if system in ran and set(ran[system]) <= families | tuned.get(system, set())
    ]
    if not complete:
        return []
    dirs = [STAGED / system for system in complete]
    staged = given_records(dirs)
    jobs = {job_of(r) for r in staged}
    restaged = {(r["system"], r["model"]) for r in staged}
    kept = [r for r in given_records([RECORDS]) if job_of(r) not in jobs]
    for system in complete:
        _refuse_unequal_budgets([r for r in [*staged, *kept] if r["system"] == system], "published")
    old = {job for job in published_jobs() if job[0] == "tuned" and (job[1], job[2]) in restaged}
    stage_and_publish([*dirs, RECORDS], [*staged, *kept], old - jobs)
    for system, model in sorted(restaged):
        target = safe_join(STUDIES, system)
        target.mkdir(parents=True, exist_ok=True)
        new = sorted(safe_join(STAGED, system, model).glob("*.json"))
        for stale in [*target.glob(f"{model}.json"), *target.glob(f"{model}.fold*.json")]:
            if stale.name not in {p.name for p in new}:
                stale.unlink()
        for path in new:
            records.atomic_write_text(safe_join(target, path.name), path.read_text())
    trash = Path(tempfile.mkdtemp(prefix=".staged-", dir=RESULTS))
    try:
        for directory in dirs:
            os.replace(directory, trash / directory.name)
    finally:
        shutil.rmtree(trash, ignore_errors=True)
    if STAGED.is_dir() and not any(STAGED.iterdir()):
        STAGED.rmdir()
    return complete


def staged_lines() -> list[str]:
    """One line per system with staged studies: its families in, and those to come."""
    from hnnbench._results.report.markdown import md_code

    ran = protocol_families(_published())
    lines = []
    for system, families in sorted(staged_families().items()):
        wanted = set(ran.get(system, {}))
        lines.append(
            f"- Tuned track, staged (not published until every family's study is in): "
            f"{md_code(system)} has {', '.join(sorted(families))} "
            f"({len(families & wanted)} of {len(wanted)} families)"
        )
    return lines


def publish_tuned(roots: list[Path], figure: str) -> int:
    """``--tuned``: stage the finished studies, publish the complete systems, rebuild
    the pages (their staged listing) when anything moved; one JSON line of what did."""
    staged, waiting = stage_tuned(roots)
    for line in waiting:
        print(f"publish: {line}", file=sys.stderr)
    published = publish_complete_systems()
    summary: dict[str, Any] = {}
    if staged or published:
        status, summary = write_pages(figure)
        if status:
            return status
    print(json.dumps({"staged": staged, "published_tuned": published, **summary}))
    return 0


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
    parser.add_argument(
        "--tuned",
        type=Path,
        action="extend",
        nargs="+",
        default=[],
        metavar="OUT",
        help="the out= folders of `hnnbench tune` runs (one per study, e.g. "
        "ROOT/*/* of scripts/maintainer/tune_sweep.sh): stage each "
        "finished study (results/staged, results/tuning), then publish every system "
        "whose staged studies cover every family its protocol ran",
    )
    args = parser.parse_args(argv)
    if args.tuned:
        if args.sweeps or args.replace or args.withdraw or args.pages_only:
            parser.error("--tuned takes no sweeps, no --replace, --withdraw or --pages-only")
        return publish_tuned(args.tuned, args.figure)
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
    entering = sorted(job for job in given - published_jobs() if job[0] == "tuned")
    if entering:
        print(
            f"publish: {entering[0]} is a tuned run not yet published: tuned rows enter with "
            "--tuned OUT (the tuner's out= folder), which checks them against their "
            "studies' summaries and publishes a system once every family's study is in",
            file=sys.stderr,
        )
        return 2
    kept = [r for r in recs if job_of(r) not in superseded]
    for line in incomplete_tuned(kept):
        print(
            f"publish: {line}: a tuned system is published with every family the protocol "
            "ran there; publish its studies with --tuned, which stages them until then",
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
    sweeps: list[Path],
    recs: list[dict],
    superseded: set[tuple[str, str, str, int]],
    target: Path | None = None,
    extra: Callable[[Path], None] | None = None,
) -> tuple[int, int, int, int]:
    """All or nothing: the new results/records (or ``target``, a tree of its layout) is
    built in a staging directory beside it (a copy of the published records, the given
    records copied in, the superseded ones removed, the figure rollouts of the records
    kept written, ``extra`` applied to it), loaded back strictly, and only then moved
    into place; any failure leaves it as it was. Returns (records copied, records
    removed, figure rollouts, their bytes)."""
    import os
    import shutil
    import tempfile

    from hnnbench import _record as records

    target = RECORDS if target is None else target
    RESULTS.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".publish-", dir=RESULTS))
    try:
        stage = staging / "records"
        if target.is_dir():
            shutil.copytree(target, stage, symlinks=True)
        else:
            stage.mkdir()
        copied = copy_records(sweeps, recs, root=stage)
        removed = remove_jobs(superseded, root=stage)
        kept = [r for r in recs if job_of(r) not in superseded]
        rollouts, rollout_bytes = copy_figure_rollouts(kept, root=stage)
        if extra is not None:
            extra(stage)
        staged, bad = records.load(stage, strict=True)
        if bad:
            raise SystemExit(
                f"publish: a staged record does not load: {bad[0]}; nothing was published"
            )
        published_jobs(stage)
        old = staging / "old"
        if target.exists():
            os.replace(target, old)
        os.replace(stage, target)
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
        studies = STUDIES if any(STUDIES.glob("*/*.json")) else None
        report = write_report([RECORDS], RESULTS, tuning=studies)
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
    for line in protocol_lines(report.records) + partial_lines(published) + staged_lines():
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
