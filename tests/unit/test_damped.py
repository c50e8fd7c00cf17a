"""The damped spring and pendulum: field, decay against the closed form, protocol."""

from __future__ import annotations

import dataclasses
from importlib.metadata import entry_points

import numpy as np
import pytest

from hnnbench._contracts.errors import ConfigError
from hnnbench._contracts.integrate import solve_batch
from hnnbench._contracts.kinematics import LinearKinematics
from hnnbench_plugins.systems.damped import (
    DEFAULT_DAMPING,
    DampedPendulum,
    DampedPendulumConfig,
    DampedSpring,
    DampedSpringConfig,
    damped_spring_solution,
    energy_half_lives,
)
from hnnbench_plugins.systems.pendulum import Pendulum, PendulumConfig
from hnnbench_plugins.systems.spring import Spring, SpringConfig

SYSTEMS = [(DampedSpring, DampedSpringConfig), (DampedPendulum, DampedPendulumConfig)]


def make(cls, cfg_cls, **kw):
    cfg = cfg_cls(name=cls.__name__, **kw)
    cfg.validate()
    return cls(cfg)


def random_states(seed: int, n: int = 40) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-2.0, 2.0, size=(n, 2))


@pytest.mark.parametrize("cls, cfg_cls", SYSTEMS)
def test_field_is_the_hamiltonian_field_plus_linear_damping(cls, cfg_cls):
    system = make(cls, cfg_cls, damping=0.3)
    x = random_states(0)
    h = 1e-6
    dh_dq = (system.energy(x + [h, 0]) - system.energy(x - [h, 0])) / (2 * h)
    dh_dp = (system.energy(x + [0, h]) - system.energy(x - [0, h])) / (2 * h)
    f = system.vector_field(x)
    np.testing.assert_allclose(f[:, 0], dh_dp, rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(f[:, 1], -dh_dq - 0.3 * x[:, 1], rtol=1e-8, atol=1e-8)
    # dH/dt along the field is -2 γ p² (the energy never increases)
    np.testing.assert_allclose(
        dh_dq * f[:, 0] + dh_dp * f[:, 1], -2 * 0.3 * x[:, 1] ** 2, rtol=1e-7, atol=1e-8
    )
    # the energy is the undamped system's H
    undamped = Spring(SpringConfig()) if cls is DampedSpring else Pendulum(PendulumConfig())
    np.testing.assert_array_equal(system.energy(x), undamped.energy(x))


def test_spring_ground_truth_matches_the_closed_form():
    system = make(DampedSpring, DampedSpringConfig, eval_n_traj=6, eval_n_points=201)
    traj = system.evaluation(0)
    exact = damped_spring_solution(traj.x0, traj.t, DEFAULT_DAMPING)
    np.testing.assert_allclose(traj.states, exact, rtol=0, atol=1e-9)
    np.testing.assert_allclose(system.energy(traj.states), system.energy(exact), atol=1e-9)
    # the closed form satisfies the ODE (central differences in time)
    t = np.linspace(0.0, 5.0, 5001)
    x = damped_spring_solution(traj.x0, t, DEFAULT_DAMPING)
    rate = (x[:, 2:] - x[:, :-2]) / (t[2] - t[0])
    np.testing.assert_allclose(rate, system.vector_field(x[:, 1:-1]), atol=1e-5)


def test_spring_energy_halves_in_about_ten_time_units():
    """γ = 0.07: the period-averaged energy decays like e^{-γ t}, half-life ln 2 / γ."""
    assert np.log(2) / DEFAULT_DAMPING == pytest.approx(9.90, abs=0.01)
    t = np.linspace(0.0, 40.0, 4001)
    x0 = np.array([[0.6, 0.0], [0.0, 0.6], [0.4, -0.45]])
    energy = np.sum(damped_spring_solution(x0, t, DEFAULT_DAMPING) ** 2, axis=-1)
    # averaged over whole periods (π) the decay is e^{-γ t} to a fraction of a percent
    period = int(round(np.pi / (t[1] - t[0])))
    mean = np.array([energy[:, i : i + period].mean(1) for i in range(0, 3000, period)])
    t_mid = t[np.arange(0, 3000, period) + period // 2]
    expected = np.exp(-DEFAULT_DAMPING * (t_mid - t_mid[0]))[:, None]
    np.testing.assert_allclose(mean / mean[:1], np.broadcast_to(expected, mean.shape), rtol=0.01)
    half, ratio = energy_half_lives(make(DampedSpring, DampedSpringConfig), "box", n=20)
    assert np.all((half > 9.5) & (half < 10.5))
    assert np.all((ratio > 0.2) & (ratio < 0.3))  # visible but not total at the horizon


def test_pendulum_decays_monotonically_over_the_evaluation_horizon():
    system = make(DampedPendulum, DampedPendulumConfig, eval_n_traj=5)
    traj = system.evaluation(0)
    energy = system.energy(traj.states)
    assert np.all(np.diff(energy, axis=1) <= 1e-12)
    ratio = energy[:, -1] / energy[:, 0]
    assert np.all((ratio > 0.2) & (ratio < 0.35))
    assert traj.t[-1] == 20.0


@pytest.mark.parametrize("cls, cfg_cls", SYSTEMS)
def test_dataset_targets_are_the_damped_field(cls, cfg_cls):
    system = make(cls, cfg_cls, n_traj=6, noise_std=0.0)
    ds = system.dataset(0)
    np.testing.assert_allclose(ds.train.dxdt, system.vector_field(ds.train.x), rtol=1e-12)
    # trajectories follow the damped dynamics
    x = ds.train.x.reshape(3, -1, 2)
    t = ds.train.t.reshape(3, -1)[0]
    again = solve_batch(system.vector_field, x[:, 0], t, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(again, x, atol=1e-8)


@pytest.mark.parametrize("cls, cfg_cls", SYSTEMS)
def test_contract_flags_kinematics_and_profiles(cls, cfg_cls):
    system = make(cls, cfg_cls)
    assert system.time_reversible is False and system.conservative is False
    assert system.lyapunov_time is None and system.dof == 1
    kin = system.kinematics()
    assert isinstance(kin, LinearKinematics) and float(kin.a) == 2.0
    assert system.cfg.damping == DEFAULT_DAMPING == 0.07
    names = {f.name for f in dataclasses.fields(cfg_cls)}
    quick = cls.profiles["quick"]
    assert set(quick) <= names and quick["steps"] <= 300 and quick["eval_n_traj"] == 5
    assert cls.version == "2" and "\n" not in cls.description
    name = "damped_spring" if cls is DampedSpring else "damped_pendulum"
    (ep,) = [e for e in entry_points(group="hnnbench.systems") if e.name == name]
    assert ep.load() is cls


@pytest.mark.parametrize("value", [0.0, -0.1])
def test_damping_must_be_positive(value):
    with pytest.raises(ConfigError, match=f"system.damping={value}") as err:
        DampedSpringConfig(damping=value).validate()
    assert "\n" not in str(err.value)
