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
