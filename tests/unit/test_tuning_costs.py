"""scripts/analysis/tuning_costs.py --from-job-costs: the tuned track's budget bounded
from the published jobs' median seconds, per system and per stage of tune_sweep.sh."""

from __future__ import annotations

import re

import pytest
from conftest import REPO, load_script


def _script():
    return load_script(REPO / "scripts/analysis/tuning_costs.py", "tuning_costs")


def test_stages_are_read_from_the_sweep_script():
    stages = _script().stages()
    assert stages[1][0] == "spring" and "real_pendulum" in stages[1]
    assert stages[2] == ["two_body", "double_pendulum"]
    assert stages[3][-1] == "three_body"
    listed = [s for systems in stages.values() for s in systems]
    assert len(listed) == len(set(listed)) == 11


def test_the_bound_counts_trials_per_study_and_final_seeds(tmp_path, monkeypatch, capsys):
    script = _script()
    costs = tmp_path / "job_costs.csv"
    rows = ["profile,system,model,seconds,n_runs,source"]
    for family in script.FAMILIES:
        rows.append(f"paper,spring,{family}_jax,36,10,x")
        rows.append(f"paper,real_pendulum,{family}_jax,36,10,x")
    rows.append("paper,two_body,mlp_jax,36,10,x")
    costs.write_text("\n".join(rows) + "\n")
    monkeypatch.setattr(script, "JOB_COSTS", costs)
    monkeypatch.setattr(script, "stages", lambda: {1: ["spring", "real_pendulum"], 2: ["two_body"]})
    assert script.main(["--from-job-costs", "--trials", "4", "--seeds", "10"]) == 0
    out = capsys.readouterr().out
    # six families x 36 s: 4 trials x 2 seeds per study = 0.48 h, 10 final seeds = 0.6 h
    assert "| 1 | spring | 1 | 0.5 | 0.6 | 1.1 |" in out
    # a measured system holds one study per fold of the final seeds
    folds = int(re.search(r"\| 1 \| real_pendulum \| (\d+) \|", out).group(1))
    assert folds > 1
    assert f"| 1 | real_pendulum | {folds} | {0.48 * folds:.1f} | 0.6 |" in out
    assert "| 2 | two_body | no job costs for hnn, dhnn, lnn, so_mlp, srnn |" in out


def test_a_tiny_run_or_the_job_costs_is_required(capsys):
    with pytest.raises(SystemExit) as exc:
        _script().main([])
    assert exc.value.code == 2
    assert "--from-job-costs" in capsys.readouterr().err
