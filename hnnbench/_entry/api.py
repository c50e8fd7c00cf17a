"""The Python API: the ``hnnbench`` command, callable from a notebook.

``run`` and ``sweep`` plan and run their jobs through the same sweep path as the CLI
(:mod:`hnnbench._sweeping`): the same composition, validation, launchers and job code,
so the records on disk are the CLI's, and they return the records of exactly the jobs
they ran. A bad input raises the CLI's one-line error as a typed exception
(:class:`~hnnbench.ConfigError`, :class:`~hnnbench.UnknownNameError`, ...). ``load``
and ``leaderboard`` read records back into pandas.

Like the CLI, a run pins this process to one CPU core and caps its BLAS threads
(:mod:`hnnbench._running.affinity`), which is what makes JAX results independent of how
jobs are launched; pass ``pin_cpu=False`` to leave the process alone (results may then
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

__all__ = ["leaderboard", "load", "run", "sweep", "tune"]

Names = Union[str, Sequence[str]]


def _settings(overrides: dict[str, Any]) -> tuple[dict[str, Any], dict[str, str]]:
    """``model__steps=500`` -> ``{"model.steps": 500}`` (``__`` stands for a dot, which a
    keyword cannot hold). A string value is a Hydra value as written (so in
    :func:`sweep`, ``model__hidden="100,200"`` sweeps over two values); any other value
    is passed as that value."""
    typed: dict[str, Any] = {}
    raw: dict[str, str] = {}
    for key, value in overrides.items():
        (raw if isinstance(value, str) else typed)[key.replace("__", ".")] = value
    return typed, raw


def _names(value: Names) -> list[str]:
    return [value] if isinstance(value, str) else list(value)


def _out_dir(out: Union[str, Path]) -> str:
    """``out`` as an absolute path for Hydra's run or sweep directory: any characters
    (quotes, ``#``, ``~``, brackets, ``=``, ``,``, non-ASCII; quoted by
    :func:`hnnbench._sweeping.overrides.hydra_value`) except ``${``, which Hydra reads again as an
    interpolation wherever it uses the directory (its log file's path)."""
    from hnnbench._contracts.errors import ConfigError

    if not isinstance(out, (str, Path)):
        raise TypeError(f"out= must be a path (str or pathlib.Path), not {type(out).__name__}")
    path = str(Path(out).resolve())
    if "${" in path:
        raise ConfigError(
            f"out={str(out)!r}: a directory whose path holds '${{' cannot be "
            "used (Hydra reads it as an interpolation); choose another"
        )
    return path


def _command(function: str, checked: Any) -> str:
    """The command line that runs the same jobs (the plan's, as the CLI would take it),
    marked as made by the API."""
    return shlex.join(["hnnbench", *checked.argv]) + f"  # via hnnbench.{function}()"


def run(
    system: str,
    model: str,
    seed: int = 0,
    profile: str = "paper",
    out: Optional[Union[str, Path]] = None,
    **overrides: Any,
) -> dict[str, Any]:
    """Run one job, as ``hnnbench system=... model=... seed=... profile=...``; return
    its record (``result.json``, decoded).

    Args:
        system, model: registered names (``hnnbench list``).
        seed: the seed of data, evaluation and initial weights.
        profile: ``paper`` or ``quick``.
        out: the job's directory (default: Hydra's run directory, under
            ``results/runs/single/``); any path, spaces and quotes included.
        **overrides: any other setting, ``__`` for a dot: ``model__steps=500``,
            ``system__n_traj=20``, ``device="cpu"``.

    Raises:
        HnnbenchError: bad input (the CLI's one-line message).
    """
    from hnnbench._sweeping.execution import run_plan
    from hnnbench._sweeping.plan import request

    typed, raw = _settings(overrides)
    single: dict[str, Any] = {
        "system": system,
        "model": model,
        "seed": seed,
        "profile": profile,
        **typed,
    }
    if out is not None:
        single["hydra.run.dir"] = _out_dir(out)
    checked = request(single=single, raw=raw, multirun=False)
    command = _command("run", checked)
    result = run_plan(checked, command)
    return result.records[0]


def sweep(
    systems: Names,
    models: Names,
    seeds: Iterable[int] = (0,),
    profile: str = "quick",
    launcher: str = "basic",
    out: Optional[Union[str, Path]] = None,
    **overrides: Any,
) -> pd.DataFrame:
    """Run a sweep, as ``hnnbench -m system=... model=... seed=...``; return its
    leaderboard (one row per system x model, mean and std over seeds) of this sweep's
    jobs (records kept from an earlier run of the same sweep included).

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
    from hnnbench._sweeping.execution import run_plan
    from hnnbench._sweeping.plan import request

    seeds = [int(s) for s in seeds]
    if out is None:
        stamp = _dt.datetime.now().strftime("%Y-%m-%d_%H-%M-%S")
        out = Path("results") / "runs" / f"{profile}_{stamp}"
    out = _out_dir(out)
    typed, raw = _settings(overrides)
    checked = request(
        single={"profile": profile, "hydra/launcher": launcher, "hydra.sweep.dir": out, **typed},
        swept={"system": _names(systems), "model": _names(models), "seed": seeds},
        raw=raw,
        multirun=True,
    )
    command = _command("sweep", checked)
    result = run_plan(checked, command)
    board = leaderboard(result.records)
    board.attrs["sweep_dir"] = str(out)
    return board


def tune(
    system: str,
    models: Names,
    trials: int,
    seeds: Iterable[int] = tuple(range(10)),
    profile: str = "paper",
    out: Optional[Union[str, Path]] = None,
    steps: Optional[int] = None,
    pruner: str = "successive_halving",
    trial_seed: int = 0,
    sampler_seed: int = 0,
    seeds_per_trial: int = 2,
    **overrides: Any,
) -> pd.DataFrame:
    """The tuned track of one system, as ``hnnbench tune system=... model=...
    trials=...``: every model gets ``trials`` trials of ``steps`` steps over its
    declared search space, selected on validation, and the selected settings train on
    each of ``seeds``; return the leaderboard of those final runs (``track`` tuned,
    with the tuning's CPU seconds), which reads the seeds no trial trained: a final run
    on a trial seed is the selected trial again (``seeds`` within the trial seeds leave
    it empty). Re-running with the same ``out`` resumes.

    Args:
        system: one registered system.
        models: models that declare a search space (``"all"``: every one).
        trials: trials per model, the same for every model.
        seeds: the seeds the selected settings train on.
        profile: ``paper`` or ``quick``.
        out: the tuned track's directory (default ``results/runs/tuned_<profile>``).
        steps: steps of every trial and final run (default: the system's protocol).
        pruner: ``successive_halving`` or ``none``.
        trial_seed, sampler_seed: the first trial seed, the samplers' seed.
        seeds_per_trial: seeds each trial trains (its score: their criteria's mean).
        **overrides: ``system__n_traj=10`` and the like (``__`` for a dot), passed to
            every job; model settings are what is tuned and are refused.

    The frame's ``attrs["tuning_dir"]`` is the tuned track's directory (records under
    ``final/``, trials under ``trials/``, studies under ``tuning/``). Needs optuna
    (``pip install 'hnnbench[tune]'``).
    """
    from hnnbench._contracts.errors import ConfigError
    from hnnbench._sweeping.overrides import hydra_value
    from hnnbench._tuning.request import PASSED_KEYS, PASSED_PREFIXES, PRUNERS, TuneRequest
    from hnnbench._tuning.tuner import run_tuning

    typed, raw = _settings(overrides)
    passed = [f"{k}={hydra_value(v)}" for k, v in typed.items()] + [
        f"{k}={v}" for k, v in raw.items()
    ]
    for text in passed:
        key = text.split("=", 1)[0]
        if not (key.startswith(PASSED_PREFIXES) or key in PASSED_KEYS):
            raise ConfigError(
                f"tune(): {key} cannot be set here (model settings are what "
                "is tuned; the step budget is steps=)"
            )
    request = TuneRequest(
        system=system,
        models=_names(models),
        trials=int(trials),
        seeds=[int(s) for s in seeds],
        profile=profile,
        out=Path(_out_dir(out)) if out is not None else None,
        steps=steps,
        pruner=pruner,
        trial_seed=int(trial_seed),
        sampler_seed=int(sampler_seed),
        seeds_per_trial=int(seeds_per_trial),
        overrides=passed,
        command=f"hnnbench.tune({system!r}, {_names(models)!r}, trials={trials})",
    )
    if request.trials < 1 or request.seeds_per_trial < 1 or pruner not in PRUNERS:
        raise ConfigError(
            "tune(): trials and seeds_per_trial must be >= 1 and pruner one of "
            + ", ".join(PRUNERS)
        )
    studies = run_tuning(request)
    board = leaderboard([r for s in studies for r in s.finals])
    board.attrs["tuning_dir"] = str(request.directory.resolve())
    return board


def load(
    *dirs: Union[str, Path], strict: bool = False, allow_unverified: bool = False
) -> pd.DataFrame:
    """The records under the directories as a DataFrame: one row per record, with
    identity columns, ``<metric>`` means and ``<metric>_sem``, timings and provenance
    (:func:`hnnbench._results.leaderboard.records_frame`). Unreadable or invalid files are named in
    a warning; ``strict=True``: the one strict validation of ``hnnbench check`` and
    publishing (:mod:`hnnbench._results.validity`), and any record that fails it an error
    (``allow_unverified``: records whose plugins cannot be verified here pass)."""
    from hnnbench._results.leaderboard import records_frame
    from hnnbench._results.report.inputs import load_sweep

    if not dirs:
        raise TypeError("load() needs at least one directory")
    return records_frame(load_sweep(*dirs, strict=strict, allow_unverified=allow_unverified))


def leaderboard(frame: Union[pd.DataFrame, Iterable[dict[str, Any]]]) -> pd.DataFrame:
    """The leaderboard of a frame of records (:func:`load`) or of records themselves:
    one row per (profile, system, model, variant), status counts, ``<metric>_mean`` and
    ``<metric>_std`` over seeds, mean timings, provenance. A tuned run on one of its
    study's trial seeds is in no row (docs/TUNING.md, "Which seeds a tuned row reads")."""
    import pandas as pd

    from hnnbench._results.leaderboard import leaderboard as from_records
    from hnnbench._results.leaderboard import leaderboard_frame

    if isinstance(frame, pd.DataFrame):
        return leaderboard_frame(frame)
    return from_records(_records_given(frame))


def _records_given(value: Any) -> list[dict[str, Any]]:
    """The records passed to :func:`leaderboard`, checked: a one-line error saying what
    was expected instead of pandas' or a ``KeyError`` from deep inside."""
    from hnnbench._contracts.errors import HnnbenchError

    expected = (
        "leaderboard() takes the frame of hnnbench.load(DIR) or a list of records "
        "(dicts, as hnnbench.run returns)"
    )
    if isinstance(value, (str, Path)):
        raise TypeError(
            f"{expected}, not a path: for the records under {str(value)!r} use "
            f"hnnbench.leaderboard(hnnbench.load({str(value)!r}))"
        )
    if isinstance(value, dict):
        raise TypeError(f"{expected}, not one record: pass [record]")
    try:
        items = list(value)
    except TypeError:
        raise TypeError(f"{expected}, not {type(value).__name__}") from None
    for i, item in enumerate(items):
        if not isinstance(item, dict):
            raise TypeError(f"{expected}; item {i} is {type(item).__name__}, not a dict")
        missing = [k for k in ("system", "model", "seed", "status") if k not in item]
        if missing:
            raise HnnbenchError(
                f"{expected}; item {i} is not a record: it has no "
                f"{', '.join(repr(k) for k in missing)}"
            )
    return items
