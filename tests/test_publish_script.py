"""scripts/publish_results.py: how sweeps become the committed records."""

from __future__ import annotations

import sys
import types

import pandas as pd
import pytest
from conftest import REPO
from report_fixtures import write_run

sys.path.insert(0, str(REPO / "scripts"))
import publish_results  # noqa: E402


def test_a_job_in_two_sweeps_is_refused_not_counted_twice(tmp_path, monkeypatch):
    """A re-run kept beside the run it supersedes would enter the report twice."""
    monkeypatch.setattr(publish_results, "RECORDS", tmp_path / "records")
    old, new = tmp_path / "old", tmp_path / "new"
    for sweep in (old, new):
        write_run(sweep, "spring", "hnn_torch", 0, profile="paper", rollout=False)
    write_run(old, "spring", "hnn_torch", 1, profile="paper", rollout=False)
    assert publish_results.copy_records([old]) == 2
    with pytest.raises(SystemExit, match=r"'hnn_torch', 0\) is in both .*move the superseded"):
        publish_results.copy_records([old, new])
    (old / "spring" / "hnn_torch" / "seed0" / "result.json").unlink()
    assert publish_results.copy_records([old, new]) == 2


def test_a_record_of_other_settings_is_not_published(tmp_path, monkeypatch):
    """Whatever its overrides say, a record whose stored config is not the paper
    defaults is refused, naming the setting."""
    import json

    monkeypatch.setattr(publish_results, "RECORDS", tmp_path / "records")
    declared = tmp_path / "declared"
    write_run(declared, "spring", "hnn_torch", 0, profile="paper", rollout=False,
              overrides=("model.hidden=300",))
    with pytest.raises(SystemExit, match=r"a variant \(model.hidden=300\), not the paper"):
        publish_results.copy_records([declared])
    stripped = tmp_path / "stripped"
    job = write_run(stripped, "spring", "hnn_torch", 0, profile="paper", rollout=False)
    record = json.loads((job / "result.json").read_text())
    record["config"]["model"]["hidden"] = 300
    (job / "result.json").write_text(json.dumps(record))
    with pytest.raises(SystemExit, match=f"{job}: .*model.hidden=300"):
        publish_results.copy_records([stripped])
    assert not (tmp_path / "records").exists()


def test_a_row_of_another_track_is_published_beside_the_protocols(tmp_path, monkeypatch):
    """A tuned or recipe record of a job the protocol also ran lands in a directory of
    its track (records/<system>/<model>/<track>/seed<k>), never over the protocol's."""
    import json

    records_dir = tmp_path / "records"
    monkeypatch.setattr(publish_results, "RECORDS", records_dir)
    protocol, recipe = tmp_path / "protocol", tmp_path / "recipe"
    write_run(protocol, "spring", "hnn_torch", 0, profile="paper", rollout=False)
    job = write_run(recipe, "spring", "hnn_torch", 0, profile="paper", rollout=False)
    record = json.loads((job / "result.json").read_text())
    (job / "result.json").write_text(json.dumps({**record, "track": "recipe"}))
    assert publish_results.copy_records([protocol, recipe]) == 2
    assert (records_dir / "spring" / "hnn_torch" / "seed0" / "result.json").is_file()
    kept = json.loads((records_dir / "spring" / "hnn_torch" / "recipe" / "seed0" /
                       "result.json").read_text())
    assert kept["track"] == "recipe"
    assert publish_results.published_jobs() == {("protocol", "spring", "hnn_torch", 0),
                                                ("recipe", "spring", "hnn_torch", 0)}
    with pytest.raises(SystemExit, match=r"\('recipe', 'spring', 'hnn_torch', 0\) is in both"):
        publish_results.copy_records([recipe, recipe])


@pytest.fixture()
def tree(tmp_path, monkeypatch):
    """A repository root of its own: README.md (no markers: the blocks are the results
    page's) and results/README.md with their markers, results/figures holding a stale
    figure; publish_results writes there."""
    root = tmp_path / "repo"
    (root / "results" / "figures").mkdir(parents=True)
    (root / "README.md").write_text("# x\n\nSee [results](results/README.md).\n")
    (root / "results" / "README.md").write_text(
        "# x\n\n<!-- aggregate:begin -->\n<!-- aggregate:end -->\n\n"
        "<!-- leaderboard:begin -->\n<!-- leaderboard:end -->\n\n"
        "<!-- tracks:begin -->\n<!-- tracks:end -->\n\n"
        "<!-- provenance:begin -->\n<!-- provenance:end -->\n")
    (root / "results" / "figures" / "old_system_energy.png").write_bytes(b"stale")
    monkeypatch.setattr(publish_results, "ROOT", root)
    monkeypatch.setattr(publish_results, "RESULTS", root / "results")
    monkeypatch.setattr(publish_results, "RECORDS", root / "results" / "records")
    fake = types.ModuleType("job_costs")
    fake.main = lambda argv: 0  # the real one rewrites the installed job costs
    monkeypatch.setitem(sys.modules, "job_costs", fake)
    return root


@pytest.mark.slow
def test_a_new_model_published_with_the_records_keeps_every_figure_and_page(tree, tmp_path):
    """docs/LEADERBOARD.md, followed literally: the published records (with their small
    figure rollouts) and a new model's sweep, published together."""
    from hnnbench import _records as records
    from hnnbench._report.figures import N_TRAJ_SHOWN, runs_for_figures
    from hnnbench._table import leaderboard

    # The protocol: JAX twins seeds 0-5 (the two-sided sign test separates from 6 shared
    # seeds: docs/STATISTICS.md), torch twins 0-2.
    first = tmp_path / "first"
    for model, seeds in (("mlp_jax", 6), ("hnn_jax", 6), ("oracle", 6), ("mlp_torch", 3),
                         ("hnn_torch", 3)):
        for seed in range(seeds):
            write_run(first, "spring", model, seed, profile="paper")
    assert publish_results.main([str(first)]) == 0
    published = tree / "results" / "records"
    rollouts = sorted(p.relative_to(published) for p in published.rglob("rollout.npz"))
    assert [str(p) for p in rollouts] == [f"spring/{m}/seed0/rollout.npz" for m in
                                          ("hnn_jax", "hnn_torch", "mlp_jax", "mlp_torch",
                                           "oracle")]
    families = pd.read_csv(tree / "results" / "families.csv").set_index("family")
    assert families.loc["hnn", "seeds_from"] == "hnn_jax" and families.loc["hnn", "n_seeds"] == 6
    assert families.loc["hnn", "twins"] == "hnn_torch agrees (3 seeds)"
    assert families.loc["hnn", "energy_mse_mark"] == "best"  # better on each of 6 seeds
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
    assert seed == 0 and {r.model for r in runs} == {"mlp_jax", "mlp_torch", "hnn_jax",
                                                     "hnn_torch", "dhnn_jax", "oracle"}
    pngs = sorted((tree / "results" / "figures").glob("*.png"))
    assert {"spring_energy.png", "performance_profile.png"} <= {p.name for p in pngs}
    page = (tree / "results" / "leaderboard.html").read_text()
    assert page.count('<img loading="lazy"') == len(pngs) and "data:image" not in page
    readme = (tree / "results" / "README.md").read_text()
    assert "| family" in readme.split("<!-- aggregate:begin -->")[1]
    assert "| dhnn " in readme.split("<!-- leaderboard:begin -->")[1]


def test_publishing_without_the_published_records_is_refused(tree, tmp_path):
    first = tmp_path / "first"
    write_run(first, "spring", "hnn_jax", 0, profile="paper", rollout=False)
    assert publish_results.copy_records([first]) == 1
    new = tmp_path / "new"
    write_run(new, "spring", "dhnn_jax", 0, profile="paper", rollout=False)
    assert publish_results.main([str(new)]) == 2  # results/records holds hnn_jax: pass it too
    assert not (tree / "results" / "records" / "spring" / "dhnn_jax").exists()


def test_the_family_table_is_published_with_the_notes_of_its_status_cells():
    markdown = "\n".join([
        "# Leaderboard", "", "- Command: `hnnbench -m system=spring`", "", "## Families", "",
        "| system | family | status |", "|---|---|---|", "| spring | mlp | ok |",
        "| spring | hnn | 1 ok, 1 diverged [1] |", "",
        "Why runs did not finish `ok` ([n] after a status):", "",
        "1. diverged (seed 1): rollout stalled", "", "## Twin agreement", "", "- not a note"])
    table, prov = publish_results.table_and_provenance(markdown)
    assert table.startswith("| system") and table.endswith("1. diverged (seed 1): rollout stalled")
    assert "Why runs did not finish" in table and "Twin" not in table
    assert prov.startswith("- Command:")


def test_pages_only_rebuilds_the_pages_of_the_committed_records(tree, tmp_path):
    """After a change of the report's code: the pages from results/records as they are,
    no sweep copied, no record checked against today's settings."""
    first = tmp_path / "first"
    for model in ("mlp_jax", "hnn_jax"):
        write_run(first, "spring", model, 0, profile="paper", rollout=False)
    assert publish_results.copy_records([first]) == 2
    assert publish_results.main(["--pages-only", "--figure", "no_such_figure"]) == 2
    assert publish_results.main(["--pages-only", "--figure", "heatmap_energy_mse"]) == 0
    page = (tree / "results" / "README.md").read_text()
    assert "| hnn " in page.split("<!-- leaderboard:begin -->")[1]
    assert (tree / "results" / "leaderboard.html").is_file()
    with pytest.raises(SystemExit):
        publish_results.main(["--pages-only", str(first)])
