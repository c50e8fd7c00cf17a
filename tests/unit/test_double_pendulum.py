"""The simulated double pendulum: H and field against separate derivations, kinematics,
ground truth, the initial-state draw, the data protocol and the chaotic default regime."""

from __future__ import annotations

import dataclasses
from importlib.metadata import entry_points

import numpy as np
import pytest

from hnnbench._contracts.errors import ConfigError
from hnnbench._contracts.kinematics import MassMatrixKinematics
from hnnbench_plugins.systems import double_pendulum as dp
from hnnbench_plugins.systems.double_pendulum import (
    LYAPUNOV_TIME,
    DoublePendulum,
    DoublePendulumConfig,
    Params,
)

#: Unit parameters (the default) and an asymmetric set, so no symmetry hides a bug.
PARAMS = [Params(), Params(m1=1.3, m2=0.7, l1=0.9, l2=1.4, g=9.81)]
SMALL = {"n_traj": 10, "n_points": 11, "eval_n_traj": 3, "eval_n_points": 21, "eval_t_end": 5.0}


def make(**kw) -> DoublePendulum:
    cfg = DoublePendulumConfig(name="double_pendulum", **{**SMALL, **kw})
    cfg.validate()
    return DoublePendulum(cfg)


def random_states(seed: int, n: int = 50) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = rng.uniform(-4.0, 4.0, size=(n, 2))
    p = rng.normal(0.0, 1.5, size=(n, 2))
    return np.concatenate([q, p], axis=1)


# --------------------------------------------------------------------------- references


def cartesian_energy(q: np.ndarray, qdot: np.ndarray, k: Params) -> np.ndarray:
    """Textbook energy from the bobs' Cartesian positions and velocities (y up, pivot at
    the origin), shifted so the downward rest state has zero energy."""
    x1, y1 = k.l1 * np.sin(q[:, 0]), -k.l1 * np.cos(q[:, 0])
    y2 = y1 - k.l2 * np.cos(q[:, 1])
    vx1, vy1 = k.l1 * np.cos(q[:, 0]) * qdot[:, 0], k.l1 * np.sin(q[:, 0]) * qdot[:, 0]
    vx2 = vx1 + k.l2 * np.cos(q[:, 1]) * qdot[:, 1]
    vy2 = vy1 + k.l2 * np.sin(q[:, 1]) * qdot[:, 1]
    kinetic = 0.5 * k.m1 * (vx1**2 + vy1**2) + 0.5 * k.m2 * (vx2**2 + vy2**2)
    potential = k.m1 * k.g * y1 + k.m2 * k.g * y2
    rest = -k.m1 * k.g * k.l1 - k.m2 * k.g * (k.l1 + k.l2)
    assert x1.shape == kinetic.shape
    return kinetic + potential - rest


def textbook_accelerations(q: np.ndarray, qdot: np.ndarray, k: Params) -> np.ndarray:
    """θ̈ of the double pendulum in the usual closed form (Lagrange's equations solved
    for the two angular accelerations)."""
    t1, t2 = q[:, 0], q[:, 1]
    w1, w2 = qdot[:, 0], qdot[:, 1]
    d = t1 - t2
    den = 2 * k.m1 + k.m2 - k.m2 * np.cos(2 * d)
    a1 = (
        -k.g * (2 * k.m1 + k.m2) * np.sin(t1)
        - k.m2 * k.g * np.sin(t1 - 2 * t2)
        - 2 * np.sin(d) * k.m2 * (w2**2 * k.l2 + w1**2 * k.l1 * np.cos(d))
    ) / (k.l1 * den)
    a2 = (
        2
        * np.sin(d)
        * (
            w1**2 * k.l1 * (k.m1 + k.m2)
            + k.g * (k.m1 + k.m2) * np.cos(t1)
            + w2**2 * k.l2 * k.m2 * np.cos(d)
        )
    ) / (k.l2 * den)
    return np.stack([a1, a2], axis=-1)


def sympy_accelerations(k: Params):
    """θ̈(q, q̇) from Euler-Lagrange equations that sympy derives from the Cartesian
    Lagrangian: ``A(q) θ̈ = -(∂²L/∂q̇∂q q̇ - ∂L/∂q)`` with ``A = ∂²L/∂q̇²``."""
    sp = pytest.importorskip("sympy")
    q1, q2, w1, w2 = sp.symbols("q1 q2 w1 w2")
    x1, y1 = k.l1 * sp.sin(q1), -k.l1 * sp.cos(q1)
    x2, y2 = x1 + k.l2 * sp.sin(q2), y1 - k.l2 * sp.cos(q2)
    qs, ws = [q1, q2], [w1, w2]

    def dt(expr):  # total time derivative of a function of q only
        return sum(sp.diff(expr, qi) * wi for qi, wi in zip(qs, ws, strict=True))

    kinetic = (k.m1 * (dt(x1) ** 2 + dt(y1) ** 2) + k.m2 * (dt(x2) ** 2 + dt(y2) ** 2)) / 2
    lagrangian = kinetic - (k.m1 * k.g * y1 + k.m2 * k.g * y2)
    a = sp.Matrix(2, 2, lambda i, j: sp.diff(lagrangian, ws[i], ws[j]))
    b = sp.Matrix(
        [
            sum(sp.diff(lagrangian, ws[i], qj) * wj for qj, wj in zip(qs, ws, strict=True))
            - sp.diff(lagrangian, qs[i])
            for i in range(2)
        ]
    )
    fa = sp.lambdify([q1, q2, w1, w2], a, "numpy")
    fb = sp.lambdify([q1, q2, w1, w2], b, "numpy")

    def accelerations(q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        out = []
        for (a1, a2), (b1, b2) in zip(q, qdot, strict=True):
            out.append(
                np.linalg.solve(
                    np.array(fa(a1, a2, b1, b2), float),
                    -np.array(fb(a1, a2, b1, b2), float).ravel(),
                )
            )
        return np.array(out)

    return accelerations


# --------------------------------------------------------------------------- physics


@pytest.mark.parametrize("params", PARAMS)
def test_field_is_the_symplectic_gradient_of_h(params):
    x = random_states(0)
    h = 1e-6
    grad = np.empty_like(x)
    for i in range(4):
        e = np.zeros(4)
        e[i] = h
        grad[:, i] = (dp.hamiltonian(x + e, params) - dp.hamiltonian(x - e, params)) / (2 * h)
    field = dp.vector_field(x, params)
    np.testing.assert_allclose(field[:, :2], grad[:, 2:], rtol=1e-7, atol=1e-7)
    np.testing.assert_allclose(field[:, 2:], -grad[:, :2], rtol=1e-7, atol=1e-7)


@pytest.mark.parametrize("params", PARAMS)
def test_h_is_the_cartesian_energy(params):
    x = random_states(1)
    qdot = dp.velocities(x, params)
    np.testing.assert_allclose(
        dp.hamiltonian(x, params),
        cartesian_energy(x[:, :2], qdot, params),
        rtol=1e-12,
        atol=1e-12,
    )
    # p = ∂L/∂q̇ = M q̇: the kinematics' inverse map gives back the momenta
    kin = make(**dataclasses.asdict(params)).kinematics()
    np.testing.assert_allclose(
        kin.to_canonical(np.concatenate([x[:, :2], qdot], 1)), x, rtol=1e-12, atol=1e-12
    )


@pytest.mark.parametrize("params", PARAMS)
def test_equations_of_motion_match_the_textbook_lagrangian(params):
    """θ̈ from the textbook closed form, mapped to canonical rates by the kinematics,
    equals the Hamiltonian field; and the Hamiltonian field's q̈ equals θ̈."""
    kin = MassMatrixKinematics(
        lambda q: dp.mass_matrix(q, params), lambda q, qd: dp.mass_rate(q, qd, params)
    )
    x = random_states(2)
    v = kin.to_velocity(x)
    qddot = textbook_accelerations(v[:, :2], v[:, 2:], params)
    rates = kin.canonical_rate(v, np.concatenate([v[:, 2:], qddot], axis=1))
    field = dp.vector_field(x, params)
    np.testing.assert_allclose(rates, field, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(kin.velocity_rate(x, field)[:, 2:], qddot, rtol=1e-10, atol=1e-10)


def test_equations_of_motion_match_sympys_euler_lagrange():
    params = PARAMS[1]
    accelerations = sympy_accelerations(params)
    x = random_states(3, n=20)
    qdot = dp.velocities(x, params)
    expected = accelerations(x[:, :2], qdot)
    np.testing.assert_allclose(
        textbook_accelerations(x[:, :2], qdot, params), expected, rtol=1e-10, atol=1e-10
    )
    system = make(**dataclasses.asdict(params))
    got = system.kinematics().velocity_rate(x, system.vector_field(x))[:, 2:]
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-10)


def test_kinematics_round_trip_and_mass_rate():
    system = make(m1=1.3, m2=0.7, l1=0.9, l2=1.4, g=9.81)
    kin, params = system.kinematics(), system.params
    x = random_states(4)
    v = kin.to_velocity(x)
    np.testing.assert_allclose(v[:, 2:], dp.velocities(x, params), rtol=1e-12)
    np.testing.assert_allclose(kin.to_canonical(v), x, rtol=1e-12, atol=1e-12)
    # tangent maps are inverse to each other and consistent with the field
    f = system.vector_field(x)
    vdot = kin.velocity_rate(x, f)
    np.testing.assert_allclose(vdot[:, :2], f[:, :2], rtol=1e-12)
    np.testing.assert_allclose(kin.canonical_rate(v, vdot), f, rtol=1e-11, atol=1e-11)
    # Ṁ is the derivative of M along q̇ (central differences)
    q, qdot, h = x[:, :2], v[:, 2:], 1e-6
    numeric = (dp.mass_matrix(q + h * qdot, params) - dp.mass_matrix(q - h * qdot, params)) / (
        2 * h
    )
    np.testing.assert_allclose(dp.mass_rate(q, qdot, params), numeric, rtol=1e-7, atol=1e-8)
    # symmetric positive definite mass matrix
    m = dp.mass_matrix(q, params)
    np.testing.assert_array_equal(m, np.swapaxes(m, -1, -2))
    assert np.all(np.linalg.eigvalsh(m) > 0)


def test_batched_leading_dimensions():
    x = random_states(5, n=12).reshape(3, 4, 4)
    flat = x.reshape(-1, 4)
    np.testing.assert_array_equal(dp.vector_field(x).reshape(-1, 4), dp.vector_field(flat))
    np.testing.assert_array_equal(dp.hamiltonian(x).reshape(-1), dp.hamiltonian(flat))
    assert dp.mass_matrix(x[..., :2]).shape == (3, 4, 2, 2)
    with pytest.raises(ValueError, match="4 numbers"):
        dp.vector_field(np.zeros((2, 3)))


def test_time_reversal_symmetry():
    system = make()
    x = random_states(6)
    np.testing.assert_allclose(system.energy(system.reverse(x)), system.energy(x))
    f, fr = system.vector_field(x), system.vector_field(system.reverse(x))
    np.testing.assert_allclose(fr[:, :2], -f[:, :2])  # R f(R x) = -f(x)
    np.testing.assert_allclose(fr[:, 2:], f[:, 2:])
    assert system.time_reversible and system.conservative and system.dof == 2


# --------------------------------------------------------------------------- data


@pytest.mark.parametrize("band", [(3.0, 4.0), (1e-4, 2e-4), (8.0, 9.0)])
def test_initial_states_hit_the_energy_band(band):
    params = PARAMS[1] if band[0] > 5 else Params()
    x0 = dp.sample_initial_states(np.random.default_rng(0), 400, params, *band)
    energy = dp.hamiltonian(x0, params)
    assert energy.min() >= band[0] - 1e-12 and energy.max() <= band[1] + 1e-12
    assert np.all(np.abs(x0[:, :2]) <= np.pi)
    assert np.all(dp.potential(x0[:, :2], params) <= energy + 1e-12)
    # the targets are drawn uniformly: the quartiles sit near their expected places
    quartiles = np.quantile((energy - band[0]) / (band[1] - band[0]), [0.25, 0.5, 0.75])
    np.testing.assert_allclose(quartiles, [0.25, 0.5, 0.75], atol=0.08)


def test_ground_truth_conserves_energy():
    system = make()
    ds = system.dataset(0)
    assert ds.meta["max_energy_drift"] < 1e-9
    traj = system.evaluation(0)
    energy = system.energy(traj.states)
    assert np.max(np.abs(energy - energy[:, :1])) < 1e-9
    assert traj.meta["max_energy_drift"] < 1e-9
    assert np.all((energy[:, 0] >= 3.0) & (energy[:, 0] <= 4.0))
    assert np.all(np.abs(traj.x0[:, :2]) <= np.pi)
    # continuous trajectories: no jumps of whole turns between samples
    assert np.max(np.abs(np.diff(traj.states[..., :2], axis=1))) < 2.0
    assert traj.dt == pytest.approx(1.0) and traj.states.shape == (3, 21, 4)


def test_dataset_shapes_split_wrapping_and_targets():
    system = make(n_traj=10, test_split=0.2)
    ds = system.dataset(0)
    assert len(ds.train) == 8 * 11 and len(ds.test) == 2 * 11
    assert set(ds.train.traj) == set(range(8)) and set(ds.test.traj) == {8, 9}
    for split in (ds.train, ds.test):
        assert split.x.shape == split.dxdt.shape == (len(split), 4)
        np.testing.assert_array_equal(split.dxdt, system.vector_field(split.x))
    # continuous by default: consecutive samples of a trajectory never jump by a turn
    q = ds.train.x[:, :2].reshape(8, 11, 2)
    assert np.max(np.abs(np.diff(q, axis=1))) < np.pi
    assert ds.meta["dt"] == pytest.approx(1.0) and ds.meta["wrap_angles"] is False
    # wrapped: the same points by whole turns, inside [-π, π); the field is 2π-periodic
    # in the angles, so the targets stay exact at the wrapped inputs
    wrapped = make(n_traj=10, test_split=0.2, wrap_angles=True).dataset(0)
    for split in (wrapped.train, wrapped.test):
        assert np.all((split.x[:, :2] >= -np.pi) & (split.x[:, :2] < np.pi))
        np.testing.assert_allclose(split.dxdt, system.vector_field(split.x), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(dp.wrap_angle(ds.train.x[:, :2]), wrapped.train.x[:, :2], atol=1e-12)
    np.testing.assert_array_equal(wrapped.train.dxdt, ds.train.dxdt)


def test_dataset_is_deterministic_noise_keeps_clean_targets():
    a, b = make().dataset(3), make().dataset(3)
    np.testing.assert_array_equal(a.train.x, b.train.x)
    assert not np.array_equal(make().dataset(4).train.x, a.train.x)
    noisy = make(noise_std=0.05).dataset(3)
    np.testing.assert_array_equal(noisy.train.dxdt, a.train.dxdt)
    resid = noisy.train.x - a.train.x
    assert 0.04 < resid.std() < 0.06
    # evaluation draws come from their own stream
    starts = a.train.x[a.train.t == 0.0]
    assert not np.any(np.all(np.isclose(make().evaluation(3).x0[:, None], starts), -1))


# --------------------------------------------------------------------------- regime


def test_the_default_regime_is_chaotic_and_matches_the_stored_lyapunov_time():
    """Re-estimate (32 states, t = 100, another seed: about 2 s) and compare with the
    stored constant (256 states, t = 400). Measured spread of this small estimate over
    seeds 1-10: 2.69-2.94 against 2.83, so 10% is a safe tolerance."""
    lyapunov_time, exponents = dp.estimate_lyapunov_time(n_states=32, t_total=100.0, seed=1)
    assert lyapunov_time == pytest.approx(LYAPUNOV_TIME, rel=0.10)
    # every sampled state is chaotic: regular orbits give about 0.03 at t = 100
    assert exponents.min() > 0.1


def test_the_estimator_tells_regular_from_chaotic():
    """Small oscillations (E in [0.2, 0.4]) are regular: finite-time exponents near
    log(growth) / t, well below the chaotic regime's."""
    _, exponents = dp.estimate_lyapunov_time(
        energy_min=0.2, energy_max=0.4, n_states=6, t_total=100.0
    )
    assert exponents.max() < 0.06


def test_lyapunov_time_only_for_the_default_regime():
    assert make().lyapunov_time == LYAPUNOV_TIME
    assert make(eval_t_end=7.0, n_traj=5).lyapunov_time == LYAPUNOV_TIME  # protocol only
    for override in ({"m2": 2.0}, {"g": 9.81}, {"energy_max": 5.0}, {"energy_min": 1.0}):
        assert make(**override).lyapunov_time is None
    assert make().evaluation(0).meta["lyapunov_time"] == LYAPUNOV_TIME


# --------------------------------------------------------------------------- config


def test_defaults_profiles_and_entry_point():
    cfg = DoublePendulumConfig()
    assert (cfg.m1, cfg.m2, cfg.l1, cfg.l2, cfg.g) == (1.0, 1.0, 1.0, 1.0, 1.0)
    assert (cfg.energy_min, cfg.energy_max) == (3.0, 4.0)
    assert (cfg.n_traj, cfg.n_points, cfg.t_end, cfg.noise_std) == (200, 51, 10.0, 0.0)
    assert cfg.wrap_angles is False
    assert (cfg.eval_n_traj, cfg.eval_t_end, cfg.eval_n_points) == (15, 10.0, 101)
    assert cfg.data_rtol == cfg.eval_rtol == 1e-12
    names = {f.name for f in dataclasses.fields(DoublePendulumConfig)}
    quick = DoublePendulum.profiles["quick"]
    assert set(quick) <= names and quick["steps"] <= 300 and quick["eval_n_traj"] == 5
    DoublePendulumConfig(name="x", **quick).validate()
    assert DoublePendulum.version == "1" and "\n" not in DoublePendulum.description
    (ep,) = [e for e in entry_points(group="hnnbench.systems") if e.name == "double_pendulum"]
    assert ep.load() is DoublePendulum


@pytest.mark.parametrize(
    "override, match",
    [
        ({"m1": 0.0}, "system.m1=0.0"),
        ({"g": -1.0}, "system.g=-1.0"),
        ({"energy_min": 0.0}, "system.energy_min=0.0"),
        ({"energy_min": 4.0, "energy_max": 3.0}, "system.energy_max=3.0"),
        ({"n_traj": 1}, "system.n_traj=1"),
        ({"n_points": 2.5}, "system.n_points=2.5"),
        ({"test_split": 1.0}, "system.test_split=1.0"),
        ({"n_traj": 3, "test_split": 0.1}, "empty train or test"),
        ({"noise_std": -0.1}, "system.noise_std=-0.1"),
        ({"wrap_angles": "yes"}, "system.wrap_angles=yes"),
        ({"eval_rtol": 0.0}, "system.eval_rtol=0.0"),
    ],
)
def test_validate_rejects_bad_values(override, match):
    with pytest.raises(ConfigError, match=match) as err:
        DoublePendulumConfig(name="double_pendulum", **override).validate()
    assert "\n" not in str(err.value)
