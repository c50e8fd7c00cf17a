"""Paths in a job and in a fresh interpreter: a job's cache_dir and data_dir reach every
cache, and importing the paths modules imports nothing heavy (the unit tests are
tests/unit/test_paths.py)."""

from __future__ import annotations

import os
import sys

import _fakeplug
import pytest
from conftest import REPO, shared_data_dir

FILENAME = "real_pend_h_1.txt"
SOURCE = shared_data_dir() / FILENAME
needs_data = pytest.mark.skipif(
    not SOURCE.is_file() and not os.environ.get("CI"),  # in CI, missing data fails
    reason=f"{FILENAME} not found (set HNNBENCH_DATA_DIR)",
)


@needs_data
def test_job_settings_reach_data_and_dataset_caches(tmp_path, tmp_path_factory):
    """A job's cache_dir and data_dir settings move every cache it uses."""
    from conftest import compose_job as compose

    from hnnbench._running.job import run_job

    site = _fakeplug.install(tmp_path_factory.mktemp("fakeplug"))
    _fakeplug.activate(site)
    try:
        job_cache = tmp_path / "job-cache"
        cfg = compose(
            [
                "profile=quick",
                "system=real_pendulum",
                "model=crash_model",
                f"cache_dir={job_cache}",
                f"data_dir={SOURCE.parent}",
            ]
        )
        record = run_job(cfg, tmp_path / "job")[0].record
    finally:
        _fakeplug.deactivate(site)
    # The data were found through data_dir and cached under cache_dir; then the model
    # crashed, as it does on purpose.
    assert record["error"] == "RuntimeError: boom: the model crashed on purpose", record
    assert any((job_cache / "datasets" / "real_pendulum").glob("*.npz"))


def test_paths_and_data_import_nothing_heavy():
    """paths and data import only the standard library and hnnbench at module level
    (pooch and platformdirs inside the functions that need them: the first download),
    so locating a data file loads no numpy, torch, JAX, pooch or requests."""
    import ast

    for name in ("paths.py", "data_files.py"):
        tree = ast.parse((REPO / "hnnbench" / "_contracts" / name).read_text())
        roots = set()
        for node in tree.body:  # module level only
            if isinstance(node, ast.Import):
                roots |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                roots.add(node.module.split(".")[0])
        outside = roots - set(sys.stdlib_module_names) - {"hnnbench", "__future__"}
        assert not outside, (name, outside)
