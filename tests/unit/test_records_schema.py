"""The record, defined once (hnnbench._record.fields): the shipped JSON Schema, a job's
new record, the table and gate names come from the definition; a record is checked on
write; one loader (hnnbench._record.loader.load), strict or not, serves every reader, so
hnnbench.sweep() and hnnbench.load() read the same records."""

from __future__ import annotations

import json
import logging
import math

import pytest
from conftest import REPO
from report_fixtures import write_run

import hnnbench
from hnnbench import _record as records
from hnnbench._contracts import names
from hnnbench._results import check
from hnnbench._results.leaderboard import leaderboard, records_frame


def _record(**changes):
    rec = records.new_record(
        system="spring",
        model="oracle",
        seed=0,
        profile="quick",
        config={},
        overrides=["system=spring"],
        command=None,
        rerun_command=None,
        environment=records.environment(),
        created_at=records.now_iso(),
    )
    rec.update(changes)
    return rec


def test_the_shipped_schema_is_written_from_the_definition():
    shipped = REPO / "hnnbench" / "resources" / "record.schema.json"
    assert shipped == records.SCHEMA_FILE
    assert shipped.read_text(encoding="utf-8") == records.schema_text(), (
        "hnnbench/resources/record.schema.json differs from hnnbench/_record/fields.py: "
        "run python scripts/maintainer/record_schema.py --write"
    )
    schema = records.schema()
    assert schema == records.json_schema()
    assert list(schema["properties"]) == [f.name for f in records.FIELDS]
    assert schema["required"] == [f.name for f in records.FIELDS if f.presence == records.REQUIRED]


def test_a_new_record_holds_every_field_a_job_writes_in_order():
    rec = _record()
    assert list(rec) == [f.name for f in records.FIELDS if f.written]
    assert rec["schema_version"] == records.SCHEMA_VERSION and rec["status"] == "failed"
    assert rec["metrics"] == {} and _record()["metrics"] is not rec["metrics"]
    assert records.validate(rec) == []
    with pytest.raises(TypeError, match="history"):
        records.new_record(history={})
    with pytest.raises(TypeError, match="no value for system"):
        records.new_record()


def test_every_field_of_the_committed_records_is_declared():
    declared = {f.name for f in records.FIELDS} | set(names.LOADER_FIELDS)
    recs = records.load(REPO / "results" / "records").records
    assert recs
    for rec in recs:
        assert set(rec) <= declared, (rec["path"], set(rec) - declared)


def test_tables_and_gate_take_their_names_from_the_definition(tmp_path):
    write_run(tmp_path, "spring", "oracle", 0, rollout=False)
    frame = records_frame(records.load(tmp_path).records)
    assert list(frame.columns[: len(names.FRAME_COLUMNS)]) == list(names.FRAME_COLUMNS)
    assert names.RESERVED == frozenset(names.FRAME_COLUMNS)
    assert check.KEY == names.BOARD_KEY and check.REQUIRED_COLUMNS[:3] == names.BOARD_KEY
    board = leaderboard(records.load(tmp_path).records)
    assert list(board.columns[: len(names.ID_COLUMNS)]) == list(names.ID_COLUMNS)
    for name in records.PROVENANCE_FIELDS:
        rec = records.load(tmp_path).records[0]
        top, _, key = name.partition(".")
        if key:
            rec[top] = {**rec[top], key: None}
        else:
            rec[top] = None
        (finding,) = check.validate_records([rec], [])
        assert finding.check == "provenance" and name in finding.current


def test_write_refuses_a_record_that_does_not_conform_naming_the_field(tmp_path):
    for rec, field in (
        (_record(seed=-3), "seed"),
        (_record(status="finished"), "status"),
        ({k: v for k, v in _record().items() if k != "model"}, "'model'"),
        (_record(metrics={"energy_mse": {"mean": "big", "sem": 0.0}}), "metrics.energy_mse.mean"),
    ):
        with pytest.raises(records.InvalidRecord) as err:
            records.write_record(tmp_path, rec)
        text = str(err.value)
        assert "\n" not in text and field in text and "invalid record" in text, text
        assert not (tmp_path / records.RECORD_NAME).exists()
    records.write_record(tmp_path, _record(metrics={"e": {"mean": math.inf, "sem": math.nan}}))
    back = records.read_record(tmp_path / records.RECORD_NAME)
    assert back["metrics"]["e"]["mean"] == math.inf and math.isnan(back["metrics"]["e"]["sem"])


def test_the_quick_check_names_the_field():
    assert records.shape_problems(_record()) == []
    assert records.shape_problems({k: v for k, v in _record().items() if k != "seed"}) == [
        "'seed' is a required property"
    ]
    assert records.shape_problems(_record(seed=True)) == ["seed: True is not of type 'integer'"]
    assert records.shape_problems(_record(metrics={"energy_mse": 3})) == [
        "metrics.energy_mse: 3 is not of type 'object'"
    ]
    assert records.shape_problems(_record(status="finished"))[0].startswith("status: 'finished'")


def test_schema_version_1_records_still_load_strictly(tmp_path):
    rec = _record(
        schema_version=1, status="ok", metrics={"energy_mse": {"mean": math.nan, "sem": math.inf}}
    )
    for key in ("device", "data", "overrides", "command", "rerun_command"):
        del rec[key]  # not written before schema version 2
    (tmp_path / "job").mkdir()
    text = json.dumps(rec)  # bare NaN / Infinity, as version 1 wrote them
    assert "NaN" in text and "Infinity" in text
    (tmp_path / "job" / records.RECORD_NAME).write_text(text)
    loaded = records.load(tmp_path, strict=True)
    assert loaded.problems == [] and len(loaded.records) == 1
    metric = loaded.records[0]["metrics"]["energy_mse"]
    assert math.isnan(metric["mean"]) and metric["sem"] == math.inf


def _mixed_directory(root):
    """A valid record, a torn JSON file, a record without its seed, and one whose seed
    is out of range (usable, but not valid against the schema)."""
    valid = write_run(root, "spring", "hnn_torch", 0, rollout=False)
    torn = write_run(root, "spring", "mlp_torch", 0, rollout=False) / records.RECORD_NAME
    torn.write_text('{"status": "ok", "metr')
    no_seed = write_run(root, "spring", "oracle", 0, rollout=False) / records.RECORD_NAME
    rec = json.loads(no_seed.read_text())
    del rec["seed"]
    no_seed.write_text(json.dumps(rec))
    out_of_range = write_run(root, "pendulum", "oracle", 0, rollout=False)
    rec = json.loads((out_of_range / records.RECORD_NAME).read_text())
    rec["seed"] = -1
    (out_of_range / records.RECORD_NAME).write_text(json.dumps(rec))
    return valid, torn, no_seed, out_of_range / records.RECORD_NAME


def test_sweep_and_load_read_the_same_records_and_strict_names_the_invalid_file(
    tmp_path, monkeypatch, caplog
):
    valid, torn, no_seed, out_of_range = _mixed_directory(tmp_path / "sweep")

    loaded = records.load(tmp_path / "sweep")
    assert sorted(r["path"] for r in loaded.records) == sorted(
        [str(valid), str(out_of_range.parent)]
    )
    reasons = {p.path: p.reason for p in loaded.problems}
    assert set(reasons) == {torn, no_seed}
    assert reasons[torn].startswith("not valid JSON")
    assert reasons[no_seed] == "invalid record: 'seed' is a required property"

    strict = records.load(tmp_path / "sweep", strict=True)
    assert [r["path"] for r in strict.records] == [str(valid)]
    reasons = {p.path: p.reason for p in strict.problems}
    assert set(reasons) == {torn, no_seed, out_of_range}
    assert reasons[out_of_range].startswith("invalid record: seed: -1 is less than the minimum")
    assert all(str(p) == f"{p.path}: {p.reason}" and "\n" not in str(p) for p in strict.problems)

    # hnnbench.load() names the same files left out, once each.
    with caplog.at_level(logging.WARNING, logger="hnnbench"):
        frame = hnnbench.load(tmp_path / "sweep")
    warnings = sorted(r.getMessage() for r in caplog.records)
    assert len(warnings) == 2 and all(str(no_seed) in w or str(torn) in w for w in warnings)
    assert sorted(frame["path"]) == sorted(r["path"] for r in loaded.records)
