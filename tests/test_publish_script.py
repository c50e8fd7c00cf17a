"""scripts/publish_results.py: how sweeps become the committed records."""

from __future__ import annotations

import sys

import pytest
from conftest import REPO
from report_fixtures import write_run

sys.path.insert(0, str(REPO / "scripts"))
import publish_results  # noqa: E402


def test_a_job_in_two_sweeps_is_refused_not_counted_twice(tmp_path, monkeypatch):
    """A re-run kept beside the run it supersedes would enter the report twice."""
    monkeypatch.setattr(publish_results, "RECORDS", tmp_path / "records")
    old, new = tmp_path / "old", tmp_path / "new"
    for sweep in (old, new):
        write_run(sweep, "spring", "hnn_torch", 0, profile="paper", rollout=False)
    write_run(old, "spring", "hnn_torch", 1, profile="paper", rollout=False)
    assert publish_results.copy_records([old]) == 2
    with pytest.raises(SystemExit, match=r"'hnn_torch', 0\) is in both .*move the superseded"):
        publish_results.copy_records([old, new])
    (old / "spring" / "hnn_torch" / "seed0" / "result.json").unlink()
    assert publish_results.copy_records([old, new]) == 2


def test_a_record_of_other_settings_is_not_published(tmp_path, monkeypatch):
    """Whatever its overrides say, a record whose stored config is not the paper
    defaults is refused, naming the setting."""
    import json

    monkeypatch.setattr(publish_results, "RECORDS", tmp_path / "records")
    declared = tmp_path / "declared"
    write_run(declared, "spring", "hnn_torch", 0, profile="paper", rollout=False,
              overrides=("model.hidden=300",))
    with pytest.raises(SystemExit, match=r"a variant \(model.hidden=300\), not the paper"):
        publish_results.copy_records([declared])
    stripped = tmp_path / "stripped"
    job = write_run(stripped, "spring", "hnn_torch", 0, profile="paper", rollout=False)
    record = json.loads((job / "result.json").read_text())
    record["config"]["model"]["hidden"] = 300
    (job / "result.json").write_text(json.dumps(record))
    with pytest.raises(SystemExit, match=f"{job}: .*model.hidden=300"):
        publish_results.copy_records([stripped])
    assert not (tmp_path / "records").exists()
