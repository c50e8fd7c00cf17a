"""Seeds trained as one batch (``seeds_per_job``) agree with seeds trained alone, keep
their own records, resume per seed, and isolate a diverging seed."""

from __future__ import annotations

import dataclasses
import json
import math
import shutil

import numpy as np
import pytest
from conftest import hnnbench

from hnnbench._contracts.plugin import Dataset, TrainSettings
from hnnbench._running.job import seed_directory
from hnnbench_plugins.systems.spring import Spring, SpringConfig

pytest.importorskip("torch")
pytest.importorskip("jax")


def test_seed_directory_replaces_the_leaders_component(tmp_path):
    leader = tmp_path / "spring" / "hnn_jax" / "seed0" / "model.hidden=8"
    assert seed_directory(leader, 0, 0) == leader
    other = tmp_path / "spring" / "hnn_jax" / "seed2" / "model.hidden=8"
    assert seed_directory(leader, 0, 2) == other
    assert seed_directory(tmp_path / "job", 0, 1) == tmp_path / "job" / "seed1"


@pytest.fixture(scope="module")
def spring_data() -> tuple[Spring, list[Dataset]]:
    system = Spring(SpringConfig(name="spring", n_traj=8, n_points=10, eval_n_traj=3))
    return system, [system.dataset(s) for s in (0, 1, 2)]


@pytest.mark.parametrize("name", ["hnn_jax", "mlp_torch"])
def test_a_diverging_seed_leaves_the_batch_unaffected(name, spring_data):
    from hnnbench._registry.groups import get_class

    system, datas = spring_data
    cls = get_class("model", name)
    poisoned = datas[1].train.dxdt.copy()
    poisoned[0, 0] = np.nan
    bad = Dataset(
        train=dataclasses.replace(datas[1].train, dxdt=poisoned),
        test=datas[1].test,
        meta=datas[1].meta,
    )
    cfg = cls.Config(name=name, hidden=16, log_every=5)
    train = TrainSettings(steps=20, batch_size=None, lr=1e-3, weight_decay=0.0)
    batched = cls(cfg, system, "cpu").fit_seeds(
        [datas[0], bad, datas[2]], train, [0, 1, 2], lambda *_: None
    )
    assert batched[1][1].diverged is not None and "at step 1" in batched[1][1].diverged
    for k in (0, 2):
        model, result = batched[k]
        assert result.diverged is None
        alone_model = cls(cfg, system, "cpu")
        alone = alone_model.fit(datas[k], train, k, lambda *_: None)
        np.testing.assert_allclose(
            result.history["train_loss"], alone.history["train_loss"], rtol=1e-5
        )
        # each seed of the batch holds its own selected checkpoint, as when alone
        assert result.selection is not None and alone.selection is not None
        assert result.selection.step == alone.selection.step
        x = datas[k].test.x
        assert np.all(np.isfinite(model.time_derivative(x)))
        np.testing.assert_allclose(
            model.time_derivative(x), alone_model.time_derivative(x), rtol=1e-4, atol=1e-6
        )


def _records(root) -> dict[tuple[str, str, int], dict]:
    out = {}
    for path in root.rglob("result.json"):
        rec = json.loads(path.read_text())
        out[(rec["system"], rec["model"], rec["seed"])] = rec
    return out


@pytest.mark.slow
def test_batched_sweep_agrees_with_separate_jobs_and_passes_check(tmp_path):
    common = [
        "-m",
        "system=spring,real_pendulum",
        "model=hnn_jax,mlp_torch",
        "seed=0,1,2",
        "profile=quick",
        "system.steps=100",
        "model.log_every=1",
    ]
    separate, batched = tmp_path / "separate", tmp_path / "batched"
    for where, extra in ((separate, []), (batched, ["seeds_per_job=3"])):
        proc = hnnbench(*common, *extra, f"hydra.sweep.dir={where}", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr[-3000:]
    assert "(seeds 0,1,2 as one batch)" in proc.stdout + proc.stderr
    a, b = _records(separate), _records(batched)
    assert set(a) == set(b) and len(a) == 12
    for key, rec in b.items():
        assert rec["status"] == a[key]["status"] == "ok"
        assert rec["seed_batch"] == [0, 1, 2] and rec["config"]["seed"] == key[2]
        assert f"seed={key[2]}" in rec["overrides"]
        # the first 100 steps of each seed's loss curve, to 1e-4 relative
        np.testing.assert_allclose(
            rec["history"]["train_loss"],
            a[key]["history"]["train_loss"],
            rtol=1e-4,
            err_msg=str(key),
        )
        assert len(rec["history"]["train_loss"]) == 100
    reference = tmp_path / "separate.csv"
    assert (
        hnnbench("check", str(separate), "--reference", str(reference), "--update").returncode == 0
    )
    proc = hnnbench("check", str(batched), "--reference", str(reference))
    assert proc.returncode == 0, proc.stdout[-3000:]

    # resume: one seed's record gone -> only that seed runs again
    before = {k: v["created_at"] for k, v in _records(batched).items()}
    shutil.rmtree(batched / "spring" / "hnn_jax" / "seed1")
    proc = hnnbench(*common, "seeds_per_job=3", f"hydra.sweep.dir={batched}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    after = _records(batched)
    assert set(after) == set(before)
    changed = {k for k in after if after[k]["created_at"] != before[k]}
    assert changed <= {("spring", "hnn_jax", 1)}
    assert "spring x hnn_jax seed=0: already finished" in proc.stdout + proc.stderr
    assert math.isfinite(after[("spring", "hnn_jax", 1)]["metrics"]["energy_mse"]["mean"])
