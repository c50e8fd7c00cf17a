"""The families' physics code, fed the true physics, reproduces each system's field.

For every built-in system whose dynamics are known and conservative (the time-reversible
ones), a Lagrangian and a Hamiltonian written here, independently of the system's own
numpy code, go through the LNN's Euler-Lagrange solve and the HNN's symplectic gradient,
in both backends, in place of the trained networks (the LNN adds its declared kinetic
term to its network's output, so the stand-in network is the true Lagrangian minus that
term; the JAX LNN's ``euler_lagrange`` takes the true Lagrangian itself). The
accelerations must match the system's ``vector_field`` seen through its ``kinematics``
(``velocity_rate``) to float64 round-off: that checks the Euler-Lagrange code, the
kinematics and the system's field against each other end to end (issue 30, item 7).

Each function below takes one state (a 1-D array of the backend) and ``xp`` (``torch``
or ``jax.numpy``) for ``cos``; everything else is operators, so one definition serves
both backends.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from conftest import compose_job

from hnnbench import _registry as registry
from hnnbench._running.config import prepare_job
from hnnbench_plugins.systems import double_pendulum as dp_module
from hnnbench_plugins.systems import nbody as nbody_module

Fn = Callable[[Any, Any, Any], Any]  # (q, second half, xp) -> scalar


def _pairwise_inverse_distance(q: Any, n_bodies: int) -> Any:
    total = 0.0
    for i in range(n_bodies):
        for j in range(i + 1, n_bodies):
            d = q[2 * i : 2 * i + 2] - q[2 * j : 2 * j + 2]
            total = total + 1.0 / (d * d).sum() ** 0.5
    return total


def _chain_potential(q: Any) -> Any:
    stretch_inner = q[1:] - q[:-1]
    return 0.5 * ((q[0] ** 2) + (q[-1] ** 2) + (stretch_inner * stretch_inner).sum())


def _double_pendulum_lagrangian(q: Any, qdot: Any, xp: Any) -> Any:
    k = dp_module.Params()
    kinetic = (
        0.5 * (k.m1 + k.m2) * k.l1**2 * qdot[0] ** 2
        + 0.5 * k.m2 * k.l2**2 * qdot[1] ** 2
        + k.m2 * k.l1 * k.l2 * qdot[0] * qdot[1] * xp.cos(q[0] - q[1])
    )
    potential = (k.m1 + k.m2) * k.g * k.l1 * (1 - xp.cos(q[0])) + k.m2 * k.g * k.l2 * (
        1 - xp.cos(q[1])
    )
    return kinetic - potential


def _double_pendulum_hamiltonian(q: Any, p: Any, xp: Any) -> Any:
    k = dp_module.Params()
    c = k.m2 * k.l1 * k.l2 * xp.cos(q[0] - q[1])
    m11, m22 = (k.m1 + k.m2) * k.l1**2, k.m2 * k.l2**2
    det = m11 * m22 - c * c  # H = p^T M(q)^-1 p / 2 + V(q)
    kinetic = 0.5 * (m22 * p[0] ** 2 - 2 * c * p[0] * p[1] + m11 * p[1] ** 2) / det
    potential = (k.m1 + k.m2) * k.g * k.l1 * (1 - xp.cos(q[0])) + k.m2 * k.g * k.l2 * (
        1 - xp.cos(q[1])
    )
    return kinetic + potential


G, M = nbody_module.G, nbody_module.MASS

#: system -> (Lagrangian L(q, q̇), Hamiltonian H(q, p)), in the system's units.
TRUE: dict[str, tuple[Fn, Fn]] = {
    # H = q² + p², q̇ = 2p  =>  L = q̇²/4 - q²
    "spring": (
        lambda q, v, xp: (v * v).sum() / 4 - (q * q).sum(),
        lambda q, p, xp: (q * q).sum() + (p * p).sum(),
    ),
    # H = 3(1 - cos q) + p², q̇ = 2p
    "pendulum": (
        lambda q, v, xp: (v * v).sum() / 4 - 3 * (1 - xp.cos(q)).sum(),
        lambda q, p, xp: 3 * (1 - xp.cos(q)).sum() + (p * p).sum(),
    ),
    "two_body": (
        lambda q, v, xp: 0.5 * M * (v * v).sum() + G * M * M * _pairwise_inverse_distance(q, 2),
        lambda q, p, xp: (p * p).sum() / (2 * M) - G * M * M * _pairwise_inverse_distance(q, 2),
    ),
    "three_body": (
        lambda q, v, xp: 0.5 * M * (v * v).sum() + G * M * M * _pairwise_inverse_distance(q, 3),
        lambda q, p, xp: (p * p).sum() / (2 * M) - G * M * M * _pairwise_inverse_distance(q, 3),
    ),
    "double_pendulum": (_double_pendulum_lagrangian, _double_pendulum_hamiltonian),
    "spring_chain": (
        lambda q, v, xp: 0.5 * (v * v).sum() - _chain_potential(q),
        lambda q, p, xp: 0.5 * (p * p).sum() + _chain_potential(q),
    ),
}


def test_every_conservative_system_with_kinematics_has_its_true_physics_here():
    """A new conservative built-in system with kinematics must be added above, or this
    file checks less than it says (the pixel pendulum is observed as images: no
    kinematics)."""
    reversible = [
        n for n in registry.available("system") if registry.get_class("system", n).time_reversible
    ]
    assert {n for n in reversible if _system(n).kinematics() is not None} == set(TRUE)


@functools.cache
def _system(name: str) -> Any:
    job = prepare_job(compose_job([f"system={name}", "profile=quick"]))
    return job.system_cls(job.system_cfg)


def _states(name: str) -> tuple[Any, np.ndarray]:
    system = _system(name)
    x = system.initial_states(np.random.default_rng(0), 8)
    return system, np.asarray(x, dtype=np.float64)


def _expected(system: Any, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Canonical states, their velocity states and the true ``(q̇, q̈)``."""
    kin = system.kinematics()
    return x, kin.to_velocity(x), kin.velocity_rate(x, system.vector_field(x))


def _jax() -> tuple[Any, Any]:
    """``(jax, jax.numpy)`` with float64 enabled (as the JAX backend enables it)."""
    jax = pytest.importorskip("jax")
    jax.config.update("jax_enable_x64", True)
    return jax, jax.numpy


@pytest.mark.parametrize("name", sorted(TRUE))
def test_the_true_lagrangian_through_the_torch_lnn(name):
    torch = pytest.importorskip("torch")
    from hnnbench_plugins.models.lnn import torch as lnn

    lagrangian = TRUE[name][0]
    system, x = _states(name)
    _, v, want = _expected(system, x)
    n = v.shape[1] // 2

    from hnnbench_plugins.models.lnn import KINETIC_PRIOR

    def network(z: Any) -> Any:  # what the network must output for L to be the true one
        return lagrangian(z[:n], z[n:], torch) - KINETIC_PRIOR * (z[n:] * z[n:]).sum()

    class TrueNet:  # the MLP's interface the LNN uses: value, gradient, Hessian rows
        def input_hessian(self, z: Any, first_row: int = 0) -> Any:
            value = torch.func.vmap(network)(z)
            grad = torch.func.vmap(torch.func.grad(network))(z)
            hess = torch.func.vmap(torch.func.hessian(network))(z)
            return value, grad, hess[:, first_row:, :]

    got = lnn.field({"L": TrueNet()}, torch.as_tensor(v, dtype=torch.float64)).numpy()
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("name", sorted(TRUE))
def test_the_true_lagrangian_through_the_jax_lnn(name):
    jax, jnp = _jax()
    from hnnbench_plugins.models.lnn import jax as lnn

    lagrangian = TRUE[name][0]
    system, x = _states(name)
    _, v, want = _expected(system, x)
    n = v.shape[1] // 2

    def true_lagrangian(z: Any) -> Any:  # one state (2n,) -> scalar
        return lagrangian(z[:n], z[n:], jnp)

    got = np.asarray(jax.jit(lambda z: lnn.euler_lagrange(true_lagrangian, z))(jnp.asarray(v)))
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("name", sorted(TRUE))
def test_the_true_hamiltonian_through_the_torch_hnn(name):
    torch = pytest.importorskip("torch")
    from hnnbench_plugins.models.hnn import torch as hnn

    hamiltonian = TRUE[name][1]
    system, x = _states(name)
    n = x.shape[1] // 2

    class TrueH:  # the MLP's interface the HNN uses: input_gradient (N, 2n) -> (N, 2n)
        def input_gradient(self, z: Any) -> Any:
            z = z.detach().requires_grad_()
            total = sum(hamiltonian(zi[:n], zi[n:], torch) for zi in z)
            return torch.autograd.grad(total, z)[0]

    got = hnn.field({"H": TrueH()}, torch.as_tensor(x, dtype=torch.float64)).numpy()
    np.testing.assert_allclose(got, system.vector_field(x), rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("name", sorted(TRUE))
def test_the_true_hamiltonian_through_the_jax_hnn(name):
    jax, jnp = _jax()
    from hnnbench_plugins.models.hnn import jax as hnn

    hamiltonian = TRUE[name][1]
    system, x = _states(name)
    n = x.shape[1] // 2

    def net(z: Any) -> Any:  # one state (2n,) -> (1,)
        return hamiltonian(z[:n], z[n:], jnp)[None]

    got = np.asarray(jax.jit(lambda z: hnn.field({"H": net}, z))(jnp.asarray(x)))
    np.testing.assert_allclose(got, system.vector_field(x), rtol=1e-10, atol=1e-10)
