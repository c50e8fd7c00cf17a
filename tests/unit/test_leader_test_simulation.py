"""The leader test, simulated through the project's own marking function
(hnnbench._results.families.simulate_marks drives mark_best), is not vacuous: five seeds
say too few, and a clearly better family is found at 10 seeds (its false-best rate, a
longer simulation: tests/integration/test_leader_test_false_best.py)."""

from __future__ import annotations

from hnnbench._results.families import simulate_marks


def test_five_seeds_say_too_few_and_ten_seeds_find_a_clear_leader():
    five = simulate_marks(2, 5, 50, "energy_mse", effect=3.0, seed=2)
    assert five["too_few"] == 1.0 and five["any_best"] == 0.0
    ten = simulate_marks(2, 10, 100, "energy_mse", effect=3.0, seed=2)
    assert ten["power"] >= 0.8 and ten["any_best"] == ten["power"]
