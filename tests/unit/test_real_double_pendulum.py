"""The measured double pendulum (Schmidt & Lipson 2009): parsing, checksum, targets,
split, evaluation chunks and the fitted energy model."""

from __future__ import annotations

import dataclasses
import os
from importlib.metadata import entry_points

import numpy as np
import pytest
from conftest import shared_data_dir

from hnnbench._contracts.errors import ConfigError, DataError
from hnnbench_plugins.systems.real_double_pendulum import (
    FILENAME,
    SHA256,
    RealDoublePendulum,
    RealDoublePendulumConfig,
    derivative_consistency,
    fit_energy_model,
    wrap_angle,
)

DATA_DIR = shared_data_dir()
SOURCE = DATA_DIR / FILENAME
pytestmark = pytest.mark.skipif(
    not SOURCE.is_file() and not os.environ.get("CI"),  # in CI, missing data fails
    reason=f"{FILENAME} not found (set HNNBENCH_DATA_DIR)",
)
N_ROWS, SPLIT_ROW = 1520, 1216  # 1520 - round(0.2 * 1520)


@pytest.fixture(autouse=True)
def data_env(monkeypatch, tmp_path):
    monkeypatch.setenv("HNNBENCH_DATA_DIR", str(DATA_DIR))
    monkeypatch.setenv("HNNBENCH_CACHE_DIR", str(tmp_path / "cache"))


def make(**overrides) -> RealDoublePendulum:
    cfg = RealDoublePendulumConfig(name="real_double_pendulum", **overrides)
    cfg.validate()
    return RealDoublePendulum(cfg)


@pytest.fixture(scope="module")
def raw() -> np.ndarray:
    """The file read independently of the plugin's parser."""
    return np.loadtxt(SOURCE, comments="%")


# --------------------------------------------------------------------------- file


def test_published_hash_matches_sha256sums():
    sums = dict(
        reversed(line.split())
        for line in (DATA_DIR / "SHA256SUMS").read_text().splitlines()
        if line.strip()
    )
    assert sums[FILENAME] == SHA256


def test_parse_handles_crlf_and_header(raw):
    head = SOURCE.read_bytes()[:40]
    assert head.startswith(b"% o1 o2 w1 w2\r\n")
    table = RealDoublePendulum.parse(SOURCE)
    assert table.shape == (N_ROWS, 10)
    np.testing.assert_array_equal(table, raw)
    trials, counts = np.unique(table[:, 0], return_counts=True)
    assert list(trials) == [0, 1] and list(counts) == [819, 701]


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda lines: lines[:3] + [" ".join(lines[3].split()[:6])] + lines[4:], "line 4"),
        (lambda lines: lines[:5] + [lines[5].replace(".", "x", 1)] + lines[6:], "line 6"),
        (lambda lines: lines[:1], "data rows"),
        (lambda lines: lines[:1] + lines[2:3] + lines[1:2] + lines[3:], "do not increase"),
    ],
    ids=["columns", "non-numeric", "empty", "time-order"],
)
def test_parse_rejects_corrupt_tables(tmp_path, mutate, match):
    lines = SOURCE.read_text().splitlines()
    bad = tmp_path / FILENAME
    bad.write_text("\r\n".join(mutate(lines)) + "\r\n")
    with pytest.raises(DataError, match=match) as info:
        RealDoublePendulum.parse(bad)
    assert str(bad) in str(info.value) and "\n" not in str(info.value)


def test_checksum_mismatch_is_a_one_line_data_error(monkeypatch, tmp_path):
    bad = tmp_path / FILENAME
    data = bytearray(SOURCE.read_bytes())
    data[100] = ord("7") if data[100] != ord("7") else ord("8")  # one digit changed
    bad.write_bytes(bytes(data))
    with pytest.raises(DataError, match="corrupt or not the expected version") as info:
        make(data_path=str(bad)).dataset(0)
    message = str(info.value)
    assert str(bad) in message and SHA256[:12] in message and "\n" not in message
    # the same through $HNNBENCH_DATA_DIR
    monkeypatch.setenv("HNNBENCH_DATA_DIR", str(tmp_path))
    with pytest.raises(DataError, match="SHA-256"):
        make().dataset(0)


def test_missing_data_is_a_data_error(monkeypatch, tmp_path):
    """No copy and no download (the archive's download: tests/integration/test_data_archive.py)."""
    monkeypatch.setenv("HNNBENCH_DATA_DIR", str(tmp_path))
    with pytest.raises(DataError, match="HNNBENCH_DATA_DIR") as info:
        make(archive_url=None).dataset(0)
    assert FILENAME in str(info.value)


def test_the_repeated_columns_and_the_derivatives(raw):
    """Figures quoted in docs/SYSTEMS_REAL_DOUBLE_PENDULUM.md."""
    report = derivative_consistency(raw)
    assert report["omega_copy_equal"] is True
    np.testing.assert_array_equal(raw[:, 4:6], raw[:, 6:8])
    t0, t1 = report["trial_0"], report["trial_1"]
    assert (t0["rows"], t0["gaps"], t1["rows"], t1["gaps"]) == (819, 32, 701, 53)
    np.testing.assert_allclose(t0["omega_vs_central_diff_theta"], [0.0143, 0.0155], atol=5e-4)
    np.testing.assert_allclose(t0["alpha_vs_central_diff_omega"], [0.0471, 0.0445], atol=5e-4)
    np.testing.assert_allclose(t1["omega_vs_central_diff_theta"], [0.0286, 0.0303], atol=5e-4)
    np.testing.assert_allclose(t1["alpha_vs_central_diff_omega"], [0.1050, 0.1049], atol=5e-4)


# --------------------------------------------------------------------------- data


def _rows(raw, split):
    return np.searchsorted(raw[:, 1], split.t)


def test_targets_are_the_files_velocities_and_accelerations(raw):
    ds = make().dataset(0)
    for split in (ds.train, ds.valid, ds.test):
        rows = _rows(raw, split)
        np.testing.assert_array_equal(split.dxdt[:, 2:], raw[rows, 8:10])
        np.testing.assert_array_equal(split.dxdt[:, :2], raw[rows, 4:6])
        np.testing.assert_array_equal(split.x[:, 2:], raw[rows, 4:6])
    # angles wrapped into [-π, π) by whole turns
    theta = np.concatenate([ds.train.x, ds.test.x])[:, :2]
    assert np.all((theta >= -np.pi) & (theta < np.pi))
    turns = (raw[np.concatenate([_rows(raw, ds.train), _rows(raw, ds.test)]), 2:4] - theta) / (
        2 * np.pi
    )
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    unwrapped = make(wrap_angles=False).dataset(0)
    np.testing.assert_array_equal(unwrapped.train.x[:, :2], raw[_rows(raw, unwrapped.train), 2:4])


@pytest.mark.parametrize("seed", [0, 3])
def test_fold_sizes_and_order(raw, seed):
    ds = make().dataset(seed)
    fold = (4 - seed) % 5
    edges = [round(i * N_ROWS / 5) for i in range(6)]
    test = _rows(raw, ds.test)
    assert (test.min(), test.max() + 1) == (edges[fold], edges[fold + 1]) and len(test) == 304
    valid = _rows(raw, ds.valid)
    before = (fold - 1) % 5
    assert (edges[before] + edges[before + 1]) // 2 + 25 <= valid.min()
    train = _rows(raw, ds.train)
    assert not set(train) & set(valid) and not set(train) & set(test)
    # 25 rows (0.25 s) between every training or validation row and another segment
    for rows, others in (
        (train, np.concatenate([valid, test])),
        (valid, np.concatenate([train, test])),
    ):
        assert np.abs(rows[:, None] - others[None, :]).min() > 25
    np.testing.assert_array_equal(ds.train.traj, raw[train, 0].astype(int))
    assert ds.meta["fold"] == fold and ds.meta["test_rows"] == [edges[fold], edges[fold + 1]]


def test_srnn_windows_are_continuous_in_the_angles():
    """With wrapped angles, the windows the SRNN trains on are unwrapped: no step jumps
    by 2π, and each window is the raw (unwrapped) data shifted by whole turns."""
    from hnnbench.neural._views import trajectory_windows

    wrapped, raw_sys = make(), make(wrap_angles=False)
    assert wrapped.wrapped_angles == (0, 1) and raw_sys.wrapped_angles == ()
    for part in ("train", "test"):
        a, b = getattr(wrapped.dataset(0), part), getattr(raw_sys.dataset(0), part)
        naive, _ = trajectory_windows(a, a.x, 5)
        assert np.abs(np.diff(naive[..., :2], axis=1)).max() > 6  # the bug it fixes
        w, dts = trajectory_windows(a, a.x, 5, wrapped.wrapped_angles)
        ref, ref_dts = trajectory_windows(b, b.x, 5)
        np.testing.assert_array_equal(dts, ref_dts)
        assert np.abs(np.diff(w[..., :2], axis=1)).max() < 1.0  # |ω| dt < 0.45 rad here
        turns = (w[..., :2] - ref[..., :2]) / (2 * np.pi)
        np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
        assert np.ptp(np.round(turns), axis=1).max() == 0  # one shift per window and rod
        np.testing.assert_array_equal(w[..., 2:], ref[..., 2:])


def test_evaluation_chunks(raw):
    traj = make().evaluation(0)
    assert traj.states.shape == (10, 19, 4) and traj.t.shape == (19,)
    assert traj.t[0] == 0.0 and traj.dt == pytest.approx(0.01, abs=1e-5)
    np.testing.assert_allclose(traj.t, np.arange(19) * 0.01, atol=1e-5)
    times = raw[:, 1]
    starts = traj.meta["chunk_start_times"]
    assert starts == sorted(starts) and starts[0] >= raw[SPLIT_ROW, 1]
    for k, start in enumerate(starts):
        row = int(np.flatnonzero(times == start)[0])
        rows = slice(row, row + 19)
        assert np.all(raw[rows, 0] == 1)  # one trial
        assert np.diff(times[rows]).max() < 1.5 * 0.01  # no gap
        np.testing.assert_array_equal(traj.states[k, :, 2:], raw[rows, 4:6])
        shift = raw[rows, 2:4] - traj.states[k, :, :2]
        np.testing.assert_allclose(shift, np.broadcast_to(shift[0], shift.shape), atol=1e-9)
        np.testing.assert_allclose(shift / (2 * np.pi), np.round(shift / (2 * np.pi)), atol=1e-9)
        np.testing.assert_allclose(traj.states[k, 0, :2], wrap_angle(raw[row, 2:4]), atol=1e-9)
    assert traj.meta["unused_test_rows"] == 304 - 190
    assert traj.meta["max_grid_deviation"] < 1e-4
    raw_chunks = make(wrap_angles=False).evaluation(0)
    assert raw_chunks.meta["chunk_start_times"] == starts
    np.testing.assert_array_equal(raw_chunks.states[..., 2:], traj.states[..., 2:])


def test_five_chunks_and_too_many_chunks():
    assert make(eval_chunks=5).evaluation(0).states.shape == (5, 21, 4)
    with pytest.raises(ConfigError, match="eval_chunks") as info:
        make(eval_chunks=200).evaluation(0)
    assert "\n" not in str(info.value)


# --------------------------------------------------------------------------- energy


def test_energy_model_is_reproducible_and_sane(raw):
    system = make()
    model = system.energy_model()
    assert system.energy_model() is model  # cached per instance
    again = make().energy_model()
    assert again == model  # deterministic: identical numbers from a fresh instance
    assert fit_energy_model(raw) == model  # fitted on every row: one model for all folds
    # the figures quoted in the docs
    assert model.mass_ratio == pytest.approx(0.567, abs=0.001)
    assert model.length_ratio == pytest.approx(0.896, abs=0.001)
    assert model.g_over_l1 == pytest.approx(67.6, abs=0.1)  # l1 = 9.81 / 67.6 = 14.5 cm
    np.testing.assert_allclose(model.relative_residual, [0.275, 0.260], atol=0.001)
    assert all(0 < k < 0.2 for k in model.damping)
    assert model.n_points == N_ROWS
    # energy: zero at rest, positive, periodic in the angles, and decaying on average
    x = np.concatenate([raw[:, 2:4], raw[:, 4:6]], axis=1)
    energy = system.energy(x)
    assert system.energy(np.zeros((1, 4)))[0] == 0.0 and np.all(energy > 0)
    np.testing.assert_allclose(system.energy(x + [2 * np.pi, -4 * np.pi, 0, 0]), energy, rtol=1e-9)
    for trial in (0, 1):
        e = energy[raw[:, 0] == trial]
        assert e[-20:].mean() < 0.85 * e[:20].mean()
        assert e.std() / e.mean() < 0.15
    # trial 1 rotates over the top (both rods), trial 0 does not
    top = model.coefficients[3] * 2  # the inner rod's potential at θ1 = π
    assert energy[raw[:, 0] == 0].max() < top < energy[raw[:, 0] == 1].min()


def test_energy_model_prefers_absolute_angles(raw):
    """Read as the angle between the rods, θ2 explains the accelerations far worse."""
    relative = raw[:SPLIT_ROW].copy()
    for cols in ((2, 3), (4, 5), (8, 9)):
        relative[:, cols[1]] += relative[:, cols[0]]
    worse = fit_energy_model(relative)
    assert min(worse.relative_residual) > 0.8
    assert max(make().energy_model().relative_residual) < 0.3


def test_contract():
    system = make()
    assert system.dof == 2 and not system.has_vector_field
    assert system.vector_field(np.zeros((1, 4))) is None
    assert system.time_reversible is False and system.conservative is False
    assert system.lyapunov_time is None
    kin = system.kinematics()
    x = np.arange(8.0).reshape(2, 4)
    np.testing.assert_array_equal(kin.to_velocity(x), x)


# --------------------------------------------------------------------------- config


@pytest.mark.parametrize(
    "overrides, key",
    [
        ({"folds": 1}, "folds"),
        ({"eval_chunks": 0}, "eval_chunks"),
        ({"max_gap_factor": 1.0}, "max_gap_factor"),
        ({"url": "example.org/x.txt"}, "url"),
        ({"wrap_angles": "no"}, "wrap_angles"),
    ],
)
def test_validate(overrides, key):
    with pytest.raises(ConfigError, match=f"system.{key}") as info:
        RealDoublePendulumConfig(**overrides).validate()
    assert "\n" not in str(info.value)


def test_protocol_profiles_cache_key_and_entry_point():
    cfg = RealDoublePendulumConfig()
    assert (cfg.steps, cfg.batch_size, cfg.weight_decay) == (2000, None, 1e-5)
    assert (cfg.folds, cfg.eval_chunks, cfg.wrap_angles) == (5, 10, True)
    assert cfg.url is None and cfg.data_path is None
    quick = RealDoublePendulum.profiles["quick"]
    assert set(quick) <= {f.name for f in dataclasses.fields(cfg)} and quick["steps"] <= 300
    key = cfg.data_fields()
    assert key["sha256"] == SHA256 and "data_path" not in key and "url" not in key
    assert RealDoublePendulumConfig(data_path="/elsewhere").data_fields() == key
    assert RealDoublePendulum.version == "2" and "\n" not in RealDoublePendulum.description
    (ep,) = [e for e in entry_points(group="hnnbench.systems") if e.name == "real_double_pendulum"]
    assert ep.load() is RealDoublePendulum
