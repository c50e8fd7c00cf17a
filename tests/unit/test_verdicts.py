"""Verdicts with confidence: the statistics (hnnbench._results.stats), one competitor per family
with its twins' agreement and its best/tied marks (hnnbench._results.families), and the
aggregate across systems (hnnbench._results.aggregate), on small synthetic records."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from report_fixtures import make_sweep, seed_metrics, write_run

from hnnbench import _record as records
from hnnbench._contracts.metric import CheckRule
from hnnbench._results import stats
from hnnbench._results.aggregate import aggregate
from hnnbench._results.families import families, mark_best, primary_rows
from hnnbench._results.leaderboard import leaderboard_frame, records_frame

# --------------------------------------------------------------------------- statistics


def test_the_sign_test_is_exact_and_counts_ties_and_gaps_against_the_leader():
    assert stats.sign_test([1, 2, 3], [2, 3, 4]) == (0.125, 3, 3)  # 3 seeds: never below 5%
    assert stats.sign_test([1, 2, 3, 4, 5], [2, 3, 4, 5, 6])[0] == pytest.approx(1 / 32)
    assert stats.sign_test([1, 2, 3, 4, 5], [2, 3, 4, 5, 5])[1] == 4  # a tie is no win
    p, wins, n = stats.sign_test([1, math.nan, 3, 4, 5], [2, 3, 4, 5, math.nan])
    assert (wins, n) == (4, 5) and p == pytest.approx(6 / 32)  # own gap loses, theirs wins
    assert stats.sign_test([3, 4], [1, 2], better="higher") == (0.25, 2, 2)
    assert stats.sign_test([1, 1], [math.inf, math.inf])[1] == 2  # a diverged rollout loses
    assert stats.sign_test([], []) == (1.0, 0, 0)
    # two-sided: with n seeds p >= 2 x 0.5^n, so 6 seeds (0.031) for one comparison,
    # and Holm's first threshold alpha/m for m comparisons: 8 seeds for five others
    assert stats.MIN_SEPARABLE_SEEDS == 6 and stats.min_separable_seeds(0.01) == 8
    assert stats.min_separable_seeds(comparisons=5) == 8


def test_holm_and_the_leader_test():
    adjusted, rejected = stats.holm([0.01, 0.04, 0.03])
    assert adjusted == pytest.approx([0.03, 0.06, 0.06]) and rejected == [True, False, False]
    ten = list(range(10))
    ps, separated = stats.leader_test(ten, [[v + 1 for v in ten], [v + 2 for v in ten]])
    assert ps == pytest.approx([2 * 2 / 1024] * 2) and separated == [True, True]
    nine = [v + 1 for v in ten[:9]] + [-5]  # the other better on one seed of ten
    ps, separated = stats.leader_test(ten, [nine])
    assert ps[0] == pytest.approx(2 * 11 / 1024) and separated == [True]
    assert stats.leader_test(ten[:5], [[v + 1 for v in ten[:5]]])[1] == [False]  # 0.0625


def test_the_paired_effect_is_a_median_with_an_order_statistic_interval():
    leader = [1.0] * 10
    other = [10.0] * 9 + [1000.0]
    median, low, high, coverage = stats.paired_effect(leader, other)
    assert median == pytest.approx(1.0) and low == pytest.approx(1.0)  # log10 ratio
    assert high == pytest.approx(1.0) and coverage >= 0.95  # x_(2), x_(9) of 10
    assert stats.paired_effect([0.9, 0.8], [0.5, 0.6], "higher", "linear")[0] == pytest.approx(0.3)
    diverged = stats.paired_effect([1.0, 1.0, math.inf], [2.0, math.inf, 2.0])
    assert (
        sorted(stats.paired_effect([1.0, 1.0, math.inf], [2.0, math.inf, 2.0])[:1])
        == [pytest.approx(math.log10(2))]
        and diverged[1] == -math.inf
        and diverged[2] == math.inf
    )


def test_cell_intervals_none_for_one_seed_or_inf_and_degenerate_when_equal():
    out = stats.mean_intervals(
        [[1.0], [1.0, math.inf], [3.5, 3.5, 3.5], [1.0, 2.0, 3.0, 10.0, 4.0]]
    )
    assert all(math.isnan(x) for x in out[0] + out[1])
    assert out[2] == (3.5, 3.5)
    low, high = out[3]
    assert 1.0 <= low < np.mean([1, 2, 3, 10, 4]) < high <= 10.0
    # A sample's interval does not depend on the others bootstrapped with it.
    assert stats.mean_intervals([[1.0, 2.0, 3.0, 10.0, 4.0]])[0] == (low, high)


def test_normalised_scores_run_from_the_baseline_to_the_floor():
    rule = CheckRule(10, 1e-10)
    scores = stats.normalised_scores(
        [1e-1, 1e-10, 1e-16, 1e-4, math.inf, math.nan], base=1e-1, floor=1e-16, rule=rule
    )
    assert scores is not None
    # baseline 0, the floor 1 (the noise floor 1e-10 counts as it), halfway in decades 0.5
    np.testing.assert_allclose(scores[:4], [0.0, 1.0, 1.0, 1 / 3])
    assert list(scores[4:]) == [stats.SCORE_RANGE[0]] * 2  # diverged, no result
    higher = CheckRule(3, 0.0, better="higher")
    assert stats.normalised_scores(
        [20.0, 2.0, 0.0], base=2.0, floor=20.0, rule=higher
    ).tolist() == [1.0, 0.0, stats.SCORE_RANGE[0]]
    # No scale where the baseline is within the metric's tolerance of the floor.
    assert stats.normalised_scores([1.0], base=3.7e-2, floor=3.9e-2, rule=CheckRule(2)) is None
    assert stats.normalisation_scale(math.inf, 1e-10, rule) is None


def test_stratified_intervals_iqm_and_probability_of_improvement():
    assert stats.iqm(np.array([0.0, 1, 2, 3, 4, 5, 6, 100])) == pytest.approx(3.5)
    strata = [np.array([0.1, 0.2, 0.3]), np.array([0.5, 0.6])]
    point, low, high = stats.stratified_interval(strata)
    assert low <= point <= high and point == pytest.approx(stats.iqm(np.r_[strata[0], strata[1]]))
    assert stats.stratified_interval([np.array([0.4]), np.array([0.6])]) == (0.5, 0.5, 0.5)
    # A system with one run stays as it is in every resample (scipy resamples two or more).
    assert stats.stratified_interval([np.array([0.1, 0.2, 0.3]), np.array([0.9])]) == pytest.approx(
        (0.25, 0.1, 0.3)
    )
    better = [s + 1.0 for s in strata]
    assert stats.probability_of_improvement(better, strata) == (1.0, 1.0, 1.0)
    assert stats.probability_of_improvement(strata, strata)[0] == pytest.approx(0.5)
    frac, low, high = stats.performance_profile(strata, np.array([0.0, 0.25, 1.0]))
    np.testing.assert_allclose(frac, [1.0, (1 / 3 + 1) / 2, 0.0])
    assert np.all(low <= frac) and np.all(frac <= high)


# --------------------------------------------------------------------------- families


def _marks(
    values: dict[str, list[float]],
    n_ok: dict[str, int] | None = None,
    better_metric: str = "energy_mse",
) -> pd.DataFrame:
    """A family board (one system) with ``values`` per family and seed, marked (the
    family ``still`` is the standing-still reference)."""
    rows, runs = [], []
    for family, vals in values.items():
        seeds = list(range(len(vals)))
        rows.append(
            {
                "profile": "paper",
                "system": "spring",
                "family": family,
                "variant": "",
                "ranked": family not in ("oracle", "still"),
                "reference": "zero_field" if family == "still" else "",
                "n_seeds": len(vals),
                "n_ok": (n_ok or {}).get(family, len(vals)),
                f"{better_metric}_mean": float(np.mean(vals)),
            }
        )
        runs += [
            {
                "profile": "paper",
                "system": "spring",
                "family": family,
                "variant": "",
                "seed": s,
                "status": "ok",
                better_metric: v,
            }
            for s, v in zip(seeds, vals, strict=True)
        ]
    return mark_best(pd.DataFrame(rows), pd.DataFrame(runs)).set_index("family")


TEN = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]


def _up(values: list[float], by: float) -> list[float]:
    return [v + by for v in values]


def test_best_needs_enough_paired_seeds_each_better():
    ten = _marks({"hnn": TEN, "mlp": _up(TEN, 1), "oracle": [0] * 10})
    assert ten.loc["hnn", "energy_mse_mark"] == "best"
    assert ten.loc["hnn", "energy_mse_p"] == pytest.approx(2 / 1024)  # two-sided
    assert ten.loc["mlp", "energy_mse_mark"] == "" and ten.loc["oracle", "energy_mse_mark"] == ""
    assert ten.loc["hnn", "energy_mse_effect_vs"] == "mlp"
    assert ten.loc["hnn", "energy_mse_effect"] > 0
    five = _marks({"hnn": [1, 2, 3, 4, 5], "mlp": [20, 30, 40, 50, 60]})
    # 5 seeds can never separate two-sided: the leader's cell says so, nothing is marked
    assert five["energy_mse_mark"].to_dict() == {"hnn": "too_few_seeds", "mlp": ""}
    two_losses = _marks({"hnn": TEN, "mlp": _up(TEN, 1)[:8] + [0.5, 0.5], "lnn": [99] * 10})
    assert two_losses["energy_mse_mark"].to_dict() == {"hnn": "tied", "mlp": "tied", "lnn": ""}


def test_a_family_with_a_diverged_seed_never_leads_and_higher_can_be_better():
    board = _marks({"lnn": [0.1] * 10, "hnn": TEN, "mlp": [99] * 10}, n_ok={"lnn": 9})
    assert board.loc["hnn", "energy_mse_mark"] == "tied"  # the leader: lnn beats it
    assert board.loc["lnn", "energy_mse_mark"] == "tied"  # ... on every seed: not separated
    vpt = _marks(
        {"hnn": _up(TEN, 4), "mlp": TEN, "still": [0.5] * 10}, better_metric="valid_prediction_time"
    )
    assert vpt.loc["hnn", "valid_prediction_time_mark"] == "best"


def test_a_rollout_cell_is_marked_only_where_its_leader_beats_standing_still():
    beaten = {"hnn": _up(TEN, 4), "mlp": TEN}
    unbeaten = _marks({**beaten, "still": [20.0] * 10}, better_metric="valid_prediction_time")
    assert unbeaten["valid_prediction_time_mark"].to_dict() == {
        "hnn": "",
        "mlp": "",
        "still": "unbeaten",
    }  # "no family beats standing still"
    mse = _marks({"hnn": TEN, "mlp": _up(TEN, 1), "still": [6.0] * 10}, better_metric="rollout_mse")
    assert mse["rollout_mse_mark"].to_dict() == {"hnn": "best", "mlp": "", "still": ""}
    still_wins = _marks(
        {"hnn": TEN, "mlp": _up(TEN, 1), "still": [5.4] * 10}, better_metric="rollout_mse"
    )
    assert still_wins.loc["still", "rollout_mse_mark"] == "unbeaten"
    # without a standing-still row nothing is claimed on such a metric
    none = _marks(beaten, better_metric="valid_prediction_time")
    assert set(none["valid_prediction_time_mark"]) == {""}
    # an energy metric keeps its guard and needs no reference row
    assert _marks({"hnn": TEN, "mlp": _up(TEN, 1)}).loc["hnn", "energy_mse_mark"] == "best"


def test_an_unranked_metric_and_an_out_of_domain_value_are_never_marked():
    board = _marks({"hnn": TEN, "mlp": _up(TEN, 1)}, better_metric="reversibility_error")
    assert "reversibility_error_mark" not in board  # a diagnostic, never a verdict
    negative = _marks({"mlp": [-5.0] * 10, "hnn": TEN, "dhnn": _up(TEN, 1)})
    assert negative["energy_mse_mark"].to_dict() == {"mlp": "", "hnn": "best", "dhnn": ""}


def test_a_model_that_does_not_move_cannot_win_an_energy_metric():
    """energy_mse declares best_requires=("rollout_skill", 0): a family whose rollout is
    no better than standing still (energy MSE 0 on a conservative system) takes no part;
    the others are ranked among themselves."""
    rows, runs = [], []
    table = {
        "still": ([0.0] * 10, -0.01),
        "hnn": (TEN, 0.6),
        "mlp": (_up(TEN, 1), 0.2),
        "zero": ([0.0] * 10, 0.0),
    }
    for family, (vals, skill) in table.items():
        rows.append(
            {
                "profile": "paper",
                "system": "spring",
                "family": family,
                "variant": "",
                "ranked": family != "zero",
                "reference": "zero_field" if family == "zero" else "",
                "n_seeds": 10,
                "n_ok": 10,
                "energy_mse_mean": float(np.mean(vals)),
                "rollout_skill_mean": skill,
            }
        )
        runs += [
            {
                "profile": "paper",
                "system": "spring",
                "family": family,
                "variant": "",
                "seed": k,
                "status": "ok",
                "energy_mse": v,
                "rollout_skill": skill,
            }
            for k, v in enumerate(vals)
        ]
    board = mark_best(pd.DataFrame(rows), pd.DataFrame(runs)).set_index("family")
    assert board["energy_mse_mark"].to_dict() == {"still": "", "hnn": "best", "mlp": "", "zero": ""}
    assert board.loc["hnn", "rollout_skill_mark"] == "best"
    # without the guard's column (records from before it), nothing is left out
    plain = mark_best(
        pd.DataFrame(rows).drop(columns="rollout_skill_mean"), pd.DataFrame(runs)
    ).set_index("family")
    assert plain.loc["still", "energy_mse_mark"] == "best"


@pytest.fixture(scope="module")
def twin_sweep(tmp_path_factory):
    """spring: JAX twins with seeds 0-9, torch twins with 0-2 (the lead's protocol), the
    oracle; hnn_torch's seed 2 a hundred times off its twin's energy MSE."""
    root = tmp_path_factory.mktemp("twins")
    make_sweep(
        root,
        pairs=(("spring", "mlp_jax"), ("spring", "hnn_jax"), ("spring", "oracle")),
        seeds=tuple(range(10)),
        rollout=False,
    )
    make_sweep(root, pairs=(("spring", "mlp_torch"),), seeds=(0, 1, 2), rollout=False)
    for seed in (0, 1, 2):
        values = seed_metrics("spring", "hnn_torch", seed)
        if seed == 2:
            values["energy_mse"] *= 100
        write_run(root, "spring", "hnn_torch", seed, metrics=values, rollout=False)
    return records.load(root).records


def test_one_row_per_family_on_the_twin_with_most_seeds(twin_sweep):
    fams = families(records_frame(twin_sweep))
    board = fams.board.set_index("family")
    assert list(board.index) == ["mlp", "hnn", "oracle"]  # registry order
    assert board.loc["hnn", "seeds_from"] == "hnn_jax" and board.loc["hnn", "n_seeds"] == 10
    assert board.loc["hnn", "models"] == "hnn_torch;hnn_jax"
    assert board.loc["hnn", "seeds"] == "0;1;2;3;4;5;6;7;8;9"
    # hnn beats mlp on each of 10 paired seeds: separated; mlp's twins agree.
    assert board.loc["hnn", "energy_mse_mark"] == "best"
    assert board.loc["mlp", "twins"] == "mlp_torch agrees (3 seeds)"
    assert board.loc["hnn", "twins_disagree"] == "energy_mse"
    twin = fams.twins.set_index("family").loc["hnn"]
    assert not twin["agree"]
    assert twin["energy_mse_apart"] == pytest.approx(100.0)
    assert "energy_mse 100x apart at seed 2 (tolerance 10x)" in twin["difference"]
    # The family rows keep the per-model row's interval columns.
    assert {"energy_mse_ci_low", "energy_mse_ci_high"} <= set(fams.board.columns)


def test_primary_rows_of_a_reference_csv_without_families(tmp_path):
    ref = pd.DataFrame(
        {
            "profile": "quick",
            "system": "spring",
            "model": ["a_torch", "a_jax", "solo"],
            "family": ["a", "a", None],
            "backend": ["torch", "jax", "numpy"],
            "n_seeds": [1, 1, 1],
            "n_ok": [1, 1, 1],
            "ranked": True,
        }
    )
    rows = primary_rows(ref).set_index("family")
    assert rows.loc["a", "seeds_from"] == "a_jax"  # tie: by backend name
    assert rows.loc["solo", "seeds_from"] == "solo"  # a model without a family is its own


# --------------------------------------------------------------------------- aggregate


def test_the_aggregate_anchors_the_baseline_at_zero_and_names_what_it_leaves_out(tmp_path):
    make_sweep(
        tmp_path,
        pairs=(
            ("spring", "mlp_jax"),
            ("spring", "hnn_jax"),
            ("spring", "oracle"),
            ("pendulum", "mlp_jax"),
            ("pendulum", "hnn_jax"),
        ),
        seeds=(0, 1, 2, 3, 4),
        rollout=False,
    )
    frame = records_frame(records.load(tmp_path).records)
    fams = families(frame, leaderboard_frame(frame))
    agg = aggregate(fams)
    assert agg.baseline == "mlp"
    energy = agg.iqm[agg.iqm["metric"] == "energy_mse"].set_index("family")
    assert set(energy.index) == {"mlp", "hnn"} and (energy["n_systems"] == 2).all()
    assert abs(energy.loc["mlp", "iqm"]) < 0.05  # its own seeds around its mean
    assert energy.loc["hnn", "iqm_low"] > energy.loc["mlp", "iqm_high"]
    assert energy.loc["hnn", "iqm_low"] <= energy.loc["hnn", "iqm"] <= energy.loc["hnn", "iqm_high"]
    p = agg.improvement[
        (agg.improvement["metric"] == "energy_mse") & (agg.improvement["family"] == "hnn")
    ].iloc[0]
    assert p["other"] == "mlp" and p["p"] == 1.0 and p["n_systems"] == 2
    scales = agg.scales.set_index(["metric", "system"])
    assert scales.loc[("energy_mse", "spring"), "floor_from"].startswith("noise floor")
    assert (
        scales.loc[("energy_mse", "pendulum"), "floor_from"]
        == "noise floor (no reference model ran)"
    )
    # valid_prediction_time has no noise floor: without an oracle there is no scale.
    assert not scales.loc[("valid_prediction_time", "pendulum"), "used"]
    assert ("quick", "energy_mse") in agg.profiles
