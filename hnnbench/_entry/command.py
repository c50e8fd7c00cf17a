"""The ``hnnbench`` command.

``hnnbench list | report | check | tune ...`` are subcommands; anything else is a Hydra
command line (``hnnbench -m system=all model=all seed=0,1,2``). Before Hydra starts,
the command line is checked here: names are validated (with a did-you-mean), ``all``
expands to every registered plugin, and each swept value is composed and validated,
so a bad input fails in one line before any job runs.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any, Optional

from hnnbench import _registry as registry
from hnnbench._contracts.errors import ConfigError, HnnbenchError
from hnnbench._sweeping.execution import execute

USAGE = """\
usage: hnnbench [-m] [KEY=VALUE ...]        run one job, or a sweep with -m (Hydra)
       hnnbench list [--json]               registered systems and models
       hnnbench report DIR [--out OUT]      tables and figures from a sweep's records
       hnnbench check DIR --reference CSV   leaderboard regression gate
       hnnbench tune system=S model=A,B trials=N [seeds=0,...,4] [steps=K] [out=DIR]
                                            the tuned track: the same tuning budget
                                            for every model, selected on validation
       hnnbench --version                   hnnbench's version (and Python's, Hydra's)

examples:
  hnnbench -m system=all model=all                  every model on every system (paper)
  hnnbench -m system=all model=all profile=quick    the smoke version
  hnnbench -m system=spring model=hnn_torch,mlp_torch seed=0,1,2
  hnnbench system=two_body model=hnn_jax            one run
  hnnbench --cfg job system=spring                  show the composed config

Hydra's own options: hnnbench --hydra-help. Docs: README.md, docs/.
"""

#: Commands that only print (a listing, a config): ``| head`` may close the pipe early.
_PRINT_ONLY = (
    "list",
    "--cfg",
    "-c",
    "--info",
    "-i",
    "--help",
    "-h",
    "help",
    "--hydra-help",
    "--version",
)


def main(argv: Sequence[str] | None = None) -> None:
    """Console-script entry point; exits with the command's status."""
    args = list(sys.argv[1:] if argv is None else argv)
    if any(a.split("=", 1)[0] in _PRINT_ONLY for a in args) and hasattr(signal, "SIGPIPE"):
        # Die quietly when the reader goes away, as Unix tools do (never for runs:
        # there a closed pipe must not kill a sweep).
        signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    sys.exit(run(args))


def run(argv: list[str]) -> int:
    """Run the command ``argv``; return its exit status. User errors (and anything
    unexpected) are one line on stderr, unless ``HYDRA_FULL_ERROR=1``."""
    try:
        if argv and argv[0] == "list":
            return cmd_list(argv[1:])
        if argv and argv[0] in ("report", "check", "tune"):
            return _subcommand(argv[0], argv[1:])
        if argv and argv[0] in ("-h", "--help", "help"):
            print(USAGE)
            return 0
        if "--version" in argv:  # hnnbench's, not Hydra's (which --version would print)
            print(version_line())
            return 0
        return run_hydra(argv)
    except HnnbenchError as err:
        if _full_error():
            raise
        _error_line(str(err))
        return 2
    except BrokenPipeError:  # `hnnbench list | head`: the reader left; nothing to say
        with contextlib.suppress(OSError, ValueError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except KeyboardInterrupt:
        how = (
            "the same command (same out=)"
            if argv and argv[0] == "tune"
            else "the same command with hydra.sweep.dir=<dir>"
        )
        print(
            f"hnnbench: interrupted; finished jobs keep their records. Re-run {how} to resume.",
            file=sys.stderr,
        )
        return 130
    except Exception as err:  # a bug, not a user error: still one line, then the way on
        if _full_error():
            raise
        _error_line(
            f"unexpected {type(err).__name__}: {err} (set HYDRA_FULL_ERROR=1 for the "
            "traceback, and please report it)"
        )
        return 1


def version_line() -> str:
    """``hnnbench 0.4.0 (Python 3.11.7, Hydra 1.3.8)``: the installed distribution's
    version (the package's ``__version__`` where it is not installed as one)."""
    import platform
    from importlib import metadata

    import hnnbench

    try:
        version = metadata.version("hnnbench")
    except metadata.PackageNotFoundError:
        version = hnnbench.__version__
    try:
        hydra = f", Hydra {metadata.version('hydra-core')}"
    except metadata.PackageNotFoundError:
        hydra = ""
    return f"hnnbench {version} (Python {platform.python_version()}{hydra})"


def _full_error() -> bool:
    return os.environ.get("HYDRA_FULL_ERROR") == "1"


def _error_line(message: str) -> None:
    """``hnnbench: error: <message>`` on one line, whatever the message holds."""
    from hnnbench._contracts.text import printable

    print(f"hnnbench: error: {' '.join(printable(message).split())}", file=sys.stderr)


# --------------------------------------------------------------------------- list


def cmd_list(args: list[str]) -> int:
    import json

    from tabulate import tabulate

    from hnnbench._contracts.space import describe, space_json

    if any(a not in ("--json",) for a in args):
        raise ConfigError(f"hnnbench list: unknown argument {args}; expected: [--json]")
    out: dict[str, list[dict[str, Any]]] = {}
    for kind in ("system", "model", "metric", "claims"):
        out[kind] = [
            {
                "name": i.name,
                "version": i.version,
                "backend": i.backend,
                "family": i.family,
                "package": f"{i.distribution} {i.dist_version}" if i.distribution else "?",
                "status": "ok" if i.ok else "error",
                "description": i.description,
                "error": i.error,
                **(
                    {
                        "search_space": space_json(i.search_space) if i.search_space else None,
                        "recipe": i.recipe,
                    }
                    if kind == "model"
                    else {}
                ),
            }
            for i in registry.discover(kind).values()
        ]
    if "--json" in args:
        print(json.dumps(out, indent=2))
        return 0
    layouts = {
        "system": ("Systems", ["name", "version", "package", "description"]),
        "model": ("Models", ["name", "version", "backend", "family", "package", "description"]),
        "metric": ("Metrics", ["name", "package", "description"]),
        "claims": ("Claim sets", ["name", "package", "description"]),
    }
    for kind, (title, headers) in layouts.items():
        rows = [
            [
                r[h] if h != "description" or r["status"] == "ok" else f"ERROR: {r['error']}"
                for h in headers
            ]
            for r in out[kind]
        ]
        print(f"{title} (entry points: {registry.GROUPS[kind]})")
        print(tabulate(rows, headers=headers, tablefmt="simple"))
        print()
    # A family's backends declare one space and one recipe: each shown once per family.
    _per_family(
        "Search spaces (hnnbench tune; docs/TUNING.md)",
        "space",
        lambda i: describe(i.search_space) if i.search_space else None,
    )
    _per_family(
        "Recipes (track=recipe: the defaults a paper's own recipe sets; docs/TUNING.md)",
        "recipe",
        lambda i: " ".join(f"{k}={v}" for k, v in i.recipe.items()) if i.recipe else None,
    )
    print("Profiles: " + ", ".join(registry.PROFILES))
    return 0


def _per_family(title: str, header: str, describe: Callable[[Any], Optional[str]]) -> None:
    """A table of what each model family (or familyless model) declares, once per
    family, for the installed models where ``describe`` gives a text."""
    from tabulate import tabulate

    rows = [
        (i.family if i.family != "-" else i.name, text)
        for i in registry.discover("model").values()
        if (text := describe(i)) is not None
    ]
    if rows:
        print(title)
        print(
            tabulate(
                list(dict.fromkeys(rows)), headers=["family or model", header], tablefmt="simple"
            )
        )
        print()


#: The module whose ``main(args)`` runs each subcommand (imported when it is run).
SUBCOMMANDS = {
    "report": "hnnbench._results.report.cli",
    "check": "hnnbench._results.check.command",
    "tune": "hnnbench._tuning.command",
}


def _subcommand(name: str, args: list[str]) -> int:
    import importlib

    try:
        module = importlib.import_module(SUBCOMMANDS[name])
    except HnnbenchError:
        raise
    except ModuleNotFoundError as err:
        if err.name == SUBCOMMANDS[name]:
            raise HnnbenchError(f"'hnnbench {name}' is not available in this version") from None
        raise HnnbenchError(
            f"'hnnbench {name}' needs {err.name}, which is not installed: {err}"
        ) from None
    except Exception as err:
        raise HnnbenchError(
            f"'hnnbench {name}' could not be loaded ({type(err).__name__}: {err})"
        ) from None
    main = getattr(module, "main", None)
    if main is None:
        raise HnnbenchError(f"'hnnbench {name}' is not available in this version")
    status = main(args)
    return int(status) if status is not None else 0


def run_hydra(argv: list[str]) -> int:
    """Run a Hydra command line. A single run: its status (0 for ``ok`` and
    ``skipped``). A sweep: 1 when a job of this run failed, timed out or returned no
    record (``diverged`` and ``skipped`` are outcomes, not failures), else 0; its last
    line says how many, and how many were kept from an earlier run."""
    result = execute(argv)
    if result.records and not result.multirun:
        return _report_single(result.records[0])
    if not result.sweep:
        return 0
    failed, line = result.verdict()
    print(f"hnnbench: {line}", file=sys.stderr)
    return 1 if failed else 0


def _report_single(record: dict) -> int:
    from tabulate import tabulate

    status = record["status"]
    if status == "failed":
        _error_line(str(record.get("error")))
        return 1
    print(tabulate(summary_rows(record), headers=["metric", "mean", "sem"], floatfmt=".4g"))
    print(f"status: {status}" + (f" ({record.get('error')})" if record.get("error") else ""))
    return 0 if status in ("ok", "skipped") else 1


def summary_rows(record: dict) -> list[list[Any]]:
    """A single run's metric rows, ``[name with its direction, mean, sem]``: only the
    metrics that apply to its system (a metric that does not records no value, NaN, and
    is left out; so is one that has no value for this model)."""
    import math

    from hnnbench._results.leaderboard import direction_header, metric_declarations

    declared = metric_declarations()
    rows = []
    for name, value in (record.get("metrics") or {}).items():
        mean = value.get("mean") if isinstance(value, dict) else None
        if mean is None or (isinstance(mean, float) and math.isnan(mean)):
            continue
        rows.append([direction_header(name, declared), mean, value.get("sem")])
    return rows
