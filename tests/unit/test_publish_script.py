"""scripts/maintainer/publish_results.py: how sweeps become the committed records."""

from __future__ import annotations

import json

import pytest
from publish_fixtures import publish_results
from report_fixtures import write_run


def test_a_job_in_two_sweeps_is_refused_not_counted_twice(tmp_path, monkeypatch):
    """A re-run kept beside the run it supersedes would enter the report twice."""
    monkeypatch.setattr(publish_results, "RECORDS", tmp_path / "records")
    old, new = tmp_path / "old", tmp_path / "new"
    for sweep in (old, new):
        write_run(sweep, "spring", "hnn_torch", 0, profile="paper", rollout=False)
    write_run(old, "spring", "hnn_torch", 1, profile="paper", rollout=False)
    assert publish_results.copy_records([old]) == 2
    with pytest.raises(
        SystemExit,
        match=r"the protocol run spring/hnn_torch seed 0 is in both .*move the superseded",
    ):
        publish_results.copy_records([old, new])
    (old / "spring" / "hnn_torch" / "seed0" / "result.json").unlink()
    assert publish_results.copy_records([old, new]) == 2


def test_a_record_of_other_settings_is_not_published(tmp_path, monkeypatch):
    """Whatever its overrides say, a record whose stored config is not the paper
    defaults is refused, naming the setting."""
    import json

    monkeypatch.setattr(publish_results, "RECORDS", tmp_path / "records")
    declared = tmp_path / "declared"
    write_run(
        declared,
        "spring",
        "hnn_torch",
        0,
        profile="paper",
        rollout=False,
        overrides=("model.hidden=300",),
    )
    with pytest.raises(SystemExit, match=r"a variant \(model.hidden=300\), not the paper"):
        publish_results.copy_records([declared])
    stripped = tmp_path / "stripped"
    job = write_run(stripped, "spring", "hnn_torch", 0, profile="paper", rollout=False)
    record = json.loads((job / "result.json").read_text())
    record["config"]["model"]["hidden"] = 300
    (job / "result.json").write_text(json.dumps(record))
    with pytest.raises(SystemExit, match=f"{job}/result.json; .*model.hidden=300"):
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
    # A recipe record's stored config is the recipe track's (check derives its track
    # and variant from it).
    from hnnbench._results.provenance import default_config

    config = {**default_config("spring", "hnn_torch", "paper", "recipe"), "seed": 0}
    (job / "result.json").write_text(json.dumps({**record, "track": "recipe", "config": config}))
    assert publish_results.copy_records([protocol, recipe]) == 2
    assert (records_dir / "spring" / "hnn_torch" / "seed0" / "result.json").is_file()
    kept = json.loads(
        (records_dir / "spring" / "hnn_torch" / "recipe" / "seed0" / "result.json").read_text()
    )
    assert kept["track"] == "recipe"
    assert publish_results.published_jobs() == {
        ("protocol", "spring", "hnn_torch", 0),
        ("recipe", "spring", "hnn_torch", 0),
    }
    with pytest.raises(SystemExit, match=r"the recipe run spring/hnn_torch seed 0 is in both"):
        publish_results.copy_records([recipe, recipe])


def test_publishing_without_the_published_records_is_refused(tree, tmp_path):
    first = tmp_path / "first"
    write_run(first, "spring", "hnn_jax", 0, profile="paper", rollout=False)
    assert publish_results.copy_records([first]) == 1
    new = tmp_path / "new"
    write_run(new, "spring", "dhnn_jax", 0, profile="paper", rollout=False)
    assert publish_results.main([str(new)]) == 2  # results/records holds hnn_jax: pass it too
    assert not (tree / "results" / "records" / "spring" / "dhnn_jax").exists()


def test_a_system_is_replaced_in_one_step(tree, tmp_path):
    """--replace S: a re-publication of S removes S's published protocol records that
    the directories given do not hold (another seed plan, a model gone), and nothing
    else; without records of S in the directories it refuses."""
    first = tmp_path / "first"
    for model, seeds in (("hnn_jax", 3), ("mlp_jax", 3)):
        for seed in range(seeds):
            write_run(first, "spring", model, seed, profile="paper", rollout=False)
    write_run(first, "pendulum", "hnn_jax", 0, profile="paper", rollout=False)
    assert publish_results.copy_records([first]) == 7
    published = tree / "results" / "records"
    again = tmp_path / "again"
    write_run(again, "spring", "hnn_jax", 0, profile="paper", rollout=False)
    write_run(again, "spring", "mlp_jax", 0, profile="paper", rollout=False)
    assert publish_results.main([str(again)]) == 2  # the published records not given
    assert publish_results.main([str(again), "--replace", "pendulum"]) == 2
    assert (
        publish_results.main([str(again), str(published / "pendulum"), "--replace", "spring"]) == 0
    )
    kept = {(p.parts[-4], p.parts[-3], p.parts[-2]) for p in published.rglob("result.json")}
    assert kept == {
        ("spring", "hnn_jax", "seed0"),
        ("spring", "mlp_jax", "seed0"),
        ("pendulum", "hnn_jax", "seed0"),
    }


def test_a_system_is_withdrawn_until_its_republication(tree, tmp_path):
    """--withdraw S removes S's published records (every track) with no replacement;
    S/TRACK only that track's; a bad name or track is one line and nothing moves."""
    first = tmp_path / "first"
    for model in ("hnn_jax", "mlp_jax"):
        write_run(first, "spring", model, 0, profile="paper", rollout=False)
        write_run(first, "pendulum", model, 0, profile="paper", rollout=False)
    tuned = tmp_path / "tuned"
    job = write_run(tuned, "pendulum", "hnn_jax", 0, profile="paper", rollout=False)
    record = json.loads((job / "result.json").read_text())
    record["track"] = "recipe"
    record["config"]["track"] = "recipe"
    (job / "result.json").write_text(json.dumps(record))
    assert publish_results.copy_records([first, tuned]) == 5
    published = tree / "results" / "records"
    spring = published / "spring"
    assert publish_results.main([str(spring), "--withdraw", "pendulum/nosuchtrack"]) == 2
    assert publish_results.main([str(spring), "--withdraw", "../x"]) == 2
    assert len(list(published.rglob("result.json"))) == 5  # nothing moved
    assert (
        publish_results.main(
            [str(spring), str(published / "pendulum" / "mlp_jax"), "--withdraw", "pendulum/recipe"]
        )
        == 2
    )  # hnn_jax protocol
    assert publish_results.main([str(spring), "--withdraw", "pendulum"]) == 0
    kept = {(p.parts[-4], p.parts[-3], p.parts[-2]) for p in published.rglob("result.json")}
    assert kept == {("spring", "hnn_jax", "seed0"), ("spring", "mlp_jax", "seed0")}


def test_the_family_table_is_published_with_the_notes_of_its_status_cells():
    markdown = "\n".join(
        [
            "# Leaderboard",
            "",
            "- Command: `hnnbench -m system=spring`",
            "",
            "## Families",
            "",
            "| system | family | status |",
            "|---|---|---|",
            "| spring | mlp | ok |",
            "| spring | hnn | 1 ok, 1 diverged [1] |",
            "",
            "Why runs did not finish `ok` ([n] after a status):",
            "",
            "1. diverged (seed 1): rollout stalled",
            "",
            "## Twin agreement",
            "",
            "- not a note",
        ]
    )
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


def test_the_results_page_says_which_protocol_each_system_was_published_under():
    """A leaderboard re-published in parts mixes protocols: the provenance block names
    each system's record schema and hnnbench version, and the systems not published."""

    def rec(system: str, schema: int, version: str, track: str = "protocol") -> dict:
        return {
            "system": system,
            "schema_version": schema,
            "track": track,
            "environment": {"hnnbench": version},
        }

    lines = publish_results.protocol_lines(
        [
            rec("spring", 2, "0.4.0"),
            rec("real_pendulum", 3, "0.5.0"),
            rec("real_pendulum", 3, "0.5.0", track="tuned"),
            rec("pendulum", 2, "0.4.0"),
            rec("three_body", 3, "0.4.0"),
            rec("three_body", 3, "0.5.0"),
        ]
    )
    assert lines[0] == (
        "- Under the current protocol (record schema 3, hnnbench 0.4.0, 0.5.0): "
        "`real_pendulum`, `three_body`"
    )
    assert lines[1] == (
        "- Under an earlier protocol (record schema 2, hnnbench 0.4.0): `pendulum`, `spring`"
    )
    assert lines[2].startswith("- Not published: `two_body`") or "`two_body`" in lines[2]
    assert "`spring`" not in lines[2] and "`real_pendulum`" not in lines[2]


def test_provenance_names_unknown_beside_known_commits():
    """Records made by an install that names its commit and records that name none: the
    provenance line names both, so it never reads as if every record came from the one
    commit it knows."""
    from hnnbench._results.report.inputs import provenance, provenance_lines

    def rec(commit: str | None) -> dict:
        return {"environment": {"git_commit": commit, "hnnbench": "0.5.0"}}

    mixed = provenance([rec("ad7180d"), rec(None), rec("")])
    assert mixed["commit"] == ["ad7180d", "unknown"]
    assert provenance_lines(mixed)[1].startswith("- Git commit: `ad7180d`, `unknown`;")
    assert provenance([rec("ad7180d")])["commit"] == ["ad7180d"]
    assert provenance([rec(None)])["commit"] == []  # the line says `unknown` (its fallback)
