"""The dataset helper for systems (hnnbench._contracts.datasets): seed streams, the trajectory split
rule and trajectory_dataset."""

from __future__ import annotations

import numpy as np
import pytest

from hnnbench import (
    DATA_STREAM,
    EVAL_STREAM,
    SPLIT_STREAM,
    ConfigError,
    TrajectorySplit,
    seed_stream,
    trajectory_dataset,
)


def trajectories(n_traj: int = 10, n_points: int = 4, d: int = 2, dtype: type = np.float64):
    """``x`` whose entries encode (trajectory, point, component), its ``dxdt`` and ``t``."""
    i, j, k = np.meshgrid(np.arange(n_traj), np.arange(n_points), np.arange(d), indexing="ij")
    x = (1000 * i + 10 * j + k).astype(dtype)
    return x, -x, np.linspace(0.0, 1.5, n_points)


# --------------------------------------------------------------------------- streams


def test_seed_stream_is_default_rng_of_seed_and_tag():
    assert len({DATA_STREAM, EVAL_STREAM, SPLIT_STREAM}) == 3
    for seed in (0, 7):
        for tag in (DATA_STREAM, EVAL_STREAM, SPLIT_STREAM, 2):
            expected = np.random.default_rng((seed, tag)).random(5)
            np.testing.assert_array_equal(seed_stream(seed, tag).random(5), expected)


def test_seed_streams_are_deterministic_and_distinct():
    draws = {
        (s, tag): seed_stream(s, tag).random(3).tobytes()
        for s in (0, 1)
        for tag in (DATA_STREAM, EVAL_STREAM, SPLIT_STREAM)
    }
    assert len(set(draws.values())) == len(draws)
    assert seed_stream(1, EVAL_STREAM).random(3).tobytes() == draws[(1, EVAL_STREAM)]


# --------------------------------------------------------------------------- split rule


@pytest.mark.parametrize(
    "n, fraction, rounding, sizes",
    [
        (10, 0.2, "test", (8, 2)),
        (10, 0.2, "train", (8, 2)),
        (5, 0.3, "test", (3, 2)),  # round(1.5) = 2 test
        (5, 0.3, "train", (4, 1)),  # round(3.5) = 4 train
        (1000, 0.2, "test", (800, 200)),
    ],
)
def test_sizes_round_the_stated_count(n, fraction, rounding, sizes):
    split = TrajectorySplit(fraction, test_from="last", rounding=rounding)
    assert split.sizes(n) == sizes


@pytest.mark.parametrize(
    "test_from, test",
    [("first", [0, 1, 2]), ("last", [7, 8, 9])],
)
def test_first_and_last_take_a_block(test_from, test):
    chosen = TrajectorySplit(0.3, test_from=test_from).indices(10)
    assert chosen.test.tolist() == test
    assert chosen.train.tolist() == sorted(set(range(10)) - set(test))


def test_shuffled_draws_from_the_split_stream_and_is_deterministic_per_seed():
    split = TrajectorySplit(0.25, test_from="shuffled")
    a, b, c = split.indices(40, seed=3), split.indices(40, seed=3), split.indices(40, seed=4)
    np.testing.assert_array_equal(a.test, b.test)
    np.testing.assert_array_equal(a.train, b.train)
    assert a.test.tolist() != c.test.tolist()
    expected = np.sort(np.random.default_rng((3, SPLIT_STREAM)).permutation(40)[:10])
    np.testing.assert_array_equal(a.test, expected)
    assert len(a.test) == 10 and len(a.train) == 30
    assert np.all(np.diff(a.test) > 0) and np.all(np.diff(a.train) > 0)


@pytest.mark.parametrize("test_from", ["first", "last", "shuffled"])
def test_indices_partition_the_trajectories(test_from):
    chosen = TrajectorySplit(0.2, test_from=test_from).indices(23, seed=0)
    assert not set(chosen.train) & set(chosen.test)
    assert sorted([*chosen.train, *chosen.test]) == list(range(23))


def test_shuffled_needs_a_seed():
    with pytest.raises(ConfigError, match="seed="):
        TrajectorySplit(0.2, test_from="shuffled").indices(10)


@pytest.mark.parametrize(
    "n, fraction, rounding",
    [(3, 0.1, "test"), (3, 0.9, "test"), (2, 0.2, "train"), (4, 0.9, "train")],
)
def test_an_empty_split_is_a_one_line_config_error(n, fraction, rounding):
    split = TrajectorySplit(fraction, test_from="last", rounding=rounding)
    with pytest.raises(ConfigError, match="leaves an empty train or test set") as info:
        split.indices(n)
    assert f"{n} trajectories" in str(info.value) and "\n" not in str(info.value)
    x, dxdt, t = trajectories(n_traj=n)
    with pytest.raises(ConfigError, match="empty train or test"):
        trajectory_dataset(x, dxdt, t, split)


def test_check_names_the_settings():
    split = TrajectorySplit(0.1, test_from="first")
    split.check(20)  # 2 test, 18 train: fine
    with pytest.raises(ConfigError) as info:
        split.check(3, count_key="n_orbits", unit="orbits")
    assert str(info.value) == (
        "system.test_split=0.1 with system.n_orbits=3 leaves an empty train or test set: "
        "use more orbits or another split."
    )


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"test_from": "middle"}, "test_from='middle'"),
        ({"test_from": "last", "rounding": "both"}, "rounding='both'"),
    ],
)
def test_an_unknown_rule_is_rejected(kwargs, match):
    with pytest.raises(ValueError, match=match):
        TrajectorySplit(0.2, **kwargs)


# --------------------------------------------------------------------------- dataset


@pytest.mark.parametrize("test_from", ["first", "last", "shuffled"])
def test_trajectory_dataset_flattens_whole_trajectories(test_from):
    x, dxdt, t = trajectories(n_traj=10, n_points=4, d=3)
    state = x[..., :2] * 2.0
    split = TrajectorySplit(0.3, test_from=test_from)
    data = trajectory_dataset(
        x, dxdt, t, split, seed=5, extras={"state": state}, meta={"dt": 0.5, "n_test_traj": 3}
    )
    chosen = split.indices(10, seed=5)
    assert data.meta == {"dt": 0.5, "n_test_traj": 3}
    for part, rows in ((data.train, chosen.train), (data.test, chosen.test)):
        n = len(rows) * 4
        assert part.x.shape == (n, 3) and part.dxdt.shape == (n, 3)
        assert part.traj.shape == (n,) and part.t.shape == (n,)
        assert part.extras["state"].shape == (n, 2)
        np.testing.assert_array_equal(part.traj, np.repeat(rows, 4))
        np.testing.assert_array_equal(part.t, np.tile(t, len(rows)))
        np.testing.assert_array_equal(part.x, x[rows].reshape(n, 3))
        np.testing.assert_array_equal(part.dxdt, -part.x)
        np.testing.assert_array_equal(part.extras["state"], 2.0 * part.x[:, :2])
        assert all(a.flags.c_contiguous for a in (part.x, part.dxdt, part.traj, part.t))
    assert not set(data.train.traj) & set(data.test.traj)
    assert len(data.train) + len(data.test) == 40


def test_trajectory_dataset_keeps_dtypes_and_copies():
    x, dxdt, t = trajectories(dtype=np.float32)
    data = trajectory_dataset(x, dxdt, t, TrajectorySplit(0.2, test_from="last"))
    assert data.train.x.dtype == np.float32 and data.test.dxdt.dtype == np.float32
    assert data.train.t.dtype == np.float64 and data.train.traj.dtype == np.arange(1).dtype
    x[:] = 0.0
    assert data.train.x.any()  # a copy, not a view of the caller's array


def test_trajectory_dataset_takes_per_trajectory_times():
    x, dxdt, _ = trajectories(n_traj=5, n_points=3)
    t = np.arange(15.0).reshape(5, 3)
    data = trajectory_dataset(x, dxdt, t, TrajectorySplit(0.4, test_from="first"))
    np.testing.assert_array_equal(data.test.t, np.arange(6.0))
    np.testing.assert_array_equal(data.train.t, np.arange(6.0, 15.0))


def test_trajectory_dataset_rejects_mismatched_shapes():
    x, dxdt, t = trajectories(n_traj=5, n_points=3)
    split = TrajectorySplit(0.4, test_from="first")
    with pytest.raises(ValueError, match="dxdt must be shaped"):
        trajectory_dataset(x, dxdt[:, :2], t, split)
    with pytest.raises(ValueError, match="extras\\['state'\\]"):
        trajectory_dataset(x, dxdt, t, split, extras={"state": x[:4]})


# --------------------------------------------------------------------------- systems


@pytest.mark.parametrize(
    "module, config, test_from, rounding",
    [
        ("spring", "SpringConfig", "last", "train"),
        ("pendulum", "PendulumConfig", "last", "train"),
        ("damped", "DampedSpringConfig", "last", "train"),
        ("nbody", "TwoBodyConfig", "first", "test"),
        ("nbody", "ThreeBodyConfig", "first", "test"),
        ("pixel_pendulum", "PixelPendulumConfig", "first", "test"),
        ("double_pendulum", "DoublePendulumConfig", "last", "test"),
        ("spring_chain", "SpringChainConfig", "last", "test"),
    ],
)
def test_each_system_declares_its_split(module, config, test_from, rounding):
    import importlib

    cfg = getattr(importlib.import_module(f"hnnbench_plugins.systems.{module}"), config)()
    assert cfg.trajectory_split() == TrajectorySplit(cfg.test_split, test_from, rounding)
