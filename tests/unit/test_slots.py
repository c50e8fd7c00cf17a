"""Slots held by file locks (hnnbench._running.slots): claimants that start together."""

from __future__ import annotations

import threading

import pytest

from hnnbench._running import slots
from hnnbench._running.slots import CLAIMING, claim_least_held

fcntl = pytest.importorskip("fcntl")

#: Two resources of eight slots each, named as the CPU slots are.
SLOTS = {k: [f"cpu{k}.lock" if n == 1 else f"cpu{k}.{n}.lock" for n in range(1, 9)] for k in (0, 1)}


def _claim_together(directory, n):
    """``n`` claimants released at once (threads: a flock belongs to its open file, so
    two opens in one process exclude each other as two processes would)."""
    start, out = threading.Barrier(n), []

    def claimant():
        start.wait()
        out.append(claim_least_held(directory, SLOTS))

    threads = [threading.Thread(target=claimant, daemon=True) for _ in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    return out


def test_claimants_that_start_together_take_distinct_resources(tmp_path):
    """Counting one at a time: before, each of two claimants started together could see
    the other's passing locks as holders, and both took resource 0 (about one start in
    ten, measured: two tuner processes of one `xargs -P 2` shared core 0)."""
    for round_ in range(100):
        directory = tmp_path / str(round_)
        directory.mkdir()
        out = _claim_together(directory, 2)
        try:
            assert sorted(key for key, _ in out) == [0, 1], f"round {round_}: {out}"
        finally:
            for _, handle in out:
                handle.close()


def test_a_claimant_waits_while_another_counts(tmp_path):
    done = threading.Event()
    out = []
    with open(tmp_path / CLAIMING, "a+") as turn:
        fcntl.flock(turn, fcntl.LOCK_EX)  # another claimant counting
        t = threading.Thread(target=lambda: (out.append(claim_least_held(tmp_path, SLOTS)),
                                             done.set()), daemon=True)  # fmt: skip
        t.start()
        assert not done.wait(0.3)
    assert done.wait(30)
    key, handle = out[0]
    handle.close()
    assert key == 0


def test_four_claimants_on_two_resources_share_them_evenly(tmp_path):
    out = _claim_together(tmp_path, 4)
    try:
        assert sorted(key for key, _ in out) == [0, 0, 1, 1]
    finally:
        for _, handle in out:
            handle.close()


def test_a_claimant_counts_anyway_when_the_counter_never_finishes(tmp_path, monkeypatch):
    """A counter stopped while it holds the turn (``SIGSTOP``) delays a claimant by
    ``TURN_WAIT_S`` at most, never for ever."""
    monkeypatch.setattr(slots, "TURN_WAIT_S", 0.2)
    with open(tmp_path / CLAIMING, "a+") as turn:
        fcntl.flock(turn, fcntl.LOCK_EX)
        key, handle = claim_least_held(tmp_path, SLOTS)
    handle.close()
    assert key == 0
