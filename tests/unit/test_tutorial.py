"""docs/tutorial.py (jupytext, paired with docs/tutorial.ipynb) is executed as a
notebook, so the tutorial cannot rot."""

from __future__ import annotations

import json

import pytest
from conftest import REPO

jupytext = pytest.importorskip("jupytext")

SOURCE = REPO / "docs" / "tutorial.py"
NOTEBOOK = REPO / "docs" / "tutorial.ipynb"


def _sources(nb) -> list[tuple[str, str]]:
    return [(c.cell_type, c.source.strip()) for c in nb.cells]


def test_the_notebook_is_the_script_without_outputs():
    script = jupytext.read(SOURCE)
    stored = json.loads(NOTEBOOK.read_text())
    notebook = jupytext.read(NOTEBOOK)
    assert _sources(notebook) == _sources(script), (
        "docs/tutorial.ipynb is out of date: jupytext --to ipynb docs/tutorial.py "
        "-o docs/tutorial.ipynb")
    assert all(not c.get("outputs") for c in stored["cells"] if c["cell_type"] == "code")


