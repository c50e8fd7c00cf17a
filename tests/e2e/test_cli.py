"""The console script: list, clean errors, single runs. (Subprocesses: the real entry.)"""

from __future__ import annotations

import json

import pytest
from conftest import assert_one_line_error, hnnbench

from hnnbench._sweeping.plan import plan


def test_list_names_builtins():
    proc = hnnbench("list")
    assert proc.returncode == 0, proc.stderr
    for name in ("spring", "pendulum", "mlp_torch", "hnn_torch", "oracle"):
        assert name in proc.stdout
    data = json.loads(hnnbench("list", "--json").stdout)
    spring = next(s for s in data["system"] if s["name"] == "spring")
    assert spring["version"] == "3" and spring["status"] == "ok"
    assert next(m for m in data["model"] if m["name"] == "hnn_torch")["backend"] == "torch"


@pytest.mark.parametrize(
    "args, needles",
    [
        (["system=sprng", "model=hnn_torch"], ["Unknown system 'sprng'", "Did you mean 'spring'"]),
        (["system=spring", "model=hnn_trch"], ["Unknown model 'hnn_trch'", "hnn_torch"]),
        (["profile=quik"], ["Unknown profile 'quik'", "quick"]),
        (["system=spring", "model=mlp_jax", "seed=abc"], ["seed"]),
        (["system=spring", "model=mlp_jax", "system.steps=-1"], ["system.steps=-1 is invalid"]),
        (["system=all", "model=hnn_torch"], ["add -m"]),
        (["-m", "system=spring", "model=hnn_torch,nope"], ["Unknown model 'nope'"]),
        (
            ["-m", "system=spring", "model=mlp_torch", "model.hidden=10,0"],
            ["model.hidden=0 is invalid"],
        ),
    ],
)
def test_bad_input_is_one_clean_line(args, needles, tmp_path):
    assert_one_line_error(hnnbench(*args, cwd=tmp_path), *needles)


def test_all_expands_to_every_registered_plugin():
    from hnnbench import _registry as registry

    p = plan(["-m", "system=all", "model=all", "seed=0,1"])
    systems = registry.available("system")
    models = registry.available("model")
    assert f"system={','.join(systems)}" in p.argv
    assert f"model={','.join(models)}" in p.argv
    assert p.n_jobs == len(systems) * len(models) * 2
