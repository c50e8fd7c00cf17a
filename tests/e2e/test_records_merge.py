"""Records as a published format: strict JSON checked against the JSON Schema, several
directories merged into one leaderboard, invalid records named (report) or failed
(check)."""

from __future__ import annotations

import json

from conftest import assert_one_line_error, hnnbench
from report_fixtures import make_sweep

from hnnbench import _record as records


def _reject_constant(name: str) -> None:
    raise AssertionError(f"non-strict JSON constant {name}")


def test_every_fixture_record_is_valid_and_strict_json(tmp_path):
    sweep = make_sweep(tmp_path / "s")
    for path in sweep.rglob("result.json"):
        json.loads(path.read_text(), parse_constant=_reject_constant)  # NaN/Infinity
        assert records.validate(records.read_record(path)) == [], path


def test_schema_names_what_is_wrong(tmp_path):
    sweep = make_sweep(tmp_path / "s", pairs=(("spring", "hnn_torch"),), seeds=(0,))
    (path,) = sweep.rglob("result.json")
    rec = records.read_record(path)
    rec.pop("seed")
    rec["status"] = "finished"
    problems = records.validate(rec)
    assert any("'seed' is a required property" in p for p in problems)
    assert any(p.startswith("status:") for p in problems)


def test_two_sweeps_merge_and_a_record_missing_a_field_is_rejected_in_one_line(tmp_path):
    a = make_sweep(tmp_path / "a", pairs=(("spring", "mlp_torch"), ("spring", "hnn_torch")))
    b = make_sweep(tmp_path / "b", pairs=(("pendulum", "mlp_torch"), ("pendulum", "hnn_torch")))
    out = tmp_path / "merged"
    proc = hnnbench("report", str(a), str(b), "--out", str(out), "--no-figures")
    assert proc.returncode == 0, proc.stderr
    board = (out / "leaderboard.csv").read_text().splitlines()
    assert len(board) == 1 + 4 and "git_commits" in board[0]
    page = (out / "leaderboard.html").read_text()
    assert '<h2 id="provenance">Provenance</h2>' in page and str(a) in page and str(b) in page

    # a submitted record without its seed: left out and named (report), failed (check)
    (victim,) = (b / "pendulum" / "hnn_torch" / "seed1").glob("result.json")
    rec = json.loads(victim.read_text())
    del rec["seed"]
    victim.write_text(json.dumps(rec))
    proc = hnnbench("report", str(a), str(b), "--out", str(out), "--no-figures")
    assert proc.returncode == 0
    warnings = [ln for ln in proc.stdout.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and str(victim) in warnings[0]
    assert "'seed' is a required property" in warnings[0]
    assert_one_line_error(
        hnnbench("report", str(a), str(b), "--out", str(out), "--strict"),
        "invalid record",
        "'seed' is a required property",
    )
    reference = tmp_path / "ref.csv"
    assert hnnbench("check", str(a), "--reference", str(reference), "--update").returncode == 0
    proc = hnnbench("check", str(a), str(b), "--reference", str(reference), "--allow-missing")
    assert proc.returncode == 1
    assert "invalid" in proc.stdout and "'seed' is a required property" in proc.stdout
