"""Each family's equations, with exact hand-written networks standing in for MLPs:
known Lagrangians, Hamiltonians, dissipations and accelerations must reproduce the
true vector field (to 1e-8), in both backends. A network here is any function of the
backend's kind: torch, a batch ``(N, d) -> (N, 1)`` with an autograd input gradient;
JAX, one vector ``(d,) -> (1,)``."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

torch = pytest.importorskip("torch")
jax = pytest.importorskip("jax")
import jax.numpy as jnp  # noqa: E402

jax.config.update("jax_enable_x64", True)

RNG = np.random.default_rng(0)
GAMMA = 0.3
M = np.array([[2.0, 0.5], [0.5, 1.0]])  # a 2-DOF mass matrix
K = np.array([[3.0, -1.0], [-1.0, 2.0]])  # and stiffness


class TorchNet:
    """A scalar function of a batch as a torch 'network' with an input gradient."""

    def __init__(self, fn):
        self.fn = fn

    def __call__(self, x):
        return self.fn(x)[:, None]

    def input_gradient(self, x):
        return torch.func.vmap(torch.func.grad(lambda xi: self.fn(xi[None])[0]))(x)

    def input_hessian(self, x, first_row=0):
        one = lambda xi: self.fn(xi[None])[0]  # noqa: E731
        hess = torch.func.vmap(torch.func.hessian(one))(x)
        return self.fn(x), self.input_gradient(x), hess[:, first_row:, :]


def torch_fn(kind):
    if kind == "quadratic":  # q^2 + p^2 (spring), or 1/2 qdot^2 - 1/2 q^2 as a Lagrangian
        return lambda x: (x**2).sum(-1)
    if kind == "lagrangian_1d":
        return lambda x: 0.5 * x[:, 1] ** 2 - 0.5 * x[:, 0] ** 2
    if kind == "lagrangian_2d":
        m, k = torch.tensor(M), torch.tensor(K)
        return lambda x: (
            0.5 * torch.einsum("ni,ij,nj->n", x[:, 2:], m, x[:, 2:])
            - 0.5 * torch.einsum("ni,ij,nj->n", x[:, :2], k, x[:, :2])
        )
    if kind == "double_pendulum":  # unit masses, lengths and g; absolute angles
        return lambda x: (
            x[:, 2] ** 2
            + 0.5 * x[:, 3] ** 2
            + x[:, 2] * x[:, 3] * torch.cos(x[:, 0] - x[:, 1])
            + 2 * torch.cos(x[:, 0])
            + torch.cos(x[:, 1])
        )
    if kind == "dissipation":  # D = -gamma p^2 / 2
        return lambda x: -0.5 * GAMMA * x[:, 1] ** 2
    if kind == "half_square":  # T(p) = p^2 / 2 or V(q) = q^2 / 2
        return lambda x: 0.5 * (x**2).sum(-1)
    raise KeyError(kind)


def jax_fn(kind):
    if kind == "quadratic":
        return lambda x: jnp.sum(x**2)[None]
    if kind == "lagrangian_1d":
        return lambda x: (0.5 * x[1] ** 2 - 0.5 * x[0] ** 2)[None]
    if kind == "lagrangian_2d":
        m, k = jnp.asarray(M), jnp.asarray(K)
        return lambda x: (0.5 * x[2:] @ m @ x[2:] - 0.5 * x[:2] @ k @ x[:2])[None]
    if kind == "double_pendulum":
        return lambda x: (
            x[2] ** 2
            + 0.5 * x[3] ** 2
            + x[2] * x[3] * jnp.cos(x[0] - x[1])
            + 2 * jnp.cos(x[0])
            + jnp.cos(x[1])
        )[None]
    if kind == "dissipation":
        return lambda x: (-0.5 * GAMMA * x[1] ** 2)[None]
    if kind == "half_square":
        return lambda x: 0.5 * jnp.sum(x**2)[None]
    raise KeyError(kind)


def _without_prior(backend: str, family: str, fn):
    """The network that makes the family's learned function equal ``fn``: for the LNN,
    ``fn`` minus its declared kinetic term (``KINETIC_PRIOR · |q̇|²``)."""
    if family != "lnn":
        return fn
    from hnnbench_plugins.models.lnn import KINETIC_PRIOR

    if backend == "torch":
        return lambda x: fn(x) - KINETIC_PRIOR * (x[:, x.shape[1] // 2 :] ** 2).sum(-1)
    return lambda x: fn(x) - KINETIC_PRIOR * jnp.sum(x[x.shape[0] // 2 :] ** 2)


def build(backend: str, family: str, nets: dict[str, str]) -> dict:
    if backend == "torch":
        return {k: TorchNet(_without_prior(backend, family, torch_fn(v))) for k, v in nets.items()}
    return {k: _without_prior(backend, family, jax_fn(v)) for k, v in nets.items()}


def field(backend: str, family: str, nets: dict[str, str], z: np.ndarray) -> np.ndarray:
    impl = importlib.import_module(f"hnnbench_plugins.models.{family}.{backend}")
    built = build(backend, family, nets)
    if backend == "torch":
        return impl.field(built, torch.tensor(z)).detach().numpy()
    return np.asarray(impl.field(built, jnp.asarray(z)))


def energy(backend: str, family: str, nets: dict[str, str], z: np.ndarray) -> np.ndarray:
    impl = importlib.import_module(f"hnnbench_plugins.models.{family}.{backend}")
    built = build(backend, family, nets)
    if backend == "torch":
        return impl.energy(built, torch.tensor(z)).detach().numpy()
    return np.asarray(impl.energy(built, jnp.asarray(z)))


BACKENDS = ["torch", "jax"]
Z1 = RNG.normal(size=(9, 2))
Z2 = RNG.normal(size=(9, 4))


@pytest.mark.parametrize("backend", BACKENDS)
def test_hnn_with_the_spring_hamiltonian_is_the_spring(backend):
    q, p = Z1[:, 0], Z1[:, 1]
    out = field(backend, "hnn", {"H": "quadratic"}, Z1)
    np.testing.assert_allclose(out, np.stack([2 * p, -2 * q], 1), atol=1e-8)
    np.testing.assert_allclose(
        energy(backend, "hnn", {"H": "quadratic"}, Z1), q**2 + p**2, atol=1e-8
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_dhnn_without_dissipation_is_the_hnn_and_with_it_the_damped_spring(backend):
    q, p = Z1[:, 0], Z1[:, 1]
    # D = 0: a zero function
    nets0 = {"H": "quadratic", "D": "dissipation"}
    out = field(backend, "dhnn", nets0, Z1)
    np.testing.assert_allclose(out, np.stack([2 * p, -2 * q - GAMMA * p], 1), atol=1e-8)
    zero = field(backend, "dhnn", {"H": "quadratic", "D": "quadratic"}, Z1) - 2 * Z1
    np.testing.assert_allclose(zero, np.stack([2 * p, -2 * q], 1), atol=1e-8)  # grad D = 2z
    np.testing.assert_allclose(energy(backend, "dhnn", nets0, Z1), q**2 + p**2, atol=1e-8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_lnn_with_a_harmonic_lagrangian_is_the_oscillator(backend):
    q, qdot = Z1[:, 0], Z1[:, 1]
    out = field(backend, "lnn", {"L": "lagrangian_1d"}, Z1)
    np.testing.assert_allclose(out, np.stack([qdot, -q], 1), atol=1e-8)
    e = energy(backend, "lnn", {"L": "lagrangian_1d"}, Z1)  # q' dL/dq' - L
    np.testing.assert_allclose(e, 0.5 * qdot**2 + 0.5 * q**2, atol=1e-8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_lnn_solves_the_euler_lagrange_system_with_a_full_mass_matrix(backend):
    q, qdot = Z2[:, :2], Z2[:, 2:]
    expected = -np.linalg.solve(M, (K @ q.T)).T
    out = field(backend, "lnn", {"L": "lagrangian_2d"}, Z2)
    np.testing.assert_allclose(out, np.concatenate([qdot, expected], 1), atol=1e-8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_lnn_handles_the_mixed_block_of_a_double_pendulum_lagrangian(backend):
    """A Lagrangian whose ∂²L/∂q∂q̇ is neither zero nor symmetric (the rods' coupling
    term), against the Euler-Lagrange equations written out by hand:
    [2, cos Δ; cos Δ, 1] q̈ = (−sin Δ ω2² − 2 sin θ1, sin Δ ω1² − sin θ2), Δ = θ1 − θ2."""
    th1, th2, w1, w2 = Z2.T
    d = th1 - th2
    mass = np.stack(
        [np.stack([2 + 0 * d, np.cos(d)], -1), np.stack([np.cos(d), 1 + 0 * d], -1)], -2
    )
    rhs = np.stack([-np.sin(d) * w2**2 - 2 * np.sin(th1), np.sin(d) * w1**2 - np.sin(th2)], -1)
    expected = np.linalg.solve(mass, rhs[..., None])[..., 0]
    out = field(backend, "lnn", {"L": "double_pendulum"}, Z2)
    np.testing.assert_allclose(out, np.concatenate([Z2[:, 2:], expected], 1), atol=1e-8)
    e = energy(backend, "lnn", {"L": "double_pendulum"}, Z2)  # T + V, V = -2cos θ1 - cos θ2
    np.testing.assert_allclose(
        e, w1**2 + 0.5 * w2**2 + w1 * w2 * np.cos(d) - 2 * np.cos(th1) - np.cos(th2), atol=1e-8
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_lnn_with_a_singular_velocity_hessian_gives_nan_not_an_error(backend):
    """L = q̇1² with a second velocity that L ignores: ∂²L/∂q̇∂q̇ is singular. Both
    backends give non-finite accelerations (so a rollout diverges) instead of raising."""
    z = Z2[:3]
    impl = importlib.import_module(f"hnnbench_plugins.models.lnn.{backend}")
    if backend == "torch":
        net = TorchNet(_without_prior(backend, "lnn", lambda x: x[:, 2] ** 2))
        out = impl.field({"L": net}, torch.tensor(z)).numpy()
    else:
        net = _without_prior(backend, "lnn", lambda x: (x[2] ** 2)[None])
        out = np.asarray(impl.field({"L": net}, jnp.asarray(z)))
    assert not np.isfinite(out[:, 2:]).any()


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_lnn_adds_its_declared_kinetic_term_to_the_network(backend):
    """A network that outputs 0 is the free particle of L = KINETIC_PRIOR · |q̇|²: no
    acceleration, energy KINETIC_PRIOR · |q̇|² (a definite velocity Hessian from the
    start, whatever the network's initial one)."""
    from hnnbench_plugins.models.lnn import KINETIC_PRIOR

    impl = importlib.import_module(f"hnnbench_plugins.models.lnn.{backend}")
    if backend == "torch":
        nets = {"L": TorchNet(lambda x: 0.0 * x.sum(-1))}
        out = impl.field(nets, torch.tensor(Z2)).numpy()
        e = impl.energy(nets, torch.tensor(Z2)).numpy()
    else:
        nets = {"L": lambda x: (0.0 * jnp.sum(x))[None]}
        out = np.asarray(impl.field(nets, jnp.asarray(Z2)))
        e = np.asarray(impl.energy(nets, jnp.asarray(Z2)))
    np.testing.assert_allclose(out, np.concatenate([Z2[:, 2:], 0 * Z2[:, 2:]], 1), atol=1e-12)
    np.testing.assert_allclose(e, KINETIC_PRIOR * (Z2[:, 2:] ** 2).sum(1), atol=1e-12)


def _so_mlp_accel(backend):
    if backend == "torch":

        class Accel:
            def __call__(self, x):
                return -x[:, :1]

        return Accel()
    return lambda x: -x[:1]


@pytest.mark.parametrize("backend", BACKENDS)
def test_so_mlp_with_a_known_acceleration_is_the_oscillator(backend):
    impl = importlib.import_module(f"hnnbench_plugins.models.so_mlp.{backend}")
    z = torch.tensor(Z1) if backend == "torch" else jnp.asarray(Z1)
    out = np.asarray(impl.field({"g": _so_mlp_accel(backend)}, z))
    np.testing.assert_allclose(out, np.stack([Z1[:, 1], -Z1[:, 0]], 1), atol=1e-8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_srnn_with_separable_quadratic_h_is_the_oscillator(backend):
    nets = {"T": "half_square", "V": "half_square"}
    out = field(backend, "srnn", nets, Z1)
    np.testing.assert_allclose(out, np.stack([Z1[:, 1], -Z1[:, 0]], 1), atol=1e-8)
    np.testing.assert_allclose(energy(backend, "srnn", nets, Z1), 0.5 * (Z1**2).sum(1), atol=1e-8)


def leapfrog_oscillator(z: np.ndarray, h: float) -> np.ndarray:
    """The leapfrog map of H = p^2/2 + q^2/2, written out by hand."""
    q, p = z[..., 0], z[..., 1]
    p = p - 0.5 * h * q
    q = q + h * p
    p = p - 0.5 * h * q
    return np.stack([q, p], -1)


@pytest.mark.parametrize("substeps", [1, 3])
@pytest.mark.parametrize("backend", BACKENDS)
def test_srnn_window_loss_is_zero_on_its_own_leapfrog_trajectories(backend, substeps):
    """Windows made by the exact leapfrog map (uneven measured steps) have zero loss;
    the true continuous trajectory has a small, positive one."""
    impl = importlib.import_module(f"hnnbench_plugins.models.srnn.{backend}")
    dts = RNG.uniform(0.05, 0.15, size=(6, 4))
    windows = np.empty((6, 5, 2))
    windows[:, 0] = RNG.normal(size=(6, 2))
    for k in range(4):
        z = windows[:, k]
        for _ in range(substeps):
            z = leapfrog_oscillator(z, 0.0 + dts[:, k] / substeps)
        windows[:, k + 1] = z
    if backend == "torch":
        nets = {k: TorchNet(torch_fn("half_square")) for k in ("T", "V")}
        loss = float(
            impl.window_loss(nets, torch.tensor(windows), torch.tensor(dts), substeps=substeps)
        )
    else:
        nets = {k: jax_fn("half_square") for k in ("T", "V")}
        loss = float(
            impl.window_loss(nets, jnp.asarray(windows), jnp.asarray(dts), substeps=substeps)
        )
    assert loss < 1e-28
    # exact flow of the oscillator: rotation; leapfrog differs at O(h^3) per step
    t = np.cumsum(np.concatenate([np.zeros((6, 1)), dts], 1), axis=1)
    q0, p0 = windows[:, 0, 0:1], windows[:, 0, 1:2]
    exact = np.stack([q0 * np.cos(t) + p0 * np.sin(t), p0 * np.cos(t) - q0 * np.sin(t)], -1)
    if backend == "torch":
        off = float(
            impl.window_loss(nets, torch.tensor(exact), torch.tensor(dts), substeps=substeps)
        )
    else:
        off = float(impl.window_loss(nets, jnp.asarray(exact), jnp.asarray(dts), substeps=substeps))
    assert 0 < off < 1e-5
