"""The measured pendulum (Schmidt & Lipson 2009): parsing, targets, splits, evaluation."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from conftest import shared_data_dir

from hnnbench._contracts.errors import ConfigError, DataError
from hnnbench_plugins.systems.real_pendulum import (
    FILENAME,
    SHA256,
    RealPendulum,
    RealPendulumConfig,
)

REPO = Path(__file__).resolve().parents[2]


DATA_DIR = shared_data_dir()
SOURCE = DATA_DIR / FILENAME
pytestmark = pytest.mark.skipif(
    not SOURCE.is_file() and not os.environ.get("CI"),  # in CI, missing data fails
    reason=f"{FILENAME} not found (set HNNBENCH_DATA_DIR)",
)


@pytest.fixture(autouse=True)
def data_env(monkeypatch, tmp_path):
    monkeypatch.setenv("HNNBENCH_DATA_DIR", str(DATA_DIR))
    monkeypatch.setenv("HNNBENCH_CACHE_DIR", str(tmp_path / "cache"))


def make(**overrides) -> RealPendulum:
    cfg = RealPendulumConfig(name="real_pendulum", **overrides)
    cfg.validate()
    return RealPendulum(cfg)


@pytest.fixture(scope="module")
def raw() -> np.ndarray:
    """The file read independently of the plugin's parser."""
    return np.loadtxt(SOURCE, comments="%")


def test_published_hash_matches_sha256sums():
    sums = dict(
        reversed(line.split())
        for line in (DATA_DIR / "SHA256SUMS").read_text().splitlines()
        if line.strip()
    )
    assert sums[FILENAME] == SHA256


def test_parse_handles_crlf_and_header(raw):
    assert b"\r\n" in SOURCE.read_bytes()[:40]
    table = RealPendulum.parse(SOURCE)
    assert table.shape == (556, 4)
    np.testing.assert_array_equal(table, raw)


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda lines: lines[:3] + [" ".join(lines[3].split()[:3])] + lines[4:], "line 4"),
        (lambda lines: lines[:5] + [lines[5].replace("e", "x", 1)] + lines[6:], "line 6"),
        (lambda lines: lines[:1], "data rows"),
    ],
    ids=["columns", "non-numeric", "empty"],
)
def test_parse_rejects_corrupt_tables(tmp_path, mutate, match):
    lines = SOURCE.read_text().splitlines()
    bad = tmp_path / FILENAME
    bad.write_text("\r\n".join(mutate(lines)) + "\r\n")
    with pytest.raises(DataError, match=match) as info:
        RealPendulum.parse(bad)
    assert str(bad) in str(info.value) and "\n" not in str(info.value)


def test_corrupt_explicit_file_is_a_data_error(tmp_path):
    bad = tmp_path / FILENAME
    bad.write_bytes(SOURCE.read_bytes()[:1000])
    with pytest.raises(DataError, match="corrupt") as info:
        make(data_path=str(bad)).dataset(0)
    assert str(bad) in str(info.value)


def test_missing_data_is_a_data_error(monkeypatch, tmp_path):
    """No copy and no download (the archive's download: tests/integration/test_data_archive.py)."""
    monkeypatch.setenv("HNNBENCH_DATA_DIR", str(tmp_path))
    with pytest.raises(DataError, match="HNNBENCH_DATA_DIR"):
        make(archive_url=None).dataset(0)


def _rows(raw, split):
    """The file rows of a split's points (a point is at its row's time)."""
    return np.searchsorted(raw[:, 1], split.t)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_the_seed_chooses_a_fold_and_no_point_crosses_an_edge(raw, seed):
    system = make()
    ds = system.dataset(seed)
    fold = (5 - 1 - seed) % 5
    edges = [round(i * 556 / 5) for i in range(6)]
    assert ds.meta["fold"] == fold == system.fold(seed) and ds.meta["folds"] == 5
    assert ds.valid is not None and "fold" in ds.meta["validation"]
    role = np.full(556, -1)
    for code, split in enumerate((ds.train, ds.valid, ds.test)):
        assert split.x.shape == split.dxdt.shape == (len(split), 2)
        assert np.all(np.isfinite(split.dxdt))
        rows = _rows(raw, split)
        assert np.all(role[rows] == -1)  # no row in two segments
        role[rows] = code
    test_rows = _rows(raw, ds.test)
    assert edges[fold] <= test_rows.min() and test_rows.max() + 1 < edges[fold + 1]
    before = (fold - 1) % 5
    valid_rows = _rows(raw, ds.valid)
    assert (edges[before] + edges[before + 1]) // 2 <= valid_rows.min()
    assert valid_rows.max() < edges[before + 1]
    # A point's forward difference stays in its segment, and every training or
    # validation point keeps 2 rows (0.25 s at dt = 1/6) from any other segment.
    for code, split in enumerate((ds.train, ds.valid)):
        for row in _rows(raw, split):
            near = role[max(0, row - 2) : row + 4]
            assert np.all((near == code) | (near == -1)), (code, row)
    assert ds.meta["sha256"] == SHA256 and ds.meta["data_file"] == str(SOURCE)


def test_seed_zero_tests_on_the_papers_segment(raw):
    ds = make().dataset(0)
    assert ds.meta["test_rows"] == [445, 556] and len(ds.test) == 110
    assert ds.train.t.max() < raw[445, 1] <= ds.test.t.min()
    assert ds.valid is not None and ds.valid.t.max() < raw[445, 1]


def test_forward_differences(raw):
    ds = make().dataset(0)
    # First row: x = (theta, omega) at t = 5, target over the next sample (dt = 1/6).
    np.testing.assert_allclose(ds.train.x[0], raw[0, 2:4])
    np.testing.assert_allclose(ds.train.dxdt[0], (raw[1, 2:4] - raw[0, 2:4]) * 6.0, rtol=1e-9)
    # Row 4 is followed by a gap of 1/3 s: no point at its time.
    assert raw[5, 1] - raw[4, 1] == pytest.approx(1 / 3)
    assert raw[4, 1] not in ds.train.t
    # Every target uses the actual dt to the next row.
    times = raw[:, 1]
    for split in (ds.train, ds.test):
        rows = np.searchsorted(times, split.t)
        dt = times[rows + 1] - times[rows]
        np.testing.assert_allclose(split.dxdt, (raw[rows + 1, 2:4] - raw[rows, 2:4]) / dt[:, None])
        assert dt.max() < 1.5 / 6


def test_dataset_is_deterministic_and_seeds_five_apart_share_a_fold():
    a, b, c = make().dataset(0), make().dataset(0), make().dataset(5)
    for other in (b, c):
        np.testing.assert_array_equal(a.train.x, other.train.x)
        np.testing.assert_array_equal(a.test.dxdt, other.test.dxdt)
    assert not np.array_equal(make().dataset(1).test.x[:5], a.test.x[:5])


def test_energy_formula():
    system = make()
    x = np.array([[0.0, 0.0], [np.pi, 0.0], [0.5, -1.5]])
    np.testing.assert_allclose(system.energy(x), [0.0, 4.8, 2.4 * (1 - np.cos(0.5)) + 2.25])
    assert system.dof == 1
    assert not system.has_vector_field
    assert system.vector_field(x) is None
    assert system.time_reversible is False


def test_evaluation_chunks(raw):
    traj = make().evaluation(0)
    assert traj.states.shape == (5, 22, 2)
    assert traj.t.shape == (22,)
    assert traj.t[0] == 0.0
    np.testing.assert_allclose(traj.t, np.arange(22) / 6, atol=1e-9)
    assert traj.dt == pytest.approx(1 / 6)
    # Chunks are contiguous, in order, from the start of the test segment.
    rows = 445 + 22 * np.arange(5)[:, None] + np.arange(22)
    np.testing.assert_array_equal(traj.states, raw[rows, 2:4])
    np.testing.assert_array_equal(traj.x0, raw[rows[:, 0], 2:4])
    assert traj.meta["unused_test_rows"] == 111 - 110
    assert traj.meta["max_grid_deviation"] < 1e-9


def test_evaluation_skips_gaps_in_the_test_segment(raw):
    # With half the rows as test (two folds), the segment contains gaps; chunks avoid them.
    traj = make(folds=2, eval_chunks=8).evaluation(0)
    times = raw[:, 1]
    for start in traj.meta["chunk_start_times"]:
        row = int(np.searchsorted(times, start))
        chunk_t = times[row : row + len(traj.t)]
        assert np.diff(chunk_t).max() < 1.5 / 6
        np.testing.assert_allclose(chunk_t - chunk_t[0], traj.t, atol=1e-9)
    assert traj.states.shape[0] == 8


def test_single_chunk_and_too_many_chunks():
    assert make(eval_chunks=1).evaluation(0).states.shape == (1, 111, 2)
    with pytest.raises(ConfigError, match="eval_chunks"):
        make(eval_chunks=100).evaluation(0)


@pytest.mark.parametrize(
    "overrides, key",
    [
        ({"folds": 1}, "folds"),
        ({"folds": 2.5}, "folds"),
        ({"fold_gap_s": -1.0}, "fold_gap_s"),
        ({"eval_chunks": 0}, "eval_chunks"),
        ({"max_gap_factor": 1.0}, "max_gap_factor"),
        ({"url": "example.org/x.txt"}, "url"),
        ({"download_timeout_s": 0}, "download_timeout_s"),
    ],
)
def test_validate(overrides, key):
    with pytest.raises(ConfigError, match=f"system.{key}") as info:
        RealPendulumConfig(**overrides).validate()
    assert "\n" not in str(info.value)


def test_paper_protocol_and_cache_key():
    cfg = RealPendulumConfig()
    assert (cfg.steps, cfg.batch_size, cfg.weight_decay) == (2000, None, 1e-5)
    assert cfg.url is None and cfg.data_path is None and cfg.folds == 5
    assert RealPendulum.profiles["quick"] == {"steps": 300}
    key = cfg.data_fields()
    assert key["sha256"] == SHA256
    assert not {"data_path", "url", "archive_url", "archive_sha256"} & set(key)
    assert RealPendulumConfig(data_path="/elsewhere").data_fields() == key


def test_registered_entry_point():
    from importlib.metadata import entry_points

    (ep,) = [e for e in entry_points(group="hnnbench.systems") if e.name == "real_pendulum"]
    assert ep.load() is RealPendulum
