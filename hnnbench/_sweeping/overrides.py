"""A command line's flags and overrides, parsed by Hydra's own parser: names checked
(did-you-mean), ``all`` expanded, seeds grouped into batches (``seeds_per_job``),
and Python values quoted as Hydra override values.
"""

from __future__ import annotations

import argparse
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn, Optional

from hnnbench import _registry as registry
from hnnbench._contracts.errors import ConfigError, UnknownNameError
from hnnbench._running.config import hydra_error_line
from hnnbench._running.hydra_private import (
    args_parser,
)

__all__ = ["hydra_value"]


@dataclass
class Entry:
    """One override of the command line."""

    text: str
    prefix: str  # "", "+", "++" or "~"
    key: str
    values: list[Any] | None  # None: a sweep hnnbench cannot enumerate (left to Hydra)
    sweep: bool


def parse_flags(argv: list[str]) -> argparse.Namespace:
    """Hydra's own argument parser, with flags and overrides in any order, raising a
    one-line :class:`ConfigError` instead of printing usage and exiting."""
    parser = args_parser()
    parser.prog = "hnnbench"

    def error(message: str) -> NoReturn:
        raise ConfigError(f"{message} (see hnnbench --help)")

    parser.error = error  # type: ignore[method-assign]
    ns = parser.parse_intermixed_args(argv)
    commands = [
        name
        for name, on in (
            ("--run", ns.run),
            ("--multirun", ns.multirun),
            ("--cfg", ns.cfg is not None),
            ("--info", ns.info is not None),
            ("--shell-completion", ns.shell_completion),
        )
        if on
    ]
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
    if ns.experimental_rerun is not None:
        # Hydra's --experimental-rerun unpickles the file it is given: a pickle runs any
        # code it holds, so hnnbench never loads one.
        raise ConfigError(
            f"--experimental-rerun {ns.experimental_rerun} is refused: it unpickles the "
            "file, which can run any code. Re-run a sweep with the command line you "
            "typed (the same hydra.sweep.dir resumes it), or check a record with "
            "hnnbench check DIR --reference CSV --rerun SYSTEM/MODEL/SEED"
        )
    return ns


def flag_args(ns: argparse.Namespace) -> list[str]:
    """The parsed flags as Hydra expects them, in canonical spelling."""
    out: list[str] = []
    for name, flag in (
        ("help", "--help"),
        ("hydra_help", "--hydra-help"),
        ("run", "--run"),
        ("multirun", "--multirun"),
        ("shell_completion", "--shell-completion"),
        ("resolve", "--resolve"),
    ):
        if getattr(ns, name):
            out.append(flag)
    for name, flag in (
        ("cfg", "--cfg"),
        ("package", "--package"),
        ("config_path", "--config-path"),
        ("config_name", "--config-name"),
        ("config_dir", "--config-dir"),
        ("info", "--info"),
    ):
        if getattr(ns, name) is not None:
            out += [flag, getattr(ns, name)]
    return out


def _expand_names(kind: str, values: list[str]) -> list[str]:
    plugins = registry.group(kind)
    names = plugins.available()
    out: list[str] = []
    for value in values:
        for name in names if value == "all" else [value]:
            if name not in plugins.discover():
                raise UnknownNameError(kind, name, names)
            plugins.get(name)  # unusable -> error
            if name not in out:
                out.append(name)
    return out


_PREFIX = {"ADD": "+", "FORCE_ADD": "++", "DEL": "~", "CHANGE": ""}


#: Hydra settings whose overrides install code or read files chosen on the command line
#: (user callbacks, config search paths, logging handlers, which may name any class):
#: refused unless :data:`DEVELOPER_ENV` is ``1``. hnnbench's own callbacks (the
#: summary, the exporters of ``log_to=``) are switched on by hnnbench settings.
CODE_OVERRIDES = (
    "hydra.callbacks",
    "hydra/callbacks",
    "hydra.searchpath",
    "hydra/job_logging",
    "hydra/hydra_logging",
    "hydra.job_logging",
    "hydra.hydra_logging",
)
#: The developer switch that allows :data:`CODE_OVERRIDES`.
DEVELOPER_ENV = "HNNBENCH_ALLOW_CODE_OVERRIDES"


def code_override_problem(key: str) -> Optional[str]:
    """Why an override of ``key`` is refused (it would install code or read files), or
    ``None``."""
    if os.environ.get(DEVELOPER_ENV) == "1":
        return None
    if any(key == k or key.startswith(f"{k}.") for k in CODE_OVERRIDES):
        return (
            "this Hydra override installs callbacks or reads files chosen on the command "
            "line, which hnnbench refuses (its own exporters are log_to=[mlflow,tensorboard]); "
            f"a developer may set {DEVELOPER_ENV}=1 to allow it"
        )
    return None


def parse_override(parser: Any, text: str) -> Entry:
    from hydra.core.override_parser.types import Glob

    try:
        (ov,) = parser.parse_overrides([text])
    except Exception as err:
        raise ConfigError(f"Cannot parse override '{text}': {hydra_error_line(err)}") from None
    key = ov.key_or_group
    if not key:
        raise ConfigError(f"Cannot parse override '{text}': expected KEY=VALUE, e.g. seed=0")
    code_problem = code_override_problem(key)
    if code_problem is not None:
        raise ConfigError(f"{text}: {code_problem}")
    prefix = _PREFIX.get(ov.type.name, "")
    if ov.is_delete():
        return Entry(text, prefix, key, [], False)
    if not ov.is_sweep_override():
        value = ov.get_value_element_as_str()
        if key in ("system", "model"):
            names = _expand_names(key, [value])
            if len(names) > 1:  # `all`
                return Entry(f"{prefix}{key}={','.join(names)}", prefix, key, names, True)
            return Entry(f"{prefix}{key}={names[0]}", prefix, key, names, False)
        return Entry(text, prefix, key, [value], False)
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
    return Entry(text, prefix, key, values, True)


def batch_seeds(entries: list[Entry]) -> list[Entry]:
    """With ``seeds_per_job=N`` (N > 1), a sweep ``seed=a,b,c,...`` becomes one job per
    N seeds: ``seed_batch=[a,b,c],[d,...]`` with ``seed=${seed_batch.0}``, the first of
    each batch (its records' directories stay ``seed<k>``; hnnbench._running.job.seed_directory)."""
    given = next((e for e in entries if e.key == "seed_batch"), None)
    if given is not None:
        raise ConfigError(
            f"{given.text}: seed_batch is set by seeds_per_job; give the seeds "
            "with seed, e.g. -m seed=0,1,2 seeds_per_job=3"
        )
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
    groups = [values[k : k + size] for k in range(0, len(values), size)]
    texts = ["[" + ",".join(map(str, g)) + "]" for g in groups]
    batch = Entry(f"seed_batch={','.join(texts)}", "", "seed_batch", texts, len(texts) > 1)
    leader = Entry("seed=${seed_batch.0}", "", "seed", ["${seed_batch.0}"], False)
    return [*entries[:i], leader, batch, *entries[i + 1 :]]


def trial_overrides(entries: list[Entry], choice: dict[int, Any]) -> list[str]:
    """Overrides of one job: each sweep replaced by its chosen value (or its first)."""
    out = []
    for i, e in enumerate(entries):
        if not e.sweep:
            out.append(e.text)
        elif e.values:  # unenumerable sweeps are left to Hydra
            out.append(f"{e.prefix}{e.key}={choice.get(i, e.values[0])}")
    return out


def is_group(key: str) -> bool:
    return key in ("system", "model", "profile") or "/" in key or key.startswith("hydra")


def hydra_value(value: Any) -> str:
    """A Python value as a Hydra override value: booleans, ``None``, numbers and lists
    as Hydra writes them; a string quoted (``'...'``, backslash-escaped) unless it is a
    plain word, so paths with spaces, quotes, ``#``, ``~``, brackets, ``=``, ``,``,
    backslashes, ``${`` or any non-ASCII character reach the job as the same string."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(hydra_value(v) for v in value) + "]"
    text = str(value)
    if text and all(c.isascii() and (c.isalnum() or c in "_-./:") for c in text):
        return text
    # OmegaConf reads ${...} as an interpolation: \${ is a literal ${ (and backslashes
    # right before it are doubled, or they would escape it).
    text = re.sub(r"(\\*)\$\{", lambda m: m.group(1) * 2 + "\\${", text)
    # In Hydra's quoted value, backslashes are literal except right before a quote or
    # the closing quote: those are doubled, and a quote is escaped.
    text = re.sub(r"(\\*)('|\Z)", lambda m: m.group(1) * 2 + ("\\'" if m.group(2) else ""), text)
    return "'" + text + "'"
