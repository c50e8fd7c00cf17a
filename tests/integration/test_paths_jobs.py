"""Paths in a job and in a fresh interpreter: a job's cache_dir and data_dir reach every
cache, and importing the paths modules imports nothing heavy (the unit tests are
tests/unit/test_paths.py)."""

from __future__ import annotations

import os
import subprocess
import sys

import _fakeplug
import pytest
from conftest import shared_data_dir

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
    """Beyond what ``import hnnbench`` loads, paths and data load no numpy, torch, JAX,
    pooch or requests (pooch is imported on the first download)."""
    code = (
        "import sys, hnnbench; before = set(sys.modules); "
        "import hnnbench._contracts.paths, hnnbench._contracts.data_files; "
        "new = {m.split('.')[0] for m in set(sys.modules) - before}; "
        "bad = new & {'numpy', 'torch', 'jax', 'pooch', 'requests', 'platformdirs'}; "
        "assert not bad, bad"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
