"""The spring chain: normal modes, H and field, ground truth, protocol and config."""

from __future__ import annotations

import dataclasses
from importlib.metadata import entry_points

import numpy as np
import pytest

from hnnbench._contracts.errors import ConfigError
from hnnbench._contracts.kinematics import LinearKinematics
from hnnbench_plugins.systems import spring_chain as sc
from hnnbench_plugins.systems.spring_chain import SpringChain, SpringChainConfig

SMALL = {"n_traj": 10, "n_points": 11, "eval_n_traj": 3, "eval_n_points": 41, "eval_t_end": 20.0}


def make(**kw) -> SpringChain:
    cfg = SpringChainConfig(name="spring_chain", **{**SMALL, **kw})
    cfg.validate()
    return SpringChain(cfg)


def dynamics_matrix(n: int) -> np.ndarray:
    """``A`` with ``f(x) = A x``, read column by column from the field."""
    return sc.vector_field(np.eye(2 * n)).T


@pytest.mark.parametrize("n", [1, 2, 5, 8])
def test_normal_mode_frequencies(n):
    eig = np.linalg.eigvals(dynamics_matrix(n))
    assert np.max(np.abs(eig.real)) < 1e-12  # undamped: purely imaginary
    omega = 2.0 * np.sin(np.arange(1, n + 1) * np.pi / (2.0 * (n + 1)))
    np.testing.assert_allclose(np.sort(np.abs(eig.imag)), np.repeat(omega, 2), rtol=1e-12)
    np.testing.assert_allclose(sc.mode_frequencies(n), omega)
    # each sine mode oscillates at its frequency: K v_k = ω_k² v_k
    k = sc.stiffness_matrix(n)
    i = np.arange(1, n + 1)
    for mode in range(1, n + 1):
        v = np.sin(mode * i * np.pi / (n + 1))
        np.testing.assert_allclose(k @ v, omega[mode - 1] ** 2 * v, atol=1e-12)


@pytest.mark.parametrize("n", [1, 5])
def test_field_is_the_symplectic_gradient_of_h(n):
    x = np.random.default_rng(n).normal(size=(20, 2 * n))
    h = 1e-6
    grad = np.empty_like(x)
    for i in range(2 * n):
        e = np.zeros(2 * n)
        e[i] = h
        grad[:, i] = (sc.hamiltonian(x + e) - sc.hamiltonian(x - e)) / (2 * h)
    f = sc.vector_field(x)
    np.testing.assert_allclose(f[:, :n], grad[:, n:], rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(f[:, n:], -grad[:, :n], rtol=1e-8, atol=1e-8)
    # H written with the stiffness matrix
    q, p = x[:, :n], x[:, n:]
    k = sc.stiffness_matrix(n)
    np.testing.assert_allclose(
        sc.hamiltonian(x),
        0.5 * np.sum(p**2, 1) + 0.5 * np.einsum("ni,ij,nj->n", q, k, q),
        rtol=1e-12,
    )
    # batched over leading dimensions
    np.testing.assert_array_equal(sc.vector_field(x.reshape(4, 5, -1)).reshape(20, -1), f)


def test_ground_truth_conserves_energy_and_matches_the_modes():
    system = make()
    traj = system.evaluation(0)
    energy = system.energy(traj.states)
    np.testing.assert_allclose(energy, np.repeat(energy[:, :1], energy.shape[1], 1), rtol=1e-9)
    # exact solution through the eigen-decomposition of A
    a = dynamics_matrix(5)
    w, v = np.linalg.eig(a)
    coef = np.linalg.solve(v, traj.x0.T)  # (10, M)
    exact = np.real(np.einsum("ik,kt,km->mti", v, np.exp(np.outer(w, traj.t)), coef))
    np.testing.assert_allclose(traj.states, exact, atol=1e-9)
    assert traj.dt == pytest.approx(1.0) and traj.states.shape == (3, 41, 10)


def test_dataset_split_initial_radii_and_targets():
    system = make(n_traj=10)
    ds = system.dataset(0)
    assert len(ds.train) == 8 * 11 and len(ds.test) == 2 * 11
    np.testing.assert_allclose(ds.train.dxdt, system.vector_field(ds.train.x), rtol=1e-12)
    starts = np.concatenate([ds.train.x[ds.train.t == 0], ds.test.x[ds.test.t == 0]])
    radius = np.linalg.norm(starts, axis=1)
    assert radius.min() >= 0.5 and radius.max() <= 1.5
    np.testing.assert_array_equal(make(n_traj=10).dataset(0).train.x, ds.train.x)
    noisy = make(n_traj=10, noise_std=0.01).dataset(0)
    np.testing.assert_array_equal(noisy.train.dxdt, ds.train.dxdt)
    assert 0.008 < (noisy.train.x - ds.train.x).std() < 0.012


def test_dof_is_configurable():
    system = make(n_masses=3)
    assert system.dof == 3
    ds = system.dataset(0)
    assert ds.train.x.shape[1] == 6 and system.evaluation(0).states.shape[-1] == 6


def test_contract_and_defaults():
    system = SpringChain(SpringChainConfig(name="spring_chain"))
    assert system.dof == 5 and system.time_reversible and system.conservative
    assert system.lyapunov_time is None
    kin = system.kinematics()
    assert isinstance(kin, LinearKinematics) and float(kin.a) == 1.0
    cfg = system.cfg
    assert (cfg.n_traj, cfg.n_points, cfg.t_end, cfg.noise_std) == (100, 51, 10.0, 0.0)
    assert (cfg.eval_n_traj, cfg.eval_t_end, cfg.eval_n_points) == (15, 50.0, 251)
    names = {f.name for f in dataclasses.fields(SpringChainConfig)}
    quick = SpringChain.profiles["quick"]
    assert set(quick) <= names and quick["steps"] <= 300 and quick["eval_n_traj"] == 5
    SpringChainConfig(name="x", **quick).validate()
    assert SpringChain.version == "1" and "\n" not in SpringChain.description
    (ep,) = [e for e in entry_points(group="hnnbench.systems") if e.name == "spring_chain"]
    assert ep.load() is SpringChain


@pytest.mark.parametrize(
    "override, match",
    [
        ({"n_masses": 0}, "system.n_masses=0"),
        ({"n_masses": 2.5}, "system.n_masses=2.5"),
        ({"radius_min": 0.0}, "system.radius_min=0.0"),
        ({"radius_min": 2.0}, "system.radius_max=1.5"),
        ({"n_traj": 1}, "system.n_traj=1"),
        ({"test_split": 0.0}, "system.test_split=0.0"),
        ({"noise_std": -1.0}, "system.noise_std=-1.0"),
    ],
)
def test_validate_rejects_bad_values(override, match):
    with pytest.raises(ConfigError, match=match) as err:
        SpringChainConfig(name="spring_chain", **override).validate()
    assert "\n" not in str(err.value)
