"""The 1-DOF toy systems (spring, pendulum): their evaluation initial-state draws."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import compose_job as compose

from hnnbench._contracts.errors import ConfigError
from hnnbench._running.config import prepare_job
from hnnbench_plugins.systems.pendulum import Pendulum, PendulumConfig
from hnnbench_plugins.systems.spring import Spring, SpringConfig


@pytest.mark.parametrize("cls, cfg_cls", [(Spring, SpringConfig), (Pendulum, PendulumConfig)])
def test_train_evaluation_draws_from_the_training_radii(cls, cfg_cls):
    cfg = cfg_cls(
        name=cls.__name__.lower(),
        eval_init="train",
        eval_n_traj=200,
        eval_n_points=3,
        eval_t_end=0.1,
    )
    traj = cls(cfg).evaluation(seed=0)
    radius = np.linalg.norm(traj.x0, axis=1)
    assert radius.min() >= cfg.radius_min and radius.max() <= cfg.radius_max
    assert traj.meta["initial_states"] == "train"


@pytest.mark.parametrize("cls, cfg_cls", [(Spring, SpringConfig), (Pendulum, PendulumConfig)])
def test_default_evaluation_draws_each_coordinate_in_the_2019_box(cls, cfg_cls):
    cfg = cfg_cls(name=cls.__name__.lower(), eval_n_traj=400, eval_n_points=5, eval_t_end=1.0)
    system = cls(cfg)
    traj = system.evaluation(seed=3)
    x0 = traj.x0
    assert np.abs(x0).min() >= 0.2 and np.abs(x0).max() <= 1.0
    # every sign quadrant is drawn, and the corners reach beyond the unit circle
    quadrants = {(bool(q > 0), bool(p > 0)) for q, p in x0}
    assert len(quadrants) == 4
    assert np.linalg.norm(x0, axis=1).max() > 1.2
    assert traj.meta["initial_states"] == "box"
    # the ground truth still conserves the true energy
    energy = system.energy(traj.states.reshape(-1, 2)).reshape(traj.states.shape[:2])
    np.testing.assert_allclose(energy, np.repeat(energy[:, :1], energy.shape[1], 1), rtol=1e-8)
    # deterministic per seed, and a new cache entry (the draw is part of the key)
    np.testing.assert_array_equal(system.evaluation(seed=3).x0, x0)
    assert cfg.data_fields()["eval_init"] == "box"


@pytest.mark.parametrize(
    "override, message",
    [
        ("system.eval_init=grid", "system.eval_init='grid' is invalid: expected one of train, box"),
        ("system.eval_box_min=2.0", "eval_box_min"),
        ("system.eval_box_min=-0.1", "system.eval_box_min=-0.1 is invalid"),
    ],
)
def test_bad_evaluation_draw_settings_are_one_line_errors(override, message):
    cfg = compose(["system=spring", "model=oracle", override])
    with pytest.raises(ConfigError) as err:
        prepare_job(cfg)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_the_paper_profile_evaluates_on_the_box_and_train_is_selectable():
    for name in ("spring", "pendulum"):
        assert prepare_job(compose([f"system={name}"])).system_cfg.eval_init == "box"
    job = prepare_job(compose(["system=pendulum", "model=oracle", "system.eval_init=train"]))
    assert job.system_cfg.eval_init == "train"
