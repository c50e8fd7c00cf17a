"""``hnnbench check --format text|json|junit|markdown [--output FILE]`` (docs/CI.md): one
check, four reports that say the same, the same exit status in each; the JUnit report
validated against a JUnit XSD (tests/schemas/junit.xsd) and read by a JUnit parser."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from conftest import REPO, assert_one_line_error, hnnbench
from report_fixtures import make_sweep, scale_metric

from hnnbench._results import check
from hnnbench._results.check.output import FORMATS, CheckReport, markdown
from hnnbench._results.check.ranks import Ranking

JUNIT_XSD = REPO / "tests" / "schemas" / "junit.xsd"


@pytest.fixture()
def sweeps(tmp_path):
    """A reference written from a sweep; the same sweep (passes) and a copy with one
    metric 100x worse (fails)."""
    sweep = make_sweep(tmp_path / "ref", rollout=False)
    reference = tmp_path / "reference.csv"
    assert check.main([str(sweep), "--reference", str(reference), "--update"]) == 0
    worse = shutil.copytree(sweep, tmp_path / "worse")
    scale_metric(worse, "pendulum", "mlp_torch", "rollout_mse", 100.0)
    return sweep, worse, reference


def _report(sweep: Path, reference: Path, fmt: str, out: Path, *extra: str) -> tuple[int, str]:
    status = check.main(
        [str(sweep), "--reference", str(reference), "--format", fmt, "--output", str(out), *extra]
    )
    return status, out.read_text()


def test_every_format_gives_the_same_exit_status(sweeps, tmp_path, capsys):
    good, worse, reference = sweeps
    for sweep, want in ((good, 0), (worse, 1)):
        assert check.main([str(sweep), "--reference", str(reference)]) == want
        text = capsys.readouterr().out
        for fmt in FORMATS:
            status, written = _report(sweep, reference, fmt, tmp_path / f"{sweep.name}.{fmt}")
            assert status == want, fmt
            # with --output the text still goes to stdout, and the file holds the format
            shown = capsys.readouterr().out
            assert shown.startswith(text) and f"wrote the {fmt} report to" in shown
            if fmt == "text":
                assert written == text


def test_json_holds_the_status_the_findings_and_the_gates(sweeps, tmp_path, capsys):
    _, worse, reference = sweeps
    capsys.readouterr()
    assert check.main([str(worse), "--reference", str(reference), "--format", "json"]) == 1
    data = json.loads(capsys.readouterr().out)  # stdout is the JSON alone
    assert (data["format"], data["version"]) == ("hnnbench-check", 1)
    assert (data["status"], data["exit_status"]) == ("failed", 1)
    assert data["counts"]["gated_values"] == len(data["gates"]) > 0
    assert data["counts"]["regressions"] == 1
    (failed,) = [g for g in data["gates"] if not g["passed"]]
    assert failed == {
        "system": "pendulum",
        "model": "mlp_torch",
        "metric": "rollout_mse",
        "passed": False,
    }
    (finding,) = [f for f in data["findings"] if f["severity"] == "regression"]
    assert finding["check"] == "metric" and finding["metric"] == "rollout_mse"
    assert finding["values"]["factor"] == "100x worse" and finding["rule"] == "<= ref x 3"
    assert data["hint"] and "--update" in data["hint"]
    assert data["verdict"] == "FAILED, 1 regression(s)"


def test_junit_validates_against_the_schema_and_reads_as_junit(sweeps, tmp_path):
    import junitparser
    import xmlschema

    schema = xmlschema.XMLSchema(str(JUNIT_XSD))
    good, worse, reference = sweeps
    for sweep, failures in ((good, 0), (worse, 2)):  # the gate and the verdict
        _, written = _report(sweep, reference, "junit", tmp_path / f"{sweep.name}.xml")
        schema.validate(str(tmp_path / f"{sweep.name}.xml"))
        xml = junitparser.JUnitXml.fromfile(str(tmp_path / f"{sweep.name}.xml"))
        suites = {suite.name: suite for suite in xml}
        assert {"hnnbench check", "spring", "pendulum"} <= set(suites)
        assert sum(suite.failures for suite in xml) == failures
        cases = {case.name: case for case in suites["pendulum"]}
        gate = cases["mlp_torch rollout_mse"]
        if failures:
            (problem,) = gate.result
            assert isinstance(problem, junitparser.Failure)
            assert "100x worse" in problem.message and "<= ref x 3" in problem.message
        else:
            assert gate.is_passed
        assert len(written) < 200_000


def test_markdown_escapes_every_cell(tmp_path):
    """A value from a record that holds a pipe, a backtick or a tag stays in its cell."""
    bad = "a|b `code` <script>"
    result = check.CheckResult(
        regressions=[check.Finding("metric", "energy_mse", "spring", "m", "1", bad, "2x worse")],
    )
    report = CheckReport(["runs/x|y"], "ref.csv", None, None, False, 1, 0, result, [], Ranking(), 1)
    text = markdown(report)
    row = next(line for line in text.splitlines() if line.startswith("| metric "))
    assert row.count("|") == 9  # 8 cells
    assert "&#124;" in row and "<script>" not in text and "&lt;script>" in row
    assert text.startswith("### \u274c hnnbench check: FAILED, 1 regression(s)")


def test_update_takes_no_format_and_a_bad_format_is_one_line(sweeps, tmp_path):
    good, _, reference = sweeps
    with pytest.raises(check.CheckError, match="--update writes a reference"):
        check.main([str(good), "--reference", str(reference), "--update", "--format", "json"])
    proc = hnnbench("check", str(good), "--reference", str(reference), "--format", "xml")
    assert proc.returncode == 2
    assert_one_line_error(proc, "--format", "junit")


def test_the_console_script_writes_junit_and_keeps_the_exit_status(sweeps, tmp_path):
    _, worse, reference = sweeps
    out = tmp_path / "reports" / "check.xml"
    proc = hnnbench(
        "check",
        str(worse),
        "--reference",
        str(reference),
        "--format",
        "junit",
        "--output",
        str(out),
    )
    assert proc.returncode == 1, proc.stderr
    assert "REGRESSIONS (1)" in proc.stdout and out.is_file()
    import xmlschema

    xmlschema.XMLSchema(str(JUNIT_XSD)).validate(str(out))
