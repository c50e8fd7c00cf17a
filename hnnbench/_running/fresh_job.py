"""One job run in a fresh process, as the ``hnnbench`` command runs it, for
``hnnbench check --rerun``.

XLA sizes its CPU thread pool from the cores the process sees when JAX starts, and the
command pins each job to one core before that (:mod:`hnnbench._running.affinity`). A
job run inside a process that started JAX unpinned, or that has run other work, gets
another pool, other last bits, and training can grow those to the size of seed noise
(measured: a tuned damped_pendulum so_mlp at seed 5 ends at a test loss of 3.19e-5
pinned and 4.17e-5 unpinned). In a fresh process pinned as its record was, a re-run
gives its record's numbers on a CPU of the record's class.

Run as ``python -m hnnbench._running.fresh_job JOB.json DIRECTORY``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Optional

from hnnbench import _record as records

__all__ = ["run_fresh"]

_JOB_FILE = "fresh_job.json"


def run_fresh(
    config: Mapping[str, Any], directory: Path, overrides: Optional[Sequence[str]] = None
) -> dict[str, Any] | str:
    """Run the job of ``config`` (a resolved job config, its ``pin_cpu`` saying whether
    to pin it) with ``overrides`` (stored in its record) in a fresh Python process that
    imports only the installed code (``-P``, started in ``directory``), its record
    written into ``directory``; its progress goes to this process's standard error.

    Returns:
        the record, or one line saying why there is none.
    """
    directory.mkdir(parents=True, exist_ok=True)
    job_file = directory / _JOB_FILE
    job_file.write_text(
        json.dumps(
            {"config": dict(config), "overrides": None if overrides is None else list(overrides)}
        ),
        encoding="utf-8",
    )
    command = [sys.executable, "-P", "-m", __name__, str(job_file), str(directory)]
    try:
        child = subprocess.run(command, cwd=directory, stdout=subprocess.DEVNULL, check=False)
    except OSError as err:
        return f"the re-run's process could not start ({err})"
    finally:
        job_file.unlink(missing_ok=True)
    record = records.read_record(directory / records.RECORD_NAME)
    if record is None:
        return f"the re-run's process (exit status {child.returncode}) wrote no readable record"
    return record


def _main(argv: list[str]) -> int:
    from omegaconf import OmegaConf

    from hnnbench._running.job import run_job

    job_file, directory = argv
    job = json.loads(Path(job_file).read_text(encoding="utf-8"))
    run_job(OmegaConf.create(job["config"]), Path(directory), overrides=job["overrides"])
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
