"""``hnnbench check --format text|json|junit|markdown [--output FILE]``: the check's
report for people (text, today's output), for programs (JSON, a stable structure), for CI
dashboards (JUnit XML) and for a pull request or a job summary (Markdown) (docs/CI.md).

Every format says the same things and the exit status is the same in every one: 0 when
nothing regressed, 1 on a regression (bad input exits 2 with one line on stderr, and no
report is written).
"""

from __future__ import annotations

import json
import math
import socket
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional
from xml.etree import ElementTree as ET

from hnnbench._results.check.findings import CheckError, CheckResult, Finding, update_hint
from hnnbench._results.check.ranks import Rank, Ranking
from hnnbench._results.check.rerun import RERUN_HEADERS, Rerun

__all__ = ["FORMATS", "JSON_FORMAT", "JSON_VERSION", "CheckReport", "emit", "render"]

FORMATS = ("text", "json", "junit", "markdown")
#: The JSON report's ``format`` and ``version`` (bumped when a key changes meaning or
#: goes; a new key does not bump it).
JSON_FORMAT, JSON_VERSION = "hnnbench-check", 1
#: Findings that are a gated metric value (a testcase of their own in JUnit).
_GATE_CHECKS = ("metric", "changed")
#: A ``--rerun`` row's keys in JSON.
_RERUN_KEYS = [*RERUN_HEADERS[:-1], "result"]
#: What a finding's fields mean where they hold nothing.
_NONE = ("", "-")


@dataclass
class CheckReport:
    """Everything one ``hnnbench check`` found, as the formats render it."""

    dirs: Sequence[str]
    reference: str
    rules: Optional[str]  # the --rules file (None: the declared rules)
    same: Optional[float]  # --same RTOL
    allow_missing: bool
    n_records: int
    n_reruns: int
    result: CheckResult
    reruns: Sequence[Rerun]
    ranking: Ranking
    exit_status: int

    @property
    def passed(self) -> bool:
        return self.exit_status == 0

    def hint(self) -> str:
        """What to do about the regressions (empty when there are none)."""
        if self.passed:
            return ""
        return update_hint(self.result, Path(self.reference)).strip()

    def verdict(self) -> str:
        n = len(self.result.regressions)
        if self.passed:
            return "OK, no regressions"
        return f"FAILED, {n} regression(s)"


def _or_none(value: str) -> Optional[str]:
    return None if value in _NONE else value


def _number(value: float) -> Optional[float]:
    """A float as JSON holds it: ``None`` for NaN (no value); infinities as the
    record format writes them would not parse in strict JSON, so as ``None`` too (the
    rank's line says ``inf``)."""
    return None if value is None or not math.isfinite(value) else float(value)


def _finding(f: Finding, severity: str) -> dict[str, Any]:
    return {
        "severity": severity,
        "check": f.check,
        "system": _or_none(f.system),
        "model": _or_none(f.model),
        "metric": _or_none(f.metric),
        "values": {
            "reference": _or_none(f.reference),
            "current": _or_none(f.current),
            "factor": _or_none(f.factor),
        },
        "rule": _or_none(f.limit),
    }


def _rank(r: Rank) -> dict[str, Any]:
    return {
        "family": r.name,
        "system": r.system,
        "metric": r.metric,
        "rank": r.rank,
        "of": r.of,
        "interval": None if r.low is None else [r.low, r.high],
        "basis": r.basis,
        "against": list(r.against),
        "n_seeds": r.n_seeds,
        "mean": _number(r.mean),
        "mean_text": r.value_text,
        "ci": None if math.isnan(r.ci_low) else [_number(r.ci_low), _number(r.ci_high)],
        "leader_test": r.leader_test or None,
        "line": r.line,
    }


def _gate_failed(report: CheckReport) -> set[tuple[str, str, str]]:
    return {
        (f.system, f.model, f.metric) for f in report.result.regressions if f.check in _GATE_CHECKS
    }


def to_json(report: CheckReport) -> dict[str, Any]:
    """The JSON report (docs/CI.md, "The JSON report", documents every key)."""
    from importlib import metadata

    result = report.result
    failed = _gate_failed(report)
    return {
        "format": JSON_FORMAT,
        "version": JSON_VERSION,
        "hnnbench": metadata.version("hnnbench"),
        "status": "ok" if report.passed else "failed",
        "exit_status": report.exit_status,
        "dirs": list(report.dirs),
        "reference": report.reference,
        "rules": {"file": report.rules, "same": report.same},
        "allow_missing": report.allow_missing,
        "counts": {
            "records": report.n_records,
            "pairs": result.n_pairs,
            "gated_values": result.n_metrics,
            "claims": result.n_claims,
            "reruns": report.n_reruns,
            "regressions": len(result.regressions),
            "information": len(result.info),
        },
        "gates": [
            {"system": s, "model": m, "metric": k, "passed": (s, m, k) not in failed}
            for s, m, k in result.gated
        ],
        "findings": [_finding(f, "regression") for f in result.regressions]
        + [_finding(f, "information") for f in result.info],
        "ranks": [_rank(r) for r in report.ranking.ranks],
        "rank_notes": list(report.ranking.notes),
        "verdicts": [
            {"family": name, "line": line} for name, line in report.ranking.verdicts.items()
        ],
        "unranked": [
            {"family": name, "reason": line}
            for name, lines in report.ranking.reasons.items()
            for line in lines
        ],
        "reruns": [
            {
                "spec": done.spec,
                "rows": [dict(zip(_RERUN_KEYS, row, strict=False)) for row in done.rows],
            }
            for done in report.reruns
        ],
        "verdict": report.verdict(),
        "hint": report.hint() or None,
    }


# --------------------------------------------------------------------------- JUnit


def _finding_text(f: Finding) -> str:
    what = " ".join(p for p in (f.system, f.model, f.metric) if p not in _NONE)
    parts = [
        f"{f.check}: {what}",
        f"reference: {f.reference}" if f.reference not in _NONE else "",
        f"current: {f.current}" if f.current not in _NONE else "",
        f.factor,
        f"rule: {f.limit}" if f.limit else "",
    ]
    return "; ".join(p for p in parts if p)


def _suite_of(f: Finding) -> str:
    return f.system if f.system not in _NONE else "records"


def junit(report: CheckReport) -> str:
    """JUnit XML (the Ant/Jenkins ``testsuites`` form that CI dashboards read): a
    testsuite ``hnnbench check`` with one testcase, the verdict; then one testsuite per
    system with a testcase per gated (model, metric) value, one per other regression
    (a failure each), one per reference pair left out with ``--allow-missing``
    (skipped), and the ranks and other information as its ``system-out``. Findings of
    no system (unreadable records) go to a testsuite ``records``."""
    result = report.result
    failed = _gate_failed(report)
    suites: dict[str, list[ET.Element]] = {}
    out: dict[str, list[str]] = {}

    def case(suite: str, name: str) -> ET.Element:
        element = ET.Element(
            "testcase", {"classname": f"hnnbench.check.{suite}", "name": name, "time": "0"}
        )
        suites.setdefault(suite, []).append(element)
        return element

    for system, model, metric in result.gated:
        element = case(system, f"{model} {metric}")
        if (system, model, metric) in failed:
            f = next(
                f
                for f in result.regressions
                if f.check in _GATE_CHECKS
                and (f.system, f.model, f.metric) == (system, model, metric)
            )
            ET.SubElement(
                element, "failure", {"message": _finding_text(f), "type": f.check}
            ).text = _finding_text(f)
    for f in result.regressions:
        if f.check in _GATE_CHECKS and (f.system, f.model, f.metric) in set(result.gated):
            continue
        name = " ".join(p for p in (f.check, f.model, f.metric) if p not in _NONE)
        element = case(_suite_of(f), name)
        ET.SubElement(
            element, "failure", {"message": _finding_text(f), "type": f.check}
        ).text = _finding_text(f)
    for f in result.info:
        if f.check == "missing":
            element = case(_suite_of(f), f"missing {f.model}")
            ET.SubElement(element, "skipped", {"message": _finding_text(f)})
        else:
            out.setdefault(_suite_of(f), []).append(_finding_text(f))
    for note in report.ranking.notes:
        out.setdefault(note.split(":", 1)[0], []).append(note)
    for r in report.ranking.ranks:
        out.setdefault(r.system, []).append(r.line)
    summary_out = [report.verdict()]
    summary_out += [line for lines in report.ranking.reasons.values() for line in lines]
    summary_out += list(report.ranking.verdicts.values())

    root = ET.Element("testsuites", {"name": "hnnbench check"})
    summary = ET.SubElement(root, "testsuite", {"name": "hnnbench check"})
    verdict = ET.SubElement(
        summary,
        "testcase",
        {
            "classname": "hnnbench.check",
            "name": f"{' '.join(report.dirs)} vs {report.reference}",
            "time": "0",
        },
    )
    if not report.passed:
        message = f"{report.verdict()}. {report.hint()}".strip()
        ET.SubElement(verdict, "failure", {"message": message, "type": "regression"}).text = message
    ET.SubElement(summary, "system-out").text = "\n".join(summary_out)
    _counts(summary)
    for name in list(suites) + [s for s in out if s not in suites]:
        suite = ET.SubElement(root, "testsuite", {"name": name})
        for element in suites.get(name, []):
            suite.append(element)
        if out.get(name):
            ET.SubElement(suite, "system-out").text = "\n".join(out[name])
        _counts(suite)
    tests = failures = skipped = 0
    for suite in root:
        tests += int(suite.get("tests", "0"))
        failures += int(suite.get("failures", "0"))
        skipped += int(suite.get("skipped", "0"))
    root.set("tests", str(tests))
    root.set("failures", str(failures))
    root.set("errors", "0")
    root.set("skipped", str(skipped))
    root.set("time", "0")
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _counts(suite: ET.Element) -> None:
    """A testsuite's attributes: its counts (in the order the schemas list them), and
    where it ran."""
    cases = suite.findall("testcase")
    attributes = {
        "name": suite.get("name", ""),
        "tests": str(len(cases)),
        "failures": str(sum(c.find("failure") is not None for c in cases)),
        "errors": "0",
        "skipped": str(sum(c.find("skipped") is not None for c in cases)),
        "time": "0",
        "hostname": socket.gethostname() or "localhost",
    }
    suite.attrib.clear()
    suite.attrib.update(attributes)
    # the schemas want the testcases before system-out
    children = sorted(suite, key=lambda e: e.tag == "system-out")
    for child in list(suite):
        suite.remove(child)
    suite.extend(children)


# --------------------------------------------------------------------------- Markdown


def markdown(report: CheckReport) -> str:
    """A summary for a pull-request comment or a job summary: the verdict, the counts,
    the regressions as a table, the ranks, and the information in a collapsed block;
    every cell and line escaped (:mod:`hnnbench._results.report.markdown`)."""
    from hnnbench._results.report.markdown import md_cell, md_code, md_text

    result = report.result
    icon = "\u2705" if report.passed else "\u274c"
    lines = [
        f"### {icon} hnnbench check: {md_text(report.verdict())}",
        "",
        f"{md_code(' '.join(report.dirs))} against {md_code(report.reference)}: "
        f"{report.n_records} record(s) validated, {result.n_pairs} pair(s) compared, "
        f"{result.n_metrics} gated value(s), {result.n_claims} claim(s)"
        + (f", {report.n_reruns} job(s) re-run" if report.n_reruns else "")
        + ".",
    ]

    def table(headers: list[str], rows: list[list[str]]) -> list[str]:
        return [
            "",
            "| " + " | ".join(md_cell(h) for h in headers) + " |",
            "|" + "---|" * len(headers),
            *("| " + " | ".join(md_cell(c) for c in row) + " |" for row in rows),
        ]

    headers = ["check", "system", "model", "metric", "reference", "current", "factor", "rule"]

    def row(f: Finding) -> list[str]:
        return [f.check, f.system, f.model, f.metric, f.reference, f.current, f.factor, f.limit]

    if result.regressions:
        lines += ["", f"**Regressions ({len(result.regressions)})**"]
        lines += table(headers, [row(f) for f in result.regressions])
        if report.hint():
            lines += ["", md_text(report.hint())]
    ranking = report.ranking
    if ranking.ranks or ranking.reasons:
        lines += ["", "**Ranks** (headline metrics; 95% intervals over seeds)"]
        if ranking.ranks:
            lines += table(
                [
                    "family",
                    "system",
                    "metric",
                    "rank",
                    "interval",
                    "against",
                    "value",
                    "leader test",
                ],
                [
                    [
                        r.name,
                        r.system,
                        r.metric,
                        f"{r.rank} of {r.of}",
                        "—"
                        if r.low is None
                        else f"[{r.low}, {r.high}]".replace(f"[{r.low}, {r.low}]", f"[{r.low}]"),
                        "the reference's families"
                        if r.basis == "reference"
                        else "beside it: " + ", ".join(r.against),
                        f"{r.value_text} over {r.n_seeds} seed(s)",
                        r.leader_test or "—",
                    ]
                    for r in ranking.ranks
                ],
            )
        lines += [""] + [
            f"- {md_text(line)}" for lines_ in ranking.reasons.values() for line in lines_
        ]
        lines += [f"- {md_text(line)}" for line in ranking.verdicts.values()]
    for done in report.reruns:
        lines += ["", f"**--rerun {md_text(done.spec)}** (record vs re-run)"]
        lines += table(_RERUN_KEYS, [list(r) for r in done.rows])
    if result.info:
        lines += ["", f"<details><summary>Information, not failing ({len(result.info)})</summary>"]
        lines += table(headers, [row(f) for f in result.info])
        lines += ["", "</details>"]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- output


def render(report: CheckReport, fmt: str, text: str) -> str:
    """``report`` in ``fmt`` (``text``: the text already printed, as is)."""
    if fmt == "json":
        return json.dumps(to_json(report), indent=2, allow_nan=False) + "\n"
    if fmt == "junit":
        return junit(report)
    if fmt == "markdown":
        return markdown(report)
    return text


def emit(report: CheckReport, fmt: str, output: Optional[str], text: str) -> None:
    """Write the report: to ``output`` (and the text to stdout), else to stdout (the
    text was printed already where ``fmt`` is text and there is no ``output``)."""
    from hnnbench._record.store import atomic_write_text

    if output is None:
        if fmt != "text":
            print(render(report, fmt, text), end="")
        return
    path = Path(output)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, render(report, fmt, text))
    except OSError as err:
        raise CheckError(f"Cannot write --output {output}: {err.strerror or err}") from None
    print(text, end="")
    print(f"hnnbench check: wrote the {fmt} report to {output}")
