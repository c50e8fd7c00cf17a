"""The rank heatmaps show the references (standing still, the oracle) below the ranked
families, never ranked, with the mark of a standing-still cell no family beats."""

from __future__ import annotations

import math

import pandas as pd

from hnnbench._results.report import figures


def _board() -> pd.DataFrame:
    rows = []
    for system, values in (
        ("spring", (1.0, 2.0, 5.0, 0.0)),
        ("real_pendulum", (3.0, 4.0, 2.0, None)),
    ):
        for (family, ranked, reference), value in zip(
            (
                ("mlp", True, ""),
                ("hnn", True, ""),
                ("standing_still", False, "zero_field"),
                ("oracle", False, "true_field"),
            ),
            values,
            strict=True,
        ):
            if value is None:
                continue
            mark = "unbeaten" if family == "standing_still" and system == "real_pendulum" else ""
            rows.append(
                {
                    "system": system,
                    "family": family,
                    "seeds_from": family,
                    "models": family + "_jax" if ranked else family,
                    "ranked": ranked,
                    "reference": reference,
                    "n_seeds": 10,
                    "rollout_mse_mean": value,
                    "rollout_mse_mark": mark,
                }
            )
    return pd.DataFrame(rows)


def test_the_references_are_their_own_rows_never_ranked():
    board = _board()
    ranks, _ = figures.rank_table(board, "rollout_mse")
    assert list(ranks.index) == ["mlp", "hnn"]  # the references take no rank
    refs = figures.reference_table(board, "rollout_mse", ["spring", "real_pendulum"])
    assert list(refs.index) == ["standing_still", "oracle"]  # REFERENCES' order
    assert refs.loc["standing_still", "real_pendulum"] == 2.0
    assert math.isnan(refs.loc["oracle", "real_pendulum"])
    assert figures._marks(board, "rollout_mse") == {("standing_still", "real_pendulum"): "unbeaten"}
    only_measured = figures.reference_table(board, "rollout_mse", ["real_pendulum"])
    assert list(only_measured.index) == ["standing_still"]  # no oracle value: no row


def test_the_heatmap_draws_the_reference_rows_below_a_line():
    board = _board()
    ranks, values = figures.rank_table(board, "rollout_mse")
    states = figures.cell_states(board, "rollout_mse", list(values.index), list(values.columns))
    refs = figures.reference_table(board, "rollout_mse", list(values.columns))
    fig = figures._heatmap(
        ranks, values, states, figures._marks(board, "rollout_mse"), "rollout_mse", "", refs
    )
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert labels == ["mlp", "hnn", "standing_still (reference)", "oracle (reference)"]
    texts = [t.get_text() for t in ax.texts]
    assert any(t.startswith("ref" + figures.UNBEATEN_MARK) for t in texts)
    assert "below the line" in ax.get_title()
