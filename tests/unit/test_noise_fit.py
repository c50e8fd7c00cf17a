"""scripts/analysis/noise_fit.py: a family's training loss at the noisy inputs against the
true field's (the oracle's, same seed), and the criterion's rise from its minimum."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import REPO, load_script
from report_fixtures import write_run

from hnnbench import _record as records


def _script():
    return load_script(REPO / "scripts/analysis/noise_fit.py", "noise_fit")


def _run(root: Path, model: str, seed: int, train: float, history: list[float] | None) -> None:
    """A spring record of ``model`` with ``train_loss`` ``train``, scored at step 20 of
    100 (criterion 1.0 there, 1.5 at the end), logging ``history`` as its training loss."""
    directory = write_run(
        root, "spring", model, seed, "ok", {"train_loss": train}, "paper", rollout=False
    )
    rec = json.loads((directory / "result.json").read_text())
    rec["steps"] = 100
    rec["selection"] = {
        "rule": "the final checkpoint, unless an earlier one is lower on the criterion by "
        "more than 2 paired standard errors",
        "criterion": "field_mse_clean",
        "step": 20,
        "validation_loss": 1.0,
        "evaluations": 2,
        "first_step": 20,
        "trained": True,
        "stopped": None,
        "points": 60,
        "best_step": 20,
        "best_value": 1.0,
        "final_step": 100,
        "final_value": 1.5,
    }
    if history is not None:
        rec["history"] = {"step": [20, 100], "train_loss": history, "val_loss": [1.0, 1.5]}
    records.write_record(directory, rec)


def test_ratios_to_the_noise_floor(tmp_path, capsys):
    # each seed its own floor: the HNN's ratios are 0.9 then 0.8 (seed 0) and 0.7 then
    # 0.6 (seed 1), paired by seed (a ratio to the other seed's floor would differ)
    for seed, floor, hnn in ((0, 0.04, (0.9, 0.8)), (1, 0.08, (0.7, 0.6))):
        _run(tmp_path, "oracle", seed, floor, None)
        scored, final = hnn[0] * floor, hnn[1] * floor
        _run(tmp_path, "hnn_jax", seed, scored, [scored, final])
        # so_mlp logs its own objective (2.5 times the metric): no final ratio
        _run(tmp_path, "so_mlp_jax", seed, floor, [2.5 * floor, 2.4 * floor])
    # two_body: the true field scores 0 (no input noise): no ratio, one line says why
    _run(tmp_path / "nbody", "oracle", 0, 0.0, None)
    for path in (tmp_path / "nbody").rglob("result.json"):
        rec = json.loads(path.read_text())
        records.write_record(path.parent, {**rec, "system": "two_body"})
    (tmp_path / "nbody" / "spring").rename(tmp_path / "nbody" / "two_body")
    argv = [str(tmp_path), "--systems", "spring,pendulum,two_body"]
    assert _script().main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    hnn = next(line.split() for line in lines if "hnn_jax" in line)
    assert hnn[2:] == ["2", "0.8", "0.7", "1.5", "0.2"]
    so_mlp = next(line.split() for line in lines if "so_mlp_jax" in line)
    assert so_mlp[2:] == ["2", "1", "-", "1.5", "0.2"]
    assert any(line.startswith("pendulum") and "no oracle record" in line for line in lines)
    assert any(line.startswith("two_body") and "no input noise" in line for line in lines)


def test_a_folder_that_is_not_one_gets_one_line(tmp_path, capsys):
    assert _script().main([str(tmp_path / "absent")]) == 2
    assert "not a directory" in capsys.readouterr().err
