"""scripts/analysis/budget_pilot.py: the same seeds of every family at two step budgets,
side by side, and whether doubling the budget changed the families' order."""

from __future__ import annotations

import importlib.util

import pandas as pd
from conftest import REPO


def _script():
    spec = importlib.util.spec_from_file_location(
        "budget_pilot", REPO / "scripts/analysis/budget_pilot.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _row(family: str, steps: int, seed: int, value: float, converged: bool) -> dict:
    return {
        "system": "two_body",
        "family": family,
        "steps": steps,
        "seed": seed,
        "converged": converged,
        "criterion": value,
        "test_loss": value,
        "energy_mse": {"srnn": 1e-9, "hnn": 1e-3, "dhnn": 1e-2}[family],  # one order at both
        "rollout_mse": value,
    }


def test_doubling_that_swaps_the_leaders_is_an_order_change():
    script = _script()
    frame = pd.DataFrame(
        [
            _row("hnn", 10000, 0, 2.0, False),
            _row("hnn", 10000, 1, 4.0, False),
            _row("dhnn", 10000, 0, 1.0, False),
            _row("dhnn", 10000, 1, 1.0, True),
            _row("srnn", 10000, 0, 5.0, True),
            _row("hnn", 20000, 0, 0.5, True),
            _row("hnn", 20000, 1, 0.5, True),
            _row("dhnn", 20000, 0, 0.9, False),
            _row("srnn", 20000, 0, 5.0, True),
        ]
    )
    table = script.summary(frame)
    hnn = table[(table["steps"] == 10000) & (table["family"] == "hnn")].iloc[0]
    assert (hnn["seeds"], hnn["converged"], hnn["test_loss"]) == (2, 0, 3.0)
    lines = script.orders(table)
    changed = "order changes (10000: dhnn < hnn < srnn; 20000: hnn < dhnn < srnn)"
    assert f"- `two_body`, test_loss: {changed}" in lines
    assert any(line.startswith("- `two_body`, energy_mse: same order") for line in lines)


def test_bad_input_gets_one_line(tmp_path, capsys):
    from report_fixtures import make_sweep

    script = _script()
    assert script.main([str(tmp_path / "absent")]) == 2
    assert "not a directory" in capsys.readouterr().err
    assert script.main([str(tmp_path), "--seeds", "a"]) == 2
    assert "expected integers" in capsys.readouterr().err
    # records without a selection (as an earlier schema wrote them) are not compared
    make_sweep(tmp_path / "sweep", pairs=(("spring", "mlp_torch"),))
    assert script.main([str(tmp_path / "sweep"), "--systems", "spring"]) == 1
    assert "no ok protocol record" in capsys.readouterr().err
