"""docs/tutorial.py (jupytext, paired with docs/tutorial.ipynb) is executed as a
notebook, so the tutorial cannot rot; the committed notebook is the script, executed
(tests/e2e/test_tutorial_runs.py runs it)."""

from __future__ import annotations

import json

import pytest
from conftest import REPO

jupytext = pytest.importorskip("jupytext")
nbclient = pytest.importorskip("nbclient")

SOURCE = REPO / "docs" / "tutorial.py"
NOTEBOOK = REPO / "docs" / "tutorial.ipynb"


def _sources(nb) -> list[tuple[str, str]]:
    return [(c.cell_type, c.source.strip()) for c in nb.cells]


#: The committed notebook's size limit: its outputs are the tables, prints and one figure.
MAX_NOTEBOOK_BYTES = 200_000


def test_the_notebook_is_the_script_with_its_outputs():
    """docs/tutorial.ipynb is docs/tutorial.py, executed (every code cell, in order, with
    its outputs, so it reads as a finished run on GitHub), small: no error, none of the
    logs of the jobs (:func:`_without_logs`), no path of the machine that ran it.
    Regenerate it with ``python tests/unit/test_tutorial.py --write``."""
    script = jupytext.read(SOURCE)
    stored = json.loads(NOTEBOOK.read_text())
    notebook = jupytext.read(NOTEBOOK)
    assert _sources(notebook) == _sources(script), (
        "docs/tutorial.ipynb is out of date: python tests/unit/test_tutorial.py --write"
    )
    code = [c for c in stored["cells"] if c["cell_type"] == "code"]
    assert [c["execution_count"] for c in code] == list(range(1, len(code) + 1))
    outputs = [o for c in code for o in c.get("outputs", [])]
    assert sum(bool(c.get("outputs")) for c in code) >= len(code) - 1  # the class: none
    assert not [o for o in outputs if o["output_type"] == "error"]
    assert not [o for o in outputs if o.get("name") == "stderr"]
    assert "] spring x" not in json.dumps(outputs)  # no job log lines
    assert any("image/png" in o.get("data", {}) for o in outputs)  # the energy figure
    text = json.dumps(outputs)
    assert "/work/" not in text and "/tmp/" not in text and "/home/" not in text
    assert NOTEBOOK.stat().st_size < MAX_NOTEBOOK_BYTES


def write_executed_notebook() -> None:
    """Execute docs/tutorial.ipynb (its cells made docs/tutorial.py's, ids kept) from
    the repository root and store it with its outputs, less the log streams (stderr)."""
    import nbformat

    script = jupytext.read(SOURCE)
    notebook = nbformat.read(NOTEBOOK, as_version=4)
    if _sources(notebook) != _sources(script):  # take the script's cells, new ids
        notebook = script
    for cell in notebook.cells:
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    client = nbclient.NotebookClient(
        notebook, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(REPO)}}
    )
    client.execute()
    for cell in notebook.cells:
        cell.metadata.pop("execution", None)
        if cell.cell_type == "code":
            cell.outputs = [kept for o in cell.outputs if (kept := _without_logs(o))]
    notebook.metadata.pop("widgets", None)
    nbformat.write(notebook, NOTEBOOK)


def _without_logs(output):  # noqa: ANN001, ANN202 - an nbformat output node
    """``output`` without what hnnbench logs while it runs (stderr; on stdout, the
    ``[hh:mm:ss]`` job lines and the end-of-sweep summary, which name this machine's
    paths), or ``None`` when nothing else is left."""
    import re

    if output.output_type != "stream":
        return output
    if output.name == "stderr":
        return None
    drop = re.compile(r"^(\[\d\d:\d\d:\d\d\]|\||this run: |records and summary|report: )")
    lines = [ln for ln in output.text.splitlines() if ln.strip() and not drop.match(ln)]
    if not lines:
        return None
    output.text = "\n".join(lines) + "\n"
    return output


if __name__ == "__main__":
    import sys

    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: python tests/unit/test_tutorial.py --write")
    write_executed_notebook()
