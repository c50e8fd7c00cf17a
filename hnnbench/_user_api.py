"""The Python API: the ``hnnbench`` command, callable from a notebook.

``run`` and ``sweep`` build the same Hydra command line as the CLI and run it through
the same machinery in this process (:func:`hnnbench._cli.execute`): the same
composition, validation, launchers and job code, so the records on disk are the
CLI's. A bad input raises the CLI's one-line error as a typed exception
(:class:`~hnnbench._errors.ConfigError`, :class:`~hnnbench._errors.UnknownNameError`,
...). ``load`` and ``leaderboard`` read records back into pandas.

Like the CLI, a run pins this process to one CPU core and caps its BLAS threads
(:mod:`hnnbench._affinity`), which is what makes JAX results independent of how jobs
are launched; pass ``pin_cpu=False`` to leave the process alone (results may then
differ from the CLI's in the last bits).
"""

from __future__ import annotations

import datetime as _dt
import shlex
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Optional, Union

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["leaderboard", "load", "run", "sweep"]

Names = Union[str, Sequence[str]]


def _value(value: Any) -> str:
    """A Python value as a Hydra override value."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(_value(v) for v in value) + "]"
    return str(value)


def _overrides(overrides: dict[str, Any]) -> list[str]:
    """``model__steps=500`` -> ``model.steps=500`` (``__`` stands for a dot, which a
    keyword cannot hold). A string value goes to Hydra as written, so in :func:`sweep`
    ``model__hidden="100,200"`` sweeps over two values."""
    return [f"{key.replace('__', '.')}={_value(value)}" for key, value in overrides.items()]


def _names(value: Names) -> str:
    return value if isinstance(value, str) else ",".join(value)


def _command(function: str, args: list[str]) -> str:
    return shlex.join(["hnnbench", *args]) + f"  # via hnnbench.{function}()"


def run(system: str, model: str, seed: int = 0, profile: str = "paper",
        out: Optional[Union[str, Path]] = None, **overrides: Any) -> dict[str, Any]:
    """Run one job, as ``hnnbench system=... model=... seed=... profile=...``; return
    its record (``result.json``, decoded).

    Args:
        system, model: registered names (``hnnbench list``).
        seed: the seed of data, evaluation and initial weights.
        profile: ``paper`` or ``quick``.
        out: the job's directory (default: Hydra's run directory, under
            ``results/runs/single/``).
        **overrides: any other setting, ``__`` for a dot: ``model__steps=500``,
            ``system__n_traj=20``, ``device="cpu"``.

    Raises:
        HnnbenchError: bad input (the CLI's one-line message).
    """
    from hnnbench._cli import execute

    args = [f"system={system}", f"model={model}", f"seed={seed}", f"profile={profile}",
            *_overrides(overrides)]
    if out is not None:
        args.append(f"hydra.run.dir={Path(out).resolve()}")
    result = execute(args, command=_command("run", args))
    return result.records[0]


def sweep(systems: Names, models: Names, seeds: Iterable[int] = (0,),
          profile: str = "quick", launcher: str = "basic",
          out: Optional[Union[str, Path]] = None, **overrides: Any) -> pd.DataFrame:
    """Run a sweep, as ``hnnbench -m system=... model=... seed=...``; return its
    leaderboard (one row per system x model, mean and std over seeds).

    Args:
        systems, models: names, lists of names, or ``"all"``.
        seeds: the seeds of every pair.
        profile: ``quick`` (default here: minutes) or ``paper``.
        launcher: a Hydra launcher (``basic``, ``joblib``, ``submitit_local``, ...).
        out: the sweep directory (default ``results/runs/<profile>_<time>``). Running
            the same sweep into the same directory again resumes it.
        **overrides: as for :func:`run`; a string value is passed as written, so
            ``model__hidden="100,200"`` adds a swept setting.

    The frame's ``attrs["sweep_dir"]`` is the directory of the records.
    """
    from hnnbench._cli import execute
    from hnnbench._report.inputs import load_sweep

    seeds = list(seeds)
    if out is None:
        stamp = _dt.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
        out = Path("results") / "runs" / f"{profile}_{stamp}"
    out = Path(out).resolve()
    args = ["-m", f"system={_names(systems)}", f"model={_names(models)}",
            f"seed={','.join(str(s) for s in seeds)}", f"profile={profile}",
            f"hydra/launcher={launcher}", f"hydra.sweep.dir={out}", *_overrides(overrides)]
    execute(args, command=_command("sweep", args))
    board = leaderboard(load_sweep(out))
    board.attrs["sweep_dir"] = str(out)
    return board


def load(*dirs: Union[str, Path]) -> pd.DataFrame:
    """The records under the directories as a DataFrame: one row per record, with
    identity columns, ``<metric>`` means and ``<metric>_sem``, timings and provenance
    (:func:`hnnbench._table.records_frame`). Unreadable or invalid files are named in
    a warning."""
    from hnnbench._report.inputs import load_sweep
    from hnnbench._table import records_frame

    if not dirs:
        raise TypeError("load() needs at least one directory")
    return records_frame(load_sweep(*dirs))


def leaderboard(frame: Union[pd.DataFrame, Iterable[dict[str, Any]]]) -> pd.DataFrame:
    """The leaderboard of a frame of records (:func:`load`) or of records themselves:
    one row per (profile, system, model, variant), status counts, ``<metric>_mean`` and
    ``<metric>_std`` over seeds, mean timings, provenance."""
    import pandas as pd

    from hnnbench._table import leaderboard as from_records
    from hnnbench._table import leaderboard_frame

    if isinstance(frame, pd.DataFrame):
        return leaderboard_frame(frame)
    return from_records(frame)
