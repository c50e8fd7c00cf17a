"""Verdicts with confidence: the statistics (hnnbench._stats)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hnnbench import _stats as S
from hnnbench._metric import CheckRule

# --------------------------------------------------------------------------- statistics


def test_the_sign_test_is_exact_and_counts_ties_and_gaps_against_the_leader():
    assert S.sign_test([1, 2, 3], [2, 3, 4]) == (0.125, 3, 3)  # 3 seeds: never below 5%
    assert S.sign_test([1, 2, 3, 4, 5], [2, 3, 4, 5, 6])[0] == pytest.approx(1 / 32)
    assert S.sign_test([1, 2, 3, 4, 5], [2, 3, 4, 5, 5])[1] == 4  # a tie is no win
    p, wins, n = S.sign_test([1, math.nan, 3, 4, 5], [2, 3, 4, 5, math.nan])
    assert (wins, n) == (4, 5) and p == pytest.approx(6 / 32)  # own gap loses, theirs wins
    assert S.sign_test([3, 4], [1, 2], better="higher") == (0.25, 2, 2)
    assert S.sign_test([1, 1], [math.inf, math.inf])[1] == 2  # a diverged rollout loses
    assert S.sign_test([], []) == (1.0, 0, 0)
    assert S.MIN_SEPARABLE_SEEDS == 5 and S.min_separable_seeds(0.01) == 7


def test_cell_intervals_none_for_one_seed_or_inf_and_degenerate_when_equal():
    out = S.mean_intervals([[1.0], [1.0, math.inf], [3.5, 3.5, 3.5], [1.0, 2.0, 3.0, 10.0, 4.0]])
    assert all(math.isnan(x) for x in out[0] + out[1])
    assert out[2] == (3.5, 3.5)
    low, high = out[3]
    assert 1.0 <= low < np.mean([1, 2, 3, 10, 4]) < high <= 10.0
    # A sample's interval does not depend on the others bootstrapped with it.
    assert S.mean_intervals([[1.0, 2.0, 3.0, 10.0, 4.0]])[0] == (low, high)


def test_normalised_scores_run_from_the_baseline_to_the_floor():
    rule = CheckRule(10, 1e-10)
    scores = S.normalised_scores([1e-1, 1e-10, 1e-16, 1e-4, math.inf, math.nan], base=1e-1,
                                 floor=1e-16, rule=rule)
    assert scores is not None
    # baseline 0, the floor 1 (the noise floor 1e-10 counts as it), halfway in decades 0.5
    np.testing.assert_allclose(scores[:4], [0.0, 1.0, 1.0, 1 / 3])
    assert list(scores[4:]) == [S.SCORE_RANGE[0]] * 2  # diverged, no result
    higher = CheckRule(3, 0.0, better="higher")
    assert S.normalised_scores([20.0, 2.0, 0.0], base=2.0, floor=20.0, rule=higher) \
        .tolist() == [1.0, 0.0, S.SCORE_RANGE[0]]
    # No scale where the baseline is within the metric's tolerance of the floor.
    assert S.normalised_scores([1.0], base=3.7e-2, floor=3.9e-2, rule=CheckRule(2)) is None
    assert S.normalisation_scale(math.inf, 1e-10, rule) is None


def test_stratified_intervals_iqm_and_probability_of_improvement():
    assert S.iqm(np.array([0.0, 1, 2, 3, 4, 5, 6, 100])) == pytest.approx(3.5)
    strata = [np.array([0.1, 0.2, 0.3]), np.array([0.5, 0.6])]
    point, low, high = S.stratified_interval(strata)
    assert low <= point <= high and point == pytest.approx(S.iqm(np.r_[strata[0], strata[1]]))
    assert S.stratified_interval([np.array([0.4]), np.array([0.6])]) == (0.5, 0.5, 0.5)
    better = [s + 1.0 for s in strata]
    assert S.probability_of_improvement(better, strata) == (1.0, 1.0, 1.0)
    assert S.probability_of_improvement(strata, strata)[0] == pytest.approx(0.5)
    frac, low, high = S.performance_profile(strata, np.array([0.0, 0.25, 1.0]))
    np.testing.assert_allclose(frac, [1.0, (1 / 3 + 1) / 2, 0.0])
    assert np.all(low <= frac) and np.all(frac <= high)
