"""The ``hnnbench`` command.

``hnnbench list | report | check ...`` are subcommands; anything else is a Hydra
command line (``hnnbench -m system=all model=all seed=0,1,2``). Before Hydra starts,
the command line is checked here: names are validated (with a did-you-mean), ``all``
expands to every registered plugin, and each swept value is composed and validated,
so a bad input fails in one line before any job runs.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import os
import shlex
import signal
import socket
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

from hnnbench import _launch as launch
from hnnbench import _registry as registry
from hnnbench._errors import ConfigError, HnnbenchError, UnknownNameError

USAGE = """\
usage: hnnbench [-m] [KEY=VALUE ...]        run one job, or a sweep with -m (Hydra)
       hnnbench list [--json]               registered systems and models
       hnnbench report DIR [--out OUT]      tables and figures from a sweep's records
       hnnbench check DIR --reference CSV   leaderboard regression gate

examples:
  hnnbench -m system=all model=all                  every model on every system (paper)
  hnnbench -m system=all model=all profile=quick    the smoke version
  hnnbench -m system=spring model=hnn_torch,mlp_torch seed=0,1,2
  hnnbench system=two_body model=hnn_jax            one run
  hnnbench --cfg job system=spring                  show the composed config

Hydra's own options: hnnbench --hydra-help. Docs: README.md, docs/.
"""

_single_run: list[dict] = []


#: Commands that only print (a listing, a config): ``| head`` may close the pipe early.
_PRINT_ONLY = ("list", "--cfg", "-c", "--info", "-i", "--help", "-h", "help", "--hydra-help")


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
        if argv and argv[0] in ("report", "check"):
            return _subcommand(argv[0], argv[1:])
        if argv and argv[0] in ("-h", "--help", "help"):
            print(USAGE)
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
        print("hnnbench: interrupted; finished jobs keep their records. Re-run the same "
              "command with hydra.sweep.dir=<dir> to resume.", file=sys.stderr)
        return 130
    except Exception as err:  # a bug, not a user error: still one line, then the way on
        if _full_error():
            raise
        _error_line(f"unexpected {type(err).__name__}: {err} (set HYDRA_FULL_ERROR=1 for the "
                    "traceback, and please report it)")
        return 1


def _full_error() -> bool:
    return os.environ.get("HYDRA_FULL_ERROR") == "1"


def _error_line(message: str) -> None:
    """``hnnbench: error: <message>`` on one line, whatever the message holds."""
    print(f"hnnbench: error: {' '.join(message.split())}", file=sys.stderr)


# --------------------------------------------------------------------------- list


def cmd_list(args: list[str]) -> int:
    import json

    from tabulate import tabulate

    if any(a not in ("--json",) for a in args):
        raise ConfigError(f"hnnbench list: unknown argument {args}; expected: [--json]")
    out: dict[str, list[dict[str, Any]]] = {}
    for kind in ("system", "model", "metric", "claims"):
        out[kind] = [
            {"name": i.name, "version": i.version, "backend": i.backend,
             "family": i.family,
             "package": f"{i.distribution} {i.dist_version}" if i.distribution else "?",
             "status": "ok" if i.ok else "error", "description": i.description,
             "error": i.error}
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
        rows = [[r[h] if h != "description" or r["status"] == "ok" else f"ERROR: {r['error']}"
                 for h in headers] for r in out[kind]]
        print(f"{title} (entry points: {registry.GROUPS[kind]})")
        print(tabulate(rows, headers=headers, tablefmt="simple"))
        print()
    print("Profiles: " + ", ".join(registry.PROFILES))
    return 0


def _subcommand(name: str, args: list[str]) -> int:
    import importlib

    try:
        module = importlib.import_module(f"hnnbench._{name}")
    except HnnbenchError:
        raise
    except ModuleNotFoundError as err:
        if err.name == f"hnnbench._{name}":
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


# --------------------------------------------------------------------------- hydra


@dataclass
class Plan:
    """A checked command line, ready for Hydra."""

    argv: list[str]
    multirun: bool
    n_jobs: int | None
    overrides: list[str] = field(default_factory=list)


@dataclass
class _Entry:
    """One override of the command line."""

    text: str
    prefix: str  # "", "+", "++" or "~"
    key: str
    values: list[Any] | None  # None: a sweep hnnbench cannot enumerate (left to Hydra)
    sweep: bool


def _parse_flags(argv: list[str]) -> argparse.Namespace:
    """Hydra's own argument parser, with flags and overrides in any order, raising a
    one-line :class:`ConfigError` instead of printing usage and exiting."""
    from hnnbench._hydra import args_parser

    parser = args_parser()
    parser.prog = "hnnbench"

    def error(message: str) -> NoReturn:
        raise ConfigError(f"{message} (see hnnbench --help)")

    parser.error = error  # type: ignore[method-assign]
    ns = parser.parse_intermixed_args(argv)
    commands = [name for name, on in (
        ("--run", ns.run), ("--multirun", ns.multirun), ("--cfg", ns.cfg is not None),
        ("--info", ns.info is not None), ("--shell-completion", ns.shell_completion)) if on]
    if len(commands) > 1:
        raise ConfigError(
            f"{' and '.join(commands)} cannot be combined: give one of --run, --multirun (-m), "
            "--cfg, --info, --shell-completion"
        )
    if ns.resolve and ns.cfg is None and not ns.help:
        raise ConfigError("--resolve only works together with --cfg, e.g. --cfg job --resolve")
    if ns.package is not None and ns.cfg is None:
        raise ConfigError("--package only works together with --cfg, e.g. --cfg job -p system")
    for flag, value in (("--config-dir", ns.config_dir), ("--config-path", ns.config_path)):
        if value is None or value.startswith("pkg://"):
            continue
        path = Path(value.removeprefix("file://")).expanduser()
        if not path.is_dir():
            raise ConfigError(f"{flag} {value}: no such directory")
        # Hydra reads a relative --config-path relative to hnnbench's own source file;
        # users mean their working directory.
        resolved = str(path.resolve())
        if flag == "--config-dir":
            ns.config_dir = resolved
        else:
            ns.config_path = resolved
    if ns.experimental_rerun is not None and not Path(ns.experimental_rerun).is_file():
        raise ConfigError(f"--experimental-rerun {ns.experimental_rerun}: no such file")
    return ns


def _flag_args(ns: argparse.Namespace) -> list[str]:
    """The parsed flags as Hydra expects them, in canonical spelling."""
    out: list[str] = []
    for name, flag in (("help", "--help"), ("hydra_help", "--hydra-help"), ("run", "--run"),
                       ("multirun", "--multirun"), ("shell_completion", "--shell-completion"),
                       ("resolve", "--resolve")):
        if getattr(ns, name):
            out.append(flag)
    for name, flag in (("cfg", "--cfg"), ("package", "--package"),
                       ("config_path", "--config-path"), ("config_name", "--config-name"),
                       ("config_dir", "--config-dir"), ("experimental_rerun",
                                                        "--experimental-rerun"),
                       ("info", "--info")):
        if getattr(ns, name) is not None:
            out += [flag, getattr(ns, name)]
    return out


def _expand_names(kind: str, values: list[str]) -> list[str]:
    names = registry.available(kind)  # type: ignore[arg-type]
    out: list[str] = []
    for value in values:
        for name in names if value == "all" else [value]:
            if name not in registry.discover(kind):  # type: ignore[arg-type]
                raise UnknownNameError(kind, name, names)
            registry.get_class(kind, name)  # type: ignore[arg-type]  # unusable -> error
            if name not in out:
                out.append(name)
    return out


_PREFIX = {"ADD": "+", "FORCE_ADD": "++", "DEL": "~", "CHANGE": ""}


def _parse_override(parser: Any, text: str) -> _Entry:
    from hydra.core.override_parser.types import Glob

    from hnnbench._config import hydra_error_line

    try:
        (ov,) = parser.parse_overrides([text])
    except Exception as err:
        raise ConfigError(f"Cannot parse override '{text}': {hydra_error_line(err)}") from None
    key = ov.key_or_group
    if not key:
        raise ConfigError(f"Cannot parse override '{text}': expected KEY=VALUE, e.g. seed=0")
    prefix = _PREFIX.get(ov.type.name, "")
    if ov.is_delete():
        return _Entry(text, prefix, key, [], False)
    if not ov.is_sweep_override():
        value = ov.get_value_element_as_str()
        if key in ("system", "model"):
            names = _expand_names(key, [value])
            if len(names) > 1:  # `all`
                return _Entry(f"{prefix}{key}={','.join(names)}", prefix, key, names, True)
            return _Entry(f"{prefix}{key}={names[0]}", prefix, key, names, False)
        return _Entry(text, prefix, key, [value], False)
    try:
        values: list[Any] | None = [str(v) for v in ov.sweep_string_iterator()]
    except Exception:  # glob(...) and interval(...): not enumerable without a config
        value = ov.value()
        values = None
        if key in ("system", "model") and isinstance(value, Glob):
            values = value.filter(registry.available(key))
            if not values:
                raise ConfigError(
                    f"{text}: the pattern matches no registered {key} "
                    f"(available: {', '.join(registry.available(key))})"
                ) from None
        elif ov.value_type is not None and ov.value_type.name == "INTERVAL_SWEEP":
            raise ConfigError(
                f"{text}: interval() needs an optimizing sweeper; the basic sweeper "
                "takes lists (a,b,c), range() and choice()"
            ) from None
    if values is not None and key in ("system", "model"):
        values = _expand_names(key, values)
        text = f"{prefix}{key}={','.join(values)}"
    return _Entry(text, prefix, key, values, True)


def _batch_seeds(entries: list[_Entry]) -> list[_Entry]:
    """With ``seeds_per_job=N`` (N > 1), a sweep ``seed=a,b,c,...`` becomes one job per
    N seeds: ``seed_batch=[a,b,c],[d,...]`` with ``seed=${seed_batch.0}``, the first of
    each batch (its records' directories stay ``seed<k>``; hnnbench._job.seed_directory)."""
    given = next((e for e in entries if e.key == "seed_batch"), None)
    if given is not None:
        raise ConfigError(f"{given.text}: seed_batch is set by seeds_per_job; give the seeds "
                          "with seed, e.g. -m seed=0,1,2 seeds_per_job=3")
    per_job = [e for e in entries if e.key == "seeds_per_job" and not e.sweep and e.values]
    if not per_job:
        return entries
    try:
        size = int(str(per_job[-1].values[0]))  # type: ignore[index]
    except ValueError:
        return entries  # validation reports the bad value
    where = [i for i, e in enumerate(entries) if e.key == "seed"]
    if size <= 1 or not where:
        return entries
    i = where[-1]
    seed = entries[i]
    if not seed.sweep or not seed.values or len(seed.values) < 2:
        return entries
    try:
        values = [int(str(v)) for v in seed.values]
    except ValueError:
        raise ConfigError(f"{seed.text}: seeds must be integers, e.g. seed=0,1,2") from None
    groups = [values[k:k + size] for k in range(0, len(values), size)]
    texts = ["[" + ",".join(map(str, g)) + "]" for g in groups]
    batch = _Entry(f"seed_batch={','.join(texts)}", "", "seed_batch", texts, len(texts) > 1)
    leader = _Entry("seed=${seed_batch.0}", "", "seed", ["${seed_batch.0}"], False)
    return [*entries[:i], leader, batch, *entries[i + 1:]]


def _trial(entries: list[_Entry], choice: dict[int, Any]) -> list[str]:
    """Overrides of one job: each sweep replaced by its chosen value (or its first)."""
    out = []
    for i, e in enumerate(entries):
        if not e.sweep:
            out.append(e.text)
        elif e.values:  # unenumerable sweeps are left to Hydra
            out.append(f"{e.prefix}{e.key}={choice.get(i, e.values[0])}")
    return out


def _is_group(key: str) -> bool:
    return key in ("system", "model", "profile") or "/" in key or key.startswith("hydra")


def plan(argv: list[str]) -> Plan:
    """Check a Hydra command line and rewrite ``all``; raise :class:`ConfigError`.

    The flags are parsed by Hydra's own parser; every override is parsed, names are
    checked, and the config of the first job and of every other swept value is
    composed (Hydra's ``hydra`` node included) and validated, so that Hydra never gets
    a command line it would reject with a multi-line error.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from omegaconf import OmegaConf, open_dict

    from hnnbench._config import (
        check_hydra_node,
        compose,
        hydra_error_line,
        prepare_job,
        profile_of,
    )

    ns = _parse_flags(argv)
    flags = _flag_args(ns)
    multirun = bool(ns.multirun)
    if ns.shell_completion:  # its arguments (install=bash) are not config overrides
        return Plan(argv=flags + list(ns.overrides), multirun=False, n_jobs=None,
                    overrides=list(ns.overrides))
    profile_of(list(ns.overrides))
    parser = OverridesParser.create()
    entries = [_parse_override(parser, text) for text in ns.overrides]
    if multirun:
        entries = _batch_seeds(entries)
    rewritten = [e.text for e in entries]
    sweeps = {i: e for i, e in enumerate(entries) if e.sweep and (e.values is None
                                                                  or len(e.values) > 1)}
    if sweeps and not multirun:
        e = next(iter(sweeps.values()))
        vals = [str(v) for v in e.values or []]
        shown = f" ({', '.join(vals[:4])}{', ...' if len(vals) > 4 else ''})" if vals else ""
        if ns.cfg is not None or ns.info is not None:
            raise ConfigError(f"{e.key} has several values{shown}: --cfg and --info show one "
                              "config, so give one value per key")
        raise ConfigError(
            f"{e.key} has {len(vals) or 'several'} values{shown}: that is a sweep, so add -m, "
            f"e.g. hnnbench -m {' '.join(rewritten)}"
        )
    kwargs: dict[str, Any] = {}
    if ns.config_name is not None:
        kwargs["config_name"] = ns.config_name
    if ns.config_path is not None and not ns.config_path.startswith("pkg://"):
        kwargs["config_dir"] = ns.config_path
    extra: list[str] = []
    if ns.config_dir:  # Hydra puts it first on the search path, as these do
        if (Path(ns.config_dir) / f"{ns.config_name or 'config'}.yaml").is_file():
            kwargs.setdefault("config_dir", ns.config_dir)
            extra = ["hydra.searchpath=[pkg://hnnbench_conf]"]
        else:
            extra = [f"hydra.searchpath=[file://{ns.config_dir}]"]

    def job_config(overrides: list[str]) -> Any:
        """The job config (validated), then the hydra node it was composed with."""
        cfg = compose(overrides + extra, return_hydra_config=True, **kwargs)
        with open_dict(cfg):
            hydra_node = cfg.pop("hydra")
        prepare_job(cfg)
        with open_dict(cfg):
            cfg["hydra"] = hydra_node
        check_hydra_node(cfg)
        with open_dict(cfg):
            del cfg["hydra"]
        return cfg

    # The first job, composed with everything (the hydra node and its directories too).
    base = job_config(_trial(entries, {}))
    # Every other swept value, against the first value of the other keys: a group
    # (system, model, hydra/...) is composed again; a plain value is merged (fast).
    for i, e in sweeps.items():
        for value in (e.values or [])[1:]:
            if _is_group(e.key) or e.prefix:
                job_config(_trial(entries, {i: value}))
                continue
            cfg = copy.deepcopy(base)
            try:
                (ov,) = parser.parse_overrides([f"{e.key}={value}"])
                OmegaConf.update(cfg, e.key, ov.value(), merge=True)
            except ConfigError:
                raise
            except Exception as err:
                raise ConfigError(
                    f"Error merging override {e.key}={value}: {hydra_error_line(err)}"
                ) from None
            prepare_job(cfg)
    n_jobs: int | None = 1
    counts: dict[str, int | None] = {}
    for e in entries:
        if not e.key.startswith("hydra"):
            counts[e.key] = None if e.values is None else max(len(e.values), 1)
    for count in counts.values():
        n_jobs = None if n_jobs is None or count is None else n_jobs * count
    return Plan(argv=flags + rewritten, multirun=multirun, n_jobs=n_jobs, overrides=rewritten)


def _task(cfg) -> None:  # noqa: ANN001 - Hydra passes a DictConfig
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    from hnnbench._job import run_seeds

    hc = HydraConfig.get()
    multirun = hc.mode == RunMode.MULTIRUN
    context = launch.current()
    total = context.n_jobs if context is not None else None
    recs = run_seeds(cfg, Path(hc.runtime.output_dir), hc.job.num if multirun else None, total,
                     overrides=list(hc.overrides.task))
    if not multirun:
        _single_run.extend(recs)


@dataclass
class Execution:
    """What a Hydra command line ran: the records of a single run (a sweep's are on
    disk under its ``hydra.sweep.dir``)."""

    multirun: bool
    records: list[dict[str, Any]]


def execute(argv: list[str], command: str | None = None) -> Execution:
    """Check and run a Hydra command line (``hnnbench`` without a subcommand) in this
    process; raise :class:`HnnbenchError` (one line) for bad input. ``command`` is the
    command line stored in the records (default: ``hnnbench`` and ``argv``)."""
    import hydra

    from hnnbench._config import profile_of, register_schema

    checked = plan(argv)
    register_schema()
    shell = "--shell-completion" in checked.argv
    registry.register_configs("paper" if shell else profile_of(checked.overrides))
    if checked.multirun and checked.n_jobs:
        print(f"hnnbench: {checked.n_jobs} job(s)", file=sys.stderr)
    # Jobs (here or in launcher workers) see the command line, the sweep's size, and
    # that the hnnbench command started them (they then pin a core: hnnbench._affinity).
    context = launch.LaunchContext(command=command or shlex.join(["hnnbench", *argv]),
                                   n_jobs=checked.n_jobs or None, cli_pid=os.getpid(),
                                   host=socket.gethostname())
    saved = sys.argv
    sys.argv = [saved[0] if saved else "hnnbench", *checked.argv]
    _single_run.clear()
    try:
        with launch.launched(context), _one_line_hydra_errors():
            hydra.main(version_base="1.3", config_path="pkg://hnnbench_conf",
                       config_name="config")(_task)()
    finally:
        sys.argv = saved
    return Execution(multirun=checked.multirun, records=list(_single_run))


def run_hydra(argv: list[str]) -> int:
    result = execute(argv)
    if result.records and not result.multirun:
        return _report_single(result.records[0])
    return 0


def _one_line_hydra_errors() -> contextlib.AbstractContextManager[None]:
    """A safety net behind :func:`plan`: an error Hydra still finds (it prints several
    lines and exits) becomes a one-line :class:`HnnbenchError`."""
    from hnnbench._config import hydra_error_line
    from hnnbench._hydra import one_line_errors

    return one_line_errors(hydra_error_line, enabled=not _full_error())


def _report_single(record: dict) -> int:
    from tabulate import tabulate

    status = record["status"]
    if status == "failed":
        _error_line(str(record.get("error")))
        return 1
    rows = [[k, v.get("mean"), v.get("sem")] for k, v in record.get("metrics", {}).items()]
    print(tabulate(rows, headers=["metric", "mean", "sem"], floatfmt=".4g"))
    print(f"status: {status}" + (f" ({record.get('error')})" if record.get("error") else ""))
    return 0 if status in ("ok", "skipped") else 1

