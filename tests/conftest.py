"""Shared fixtures. Tests read the measured data through HNNBENCH_DATA_DIR and cache
generated datasets in a per-session temporary directory."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import settings

# The property tests draw a fixed set of examples, so `make test` passes or fails the
# same way on every run (a gate is not a lottery); `make fuzz` draws fresh examples.
settings.register_profile("gate", derandomize=True)
settings.register_profile("explore", derandomize=False, database=None)
settings.load_profile(os.environ.get("HNNBENCH_HYPOTHESIS", "gate"))

REPO = Path(__file__).resolve().parents[1]
#: The oracle's energy MSE stays below this in a quick-profile job: its rollouts run at
#: the quick profile's tolerances (rtol = atol = 1e-6, conf/profile/quick.yaml).
QUICK_ORACLE_BOUND = 1e-7
SHARED_DATA = REPO.parent / "shared" / "data" / "schmidt-lipson-2009"


def shared_data_dir() -> Path:
    """``$HNNBENCH_DATA_DIR`` (relative paths: to the cwd, else the repo), else the
    shared checkout next to the repo."""
    value = os.environ.get("HNNBENCH_DATA_DIR", "").strip()
    if value:
        path = Path(value).expanduser()
        if not path.is_absolute() and not path.is_dir():
            path = REPO / path
        return path.resolve()
    return SHARED_DATA


#: Under `make test`'s workers (pytest-xdist), the folders in this order: an end-to-end
#: file holds minutes of work, and one taken last keeps a worker busy while the other
#: idles. A single process keeps the plain order (the unit tests fail fastest).
_FOLDER_ORDER = {"e2e": 0, "integration": 1, "unit": 2}


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if hasattr(config, "workerinput"):  # a pytest-xdist worker: it sends this order
        items.sort(key=lambda item: _FOLDER_ORDER.get(item.path.parent.name, 1))


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Generated datasets go to a temp cache unless HNNBENCH_CACHE_DIR is set."""
    if not os.environ.get("HNNBENCH_CACHE_DIR"):
        os.environ["HNNBENCH_CACHE_DIR"] = str(tmp_path_factory.mktemp("hnnbench-cache"))
    if not os.environ.get("HNNBENCH_DATA_DIR") and SHARED_DATA.is_dir():
        os.environ["HNNBENCH_DATA_DIR"] = str(SHARED_DATA)
    os.environ.setdefault("HNNBENCH_PROGRESS", "log")


def load_script(path: Path, name: str):
    """Import a script of benchmarks/ or scripts/ (not a package) as module ``name``."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def pip_install(target: Path, spec: str, *options: str) -> None:
    """pip-install ``spec`` (a path, a wheel, ``name @ url``) without its dependencies
    into the directory ``target``, with pip's ``options``."""
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", *options]
        + ["--target", str(target), spec],
        check=True,
        capture_output=True,
        text=True,
    )


def install_test_package(
    name: str, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, dict[str, str]]:
    """pip-install ``tests/<name>`` (built from a copy, so the source tree stays clean)
    into a temporary site directory; returns it and the environment that puts it on
    ``PYTHONPATH`` for a subprocess."""
    site = tmp_path_factory.mktemp(f"{name}-site")
    build = tmp_path_factory.mktemp(f"{name}-src")
    subprocess.run(["cp", "-r", str(REPO / "tests" / name), str(build)], check=True)
    pip_install(site, str(build / name), "--no-build-isolation", "--no-index")
    path = os.pathsep.join(p for p in (str(site), os.environ.get("PYTHONPATH", "")) if p)
    return site, {"PYTHONPATH": path}


def hnnbench(
    *args: str, cwd: Path | None = None, env: dict | None = None, timeout: float = 900
) -> subprocess.CompletedProcess:
    """Run the installed console script."""
    exe = Path(sys.executable).parent / "hnnbench"
    return subprocess.run(
        [str(exe), *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, **(env or {})},
    )


def assert_one_line_error(proc: subprocess.CompletedProcess, *needles: str) -> str:
    """A clean user error: non-zero exit, no traceback, one line naming the problem."""
    assert proc.returncode != 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout, proc.stderr
    lines = [line for line in proc.stderr.strip().splitlines() if line.strip()]
    assert len(lines) == 1, proc.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def compose_job(overrides: list[str] | None = None, **kwargs):
    """:func:`hnnbench._running.compose.compose` with the suite's usual pair (spring x hnn_torch)
    where ``overrides`` choose none: the shipped config names no plugin, so every job
    chooses both (``tests/integration/test_layers.py``)."""
    from hnnbench._running.compose import compose

    overrides = list(overrides or [])
    keys = {o.lstrip("+~").split("=", 1)[0] for o in overrides}
    defaults = [
        f"{k}={v}" for k, v in (("system", "spring"), ("model", "hnn_torch")) if k not in keys
    ]
    return compose(defaults + overrides, **kwargs)


def with_pair(argv: list[str] | tuple[str, ...]) -> list[str]:
    """A job command line with the suite's usual pair (spring x hnn_torch) where it
    chooses none (subcommands and help left as they are); see :func:`compose_job`."""
    argv = list(argv)
    if argv and argv[0] in ("list", "report", "check", "-h", "--help", "help"):
        return argv
    keys = {a.lstrip("+~").split("=", 1)[0] for a in argv if "=" in a}
    return [
        *(f"{k}={v}" for k, v in (("system", "spring"), ("model", "hnn_torch")) if k not in keys),
        *argv,
    ]


def sweep_records(directory: Path) -> dict:
    """A sweep's records by (system, model, seed), each with its ``path`` (the
    ``result.json``); two records of one job fail."""
    import json

    out: dict = {}
    for path in sorted(Path(directory).rglob("result.json")):
        rec = json.loads(path.read_text())
        key = (rec["system"], rec["model"], rec["seed"])
        assert key not in out, f"two records for {key} under {directory}"
        out[key] = {**rec, "path": path}
    return out


@pytest.fixture(autouse=True)
def _cores_given_back():
    """A job run in this process under the hnnbench command's launch context pins the
    whole process to one core for good (hnnbench._running.affinity): give every thread
    its cores back and release the claimed core after the test, so that no test depends
    on the ones before it (tests/integration/test_affinity.py needs the machine's cores)."""
    if not hasattr(os, "sched_getaffinity"):
        yield
        return
    before = os.sched_getaffinity(0)
    yield
    if os.sched_getaffinity(0) == before:
        return
    from hnnbench._running import affinity

    handle = affinity._held.pop("handle", None)
    if handle is not None:
        handle.close()  # releases the core's lock
    affinity._held.clear()
    tasks = Path("/proc/self/task")
    for tid in [int(t.name) for t in tasks.iterdir()] if tasks.is_dir() else []:
        try:
            os.sched_setaffinity(tid, before)
        except OSError:  # a thread that ended meanwhile
            pass
    os.sched_setaffinity(0, before)


@pytest.fixture(autouse=True)
def _restore_logging():
    """A command run in-process configures logging (Hydra's job logging) with handlers
    on the streams of that moment, e.g. a test's captured stdout, which pytest closes
    when the test ends: put every logger's handlers back as they were, so no later log
    line writes to a closed stream."""
    import logging

    loggers = [
        logging.getLogger(),
        *(logging.getLogger(name) for name in list(logging.Logger.manager.loggerDict)),
    ]
    saved = {id(lg): (lg, lg.handlers[:], lg.level, lg.propagate) for lg in loggers}
    yield
    for lg, handlers, level, propagate in saved.values():
        lg.handlers[:] = handlers
        lg.setLevel(level)
        lg.propagate = propagate
    for name in list(logging.Logger.manager.loggerDict):
        lg = logging.getLogger(name)
        if id(lg) not in saved:  # created during the test: no handlers of its streams
            lg.handlers[:] = []


@pytest.fixture(autouse=True)
def _absl_logging_writes_to_the_real_stderr():
    """absl's logging handler (imported with JAX's dependencies) keeps the ``sys.stderr``
    of the moment it was imported, pytest's capture stream of some earlier test; Hydra's
    logging set-up (``logging.shutdown`` of every handler) then closes that stream unless
    it is the current ``sys.stderr``, and pytest dies at its end. Point it at the real
    stderr, which absl never closes."""
    module = sys.modules.get("absl.logging")
    if module is not None:
        handler = module.get_absl_handler().python_handler
        if handler.stream is not sys.__stderr__:
            handler.stream = sys.__stderr__
    yield


@pytest.fixture()
def tree(tmp_path, monkeypatch):
    """A repository root of its own: README.md (no markers: the blocks are the results
    page's) and results/README.md with their markers, results/figures holding a stale
    figure; publish_results writes there."""
    import types

    from publish_fixtures import publish_results

    root = tmp_path / "repo"
    (root / "results" / "figures").mkdir(parents=True)
    (root / "README.md").write_text("# x\n\nSee [results](results/README.md).\n")
    (root / "results" / "README.md").write_text(
        "# x\n\n<!-- aggregate:begin -->\n<!-- aggregate:end -->\n\n"
        "<!-- leaderboard:begin -->\n<!-- leaderboard:end -->\n\n"
        "<!-- tracks:begin -->\n<!-- tracks:end -->\n\n"
        "<!-- provenance:begin -->\n<!-- provenance:end -->\n"
    )
    (root / "results" / "figures" / "old_system_energy.png").write_bytes(b"stale")
    monkeypatch.setattr(publish_results, "ROOT", root)
    monkeypatch.setattr(publish_results, "RESULTS", root / "results")
    monkeypatch.setattr(publish_results, "RECORDS", root / "results" / "records")
    monkeypatch.setattr(publish_results, "STAGED", root / "results" / "staged")
    monkeypatch.setattr(publish_results, "STUDIES", root / "results" / "tuning")
    fake = types.ModuleType("job_costs")
    fake.main = lambda argv: 0  # the real one rewrites the installed job costs
    monkeypatch.setitem(sys.modules, "job_costs", fake)
    return root


@pytest.fixture()
def published_spring(tree, tmp_path):
    """``tree``'s results/ with spring's protocol track published
    (``publish_fixtures.publish_spring_protocol``)."""
    from publish_fixtures import publish_spring_protocol

    return publish_spring_protocol(tree, tmp_path)
