"""One core per launcher worker (hnnbench.affinity), with real processes and locks."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

from hnnbench import affinity

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
    from hnnbench.affinity import claim_core
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
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(lock_dir)], text=True,
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    cpu, again, early = proc.stdout.readline().split(" ", 2)
    return proc, cpu, again, early.strip()


def test_concurrent_claimants_get_distinct_cores_then_none(tmp_path):
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
        proc, cpu, again, early = _claimant(tmp_path)  # every core taken: share one
        held.append(proc)
        assert cpu == again and int(cpu) in allowed and early == f"[{cpu}]"
    finally:
        for proc in held:
            proc.communicate("")
    # the locks died with their processes: a new claimant gets the first core again
    proc, cpu, _, _ = _claimant(tmp_path)
    proc.communicate("")
    assert cpu == str(allowed[0])


def test_only_jobs_of_the_hnnbench_command_pin(monkeypatch):
    monkeypatch.delenv(affinity.CLI_ENV, raising=False)
    assert not affinity.started_by_cli()  # run_job from a notebook or a test
    monkeypatch.setenv(affinity.CLI_ENV, "123")
    assert affinity.started_by_cli()
