"""docs/PLUGINS.md and the example package it links (tests/plugin_pkg) say the same
thing, and the docs cover what a newcomer had to ask (#51)."""

from __future__ import annotations

import pytest
from conftest import REPO


def test_the_example_plugin_draws_its_evaluation_as_the_docs_say():
    """tests/plugin_pkg, linked from docs/PLUGINS.md, draws its data and its evaluation
    trajectories from seed_stream(seed, DATA_STREAM / EVAL_STREAM), as the docs ask."""
    source = (
        REPO / "tests" / "plugin_pkg" / "src" / "hnnbench_toy_plugin" / "__init__.py"
    ).read_text()
    assert "seed_stream(seed, EVAL_STREAM)" in source and "seed_stream(seed, DATA_STREAM)" in source
    assert "10_000" not in source and "default_rng(seed" not in source
    docs = (REPO / "docs" / "PLUGINS.md").read_text()
    assert "seed_stream(seed, EVAL_STREAM)" in docs


@pytest.mark.parametrize("gap", ["network_inputs", "evaluation(", "clean", "CLEAN_INPUTS"])
def test_the_plugin_docs_cover_what_a_newcomer_asked(gap):
    assert gap in (REPO / "docs" / "PLUGINS.md").read_text()
