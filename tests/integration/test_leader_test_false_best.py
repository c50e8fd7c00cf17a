"""The leader test's false-best rate, simulated through the project's own marking function
(hnnbench._results.families.simulate_marks drives mark_best): among k identical families
over n paired seeds, a "best" mark, the leader's choice included, appears in at most 5 % of
the cells (slow for the unit loop: 600 simulated sweeps per family count)."""

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
