"""One core per launcher worker (hnnbench._running.affinity), with real processes and locks."""

from __future__ import annotations

import os
import select
import subprocess
import sys
import textwrap

import pytest
from conftest import compose_job as compose

from hnnbench._running import affinity
from hnnbench._running.job import run_job

pytestmark = pytest.mark.skipif(
    not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2,
    reason="needs Linux CPU affinity and at least 2 allowed CPUs",
)

#: A claimant: claims a core, reports it and the affinity of a thread started before
#: the claim, then holds the claim until its stdin closes.
CHILD = textwrap.dedent(
    """
    import os, sys, threading
    from pathlib import Path
    from hnnbench._running.affinity import claim_core
    stop = threading.Event()
    early = threading.Thread(target=stop.wait)
    early.start()
    cpu = claim_core(Path(sys.argv[1]))
    again = claim_core(Path(sys.argv[1]))
    print(cpu, again, sorted(os.sched_getaffinity(early.native_id)), flush=True)
    sys.stdin.read()
    stop.set()
    """
)


def _claimant(lock_dir):
    proc = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(lock_dir)],
        text=True,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
    )
    ready, _, _ = select.select([proc.stdout], [], [], 60)
    if not ready:
        proc.kill()
        pytest.fail("a claimant printed nothing within 60 s")
    cpu, again, early = proc.stdout.readline().split(" ", 2)
    return proc, cpu, again, early.strip()


def test_concurrent_claimants_get_distinct_cores_then_share_them_evenly(tmp_path):
    allowed = sorted(os.sched_getaffinity(0))
    held, cpus = [], []
    try:
        for _ in allowed:
            proc, cpu, again, early = _claimant(tmp_path)
            held.append(proc)
            assert cpu == again != "None"  # idempotent within a process
            assert early == f"[{cpu}]"  # threads that existed before the claim moved too
            cpus.append(int(cpu))
        assert sorted(cpus) == allowed  # one core each, in order
        # every core taken: the next claimants share them evenly, one per core, in
        # order (two workers started beside a stopped sweep never share one core)
        second = []
        for _ in allowed:
            proc, cpu, again, early = _claimant(tmp_path)
            held.append(proc)
            assert cpu == again and early == f"[{cpu}]"
            second.append(int(cpu))
        assert second == allowed
    finally:
        for proc in held:
            proc.communicate("")
    # the locks died with their processes: a new claimant gets the first core again
    proc, cpu, _, _ = _claimant(tmp_path)
    proc.communicate("")
    assert cpu == str(allowed[0])


def test_a_claimant_takes_the_least_held_core(tmp_path):
    """Cores 0 and 1 held, a third claimant on core 0's second slot; once the first two
    exit, the next claimant goes to the idle core 1, not beside the third on core 0."""
    allowed = sorted(os.sched_getaffinity(0))[:2]
    lock_dir = tmp_path
    first = [_claimant(lock_dir) for _ in allowed]
    extra = [_claimant(lock_dir) for _ in range(len(os.sched_getaffinity(0)) - 2)]
    third, cpu3, _, _ = _claimant(lock_dir)
    try:
        assert [int(c) for _, c, _, _ in first] == allowed and int(cpu3) == allowed[0]
        for proc, *_ in first:
            proc.communicate("")
        nxt, cpu4, _, _ = _claimant(lock_dir)
        nxt.communicate("")
        assert int(cpu4) == allowed[1]
    finally:
        for proc, *_ in [*extra, (third,)]:
            proc.communicate("")


def test_only_jobs_of_the_hnnbench_command_pin(monkeypatch):
    monkeypatch.delenv(affinity.CLI_ENV, raising=False)
    assert not affinity.started_by_cli()  # run_job from a notebook or a test
    monkeypatch.setenv(affinity.CLI_ENV, "123")
    assert affinity.started_by_cli()


@pytest.mark.parametrize(
    "cli, overrides, pinned",
    [
        (True, [], True),  # threads=1 under the CLI: pinned
        (False, [], False),  # run_job from a notebook: left alone
        (True, ["threads=2"], False),  # more threads asked for: left alone
        (True, ["pin_cpu=false"], False),
        (False, ["pin_cpu=true"], True),
    ],
)
def test_which_jobs_pin(monkeypatch, tmp_path, cli, overrides, pinned):
    claims = []
    monkeypatch.setattr(affinity, "claim_core", lambda: claims.append(1) or 7)
    if cli:
        monkeypatch.setenv(affinity.CLI_ENV, "123")
    else:
        monkeypatch.delenv(affinity.CLI_ENV, raising=False)
    cfg = compose(["system=spring", "model=oracle", "profile=quick", *overrides])
    rec = run_job(cfg, tmp_path / "job")[0].record
    assert rec["status"] == "ok", rec["error"]
    assert (rec.get("cpu_pin") == 7) is pinned and bool(claims) is pinned


def test_the_cli_flag_does_not_outlive_an_in_process_run(monkeypatch, capsys):
    from hnnbench._entry.command import run

    monkeypatch.delenv(affinity.CLI_ENV, raising=False)
    assert run(["--cfg", "job", "system=spring", "model=oracle"]) == 0
    capsys.readouterr()
    assert affinity.CLI_ENV not in os.environ


def test_an_unwritable_lock_directory_leaves_the_job_unpinned(tmp_path, caplog):
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("")
    affinity._held.clear()
    assert affinity.claim_core(blocker / "sub") is None
    assert "could not pin" in caplog.text and not affinity._held
