"""Config composition (Hydra compose), profiles and validation."""

from __future__ import annotations

import pytest
from conftest import compose_job as compose

from hnnbench._contracts.errors import ConfigError
from hnnbench._contracts.plugin import TrainSettings
from hnnbench._running.config import prepare_job


def test_defaults_are_paper_settings():
    cfg = compose([])
    assert cfg.system.name == "spring" and cfg.model.name == "hnn_torch"
    assert cfg.profile.name == "paper"
    job = prepare_job(cfg)
    train = TrainSettings.resolve(job.system_cfg, job.model_cfg)
    assert train == TrainSettings(steps=2000, batch_size=None, lr=1e-3, weight_decay=1e-4)
    assert job.model_cfg.hidden == 200 and job.model_cfg.layers == 3


def test_quick_profile_shrinks_and_user_overrides_win():
    cfg = compose(["system=pendulum", "profile=quick"])
    assert cfg.system.steps == 300 and cfg.profile.name == "quick"
    cfg = compose(["system=pendulum", "profile=quick", "system.steps=7"])
    assert cfg.system.steps == 7


def test_model_overrides_training_protocol():
    job = prepare_job(compose(["model=mlp_torch", "model.steps=5", "model.lr=0.01"]))
    train = TrainSettings.resolve(job.system_cfg, job.model_cfg)
    assert (train.steps, train.lr, train.weight_decay) == (5, 0.01, 1e-4)


@pytest.mark.parametrize(
    "override, needle",
    [
        ("system.steps=-3", "system.steps=-3 is invalid"),
        ("model.hidden=0", "model.hidden=0 is invalid"),
        ("system.test_split=1.5", "system.test_split=1.5 is invalid"),
        ("system.t_end=0", "system.t_end=0"),
        ("model.activation=relu6", "model.activation='relu6' is invalid"),
        ("device=gpu", "device=gpu is invalid"),
        ("seed=-1", "seed=-1 is invalid"),
        ("evaluation.rtol=0", "evaluation.rtol=0"),
    ],
)
def test_invalid_values_fail_with_one_line(override, needle):
    with pytest.raises(ConfigError) as err:
        prepare_job(compose([override]))
    assert needle in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize(
    "override, needle",
    [
        ("seed=abc", "seed"),
        ("system.steps=many", "steps"),
        ("system.nonsense=1", "nonsense"),
        ("system=sprng", "sprng"),
        ("profile=fast", "Unknown profile 'fast'"),
    ],
)
def test_bad_overrides_fail_at_compose(override, needle):
    with pytest.raises(ConfigError) as err:
        prepare_job(compose([override]))
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_job_directory_names_leave_out_exactly_the_run_only_keys():
    from hnnbench._results.leaderboard import NON_VARIANT_KEYS
    from hnnbench._running.config import RUN_ONLY_KEYS

    cfg = compose([], return_hydra_config=True)
    excluded = set(cfg.hydra.job.config.override_dirname.exclude_keys)
    assert {k for k in excluded if not k.startswith("hydra")} == set(NON_VARIANT_KEYS)
    assert RUN_ONLY_KEYS < NON_VARIANT_KEYS
