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

XLA compiles for the CPU it runs on, so the same commit gives other last bits on
another kind of processor (an AMD EPYC and an Intel Xeon with AVX-512 differ by up to
50 % on these pairs' diagnostics; pinning XLA to AVX2 does not bring them together).
So there is one reference per kind of CPU, `results/reference/guard-<vendor>[-avx512].csv`
(the most specific that exists); on a kind with none the test is skipped and says how to
make one.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/: conftest
from conftest import REPO, hnnbench  # noqa: E402

pytestmark = pytest.mark.slow

REFERENCES = REPO / "results" / "reference"


def cpu_kind() -> tuple[str, ...]:
    """This machine's kinds of CPU, most specific first: ``("GenuineIntel-avx512",
    "GenuineIntel")``; ``("unknown",)`` where /proc/cpuinfo cannot be read."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return ("unknown",)
    fields = dict(
        (k.strip(), v.strip()) for k, _, v in (line.partition(":") for line in info.splitlines())
    )
    vendor = fields.get("vendor_id") or fields.get("CPU implementer") or "unknown"
    flags = set(fields.get("flags", "").split())
    return (f"{vendor}-avx512", vendor) if "avx512f" in flags else (vendor,)


def reference_for(kinds: tuple[str, ...]) -> Path:
    """The guard reference of the most specific kind that has one, else the most
    specific kind's path (to be written by ``--update``)."""
    for kind in kinds:
        if (REFERENCES / f"guard-{kind}.csv").exists():
            return REFERENCES / f"guard-{kind}.csv"
    return REFERENCES / f"guard-{kinds[0]}.csv"


REFERENCE = reference_for(cpu_kind())
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
    if not REFERENCE.exists():
        pytest.skip(
            f"no guard reference for this kind of CPU ({', '.join(cpu_kind())}): "
            f"`make guard-reference` writes {REFERENCE.relative_to(REPO)}"
        )
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
