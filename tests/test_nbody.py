"""N-body systems: analytic H and forces against REBOUND, data protocol, config checks."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import rebound

from hnnbench.errors import ConfigError, DataError
from hnnbench_plugins.systems import nbody
from hnnbench_plugins.systems.nbody import (
    NBody,
    NBodyConfig,
    ThreeBody,
    ThreeBodyConfig,
    TwoBody,
    TwoBodyConfig,
)

SMALL = {"n_orbits": 10, "n_points": 11, "eval_n_orbits": 3, "eval_n_points": 21}


def two_body(**kw) -> TwoBody:
    return TwoBody(TwoBodyConfig(name="two_body", **{**SMALL, **kw}))


def three_body(**kw) -> ThreeBody:
    return ThreeBody(ThreeBodyConfig(name="three_body", **{**SMALL, **kw}))


def random_states(rng: np.random.Generator, n: int, n_bodies: int) -> np.ndarray:
    q = rng.uniform(-2.0, 2.0, size=(n, 2 * n_bodies))
    p = rng.normal(0.0, 0.7, size=(n, 2 * n_bodies))
    return np.concatenate([q, p], axis=1)


def rebound_sim(x: np.ndarray, n_bodies: int) -> rebound.Simulation:
    """A REBOUND simulation holding state ``x`` (same frame; no move to the COM)."""
    sim = rebound.Simulation()
    sim.G = 1.0
    q = x[: 2 * n_bodies].reshape(n_bodies, 2)
    v = x[2 * n_bodies :].reshape(n_bodies, 2)
    for i in range(n_bodies):
        sim.add(m=1.0, x=q[i, 0], y=q[i, 1], vx=v[i, 0], vy=v[i, 1])
    return sim


def rebound_accelerations(x: np.ndarray, n_bodies: int) -> np.ndarray:
    """REBOUND's gravitational accelerations at ``x``: a leapfrog step of length 0
    computes forces at the current positions without moving anything."""
    sim = rebound_sim(x, n_bodies)
    sim.integrator = "leapfrog"
    sim.dt = 0.0
    sim.steps(1)
    acc = np.array([[p.ax, p.ay] for p in sim.particles])
    pos = np.array([[p.x, p.y] for p in sim.particles])
    np.testing.assert_array_equal(pos.reshape(-1), x[: 2 * n_bodies])
    return acc.reshape(-1)


# --------------------------------------------------------------------------- physics


@pytest.mark.parametrize("n_bodies", [2, 3, 4])
def test_energy_matches_rebound(n_bodies):
    system = NBody(NBodyConfig(name="nbody", n_bodies=n_bodies))
    x = random_states(np.random.default_rng(n_bodies), 20, n_bodies)
    ours = system.energy(x)
    theirs = np.array([rebound_sim(row, n_bodies).energy() for row in x])
    np.testing.assert_allclose(ours, theirs, rtol=1e-10, atol=0)


@pytest.mark.parametrize("n_bodies", [2, 3, 4])
def test_vector_field_matches_rebound_accelerations(n_bodies):
    system = NBody(NBodyConfig(name="nbody", n_bodies=n_bodies))
    x = random_states(np.random.default_rng(10 + n_bodies), 20, n_bodies)
    f = system.vector_field(x)
    np.testing.assert_array_equal(f[:, : 2 * n_bodies], x[:, 2 * n_bodies :])  # dq/dt = p/m
    acc = np.array([rebound_accelerations(row, n_bodies) for row in x])
    scale = np.max(np.abs(acc), axis=1, keepdims=True)
    assert np.max(np.abs(f[:, 2 * n_bodies :] - acc) / scale) < 1e-10


def test_vector_field_is_the_symplectic_gradient_of_h():
    system = three_body()
    x = random_states(np.random.default_rng(3), 5, 3)
    h, n = 1e-6, system.dof
    grad = np.empty_like(x)
    for k in range(2 * n):
        e = np.zeros(2 * n)
        e[k] = h
        grad[:, k] = (system.energy(x + e) - system.energy(x - e)) / (2 * h)
    expected = np.concatenate([grad[:, n:], -grad[:, :n]], axis=1)
    np.testing.assert_allclose(system.vector_field(x), expected, rtol=1e-6, atol=1e-6)


def test_batched_leading_dimensions_and_reversal():
    system = two_body()
    x = random_states(np.random.default_rng(4), 12, 2).reshape(3, 4, 8)
    assert system.energy(x).shape == (3, 4)
    assert system.vector_field(x).shape == (3, 4, 8)
    np.testing.assert_allclose(system.vector_field(x).reshape(12, 8),
                               system.vector_field(x.reshape(12, 8)))
    assert system.dof == 4 and three_body().dof == 6
    assert system.time_reversible
    np.testing.assert_allclose(system.energy(system.reverse(x)), system.energy(x))
    with pytest.raises(ValueError, match="12 numbers"):
        three_body().energy(np.zeros((2, 8)))


@pytest.mark.parametrize("n_bodies", [2, 3, 5])
def test_ring_speed_is_circular(n_bodies):
    """Without noise the ring rotates rigidly: centripetal acceleration = v^2 / r."""
    rng = np.random.default_rng(0)
    x = nbody.ring_states(rng, 7, n_bodies, 0.5, 1.5, velocity_noise=0.0)
    system = NBody(NBodyConfig(name="nbody", n_bodies=n_bodies))
    q = x[:, : 2 * n_bodies].reshape(7, n_bodies, 2)
    p = x[:, 2 * n_bodies :].reshape(7, n_bodies, 2)
    a = system.vector_field(x)[:, 2 * n_bodies :].reshape(7, n_bodies, 2)
    r = np.linalg.norm(q, axis=-1)
    v2 = np.sum(p**2, axis=-1)
    np.testing.assert_allclose(np.sum(a * q, axis=-1) / r, -v2 / r, rtol=1e-12)
    np.testing.assert_allclose(np.sum(q * p, axis=-1), 0.0, atol=1e-12)  # tangential
    np.testing.assert_allclose(q.sum(axis=1), 0.0, atol=1e-12)  # centred ring
    if n_bodies == 2:
        np.testing.assert_allclose(q[:, 1], -q[:, 0])  # mirrored through the origin


def test_rebound_orbits_flags_a_collision():
    # Two bodies released from rest fall onto each other: REBOUND stops, drift is inf.
    x0 = np.array([[0.5, 0.0, -0.5, 0.0, 0.0, 0.0, 0.0, 0.0]])
    states, drift = nbody.rebound_orbits(x0, np.linspace(0.0, 2.0, 5), 2)
    assert drift[0] == np.inf
    assert states.shape == (1, 5, 8)


# --------------------------------------------------------------------------- data


@pytest.mark.parametrize("make", [two_body, three_body])
def test_dataset_shapes_split_and_targets(make):
    system = make()
    c = system.cfg
    data = system.dataset(0)
    d = 4 * c.n_bodies
    n_test = round(c.n_orbits * c.test_split)
    assert data.test.x.shape == (n_test * c.n_points, d)
    assert data.train.x.shape == ((c.n_orbits - n_test) * c.n_points, d)
    assert data.train.dxdt.shape == data.train.x.shape
    # The first orbits are the test set.
    assert set(data.test.traj) == set(range(n_test))
    assert set(data.train.traj) == set(range(n_test, c.n_orbits))
    np.testing.assert_allclose(data.train.t[: c.n_points], np.linspace(0, c.t_end, c.n_points))
    # No input noise; targets are the analytic field at the states.
    np.testing.assert_array_equal(data.train.dxdt, system.vector_field(data.train.x))
    np.testing.assert_array_equal(data.test.dxdt, system.vector_field(data.test.x))
    meta = data.meta
    assert meta["reference"] == "REBOUND IAS15"
    assert meta["ias15_adaptive_mode"] == "global"
    assert 0 <= meta["max_rel_energy_drift"] < 1e-10
    assert meta["n_train_traj"] == c.n_orbits - n_test and meta["n_test_traj"] == n_test
    assert meta["dt"] == pytest.approx(c.t_end / (c.n_points - 1))
    json.dumps(meta)
    # The analytic energy is conserved along every orbit.
    for split in (data.train, data.test):
        e = system.energy(split.x).reshape(-1, c.n_points)
        assert np.max(np.abs(e - e[:, :1]) / np.abs(e[:, :1])) < 1e-10


def test_dataset_is_deterministic_and_seeded(tmp_path):
    system = three_body()
    a, b, other = system.dataset(3), system.dataset(3), system.dataset(4)
    for key in ("x", "dxdt", "traj", "t"):
        np.testing.assert_array_equal(getattr(a.train, key), getattr(b.train, key))
        np.testing.assert_array_equal(getattr(a.test, key), getattr(b.test, key))
    assert a.meta == b.meta
    assert not np.allclose(a.train.x, other.train.x)
    a.save(tmp_path / "d.npz")
    loaded = type(a).load(tmp_path / "d.npz")
    np.testing.assert_array_equal(loaded.train.x, a.train.x)
    assert loaded.meta == a.meta


def test_input_noise_option_keeps_clean_targets():
    clean, noisy = two_body().dataset(0), two_body(noise_std=0.1).dataset(0)
    np.testing.assert_array_equal(noisy.train.dxdt, clean.train.dxdt)
    assert 0.05 < np.std(noisy.train.x - clean.train.x) < 0.15


def test_initial_state_distribution():
    system = TwoBody(TwoBodyConfig(name="two_body"))
    x0 = system.initial_states(np.random.default_rng(0), 2000)
    r = np.linalg.norm(x0[:, :2], axis=1)
    assert 0.5 <= r.min() and r.max() <= 1.5
    speed_ratio = np.linalg.norm(x0[:, 4:6], axis=1) / nbody.circular_speed(r, 2)
    assert abs(np.std(speed_ratio) - 0.05) < 0.005
    x3 = ThreeBody(ThreeBodyConfig(name="three_body")).initial_states(
        np.random.default_rng(0), 2000
    )
    r3 = np.linalg.norm(x3[:, :6].reshape(-1, 3, 2), axis=-1)
    assert 0.9 <= r3.min() and r3.max() <= 1.2
    np.testing.assert_allclose(r3 - r3[:, :1], 0.0, atol=1e-12)  # all three on one ring


@pytest.mark.parametrize("make", [two_body, three_body])
def test_evaluation_trajectories(make):
    system = make()
    c = system.cfg
    ev = system.evaluation(0)
    assert ev.states.shape == (c.eval_n_orbits, c.eval_n_points, 4 * c.n_bodies)
    np.testing.assert_allclose(ev.t, np.linspace(0.0, c.eval_t_end, c.eval_n_points))
    assert ev.dt == pytest.approx(c.t_end / (c.n_points - 1))
    assert 0 <= ev.meta["max_rel_energy_drift"] < 1e-10
    json.dumps(ev.meta)
    e = system.energy(ev.states)
    assert np.max(np.abs(e - e[:, :1]) / np.abs(e[:, :1])) < 1e-10
    again = system.evaluation(0)
    np.testing.assert_array_equal(again.states, ev.states)
    # Evaluation orbits come from another random stream than the data.
    data_x0 = system.dataset(0).test.x[0]
    assert not np.allclose(ev.x0[0], data_x0)


def test_near_collisions_are_redrawn(monkeypatch):
    """Orbits over the drift limit are replaced by new draws, and counted."""
    real = nbody.rebound_orbits
    calls = []

    def flaky(x0, t, n_bodies):
        states, drift = real(x0, t, n_bodies)
        calls.append(len(x0))
        if len(calls) == 1:
            drift[[1, 4]] = np.inf  # pretend two orbits hit a near-collision
        return states, drift

    monkeypatch.setattr(nbody, "rebound_orbits", flaky)
    data = two_body().dataset(0)
    assert calls == [10, 2]
    assert data.meta["n_rejected_orbits"] == 2
    assert data.meta["max_rel_energy_drift"] < 1e-10
    # Too many failures is a clear error.
    monkeypatch.setattr(nbody, "MAX_REL_ENERGY_DRIFT", -1.0)
    with pytest.raises(DataError, match="energy-drift limit"):
        two_body().dataset(0)


# --------------------------------------------------------------------------- config


def test_paper_defaults_and_profiles():
    two, three = TwoBodyConfig(), ThreeBodyConfig()
    assert (two.n_bodies, two.n_orbits, two.n_points, two.t_end) == (2, 1000, 50, 20.0)
    assert (two.steps, two.batch_size, two.weight_decay) == (10000, 200, 0.0)
    assert (two.eval_n_orbits, two.eval_t_end, two.eval_n_points) == (15, 25.0, 500)
    assert (three.n_bodies, three.n_orbits, three.n_points, three.t_end) == (3, 5000, 20, 5.0)
    assert (three.steps, three.batch_size, three.weight_decay) == (10000, 600, 1e-4)
    assert (three.eval_n_orbits, three.eval_t_end, three.eval_n_points) == (15, 3.0, 500)
    assert two.noise_std == three.noise_std == 0.0
    for cls in (TwoBody, ThreeBody):
        names = {f.name for f in dataclasses.fields(cls.Config)}
        for profile in cls.profiles.values():
            assert set(profile) <= names
            cls.Config(name="x", **profile).validate()
        assert cls.version == "1" and cls.description and "\n" not in cls.description


@pytest.mark.parametrize(
    "override, match",
    [
        ({"n_orbits": 1}, "n_orbits=1"),
        ({"n_points": 0}, "n_points=0"),
        ({"n_bodies": 1}, "n_bodies=1"),
        ({"eval_n_points": 1}, "eval_n_points=1"),
        ({"n_orbits": 2.5}, "n_orbits=2.5"),
        ({"test_split": 0.0}, "test_split=0.0"),
        ({"test_split": 1.0}, "test_split=1.0"),
        ({"t_end": 0.0}, "t_end=0.0"),
        ({"eval_t_end": -1.0}, "eval_t_end=-1.0"),
        ({"radius_min": 0.0}, "radius_min=0.0"),
        ({"radius_min": 2.0, "radius_max": 1.0}, "radius_max=1.0"),
        ({"velocity_noise": -0.1}, "velocity_noise=-0.1"),
        ({"noise_std": float("nan")}, "noise_std=nan"),
        ({"n_orbits": 3, "test_split": 0.1}, "empty train or test"),
        ({"steps": 0}, "steps=0"),
    ],
)
def test_validate_rejects_bad_values(override, match):
    cfg = TwoBodyConfig(name="two_body", **override)
    with pytest.raises(ConfigError, match=match) as err:
        cfg.validate()
    assert "\n" not in str(err.value)


# --------------------------------------------------------------------------- paper size


@pytest.mark.slow
def test_paper_three_body_dataset():
    system = ThreeBody(ThreeBodyConfig(name="three_body"))
    data = system.dataset(0)
    assert len(data.train) == 4000 * 20 and len(data.test) == 1000 * 20
    assert data.meta["max_rel_energy_drift"] < 1e-10
    assert data.meta["n_rejected_orbits"] <= 5
