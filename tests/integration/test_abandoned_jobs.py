"""A job stops when the hnnbench command on its host has gone (a real process that exits),
and not otherwise."""

from __future__ import annotations

import os

from hnnbench._running import launch_context


def test_a_job_is_abandoned_only_when_its_command_on_this_host_has_gone(monkeypatch):
    import socket
    import subprocess
    import sys

    monkeypatch.delenv(launch_context.ENV, raising=False)
    assert not launch_context.abandoned()  # not started by a command
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()  # reaped: its pid names no process now
    here = socket.gethostname()
    with launch_context.launched(launch_context.LaunchContext(cli_pid=gone.pid, host=here)):
        assert launch_context.abandoned()
    other = launch_context.LaunchContext(cli_pid=gone.pid, host=here + "-other")
    with launch_context.launched(other):
        assert not launch_context.abandoned()  # another host's pid says nothing here
    with launch_context.launched(launch_context.LaunchContext(cli_pid=gone.pid)):
        assert not launch_context.abandoned()  # host unknown
    for alive in (os.getpid(), os.getppid()):
        with launch_context.launched(launch_context.LaunchContext(cli_pid=alive, host=here)):
            assert not launch_context.abandoned()
