"""The core's structure: one folder per layer, layers that import only downward
(import-linter, run by ``make test`` too), no import cycle, a core that names no
built-in plugin, and one sweep path whose jobs each compose and validate their config
once."""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from conftest import REPO

LINT = Path(sys.executable).parent / "lint-imports"


def _lint(root: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(LINT), "--config", str(root / "pyproject.toml")],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=300,
        env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"},
    )


def test_the_layer_and_cycle_contracts_hold():
    proc = _lint(REPO)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "2 kept, 0 broken" in proc.stdout


#: hnnbench/'s entries besides the layers' packages.
NOT_LAYERS = {"__init__.py", "py.typed", "resources", "__pycache__"}


def test_every_module_is_in_a_layer_folder():
    """``ls hnnbench`` shows the layers: each folder is one layer of the contract (or
    ``neural``, the public namespace beside the registry), and no module sits loose."""
    import tomllib

    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["importlinter"]
    (layers,) = [c["layers"] for c in config["contracts"] if c["type"] == "layers"]
    declared = {name.strip() for layer in layers for name in layer.split("|")}
    present = {p.name for p in (REPO / "hnnbench").iterdir()} - NOT_LAYERS
    assert present == declared, present ^ declared
    assert all((REPO / "hnnbench" / name).is_dir() for name in present)


@pytest.mark.parametrize(
    "module, planted, broken",
    [
        # a contract (metric) importing an entry point, inside a function
        (
            "_contracts/metric.py",
            "def _planted():\n    from hnnbench._entry import command  # noqa\n",
            "Layers",
        ),
        # the record importing the job that writes it: running is above the record
        (
            "_record/store.py",
            "def _planted():\n    from hnnbench._running import job  # noqa\n",
            "Layers",
        ),
        # two running modules importing each other: a cycle within a layer
        (
            "_running/dataset_cache.py",
            "def _planted():\n    from hnnbench._running import job  # noqa\n",
            "cycles",
        ),
    ],
)
def test_a_planted_import_breaks_a_contract(module, planted, broken, tmp_path):
    """The contracts are not vacuous: an upward import, or a cycle, fails them."""
    shutil.copytree(
        REPO / "hnnbench", tmp_path / "hnnbench", ignore=shutil.ignore_patterns("__pycache__")
    )
    shutil.copy(REPO / "pyproject.toml", tmp_path / "pyproject.toml")
    target = tmp_path / "hnnbench" / module
    target.write_text(target.read_text() + "\n\n" + planted)
    proc = _lint(tmp_path)
    assert proc.returncode != 0, proc.stdout
    assert f"{broken}" in proc.stdout and "BROKEN" in proc.stdout, proc.stdout


def _builtin_names() -> set[str]:
    from hnnbench import _registry as registry

    names: set[str] = set()
    for kind in ("system", "model", "metric", "claims"):
        for info in registry.discover(kind).values():
            if info.distribution == "hnnbench":
                names.add(info.name)
    return names


def _code_strings(path: Path) -> list[tuple[int, str]]:
    """String constants of a module that are not docstrings."""
    tree = ast.parse(path.read_text())
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = getattr(node, "body", [])
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                docstrings.add(id(body[0].value))
    return [
        (n.lineno, n.value)
        for n in ast.walk(tree)
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docstrings
    ]


def test_the_core_names_no_builtin_plugin():
    """No code string in hnnbench/ is the name of a built-in system, model, metric or
    claim set (examples in docstrings are fine); the shipped config chooses none."""
    names = _builtin_names()
    assert {"spring", "hnn_torch", "test_loss", "energy_mse"} <= names
    from hnnbench._contracts.plugin import HISTORY_TRAIN, HISTORY_VALID

    # The training log's column names, declared once in the plugin contract, coincide
    # with two loss metrics' names (records keep them): the one allowed place.
    # And a schema-1 record's log column of the test loss, read by its legacy rule.
    allowed = {
        ("plugin.py", HISTORY_TRAIN),
        ("plugin.py", HISTORY_VALID),
        ("consistency.py", "test_loss"),
    }
    found = []
    for path in sorted((REPO / "hnnbench").rglob("*.py")):
        for line, text in _code_strings(path):
            if text in names and (path.name, text) not in allowed:
                found.append(f"{path.relative_to(REPO)}:{line}: {text!r}")
    assert not found, "\n".join(found)
    config = yaml.safe_load((REPO / "conf" / "config.yaml").read_text())
    defaults = {
        k: v for item in config["defaults"] if isinstance(item, dict) for k, v in item.items()
    }
    assert defaults["system"] is None and defaults["model"] is None
    for conf in (REPO / "conf").rglob("*.yaml"):
        words = set(conf.read_text().replace(":", " ").split())
        assert not (words & names), f"{conf} names {words & names}"


def test_a_command_without_a_plugin_is_one_line(tmp_path):
    from conftest import assert_one_line_error, hnnbench

    assert_one_line_error(hnnbench("seed=1", cwd=tmp_path), "no system chosen", "system=<name>")
    assert_one_line_error(hnnbench("system=spring", cwd=tmp_path), "no model chosen")


def test_a_job_composes_and_validates_its_config_once(tmp_path, monkeypatch):
    """A sweep of N jobs composes N job configs plus a constant (the plan's check of the
    command line, Hydra's mode probe, the sweep's base), never N per validation pass,
    and validates each job's config once (the plan's validation is the in-process job's);
    the plugins' configs are registered once per profile; under the basic launcher the
    launch context is never put into the environment."""
    from hydra._internal import config_loader_impl

    from hnnbench import _registry as registry
    from hnnbench._running import config, launch_context
    from hnnbench._sweeping.execution import execute

    counts = {"compose": 0, "plugin_configs": 0, "validate": 0}
    compose = config_loader_impl.ConfigLoaderImpl.load_configuration
    defaults = registry.config_defaults
    validate = config.validate_run
    exported = launch_context.exported
    environments: list[object] = []

    def counting_compose(self, *args, **kwargs):
        counts["compose"] += 1
        return compose(self, *args, **kwargs)

    def counting_defaults(*args, **kwargs):
        counts["plugin_configs"] += 1
        return defaults(*args, **kwargs)

    def counting_validate(*args, **kwargs):
        counts["validate"] += 1
        return validate(*args, **kwargs)

    def spying_export(context):
        environments.append(context)
        return exported(context)

    monkeypatch.setattr(config_loader_impl.ConfigLoaderImpl, "load_configuration", counting_compose)
    monkeypatch.setattr(registry, "config_defaults", counting_defaults)
    monkeypatch.setattr(config, "validate_run", counting_validate)
    monkeypatch.setattr(launch_context, "exported", spying_export)
    registry.refresh()
    argv = [
        "-m",
        "system=spring",
        "model=oracle",
        "seed=0,1,2,3",
        "profile=quick",
        "pin_cpu=false",
        f"hydra.sweep.dir={tmp_path}",
    ]
    result = execute(argv)
    assert len(result.records) == 4 and not any(result.kept)
    assert counts["compose"] == 4 + 3, counts
    assert counts["validate"] == 4, counts
    n_plugins = len(registry.available("system")) + len(registry.available("model"))
    assert counts["plugin_configs"] == n_plugins, counts
    assert environments == [None]
    assert launch_context.ENV not in os.environ
    # The same sweep again: every job kept, and said so.
    again = execute(argv)
    assert sorted(r["seed"] for r in again.records) == [0, 1, 2, 3] and all(again.kept)


def test_a_swept_group_takes_overrides_of_its_keys(tmp_path):
    """Hydra composes a sweep-wide config that skips sweeps of groups; with no system
    chosen by default, ``system.eval_t_end=2`` would not compose there. The plan pins
    the swept group to its first value for that config, and every job still gets its
    own value and the override (its directory named as before)."""
    from hnnbench._sweeping.execution import execute
    from hnnbench._sweeping.plan import plan

    argv = [
        "-m",
        "system=spring,pendulum",
        "model=oracle",
        "profile=quick",
        "seed=0",
        "system.eval_t_end=2",
        "pin_cpu=false",
        f"hydra.sweep.dir={tmp_path}",
    ]
    checked = plan(argv)
    assert checked.pinned == {"system=spring": "system=spring,pendulum"}
    assert "system=spring" in checked.hydra_argv and "system=spring,pendulum" in checked.argv
    result = execute(argv)
    got = {(r["system"], r["config"]["system"]["eval_t_end"]) for r in result.records}
    assert got == {("spring", 2), ("pendulum", 2)}, got
    for system in ("spring", "pendulum"):
        assert (
            tmp_path / system / "oracle" / "seed0" / "system.eval_t_end=2" / "result.json"
        ).is_file()
    # Nothing is pinned where nothing needs it.
    assert not plan(["-m", "system=spring,pendulum", "model=oracle"]).pinned


def test_plugins_import_only_the_public_surface():
    """Built-in plugins use ``hnnbench`` and ``hnnbench.neural`` (and its backend
    namespaces), never a private module, as a third party's would."""
    bad = []
    for path in sorted((REPO / "plugins").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.ImportFrom)
                and node.module
                and "._" in f".{node.module}"
                and node.module.startswith("hnnbench")
            ):
                bad.append(f"{path.relative_to(REPO)}:{node.lineno}: {node.module}")
    assert not bad, "\n".join(bad)


@pytest.mark.slow
def test_without_torch_model_all_runs_every_jax_model_and_the_oracle(tmp_path):
    """torch made unimportable (as when it is not installed): ``model=all`` is every
    model that can run, the sweep exits 0."""
    # An import hook that finds no torch, as on an install without it (a None in
    # sys.modules would also block it, but trips libraries that look torch up there).
    code = (
        "import sys\n"
        "class NoTorch:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] == 'torch':\n"
        "            raise ModuleNotFoundError(f'No module named {name!r}', name=name)\n"
        "sys.meta_path.insert(0, NoTorch())\n"
        "from hnnbench._entry.command import run\n"
        "sys.exit(run(sys.argv[1:]))\n"
    )
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            code,
            "-m",
            "system=spring",
            "model=all",
            "profile=quick",
            f"hydra.sweep.dir={tmp_path}",
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    from hnnbench._record.loader import load_records

    models = {r["model"]: r["status"] for r in load_records(tmp_path)}
    assert models and not any(m.endswith("_torch") for m in models), models
    assert {"mlp_jax", "hnn_jax", "dhnn_jax", "lnn_jax", "so_mlp_jax", "srnn_jax", "oracle"} <= set(
        models
    ), models
    assert all(s in ("ok", "diverged") for s in models.values()), models
