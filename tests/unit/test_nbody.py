"""N-body systems: analytic H and forces against REBOUND, data protocol, config checks."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import rebound

from hnnbench._contracts.errors import ConfigError, DataError
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
    np.testing.assert_allclose(
        system.vector_field(x).reshape(12, 8), system.vector_field(x.reshape(12, 8))
    )
    assert system.dof == 4 and three_body().dof == 6
    assert system.time_reversible
    np.testing.assert_allclose(system.energy(system.reverse(x)), system.energy(x))
    with pytest.raises(ValueError, match="12 numbers"):
        three_body().energy(np.zeros((2, 8)))


def noiseless_states(sampler: str, n_bodies: int, n: int = 7) -> np.ndarray:
    rng = np.random.default_rng(0)
    if sampler == "ring":
        return nbody.ring_states(rng, n, n_bodies, 0.5, 1.5, velocity_noise=0.0)
    if n_bodies == 2:
        return nbody.box_mirror_states(rng, n, 0.5, 1.5, velocity_noise=0.0)
    return nbody.triangle_states(rng, n, 0.9, 1.2, velocity_noise=0.0)


@pytest.mark.parametrize(
    "sampler, n_bodies", [("ring", 2), ("ring", 3), ("ring", 5), ("2019", 2), ("2019", 3)]
)
def test_speed_before_the_factor_is_circular(sampler, n_bodies):
    """Without noise every sampler gives a rigidly rotating, centred configuration:
    tangential velocities and centripetal acceleration = v^2 / r for every body."""
    x = noiseless_states(sampler, n_bodies)
    system = NBody(NBodyConfig(name="nbody", n_bodies=n_bodies))
    q = x[:, : 2 * n_bodies].reshape(7, n_bodies, 2)
    p = x[:, 2 * n_bodies :].reshape(7, n_bodies, 2)
    a = system.vector_field(x)[:, 2 * n_bodies :].reshape(7, n_bodies, 2)
    r = np.linalg.norm(q, axis=-1)
    v2 = np.sum(p**2, axis=-1)
    np.testing.assert_allclose(np.sum(a * q, axis=-1) / r, -v2 / r, rtol=1e-12)
    np.testing.assert_allclose(np.sum(q * p, axis=-1), 0.0, atol=1e-12)  # tangential
    np.testing.assert_allclose(
        q[..., 0] * p[..., 1] - q[..., 1] * p[..., 0], r * np.sqrt(v2), rtol=1e-12
    )  # counter-clockwise
    np.testing.assert_allclose(q.sum(axis=1), 0.0, atol=1e-12)  # centred
    np.testing.assert_allclose(r - r[:, :1], 0.0, atol=1e-12)  # one ring
    if n_bodies == 2:
        np.testing.assert_allclose(q[:, 1], -q[:, 0])  # mirrored through the origin


def test_rebound_orbits_flags_a_collision():
    # Two bodies released from rest fall onto each other: REBOUND stops, drift is inf.
    x0 = np.array([[0.5, 0.0, -0.5, 0.0, 0.0, 0.0, 0.0, 0.0]])
    states, drift = nbody.rebound_orbits(x0, np.linspace(0.0, 2.0, 5), 2)
    assert drift[0] == np.inf
    assert states.shape == (1, 5, 8)


# --------------------------------------------------------------------------- data


@pytest.mark.parametrize(
    "make, init",
    [(two_body, "2019"), (three_body, "2019"), (two_body, "ring"), (three_body, "ring")],
)
def test_dataset_shapes_split_and_targets(make, init):
    system = make(init=init)
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
    assert meta["init"] == init
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


def test_ring_initial_state_distribution():
    """init=ring: hnnbench's sampler up to version 1 (radius U[a, b], per-body factor)."""
    system = TwoBody(TwoBodyConfig(name="two_body", init="ring"))
    x0 = system.initial_states(np.random.default_rng(0), 2000)
    r = np.linalg.norm(x0[:, :2], axis=1)
    assert 0.5 <= r.min() and r.max() <= 1.5
    speed_ratio = np.linalg.norm(x0[:, 4:6], axis=1) / nbody.circular_speed(r, 2)
    assert abs(np.std(speed_ratio) - 0.05) < 0.005
    # each body has its own factor: the total momentum is not zero
    assert np.std(x0[:, 4:6] + x0[:, 6:8]) > 0.01
    x3 = ThreeBody(ThreeBodyConfig(name="three_body", init="ring")).initial_states(
        np.random.default_rng(0), 2000
    )
    r3 = np.linalg.norm(x3[:, :6].reshape(-1, 3, 2), axis=-1)
    assert 0.9 <= r3.min() and r3.max() <= 1.2
    np.testing.assert_allclose(r3 - r3[:, :1], 0.0, atol=1e-12)  # all three on one ring
    x_ring = nbody.ring_states(np.random.default_rng(0), 2000, 3, 0.9, 1.2, 0.2)
    np.testing.assert_array_equal(x3, x_ring)  # bit for bit the version-1 sampler


def test_2019_two_body_distribution():
    """Default two-body sampler = the 2019 code's: body 1 in the box [0.5, 1.5]^2, body 2
    at (-q, -v), circular speed times ONE Gaussian factor, centre of mass at rest."""
    n = 4000
    x0 = TwoBody(TwoBodyConfig(name="two_body")).initial_states(np.random.default_rng(0), n)
    q1, q2, p1, p2 = x0[:, 0:2], x0[:, 2:4], x0[:, 4:6], x0[:, 6:8]
    # position box per coordinate (not a radius): first quadrant, filled to the corners
    assert q1.min() >= 0.5 and q1.max() <= 1.5
    assert q1.min() < 0.502 and q1.max() > 1.498
    r = np.linalg.norm(q1, axis=1)
    assert r.min() < 0.75 and r.max() > 2.05  # radii up to 1.5 sqrt(2)
    # mirror point and centre of mass at rest (exactly)
    np.testing.assert_array_equal(q2, -q1)
    np.testing.assert_array_equal(p2, -p1)
    np.testing.assert_array_equal(q1 + q2, 0.0)
    np.testing.assert_array_equal(p1 + p2, 0.0)
    # tangential, counter-clockwise, circular speed times 1 + 0.05 N(0, 1)
    np.testing.assert_allclose(np.sum(q1 * p1, axis=1), 0.0, atol=1e-12)
    assert np.all(q1[:, 0] * p1[:, 1] - q1[:, 1] * p1[:, 0] > 0)
    factor = np.linalg.norm(p1, axis=1) / nbody.circular_speed(r, 2)
    assert abs(np.mean(factor) - 1.0) < 0.003 and abs(np.std(factor) - 0.05) < 0.003
    assert 0.03 < np.mean(np.abs(factor - 1) > 0.1) < 0.065  # Gaussian: 4.6% beyond 2 sigma
    assert np.mean(factor < 0.95) > 0.1  # factors below 1 - 0.05 exist (not a U(-1, 1) law)


def test_2019_three_body_distribution():
    """Default three-body sampler = the 2019 code's: radius U[0.9, 1.2], direction of a
    uniform point of [-1, 1]^2, bodies 120 degrees apart, circular speed, and each
    velocity COMPONENT times its own 1 + 0.2 U(-1, 1)."""
    n = 4000
    x0 = ThreeBody(ThreeBodyConfig(name="three_body")).initial_states(np.random.default_rng(0), n)
    q = x0[:, :6].reshape(n, 3, 2)
    p = x0[:, 6:].reshape(n, 3, 2)
    r = np.linalg.norm(q, axis=-1)
    assert 0.9 <= r.min() and r.max() <= 1.2 and r.min() < 0.901 and r.max() > 1.199
    np.testing.assert_allclose(r - r[:, :1], 0.0, atol=1e-12)
    for k in (1, 2):  # body k+1 = body 1 rotated by k * 120 degrees
        c, s = np.cos(2 * np.pi * k / 3), np.sin(2 * np.pi * k / 3)
        rotated = np.stack([c * q[:, 0, 0] - s * q[:, 0, 1], s * q[:, 0, 0] + c * q[:, 0, 1]], 1)
        np.testing.assert_allclose(q[:, k], rotated, atol=1e-12)
    np.testing.assert_allclose(q.sum(axis=1), 0.0, atol=1e-12)
    # per-component factors: v = factor * (circular velocity), factor in [0.8, 1.2]
    tangent = np.stack([-q[..., 1], q[..., 0]], axis=-1) / r[..., None]
    v_circ = nbody.circular_speed(r, 3)[..., None] * tangent
    factor = p / v_circ
    assert factor.min() >= 0.8 and factor.max() <= 1.2
    assert factor.min() < 0.801 and factor.max() > 1.199
    flat = factor.reshape(n, 6)
    assert np.all(np.abs(flat.mean(axis=0) - 1) < 0.01)
    np.testing.assert_allclose(flat.std(axis=0), 0.2 / np.sqrt(3), rtol=0.05)  # uniform
    corr = np.corrcoef(flat.T) - np.eye(6)
    assert np.max(np.abs(corr)) < 0.06  # independent components
    # ... so the total momentum is not zero (the 2019 triangle drifts)
    assert np.std(p.sum(axis=1)) > 0.05
    # direction of a uniform point of the square: near-diagonal angles are favoured
    angle = np.arctan2(q[:, 0, 1], q[:, 0, 0]) % (np.pi / 2)
    near_diagonal = np.mean(np.abs(angle - np.pi / 4) < np.pi / 8)
    assert abs(near_diagonal - (1 - np.tan(np.pi / 8))) < 0.03  # 0.586 (uniform angle: 0.5)


class Replay:
    """A Generator stand-in returning fixed numbers, to pin the 2019 formulas."""

    def __init__(self, uniforms, normals=()):
        self.uniforms, self.normals = list(uniforms), list(normals)

    def uniform(self, lo, hi, size):
        u = np.array([self.uniforms.pop(0) for _ in range(int(np.prod(size)))])
        return lo + (hi - lo) * u.reshape(size)

    def standard_normal(self, size):
        return np.array([self.normals.pop(0) for _ in range(int(np.prod(size)))]).reshape(size)


def test_2019_samplers_pin_the_original_formulas():
    # two bodies: pos = (0.6, 0.8) (r = 1), factor 1 + 0.05 * 0.5; v = (-y, x) / (2 r^1.5)
    x = nbody.box_mirror_states(Replay([0.1, 0.3], [0.5]), 1, 0.5, 1.5, 0.05)[0]
    v = np.array([-0.8, 0.6]) / 2.0 * 1.025
    np.testing.assert_allclose(x, [0.6, 0.8, -0.6, -0.8, *v, *-v], atol=1e-15)
    # three bodies: p1 = 2 u - 1 = (0.3, -0.4) -> direction (0.6, -0.8), r = 0.9 + 0.3 * 0.5,
    # v1 = rot90(p1) / r^1.5 * sqrt(sin(pi/3) / (2 cos(pi/6)^2)), times 1 + 0.2 (2 u - 1)
    u_factor = [0.5, 1.0, 0.0, 0.75, 0.25, 0.5]
    x = nbody.triangle_states(Replay([0.65, 0.3, 0.5, *u_factor]), 1, 0.9, 1.2, 0.2)[0]
    r = 1.05
    p1 = np.array([0.6, -0.8]) * r
    v1 = (
        np.array([0.8, 0.6])
        * r
        / r**1.5
        * np.sqrt(np.sin(np.pi / 3) / (2 * np.cos(np.pi / 6) ** 2))
    )

    def rot(v, k):
        c, s = np.cos(2 * np.pi * k / 3), np.sin(2 * np.pi * k / 3)
        return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])

    factors = 1 + 0.2 * (2 * np.array(u_factor) - 1)
    expected_q = np.concatenate([rot(p1, k) for k in range(3)])
    expected_v = np.concatenate([rot(v1, k) for k in range(3)]) * factors
    np.testing.assert_allclose(x, np.concatenate([expected_q, expected_v]), atol=1e-14)


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
    assert (two.steps, two.batch_size, two.weight_decay) == (20000, 200, 0.0)  # 2x the paper
    assert (two.eval_n_orbits, two.eval_t_end, two.eval_n_points) == (15, 25.0, 500)
    assert (three.n_bodies, three.n_orbits, three.n_points, three.t_end) == (3, 5000, 20, 5.0)
    assert (three.steps, three.batch_size, three.weight_decay) == (10000, 600, 1e-4)
    assert (three.eval_n_orbits, three.eval_t_end, three.eval_n_points) == (15, 3.0, 500)
    assert two.noise_std == three.noise_std == 0.0
    assert two.init == three.init == "2019" and NBodyConfig().init == "ring"
    assert (two.radius_min, two.radius_max, two.velocity_noise) == (0.5, 1.5, 0.05)
    assert (three.radius_min, three.radius_max, three.velocity_noise) == (0.9, 1.2, 0.2)
    for cls in (TwoBody, ThreeBody):
        names = {f.name for f in dataclasses.fields(cls.Config)}
        for profile in cls.profiles.values():
            assert set(profile) <= names
            cls.Config(name="x", **profile).validate()
        # 2: the 2019 samplers became the default (init="2019")
        assert cls.version == "2" and cls.description and "\n" not in cls.description


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
        ({"init": "circle"}, "init='circle'"),
        ({"init": "2019", "n_bodies": 4}, "init=2019 with system.n_bodies=4"),
    ],
)
def test_validate_rejects_bad_values(override, match):
    cfg = TwoBodyConfig(name="two_body", **override)
    with pytest.raises(ConfigError, match=match) as err:
        cfg.validate()
    assert "\n" not in str(err.value)


# --------------------------------------------------------------------------- paper size
