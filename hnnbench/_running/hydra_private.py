"""The private Hydra API hnnbench still uses, in one place.

Everything else goes through Hydra's public API (``hydra.main``, ``hydra.compose``,
the launcher and sweeper plugins, ``hydra.core``). What is here has no public
equivalent in Hydra 1.3:

- :func:`args_parser`: Hydra's own command-line parser, so ``hnnbench`` accepts
  exactly Hydra's flags (and can check a command line before Hydra runs it);
- :func:`one_line_errors`: Hydra prints composition errors over several lines and
  exits from ``hydra._internal.utils.run_and_report``; while a command runs, that
  function is replaced by one that raises a one-line :class:`HnnbenchError`;
- :func:`group_lister`: Hydra's config repository over an extended search path, so
  that a user's own ``hydra/launcher/<x>.yaml`` on ``hydra.searchpath`` is known
  before Hydra starts;
- :func:`runs_in_process`: whether a launcher is Hydra's basic one, whose jobs run in
  the command's own process (they then need no environment variable to learn the
  launch context).

``tests/unit/test_hydra_private.py`` pins the behaviour each of these relies on, so a
Hydra upgrade that moves them fails there, by name.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
from collections.abc import Callable, Iterator
from typing import Any

from hydra.plugins.sweeper import Sweeper as HydraSweeper

from hnnbench._contracts.errors import HnnbenchError

__all__ = [
    "HydraSweeper",
    "args_parser",
    "basic_sweeper_class",
    "group_lister",
    "one_line_errors",
    "runs_in_process",
    "waiting_for_every_submitit_job",
]


def basic_sweeper_class() -> type:
    """Hydra's basic sweeper class, as its module holds it now (Hydra's plugin scan
    executes the module again, so a reference taken earlier may be stale)."""
    from hydra._internal.core_plugins import basic_sweeper

    return basic_sweeper.BasicSweeper


def runs_in_process(launcher: Any) -> bool:
    """Whether ``launcher`` is Hydra's basic launcher (``hydra._internal.core_plugins.
    basic_launcher.BasicLauncher``, compared by name: Hydra's plugin scan executes its
    module again), which runs each job in this process."""
    kind = type(launcher)
    return (kind.__module__, kind.__name__) == (
        "hydra._internal.core_plugins.basic_launcher",
        "BasicLauncher",
    )


def args_parser() -> argparse.ArgumentParser:
    """Hydra's argument parser (``hydra._internal.utils.get_args_parser``)."""
    from hydra._internal.utils import get_args_parser

    return get_args_parser()


@contextlib.contextmanager
def one_line_errors(
    to_line: Callable[[BaseException], str], enabled: bool = True
) -> Iterator[None]:
    """While active, an exception Hydra reports from ``run_and_report`` (composition
    errors found after hnnbench's own checks) is raised as a one-line
    :class:`HnnbenchError` built by ``to_line``."""
    import hydra._internal.utils as hydra_utils

    original = getattr(hydra_utils, "run_and_report", None)
    if original is None or not enabled:
        yield
        return

    def run_and_report(func: Any) -> Any:
        try:
            return func()
        except HnnbenchError:
            raise
        except Exception as err:
            raise HnnbenchError(to_line(err)) from None

    hydra_utils.run_and_report = run_and_report
    try:
        yield
    finally:
        hydra_utils.run_and_report = original


def group_lister(
    loader: Any, extra_paths: list[str]
) -> tuple[Callable[[str], list[str]], Callable[[str], list[str]]]:
    """``(list_groups(parent), group_options(group))`` over ``loader``'s search path
    (a Hydra config loader) plus ``extra_paths`` (``hydra.searchpath`` entries)."""
    from hydra._internal.config_repository import ConfigRepository
    from hydra.core.object_type import ObjectType

    if not extra_paths:
        return loader.list_groups, loader.get_group_options
    search_path = copy.deepcopy(loader.config_search_path)
    for entry in extra_paths:
        search_path.append(provider="hydra.searchpath (command line)", path=entry)
    repo = ConfigRepository(config_search_path=search_path)
    return (
        lambda parent: repo.get_group_options(parent, ObjectType.GROUP),
        lambda group: repo.get_group_options(group, ObjectType.CONFIG),
    )


@contextlib.contextmanager
def waiting_for_every_submitit_job(launcher: Any) -> Iterator[None]:
    """While a batch runs under a submitit launcher: wait for every job.

    Hydra's submitit launcher collects ``job.results()`` job by job and stops at the
    first that raises (a task cancelled with ``scancel``, preempted, or killed), so the
    command ends while the other tasks still run (on its own host they then exit,
    abandoned, and their work is lost). Here a job that raises gives a failed
    ``JobReturn`` holding the error instead: the launcher goes on waiting for the
    others, and the sweeper records the failed one as returning no record. Other
    launchers are left as they are."""
    if not type(launcher).__module__.startswith("hydra_plugins.hydra_submitit_launcher"):
        yield
        return
    from hydra.core.utils import JobReturn, JobStatus
    from submitit.core.core import Job

    original = Job.results

    def results(self: Any) -> list[Any]:
        try:
            return list(original(self))
        except Exception as err:  # noqa: BLE001 - whatever ended the task
            failed = JobReturn()
            failed.status = JobStatus.FAILED
            failed.return_value = err
            return [failed]

    Job.results = results  # type: ignore[method-assign]
    try:
        yield
    finally:
        Job.results = original  # type: ignore[method-assign]
