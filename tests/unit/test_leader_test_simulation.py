"""The leader test's false-best rate, simulated through the project's own marking function
(hnnbench._results.families.simulate_marks drives mark_best): among k identical families over n
paired seeds, a "best" mark, the leader's choice included, appears in at most 5 % of the
cells; and the test is not vacuous: a clearly better family is found at 10 seeds."""

from __future__ import annotations

import pytest

from hnnbench._results.families import simulate_marks


@pytest.mark.slow
@pytest.mark.parametrize("families", [2, 3, 4, 5, 6])
def test_identical_families_get_a_false_best_in_at_most_five_percent(families):
    # five seeds cannot separate
    assert simulate_marks(families, 5, 200, "energy_mse", seed=1)["any_best"] == 0.0
    rate = simulate_marks(families, 10, 600, "energy_mse", seed=1)["any_best"]
    assert rate <= 0.05, rate


def test_five_seeds_say_too_few_and_ten_seeds_find_a_clear_leader():
    five = simulate_marks(2, 5, 50, "energy_mse", effect=3.0, seed=2)
    assert five["too_few"] == 1.0 and five["any_best"] == 0.0
    ten = simulate_marks(2, 10, 100, "energy_mse", effect=3.0, seed=2)
    assert ten["power"] >= 0.8 and ten["any_best"] == ten["power"]
