"""The core's structure: layers that import only downward (import-linter, run by
``make test`` too), no import cycle, a core that names no built-in plugin, one sweep
path whose jobs each compose their config once, and the 0.2 module names as shims."""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import pytest
import yaml
from conftest import REPO

LINT = Path(sys.executable).parent / "lint-imports"


def _lint(root: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(LINT), "--config", str(root / "pyproject.toml")], cwd=root,
                          capture_output=True, text=True, timeout=300,
                          env={"PYTHONPATH": str(root), "PATH": "/usr/bin:/bin"})


def test_the_layer_and_cycle_contracts_hold():
    proc = _lint(REPO)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "2 kept, 0 broken" in proc.stdout


@pytest.mark.parametrize("module, planted, broken", [
    # a contract (metric) importing an entry point, inside a function
    ("_metric.py", "def _planted():\n    from hnnbench import _cli  # noqa\n", "Layers"),
    # two running modules importing each other: a cycle within a layer
    ("_records.py", "def _planted():\n    from hnnbench import _job  # noqa\n", "cycles"),
])
def test_a_planted_import_breaks_a_contract(module, planted, broken, tmp_path):
    """The contracts are not vacuous: an upward import, or a cycle, fails them."""
    shutil.copytree(REPO / "hnnbench", tmp_path / "hnnbench",
                    ignore=shutil.ignore_patterns("__pycache__"))
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
    return [(n.lineno, n.value) for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str)
            and id(n) not in docstrings]


def test_the_core_names_no_builtin_plugin():
    """No code string in hnnbench/ is the name of a built-in system, model, metric or
    claim set (examples in docstrings are fine); the shipped config chooses none."""
    names = _builtin_names()
    assert {"spring", "hnn_torch", "test_loss", "energy_mse"} <= names
    from hnnbench._contract import HISTORY_TRAIN, HISTORY_VALID

    # The training log's column names, declared once in the plugin contract, coincide
    # with two loss metrics' names (records keep them): the one allowed place.
    allowed = {("_contract.py", HISTORY_TRAIN), ("_contract.py", HISTORY_VALID)}
    found = []
    for path in sorted((REPO / "hnnbench").rglob("*.py")):
        for line, text in _code_strings(path):
            if text in names and (path.name, text) not in allowed:
                found.append(f"{path.relative_to(REPO)}:{line}: {text!r}")
    assert not found, "\n".join(found)
    config = yaml.safe_load((REPO / "conf" / "config.yaml").read_text())
    defaults = {k: v for item in config["defaults"] if isinstance(item, dict)
                for k, v in item.items()}
    assert defaults["system"] is None and defaults["model"] is None
    for conf in (REPO / "conf").rglob("*.yaml"):
        words = set(conf.read_text().replace(":", " ").split())
        assert not (words & names), f"{conf} names {words & names}"


def test_a_command_without_a_plugin_is_one_line(tmp_path):
    from conftest import assert_one_line_error, hnnbench

    assert_one_line_error(hnnbench("seed=1", cwd=tmp_path), "no system chosen",
                          "system=<name>")
    assert_one_line_error(hnnbench("system=spring", cwd=tmp_path), "no model chosen")


def test_a_job_composes_its_config_once(tmp_path, monkeypatch):
    """A sweep of N jobs composes N job configs plus a constant (the plan's, Hydra's
    mode probe, the sweep's base), never N per validation pass; the plugins' configs
    are registered once per profile."""
    from hydra._internal import config_loader_impl

    from hnnbench import _registry as registry
    from hnnbench import _sweep

    counts = {"compose": 0, "plugin_configs": 0}
    compose = config_loader_impl.ConfigLoaderImpl.load_configuration
    defaults = registry.config_defaults

    def counting_compose(self, *args, **kwargs):
        counts["compose"] += 1
        return compose(self, *args, **kwargs)

    def counting_defaults(*args, **kwargs):
        counts["plugin_configs"] += 1
        return defaults(*args, **kwargs)

    monkeypatch.setattr(config_loader_impl.ConfigLoaderImpl, "load_configuration",
                        counting_compose)
    monkeypatch.setattr(registry, "config_defaults", counting_defaults)
    registry.refresh()
    result = _sweep.execute(["-m", "system=spring", "model=oracle", "seed=0,1,2,3",
                             "profile=quick", "pin_cpu=false", f"hydra.sweep.dir={tmp_path}"])
    assert len(result.records) == 4 and not any(result.kept)
    assert counts["compose"] == 4 + 3, counts
    n_plugins = len(registry.available("system")) + len(registry.available("model"))
    assert counts["plugin_configs"] == n_plugins, counts
    # The same sweep again: every job kept, and said so.
    again = _sweep.execute(["-m", "system=spring", "model=oracle", "seed=0,1,2,3",
                            "profile=quick", "pin_cpu=false", f"hydra.sweep.dir={tmp_path}"])
    assert sorted(r["seed"] for r in again.records) == [0, 1, 2, 3] and all(again.kept)


def test_a_swept_group_takes_overrides_of_its_keys(tmp_path):
    """Hydra composes a sweep-wide config that skips sweeps of groups; with no system
    chosen by default, ``system.eval_t_end=2`` would not compose there. The plan pins
    the swept group to its first value for that config, and every job still gets its
    own value and the override (its directory named as before)."""
    from hnnbench import _sweep

    argv = ["-m", "system=spring,pendulum", "model=oracle", "profile=quick", "seed=0",
            "system.eval_t_end=2", "pin_cpu=false", f"hydra.sweep.dir={tmp_path}"]
    checked = _sweep.plan(argv)
    assert checked.pinned == {"system=spring": "system=spring,pendulum"}
    assert "system=spring" in checked.hydra_argv and "system=spring,pendulum" in checked.argv
    result = _sweep.execute(argv)
    got = {(r["system"], r["config"]["system"]["eval_t_end"]) for r in result.records}
    assert got == {("spring", 2), ("pendulum", 2)}, got
    for system in ("spring", "pendulum"):
        assert (tmp_path / system / "oracle" / "seed0" / "system.eval_t_end=2"
                / "result.json").is_file()
    # Nothing is pinned where nothing needs it.
    assert not _sweep.plan(["-m", "system=spring,pendulum", "model=oracle"]).pinned


def test_old_module_names_still_import_with_a_warning():
    import hnnbench

    for old, name in (("api", "System"), ("metric", "Metric"), ("records", "RECORD_NAME"),
                      ("neural.model", "NeuralModel")):
        sys.modules.pop(f"hnnbench.{old}", None)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            module = __import__(f"hnnbench.{old}", fromlist=[name])
            value = getattr(module, name)
        assert value is not None
        assert any(issubclass(w.category, DeprecationWarning) and f"hnnbench.{old}"
                   in str(w.message) for w in caught), old
    assert hnnbench.System.__module__ == "hnnbench._contract"


def test_plugins_import_only_the_public_surface():
    """Built-in plugins use ``hnnbench`` and ``hnnbench.neural`` (and its backend
    namespaces), never a private module, as a third party's would."""
    bad = []
    for path in sorted((REPO / "plugins").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and \
                    "._" in f".{node.module}" and node.module.startswith("hnnbench"):
                bad.append(f"{path.relative_to(REPO)}:{node.lineno}: {node.module}")
    assert not bad, "\n".join(bad)


@pytest.mark.slow
def test_without_torch_model_all_runs_every_jax_model_and_the_oracle(tmp_path):
    """torch made unimportable (as when it is not installed): ``model=all`` is every
    model that can run, the sweep exits 0."""
    # An import hook that finds no torch, as on an install without it (a None in
    # sys.modules would also block it, but trips libraries that look torch up there).
    code = ("import sys\n"
            "class NoTorch:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name.split('.')[0] == 'torch':\n"
            "            raise ModuleNotFoundError(f'No module named {name!r}', name=name)\n"
            "sys.meta_path.insert(0, NoTorch())\n"
            "from hnnbench._cli import run\n"
            "sys.exit(run(sys.argv[1:]))\n")
    proc = subprocess.run(
        [sys.executable, "-c", code, "-m", "system=spring", "model=all", "profile=quick",
         f"hydra.sweep.dir={tmp_path}"], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    from hnnbench._records import load_records

    models = {r["model"]: r["status"] for r in load_records(tmp_path)}
    assert models and not any(m.endswith("_torch") for m in models), models
    assert {"mlp_jax", "hnn_jax", "dhnn_jax", "lnn_jax", "so_mlp_jax", "srnn_jax",
            "oracle"} <= set(models), models
    assert all(s in ("ok", "diverged") for s in models.values()), models
