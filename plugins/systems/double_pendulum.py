"""Ideal planar double pendulum in canonical coordinates (simulated, chaotic by default).

Two point masses ``m1``, ``m2`` on massless rigid rods of lengths ``l1``, ``l2`` under
gravity ``g`` (defaults 1: dimensionless units, time in units of ``sqrt(l1 / g)``). The
angles ``q = (q1, q2)`` are measured from the downward vertical, each rod's own angle
(not the angle between the rods), counter-clockwise positive, in radians. They are
continuous (a rod that goes over the top keeps counting turns), in the data and the
evaluation alike; ``wrap_angles`` wraps the data points' angles instead (see below).
``p = (p1, p2)`` are the canonical momenta conjugate to them, ``p = M(q) q̇``, with the
mass matrix

    M(q) = [[(m1 + m2) l1²,        m2 l1 l2 cos(q1 - q2)],
            [m2 l1 l2 cos(q1 - q2), m2 l2²              ]]

and the Hamiltonian (energy relative to the downward rest state, ``H(0) = 0``)

    H(q, p) = ½ pᵀ M(q)⁻¹ p + (m1 + m2) g l1 (1 - cos q1) + m2 g l2 (1 - cos q2).

The vector field is ``dq/dt = M⁻¹ p``, ``dp/dt = -∂H/∂q``:

    dp1/dt = -m2 l1 l2 q̇1 q̇2 sin(q1 - q2) - (m1 + m2) g l1 sin q1
    dp2/dt = +m2 l1 l2 q̇1 q̇2 sin(q1 - q2) - m2 g l2 sin q2

(``∂/∂q`` of the kinetic term at fixed ``p`` is ``-½ q̇ᵀ (∂M/∂q) q̇``). Everything here is
vectorised over any leading batch dimensions.

Initial states are drawn by energy: a target ``E ~ U[energy_min, energy_max]``, angles
uniform in ``[-π, π]²`` (redrawn while their potential exceeds ``E``), a momentum
direction uniform on the circle, and the momenta scaled so that ``H = E`` exactly.

Data: ``n_traj`` trajectories of ``n_points`` samples over ``[0, t_end]`` (DOP853, rtol =
atol = ``data_rtol``); the dx/dt targets are the analytic field at the clean states.
The angles stay continuous by default, so the training points come from the same
distribution as the evaluation trajectories (46% of the default data's q2 values lie
beyond ±π, up to ±26 rad, as the outer rod turns over). With ``wrap_angles`` each
point's angles are wrapped into ``[-π, π)`` (the field is 2π-periodic, so the targets
stay exact): the training domain is compact and the derivative fit better, but
evaluation trajectories then leave it whenever a rod turns over (measured trade-off in
docs/SYSTEMS_DOUBLE_PENDULUM.md). Gaussian noise of std ``noise_std`` (default 0) is
added to the inputs; the first ``1 - test_split`` of the trajectories train, the rest
(the LAST ``round(n_traj * test_split)``, :meth:`DoublePendulumConfig.trajectory_split`)
test. Evaluation:
``eval_n_traj`` fresh trajectories (their own seed stream) over ``[0, eval_t_end]``,
continuous (rollouts are compared with them), starting in ``[-π, π]²``.

The default regime (``E ∈ [3, 4]``, unit parameters) is chaotic: all 256 states of the
Lyapunov estimate have exponents of 0.25-0.46, Lyapunov time 2.83 (:data:`LYAPUNOV_TIME`,
:func:`estimate_lyapunov_time`, docs/SYSTEMS_DOUBLE_PENDULUM.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Optional

import numpy as np

from hnnbench import (
    CLEAN_INPUTS,
    DATA_STREAM,
    EVAL_STREAM,
    ConfigError,
    Dataset,
    Kinematics,
    MassMatrixKinematics,
    System,
    SystemConfig,
    Trajectories,
    TrajectorySplit,
    VectorField,
    check_fraction,
    check_int_at_least,
    check_ordered,
    check_positive,
    seed_stream,
    solve_batch,
    trajectory_dataset,
)

__all__ = [
    "LYAPUNOV_TIME",
    "REGIME_FIELDS",
    "DoublePendulum",
    "DoublePendulumConfig",
    "Params",
    "estimate_lyapunov_time",
    "hamiltonian",
    "lyapunov_exponents",
    "mass_matrix",
    "mass_rate",
    "potential",
    "regime_scan",
    "sample_initial_states",
    "vector_field",
    "velocities",
    "wrap_angle",
]

#: Seed stream of the Lyapunov estimate's initial states (data and evaluation draw from
#: hnnbench's DATA_STREAM and EVAL_STREAM, :func:`hnnbench.seed_stream`).
LYAPUNOV_STREAM = 2

#: Lyapunov time (1 / mean largest Lyapunov exponent) of the default regime, in units
#: of sqrt(l1 / g): mean exponent 0.3538 ± 0.0025 (s.e.m. over the states). Re-derive
#: it with ``python -m hnnbench_plugins.systems.double_pendulum``
#: (:func:`estimate_lyapunov_time` with its defaults: 256 initial states drawn like the
#: data, Benettin two-trajectory method over t = 400).
LYAPUNOV_TIME = 2.826
#: Config fields that set the dynamical regime: :attr:`DoublePendulum.lyapunov_time` is
#: ``None`` unless all of them keep their defaults.
REGIME_FIELDS = ("m1", "m2", "l1", "l2", "g", "energy_min", "energy_max")


# --------------------------------------------------------------------------- physics


@dataclass(frozen=True)
class Params:
    """Physical parameters: masses (``m1``, ``m2``), rod lengths (``l1``, ``l2``), gravity."""

    m1: float = 1.0
    m2: float = 1.0
    l1: float = 1.0
    l2: float = 1.0
    g: float = 1.0


def _split(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(..., 4)`` states -> ``q``, ``p``, each ``(..., 2)``."""
    x = np.asarray(x, dtype=np.float64)
    if x.shape[-1] != 4:
        raise ValueError(f"expected double-pendulum states with 4 numbers, got shape {x.shape}")
    return x[..., :2], x[..., 2:]


def mass_matrix(q: np.ndarray, params: Params = Params()) -> np.ndarray:
    """``M(q)`` of angles ``(..., 2)``, shape ``(..., 2, 2)`` (units of mass x length²)."""
    q = np.asarray(q, dtype=np.float64)
    k = params
    c = k.m2 * k.l1 * k.l2 * np.cos(q[..., 0] - q[..., 1])
    m11 = np.full_like(c, (k.m1 + k.m2) * k.l1**2)
    m22 = np.full_like(c, k.m2 * k.l2**2)
    return np.stack([np.stack([m11, c], -1), np.stack([c, m22], -1)], -2)


def mass_rate(q: np.ndarray, qdot: np.ndarray, params: Params = Params()) -> np.ndarray:
    """``Ṁ = Σ_k ∂M/∂q_k q̇_k`` along angles ``(..., 2)`` moving at ``q̇`` ``(..., 2)``,
    shape ``(..., 2, 2)``."""
    q, qdot = np.asarray(q, dtype=np.float64), np.asarray(qdot, dtype=np.float64)
    k = params
    s = -k.m2 * k.l1 * k.l2 * np.sin(q[..., 0] - q[..., 1]) * (qdot[..., 0] - qdot[..., 1])
    zero = np.zeros_like(s)
    return np.stack([np.stack([zero, s], -1), np.stack([s, zero], -1)], -2)


def velocities(x: np.ndarray, params: Params = Params()) -> np.ndarray:
    """``q̇ = M(q)⁻¹ p`` of states ``(..., 4)``, shape ``(..., 2)`` (closed-form inverse)."""
    q, p = _split(x)
    k = params
    delta = q[..., 0] - q[..., 1]
    c = k.m2 * k.l1 * k.l2 * np.cos(delta)
    a, b = (k.m1 + k.m2) * k.l1**2, k.m2 * k.l2**2
    det = a * b - c**2  # = m2 l1² l2² (m1 + m2 sin²Δ) > 0
    qdot1 = (b * p[..., 0] - c * p[..., 1]) / det
    qdot2 = (a * p[..., 1] - c * p[..., 0]) / det
    return np.stack([qdot1, qdot2], axis=-1)


def potential(q: np.ndarray, params: Params = Params()) -> np.ndarray:
    """Potential energy of angles ``(..., 2)``, zero at the downward rest state, ``(...)``."""
    q = np.asarray(q, dtype=np.float64)
    k = params
    return (k.m1 + k.m2) * k.g * k.l1 * (1.0 - np.cos(q[..., 0])) + k.m2 * k.g * k.l2 * (
        1.0 - np.cos(q[..., 1])
    )


def hamiltonian(x: np.ndarray, params: Params = Params()) -> np.ndarray:
    """``H`` of states ``(..., 4)``, shape ``(...)``."""
    q, p = _split(x)
    qdot = velocities(x, params)
    return 0.5 * np.sum(p * qdot, axis=-1) + potential(q, params)


def vector_field(x: np.ndarray, params: Params = Params()) -> np.ndarray:
    """``dx/dt = (M⁻¹ p, -∂H/∂q)`` of states ``(..., 4)``, same shape."""
    q, _ = _split(x)
    k = params
    qdot = velocities(x, params)
    coupling = k.m2 * k.l1 * k.l2 * qdot[..., 0] * qdot[..., 1] * np.sin(q[..., 0] - q[..., 1])
    pdot1 = -coupling - (k.m1 + k.m2) * k.g * k.l1 * np.sin(q[..., 0])
    pdot2 = coupling - k.m2 * k.g * k.l2 * np.sin(q[..., 1])
    return np.concatenate([qdot, np.stack([pdot1, pdot2], axis=-1)], axis=-1)


def wrap_angle(theta: np.ndarray) -> np.ndarray:
    """Angles wrapped into ``[-π, π)``, same shape."""
    return (np.asarray(theta, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi


def sample_initial_states(
    rng: np.random.Generator,
    n: int,
    params: Params,
    energy_min: float,
    energy_max: float,
) -> np.ndarray:
    """``(n, 4)`` states with ``H`` uniform in ``[energy_min, energy_max]``.

    Per state: a target energy ``E ~ U[energy_min, energy_max]``; angles uniform on
    ``{q ∈ [-π, π]² : V(q) <= E}`` (drawn in the smallest box around that set, redrawn
    while ``V(q) > E``); a momentum direction ``u`` uniform on the
    unit circle; then ``p = s u`` with ``s`` chosen so that ``½ pᵀ M⁻¹ p = E - V(q)``.
    """
    k = params
    energy = rng.uniform(energy_min, energy_max, size=n)
    # Each angle can reach at most where its own potential term alone uses up E: drawing
    # in that (per-state) box and rejecting V(q) > E gives the same uniform distribution
    # on {V <= E} as drawing in [-π, π]², with acceptance >= π/4 even at low energy.
    reach = np.stack(
        [
            np.arccos(np.clip(1.0 - energy / ((k.m1 + k.m2) * k.g * k.l1), -1.0, 1.0)),
            np.arccos(np.clip(1.0 - energy / (k.m2 * k.g * k.l2), -1.0, 1.0)),
        ],
        axis=-1,
    )  # (n, 2)
    q = reach * rng.uniform(-1.0, 1.0, size=(n, 2))
    redraw = potential(q, params) > energy
    while redraw.any():
        q[redraw] = reach[redraw] * rng.uniform(-1.0, 1.0, size=(int(redraw.sum()), 2))
        redraw = potential(q, params) > energy
    angle = rng.uniform(0.0, 2.0 * np.pi, size=n)
    u = np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    unit_kinetic = 0.5 * np.sum(u * velocities(np.concatenate([q, u], -1), params), -1)
    scale = np.sqrt((energy - potential(q, params)) / unit_kinetic)
    return np.concatenate([q, scale[:, None] * u], axis=-1)


# --------------------------------------------------------------------------- Lyapunov


def lyapunov_exponents(
    field: VectorField,
    x0: np.ndarray,
    t_total: float,
    interval: float = 1.0,
    d0: float = 1e-8,
    rtol: float = 1e-11,
    seed: int = 0,
) -> np.ndarray:
    """Largest Lyapunov exponent of each initial state, Benettin's two-trajectory method.

    Each state ``x0[i]`` (``(M, D)``) gets a companion at distance ``d0`` in a random
    direction. Both are integrated (DOP853, one batch) for ``interval`` time units; the
    log of the separation's growth ``log(|d| / d0)`` is accumulated and the companion is
    put back at distance ``d0`` along the current separation. After
    ``round(t_total / interval)`` intervals the exponent is the sum over the elapsed time.

    Returns:
        ``(M,)`` finite-time exponents in 1 / time units (≈ log(growth) / t_total for
        regular orbits, which tends to 0 as ``t_total`` grows).
    """
    x = np.asarray(x0, dtype=np.float64)
    rng = np.random.default_rng(seed)
    direction = rng.standard_normal(x.shape)
    direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
    y = x + d0 * direction
    n = x.shape[0]
    n_intervals = max(1, int(round(t_total / interval)))
    grid = np.array([0.0, interval])
    total = np.zeros(n)
    for _ in range(n_intervals):
        out = solve_batch(field, np.concatenate([x, y]), grid, rtol=rtol, atol=rtol)[:, -1]
        x, y = out[:n], out[n:]
        sep = y - x
        dist = np.linalg.norm(sep, axis=-1)
        total += np.log(dist / d0)
        y = x + (d0 / dist)[:, None] * sep
    return total / (n_intervals * interval)


def estimate_lyapunov_time(
    params: Params = Params(),
    energy_min: float = 3.0,
    energy_max: float = 4.0,
    n_states: int = 256,
    t_total: float = 400.0,
    interval: float = 1.0,
    seed: int = 0,
) -> tuple[float, np.ndarray]:
    """Lyapunov time of a regime: ``1 / mean(λ)`` over ``n_states`` initial states drawn
    as the data's (:func:`sample_initial_states`, seed stream ``(seed, 2)``).

    Returns:
        the Lyapunov time (time units of ``sqrt(l1 / g)``) and the ``(n_states,)``
        finite-time exponents of :func:`lyapunov_exponents`.
    """
    rng = seed_stream(seed, LYAPUNOV_STREAM)
    x0 = sample_initial_states(rng, n_states, params, energy_min, energy_max)

    def field(x: np.ndarray) -> np.ndarray:
        return vector_field(x, params)

    exponents = lyapunov_exponents(field, x0, t_total, interval=interval, seed=seed)
    return float(1.0 / np.mean(exponents)), exponents


# --------------------------------------------------------------------------- config


@dataclass
class DoublePendulumConfig(SystemConfig):
    """Data and evaluation protocol of the double pendulum (units: sqrt(l1 / g) for time).

    Defaults: unit masses, lengths and gravity; energies U[3, 4] (chaotic; the outer rod
    can go over the top, the inner one cannot: that needs E >= 4); 200 trajectories x 51
    points over [0, 10].
    """

    m1: float = 1.0
    m2: float = 1.0
    l1: float = 1.0
    l2: float = 1.0
    g: float = 1.0
    #: Range of the initial energies H, relative to the downward rest state (H = 0).
    energy_min: float = 3.0
    energy_max: float = 4.0
    n_traj: int = 200
    t_end: float = 10.0
    n_points: int = 51
    #: Wrap the data points' angles into [-π, π) (evaluation trajectories stay continuous).
    wrap_angles: bool = False
    #: Gaussian noise added to the model inputs (targets stay clean).
    noise_std: float = 0.0
    #: Fraction of the trajectories (the last ones) held out as the test set.
    test_split: float = 0.2
    data_rtol: float = 1e-12
    eval_n_traj: int = 15
    eval_t_end: float = 10.0
    eval_n_points: int = 101
    eval_rtol: float = 1e-12
    #: 10000 (5000 before): a pilot (two seeds of every family) found most families'
    #: validation criterion still falling over the last 20 % of 5000 steps
    #: (docs/SYSTEMS_DOUBLE_PENDULUM.md, "Training budget"); raised for every family alike.
    steps: int = 10000
    batch_size: Optional[int] = 500
    lr: float = 1e-3
    weight_decay: float = 0.0

    def validate(self) -> None:
        super().validate()
        check_positive(
            "system",
            m1=self.m1,
            m2=self.m2,
            l1=self.l1,
            l2=self.l2,
            g=self.g,
            energy_min=self.energy_min,
            t_end=self.t_end,
            data_rtol=self.data_rtol,
            eval_t_end=self.eval_t_end,
            eval_rtol=self.eval_rtol,
        )
        check_ordered("system", "energy_min", self.energy_min, "energy_max", self.energy_max)
        check_int_at_least(
            "system",
            2,
            n_traj=self.n_traj,
            n_points=self.n_points,
            eval_n_traj=self.eval_n_traj,
            eval_n_points=self.eval_n_points,
        )
        check_fraction("system", "test_split", self.test_split, 0.2)
        if not isinstance(self.wrap_angles, bool):
            raise ConfigError(
                f"system.wrap_angles={self.wrap_angles} is invalid: expected true or false."
            )
        if not self.noise_std >= 0:
            raise ConfigError(
                f"system.noise_std={self.noise_std} is invalid: expected a number >= 0. "
                "Fix it with system.noise_std=0 or another non-negative value."
            )
        self.trajectory_split().check(self.n_traj)

    def trajectory_split(self) -> TrajectorySplit:
        """The LAST ``round(n_traj * test_split)`` trajectories test, the rest train."""
        return TrajectorySplit(self.test_split, test_from="last")

    @property
    def params(self) -> Params:
        return Params(m1=self.m1, m2=self.m2, l1=self.l1, l2=self.l2, g=self.g)


# --------------------------------------------------------------------------- system


class DoublePendulum(System):
    """Ideal double pendulum in canonical coordinates, chaotic energies by default."""

    order = 90

    Config: ClassVar[type[SystemConfig]] = DoublePendulumConfig
    cfg: DoublePendulumConfig
    version = "1"
    description = "Ideal double pendulum, canonical (q1, q2, p1, p2), chaotic energies E in [3, 4]"
    time_reversible = True
    conservative = True
    profiles: ClassVar[dict[str, dict[str, Any]]] = {
        "quick": {
            "n_traj": 20,
            "steps": 300,
            "eval_n_traj": 5,
            "eval_t_end": 5.0,
            "eval_n_points": 51,
        }
    }

    @property
    def dof(self) -> int:
        return 2

    @property
    def params(self) -> Params:
        return self.cfg.params

    def energy(self, x: np.ndarray) -> np.ndarray:
        return hamiltonian(x, self.params)

    def vector_field(self, x: np.ndarray) -> np.ndarray:
        return vector_field(x, self.params)

    def kinematics(self) -> Kinematics:
        """``p = M(q) q̇`` with the configured masses and lengths."""
        params = self.params
        return MassMatrixKinematics(
            lambda q: mass_matrix(q, params), lambda q, qdot: mass_rate(q, qdot, params)
        )

    @property
    def angles(self) -> tuple[int, ...]:
        """Both rods' angles."""
        return (0, 1)

    @property
    def wrapped_angles(self) -> tuple[int, ...]:
        """Both rods' angles, when ``wrap_angles`` is set."""
        return (0, 1) if self.cfg.wrap_angles else ()

    @property
    def lyapunov_time(self) -> Optional[float]:
        """:data:`LYAPUNOV_TIME` for the default regime; ``None`` once any of
        :data:`REGIME_FIELDS` differs from its default (not estimated there)."""
        defaults = DoublePendulumConfig()
        if all(getattr(self.cfg, key) == getattr(defaults, key) for key in REGIME_FIELDS):
            return LYAPUNOV_TIME
        return None

    def initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``(n, 4)`` initial states with energies U[energy_min, energy_max]."""
        c = self.cfg
        return sample_initial_states(rng, n, self.params, c.energy_min, c.energy_max)

    @property
    def data_dt(self) -> float:
        """Sampling interval of the training data."""
        return float(self.cfg.t_end) / (self.cfg.n_points - 1)

    def dataset(self, seed: int) -> Dataset:
        c = self.cfg
        rng = seed_stream(seed, DATA_STREAM)  # initial states, then the noise
        t = np.linspace(0.0, c.t_end, c.n_points)
        x0 = self.initial_states(rng, c.n_traj)
        clean = solve_batch(self.vector_field, x0, t, rtol=c.data_rtol, atol=c.data_rtol)
        dxdt = self.vector_field(clean)
        x = clean.copy()
        if c.wrap_angles:
            x[..., :2] = wrap_angle(x[..., :2])
        exact = x
        if c.noise_std > 0:
            x = x + rng.normal(0.0, c.noise_std, size=clean.shape)
        split = c.trajectory_split()
        n_train, n_test = split.sizes(c.n_traj)
        energy = self.energy(clean)
        drift = np.max(np.abs(energy - energy[:, :1]))
        return trajectory_dataset(
            x,
            dxdt,
            t,
            split,
            extras={CLEAN_INPUTS: exact} if c.noise_std > 0 else None,
            meta={
                "dt": self.data_dt,
                "n_train_traj": n_train,
                "n_test_traj": n_test,
                "reference": "DOP853",
                "rtol": c.data_rtol,
                "max_energy_drift": float(drift),
                "wrap_angles": c.wrap_angles,
            },
        )

    def evaluation(self, seed: int) -> Trajectories:
        c = self.cfg
        rng = seed_stream(seed, EVAL_STREAM)
        t = np.linspace(0.0, c.eval_t_end, c.eval_n_points)
        x0 = self.initial_states(rng, c.eval_n_traj)
        states = solve_batch(self.vector_field, x0, t, rtol=c.eval_rtol, atol=c.eval_rtol)
        energy = self.energy(states)
        return Trajectories(
            t=t,
            states=states,
            dt=self.data_dt,
            meta={
                "horizon": float(c.eval_t_end),
                "n_traj": int(c.eval_n_traj),
                "reference": "DOP853",
                "rtol": c.eval_rtol,
                "energy_range": [c.energy_min, c.energy_max],
                "lyapunov_time": self.lyapunov_time,
                "max_energy_drift": float(np.max(np.abs(energy - energy[:, :1]))),
            },
        )


#: Energy bands of :func:`regime_scan` (the default regime is (3, 4)).
SCAN_BANDS = ((0.5, 1.0), (1.0, 2.0), (2.0, 3.0), (3.0, 4.0), (4.0, 5.0), (5.0, 7.0))


def regime_scan(
    bands: tuple[tuple[float, float], ...] = SCAN_BANDS,
    n_states: int = 32,
    t_total: float = 100.0,
    threshold: float = 0.1,
) -> list[dict[str, float]]:
    """Per energy band (unit parameters): the Lyapunov time and the fraction of chaotic
    initial states, those whose finite-time exponent over ``t_total`` exceeds
    ``threshold`` (regular orbits give about 0.03 at t = 100)."""
    rows = []
    for low, high in bands:
        lyapunov_time, exponents = estimate_lyapunov_time(
            energy_min=low, energy_max=high, n_states=n_states, t_total=t_total
        )
        rows.append(
            {
                "energy_min": low,
                "energy_max": high,
                "lyapunov_time": lyapunov_time,
                "median_exponent": float(np.median(exponents)),
                "chaotic_fraction": float(np.mean(exponents > threshold)),
            }
        )
    return rows


def angle_coverage(seed: int = 0) -> dict[str, float]:
    """How far the default protocol's angles leave ``[-π, π)`` (seed ``seed``): in the
    training data unwrapped, and along the (continuous) evaluation trajectories."""
    system = DoublePendulum(DoublePendulumConfig(name="double_pendulum", wrap_angles=False))
    x = np.concatenate([system.dataset(seed).train.x, system.dataset(seed).test.x])
    traj = system.evaluation(seed)
    outside = np.any(np.abs(traj.states[..., :2]) > np.pi, axis=-1)  # (M, T)
    return {
        "data_q2_beyond_pi": float(np.mean(np.abs(x[:, 1]) > np.pi)),
        "data_q1_beyond_pi": float(np.mean(np.abs(x[:, 0]) > np.pi)),
        "data_max_abs_q2": float(np.max(np.abs(x[:, 1]))),
        "eval_states_beyond_pi": float(outside.mean()),
        "eval_traj_leaving": float(outside.any(axis=1).mean()),
        "eval_max_energy_drift": float(traj.meta["max_energy_drift"]),
    }


def _main(argv: Optional[list[str]] = None) -> None:
    """Re-derive :data:`LYAPUNOV_TIME` (about 20 s on one core); ``--scan`` also prints
    the regime scan and the angle coverage of docs/SYSTEMS_DOUBLE_PENDULUM.md."""
    import sys

    args = sys.argv[1:] if argv is None else argv
    lyapunov_time, exponents = estimate_lyapunov_time()
    sem = exponents.std(ddof=1) / np.sqrt(exponents.size)
    print(
        f"Lyapunov time {lyapunov_time:.4f} (mean exponent {exponents.mean():.5f} ± {sem:.5f} "
        f"s.e.m. over {exponents.size} states; min {exponents.min():.4f}, max "
        f"{exponents.max():.4f}; stored constant {LYAPUNOV_TIME})"
    )
    if "--scan" in args:
        for row in regime_scan():
            print(
                f"E in [{row['energy_min']:g}, {row['energy_max']:g}]: Lyapunov time "
                f"{row['lyapunov_time']:.2f}, median exponent {row['median_exponent']:.3f}, "
                f"chaotic fraction {row['chaotic_fraction']:.2f}"
            )
        print(angle_coverage())


if __name__ == "__main__":
    _main()
