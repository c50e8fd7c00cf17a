"""A sweep's records and the loader agree (tests/unit/test_records_schema.py checks the
definition)."""

from __future__ import annotations

import hnnbench


def test_sweep_and_load_agree_on_the_directory_a_sweep_wrote(tmp_path):
    """hnnbench.sweep() returns the leaderboard of the jobs it ran; hnnbench.load() of
    its directory gives the same one."""
    out = tmp_path / "sweep"
    board = hnnbench.sweep("spring", "oracle", seeds=[0, 1], out=out, pin_cpu=False)
    again = hnnbench.leaderboard(hnnbench.load(out))
    assert board.drop(columns=["dates"]).equals(again.drop(columns=["dates"]))
    assert int(board["n_seeds"].iloc[0]) == 2
