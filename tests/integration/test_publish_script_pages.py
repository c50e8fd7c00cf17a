"""Publishing a new model with the published records keeps every figure and page, and a
published tuned system's pages show its studies (slow: a whole report;
tests/unit/test_publish_script.py and test_publish_tuned.py have the rest)."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from publish_fixtures import publish_results, write_study
from report_fixtures import write_run


@pytest.mark.slow
def test_a_new_model_published_with_the_records_keeps_every_figure_and_page(tree, tmp_path):
    """docs/LEADERBOARD.md, followed literally: the published records (with their small
    figure rollouts) and a new model's sweep, published together."""
    from hnnbench import _record as records
    from hnnbench._results.leaderboard import leaderboard
    from hnnbench._results.report.figures import N_TRAJ_SHOWN, runs_for_figures

    # The protocol: JAX twins seeds 0-9, torch twins 0-2 (docs/STATISTICS.md).
    first = tmp_path / "first"
    for model, seeds in (
        ("mlp_jax", 10),
        ("hnn_jax", 10),
        ("oracle", 10),
        ("mlp_torch", 3),
        ("hnn_torch", 3),
    ):
        for seed in range(seeds):
            write_run(first, "spring", model, seed, profile="paper")
    assert publish_results.main([str(first)]) == 0
    published = tree / "results" / "records"
    rollouts = sorted(p.relative_to(published) for p in published.rglob("rollout.npz"))
    assert [str(p) for p in rollouts] == [
        f"spring/{m}/seed0/rollout.npz"
        for m in ("hnn_jax", "hnn_torch", "mlp_jax", "mlp_torch", "oracle")
    ]
    families = pd.read_csv(tree / "results" / "families.csv").set_index("family")
    assert families.loc["hnn", "seeds_from"] == "hnn_jax" and families.loc["hnn", "n_seeds"] == 10
    assert families.loc["hnn", "twins"] == "hnn_torch agrees (3 seeds)"
    assert families.loc["hnn", "energy_mse_mark"] == "best"  # better on each of 10 seeds
    board = pd.read_csv(tree / "results" / "leaderboard.csv")
    assert {"energy_mse_ci_low", "energy_mse_ci_high", "cpu_s_mean", "reason"} <= set(board)
    aggregate = pd.read_csv(tree / "results" / "aggregate.csv")
    assert set(aggregate[aggregate["metric"] == "energy_mse"]["family"]) == {"mlp", "hnn"}
    assert len(pd.read_csv(tree / "results" / "twins.csv")) == 2
    assert (tree / "README.md").read_text() == "# x\n\nSee [results](results/README.md).\n"
    readme = (tree / "results" / "README.md").read_text()
    assert "**" in readme.split("<!-- leaderboard:begin -->")[1]  # a separated best, bold
    assert "](figures/heatmap_energy_mse.png)" in readme  # links relative to results/
    kept = records.load_arrays(published / rollouts[0])
    assert kept["states_hat"].shape[0] <= N_TRAJ_SHOWN and kept["states_hat"].dtype == "float32"
    assert not (tree / "results" / "figures" / "old_system_energy.png").exists()  # stale

    new = tmp_path / "new"
    for seed in (0, 1, 2):
        write_run(new, "spring", "dhnn_jax", seed, profile="paper")
    assert publish_results.main([str(new), str(published)]) == 0
    recs = records.load(published).records
    board = pd.read_csv(tree / "results" / "leaderboard.csv")
    assert list(board["model"]) == list(leaderboard(recs)["model"])
    assert "dhnn_jax" in set(board["model"])
    seed, runs = runs_for_figures(recs)  # the merged page draws every model
    assert seed == 0 and {r.model for r in runs} == {
        "mlp_jax",
        "mlp_torch",
        "hnn_jax",
        "hnn_torch",
        "dhnn_jax",
        "oracle",
    }
    pngs = sorted((tree / "results" / "figures").glob("*.png"))
    assert {"spring_energy.png", "performance_profile.png"} <= {p.name for p in pngs}
    page = (tree / "results" / "leaderboard.html").read_text()
    assert page.count('<img loading="lazy"') == len(pngs) and "data:image" not in page
    readme = (tree / "results" / "README.md").read_text()
    assert "| family" in readme.split("<!-- aggregate:begin -->")[1]
    assert "| dhnn " in readme.split("<!-- leaderboard:begin -->")[1]


@pytest.mark.slow
def test_the_pages_of_a_published_tuned_system_show_how_its_studies_converged(
    published_spring, tmp_path, capsys
):
    """The pages rebuilt after a tuned publication read results/tuning: a row per study
    in tuning_convergence.csv, its figure, and the section of tracks.md."""
    hnn, mlp = tmp_path / "hnn", tmp_path / "mlp"
    write_study(hnn, "spring", "hnn_jax")
    write_study(mlp, "spring", "mlp_jax")
    assert publish_results.main(["--tuned", str(hnn), str(mlp)]) == 0
    assert json.loads(capsys.readouterr().out)["published_tuned"] == ["spring"]
    table = (published_spring / "tuning_convergence.csv").read_text().splitlines()
    assert len(table) == 3 and table[1].startswith("spring,hnn_jax,,16,160.0,")
    assert (published_spring / "figures" / "tuning_convergence.png").is_file()
    assert "## Has the criterion flattened?" in (published_spring / "tracks.md").read_text()
    # the trials' values fall to trial 3 (the last complete one): set in the first half
    assert (
        "2 of 2 studies had their best criterion by the end of the first half"
        in (published_spring / "README.md").read_text()
    )
