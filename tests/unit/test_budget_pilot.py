"""scripts/analysis/budget_pilot.py: every family's seeds at two step budgets side by side,
read against how much a change of seeds alone moves the families' order."""

from __future__ import annotations

import json
import math
from pathlib import Path

from conftest import REPO, load_script
from report_fixtures import make_sweep, write_run

from hnnbench import _record as records


def _script():
    return load_script(REPO / "scripts/analysis/budget_pilot.py", "budget_pilot")


def _selection(steps: int, value: float) -> dict:
    """A record's ``selection``: the final checkpoint scored, converged."""
    return {
        "rule": "the final checkpoint, unless an earlier one is lower on the criterion by "
        "more than 2 paired standard errors",
        "criterion": "field_mse",
        "step": steps,
        "validation_loss": value,
        "evaluations": 10,
        "first_step": steps // 10,
        "trained": True,
        "stopped": None,
        "points": 100,
        "best_step": steps,
        "best_value": value,
        "final_step": steps,
        "final_value": value,
        "final_se": value / 100,
        "late_step": steps * 8 // 10,
        "late_value": value,
        "late_se": value / 100,
        "converged": True,
    }


def _pilot(root: Path, steps: int, test_loss: dict[str, list[float]], diverged=()) -> Path:
    """two_body records of the JAX twins at ``steps``: per family, a test loss per seed
    (the criterion and energy MSE follow one fixed order: hnn < dhnn < mlp < srnn)."""
    energy = {"hnn": 1e-4, "dhnn": 1e-3, "mlp": 1e-2, "srnn": 1e-1}
    for family, values in test_loss.items():
        for seed, value in enumerate(values):
            status = "diverged" if (family, seed) in diverged else "ok"
            metrics = {
                "test_loss": value,
                "energy_mse": math.inf if status == "diverged" else energy[family],
                "rollout_mse": math.inf if status == "diverged" else value,
            }
            directory = write_run(
                root, "two_body", f"{family}_jax", seed, status, metrics, "paper", rollout=False
            )
            rec = json.loads((directory / "result.json").read_text())
            rec["steps"] = steps
            rec["selection"] = _selection(steps, energy[family])
            records.write_record(directory, rec)
    return root


def test_doubling_that_reorders_more_than_a_change_of_seeds_is_said(tmp_path, capsys):
    script = _script()
    # 20000 steps, seeds 0-3: seeds 0-1 and 2-3 order the test loss alike (tau 1)
    _pilot(
        tmp_path / "long",
        20000,
        {"hnn": [1, 1, 1, 1], "dhnn": [2, 2, 2, 2], "mlp": [3, 3, 3, 3], "srnn": [4, 4, 4, 4]},
    )
    # 10000 steps, seeds 0-1: the srnn leads on test loss; the mlp's seed 1 diverged
    _pilot(
        tmp_path / "short",
        10000,
        {"hnn": [2, 2], "dhnn": [3, 3], "mlp": [4, 4], "srnn": [1, 1]},
        diverged={("mlp", 1)},
    )
    assert script.main([str(tmp_path / "short"), str(tmp_path / "long")]) == 0
    out = capsys.readouterr().out
    mlp = next(line for line in out.splitlines() if "| two_body" in line and "10000 | mlp" in line)
    cells = [c.strip() for c in mlp.strip("|").split("|")]
    assert cells[3:6] == ["2", "1", "1"]  # seeds, diverged, converged (a diverged seed is not)
    assert cells[-2:] == ["inf", "inf"]  # its energy and rollout MSE: the diverged seed's
    assert "`two_body`, test_loss: tau between budgets 0.00, seed pairs 1.00 to 1.00" in out
    assert (
        "test_loss: tau between budgets 0.00, seed pairs 1.00 to 1.00 (median 1.00, 1): "
        "doubling moves the order more than a change of seeds" in out
    )
    assert "`two_body`, criterion: tau between budgets 1.00" in out
    assert (
        "criterion: tau between budgets 1.00, seed pairs 1.00 to 1.00 (median 1.00, 1): "
        "doubling moves the order no more than a change of seeds" in out
    )


def test_bad_input_gets_one_line(tmp_path, capsys):
    script = _script()
    assert script.main([str(tmp_path / "absent")]) == 2
    assert "not a directory" in capsys.readouterr().err
    assert script.main([str(tmp_path), "--seeds", "a"]) == 2
    assert "expected integers" in capsys.readouterr().err
    make_sweep(tmp_path / "sweep", pairs=(("spring", "mlp_torch"),))
    assert script.main([str(tmp_path / "sweep"), "--systems", "two_body"]) == 1
    assert "no ok or diverged protocol record" in capsys.readouterr().err
