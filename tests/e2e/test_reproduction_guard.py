"""The reproduction guard: seed 0 of a few sensitive pairs, with the paper profile's
data and models at reduced steps, must give the committed reference's metrics within
1e-3 relative, in either direction (``hnnbench check --same``).

The CI gate (tests/e2e/test_ci_gate.py) lets a metric move within its tolerance and
welcomes improvements; that is how a change moved the committed pixel-pendulum HNN into
another basin unnoticed. Training is deterministic on CPU, so any change of numerics
(initial weights, data, chunking of the training loop, thread settings) moves these
numbers, and a commit that does so must regenerate the reference on purpose:

    make guard-reference      # = python tests/e2e/test_reproduction_guard.py --update

Pairs: the pixel pendulum's HNN and baseline (the pair that moved) and the two-body
HNN and baseline (the 2019 posing), 2000 steps each.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: conftest
from conftest import REPO, hnnbench  # noqa: E402

pytestmark = pytest.mark.slow

REFERENCE = REPO / "results" / "reference" / "guard.csv"
#: The guard sweep (paper profile): one command line, shared by the test and --update.
SWEEP = [
    "-m",
    "system=pixel_pendulum,two_body",
    "model=hnn_jax,mlp_jax",
    "seed=0",
    "system.steps=2000",
    "hydra/launcher=joblib",
    "hydra.launcher.n_jobs=2",
]
RTOL = "1e-3"


def _sweep(directory: Path, cwd: Path) -> None:
    proc = hnnbench(*SWEEP, f"hydra.sweep.dir={directory}", cwd=cwd, timeout=2400)
    assert proc.returncode == 0, proc.stderr[-4000:]


def test_sensitive_pairs_reproduce_the_committed_guard_reference(tmp_path):
    assert REFERENCE.exists(), "results/reference/guard.csv is missing: make guard-reference"
    sweep = tmp_path / "guard"
    _sweep(sweep, tmp_path)
    check = hnnbench("check", str(sweep), "--reference", str(REFERENCE), "--same", RTOL)
    assert check.returncode == 0, (
        check.stdout[-4000:]
        + check.stderr[-2000:]
        + "\nThe guard pairs' metrics changed. If the change is intended, regenerate "
        "the reference with `make guard-reference` and regenerate every affected row "
        "of the committed leaderboard (results/README.md)."
    )


if __name__ == "__main__":  # make guard-reference
    import tempfile

    if sys.argv[1:] != ["--update"]:
        raise SystemExit("usage: python tests/e2e/test_reproduction_guard.py --update")
    with tempfile.TemporaryDirectory() as tmp:
        _sweep(Path(tmp) / "guard", Path(tmp))
        proc = hnnbench(
            "check", str(Path(tmp) / "guard"), "--reference", str(REFERENCE), "--update"
        )
        print(proc.stdout + proc.stderr, end="")
        raise SystemExit(proc.returncode)
