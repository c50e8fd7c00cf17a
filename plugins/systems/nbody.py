"""N gravitating point masses in the plane (G = m = 1): the HNN paper's two- and three-body tasks.

State layout (``dof = 2N``, a state has ``4N`` numbers)::

    x = (q, p),  q = (x_1, y_1, x_2, y_2, ..., x_N, y_N),  p = (px_1, py_1, ..., px_N, py_N)

positions of each body first, then their momenta ``p_i = m v_i`` (with m = 1, the
velocities). The Hamiltonian is

    H = sum_i |p_i|^2 / (2 m) - sum_{i<j} G m^2 / |q_i - q_j|

(every pair counted once, so it is right for any N, unlike the original code whose
potential accumulated outside its loop), and the vector field is ``dq_i/dt = p_i / m``,
``dp_i/dt = sum_{j != i} G m^2 (q_j - q_i) / |q_j - q_i|^3``. Both are vectorised over any
leading batch dimensions.

Initial states (``init``; docs/SYSTEMS_NBODY.md has the formulas):

- ``"2019"`` (default of :class:`TwoBody` and :class:`ThreeBody`): the samplers of the
  2019 code (``experiment-2body/data.py`` and ``experiment-3body/data.py``,
  ``random_config``). Two bodies (:func:`box_mirror_states`): both coordinates of body
  1's position uniform in ``[radius_min, radius_max]`` (the original's ``min_radius`` and
  ``max_radius`` bound each coordinate, not the radius), body 2 at ``(-q, -v)``, the
  circular speed times ONE factor ``1 + velocity_noise * N(0, 1)`` shared by both bodies,
  so the centre of mass stays at the origin, at rest. Three bodies
  (:func:`triangle_states`): body 1 at radius ``U[radius_min, radius_max]`` in the
  direction of a uniform point of the square ``[-1, 1]^2`` (not a uniform angle), the
  others rotated by 120 and 240 degrees, circular speed, and each velocity COMPONENT
  times its own ``1 + velocity_noise * U(-1, 1)``.
- ``"ring"`` (hnnbench's sampler up to system version 1, any N; :func:`ring_states`):
  the N bodies sit on a ring of radius ``r ~ U[radius_min, radius_max]``, evenly spaced
  (360/N degrees apart) at a uniformly random rotation, each moving tangentially at the
  circular speed times its own factor ``1 + velocity_noise * N(0, 1)``, so the centre of
  mass may drift.

Bodies move counter-clockwise at the speed of the circular orbit of their ring (so every
orbit of the training, validation, test and evaluation sets turns the same way, and
the momentum-flipped states of the reversibility test are out of distribution:
``reversal_in_distribution = False``),
``v = sqrt(S / (4 r))`` with ``S = sum_{k=1}^{N-1} 1 / sin(pi k / N)`` (G = m = 1): for
two bodies ``1 / (2 sqrt(r))``, for three ``sqrt(1 / (sqrt(3) r))``, the speeds the
original wrote as ``r / (2 r^1.5)`` and ``r / r^1.5 * sqrt(sin(pi/3) / (2 cos(pi/6)^2))``.

Ground truth: every trajectory is integrated by REBOUND with IAS15 (``adaptive_mode =
"global"``, default epsilon), stopping exactly at each sample time. The worst relative
energy drift ``|E(t) - E(0)| / |E(0)|`` (REBOUND's ``sim.energy()``) over all trajectories
and sample times is recorded in ``Dataset.meta`` / ``Trajectories.meta`` as
``max_rel_energy_drift`` and is at most :data:`MAX_REL_ENERGY_DRIFT` (1e-10). An orbit that
breaks that limit is a near-collision (bodies closer than ~1e-4; about 1 in 5000 of the
paper's three-body orbits) that IAS15 cannot follow to that accuracy: it is replaced
by a fresh draw from the same random stream, and ``n_rejected_orbits`` counts these. If
more than 5% of the orbits (at least 3) need replacing, generation fails with
:class:`DataError`.

Data: ``n_orbits`` orbits with ``n_points`` samples over ``[0, t_end]``. The dx/dt targets
are the analytic vector field at the states. The original added no noise to n-body
inputs, so ``noise_std`` defaults to 0. The FIRST ``test_split`` of the orbits are the
test set (``round(n_orbits * test_split)`` of them), the rest train
(:meth:`NBodyConfig.trajectory_split`).

Evaluation: ``eval_n_orbits`` fresh orbits from the same distribution (another random
stream), ``eval_n_points`` samples over ``[0, eval_t_end]``, also from REBOUND IAS15;
``dt`` is the training data's sampling interval.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import rebound

from hnnbench import (
    CLEAN_INPUTS,
    DATA_STREAM,
    EVAL_STREAM,
    ConfigError,
    DataError,
    Dataset,
    Kinematics,
    LinearKinematics,
    System,
    SystemConfig,
    Trajectories,
    TrajectorySplit,
    check_fraction,
    check_int_at_least,
    check_ordered,
    check_positive,
    seed_stream,
    trajectory_dataset,
)

__all__ = [
    "INITS",
    "MAX_REL_ENERGY_DRIFT",
    "NBody",
    "NBodyConfig",
    "ThreeBody",
    "ThreeBodyConfig",
    "TwoBody",
    "TwoBodyConfig",
    "box_mirror_states",
    "circular_speed",
    "hamiltonian",
    "initial_states",
    "rebound_orbits",
    "ring_states",
    "triangle_states",
    "vector_field",
]

#: Gravitational constant and the mass of every body.
G = 1.0
MASS = 1.0

#: Largest relative energy drift of REBOUND ground truth a dataset may have.
MAX_REL_ENERGY_DRIFT = 1e-10

#: REBOUND stops an orbit whose bodies come closer than this (a near-collision that IAS15
#: cannot follow to MAX_REL_ENERGY_DRIFT anyway, and that could take very many steps).
ENCOUNTER_DISTANCE = 1e-6

#: Initial-state samplers (``NBodyConfig.init``): the 2019 code's (two or three bodies)
#: and hnnbench's earlier evenly spaced ring (any N).
INITS = ("2019", "ring")


# --------------------------------------------------------------------------- config


@dataclass
class NBodyConfig(SystemConfig):
    """Data and evaluation protocol of N bodies on a perturbed circular orbit."""

    n_bodies: int = 2
    #: Initial-state sampler: ``"2019"`` (the 2019 code's, two or three bodies only) or
    #: ``"ring"`` (any N); see the module docstring. The generic class defaults to
    #: ``"ring"``; :class:`TwoBodyConfig` and :class:`ThreeBodyConfig` to ``"2019"``.
    init: str = "ring"
    n_orbits: int = 1000
    t_end: float = 20.0
    n_points: int = 50
    #: Radius bounds of the ring; for ``init="2019"`` with two bodies, the bounds of EACH
    #: coordinate of body 1's position (as the original's ``min_radius``/``max_radius``).
    radius_min: float = 0.5
    radius_max: float = 1.5
    #: Relative speed perturbation: the std of ``1 + velocity_noise * N(0, 1)`` (ring;
    #: 2019 two bodies) or the half-width of ``1 + velocity_noise * U(-1, 1)`` (2019
    #: three bodies).
    velocity_noise: float = 0.05
    #: Gaussian noise added to the model inputs (targets stay clean); 0 as in the paper.
    noise_std: float = 0.0
    #: Fraction of orbits (the first ones) held out as the test set.
    test_split: float = 0.2
    eval_n_orbits: int = 15
    eval_t_end: float = 25.0
    eval_n_points: int = 500

    def validate(self) -> None:
        super().validate()
        check_positive(
            "system", t_end=self.t_end, radius_min=self.radius_min, eval_t_end=self.eval_t_end
        )
        check_int_at_least(
            "system",
            2,
            n_bodies=self.n_bodies,
            n_orbits=self.n_orbits,
            n_points=self.n_points,
            eval_n_orbits=self.eval_n_orbits,
            eval_n_points=self.eval_n_points,
        )
        check_fraction("system", "test_split", self.test_split, 0.2)
        check_ordered("system", "radius_min", self.radius_min, "radius_max", self.radius_max)
        if str(self.init) not in INITS:
            raise ConfigError(
                f"system.init='{self.init}' is invalid: expected one of {', '.join(INITS)} "
                "(see docs/SYSTEMS_NBODY.md)."
            )
        if str(self.init) == "2019" and self.n_bodies not in (2, 3):
            raise ConfigError(
                f"system.init=2019 with system.n_bodies={self.n_bodies} is invalid: the 2019 "
                "samplers exist for two and three bodies only. Use system.init=ring."
            )
        for key in ("velocity_noise", "noise_std"):
            if not getattr(self, key) >= 0:
                raise ConfigError(
                    f"system.{key}={getattr(self, key)} is invalid: expected a number >= 0. "
                    f"Fix it with system.{key}=0 or another non-negative value."
                )
        self.trajectory_split().check(self.n_orbits, count_key="n_orbits", unit="orbits")

    def trajectory_split(self) -> TrajectorySplit:
        """The FIRST ``round(n_orbits * test_split)`` orbits test, the rest train."""
        return TrajectorySplit(self.test_split, test_from="first")


@dataclass
class TwoBodyConfig(NBodyConfig):
    """Paper settings: 1000 orbits x 50 points over [0, 20]; body 1 in [0.5, 1.5]^2;
    20000 steps (the paper: 10000)."""

    n_bodies: int = 2
    init: str = "2019"
    n_orbits: int = 1000
    t_end: float = 20.0
    n_points: int = 50
    radius_min: float = 0.5
    radius_max: float = 1.5
    velocity_noise: float = 0.05
    test_split: float = 0.2
    eval_t_end: float = 25.0
    eval_n_points: int = 500
    #: Twice the paper's 10000: a pilot (two seeds of every family) found most families'
    #: validation criterion still falling over the last 20 % of 10000 steps (docs/
    #: SYSTEMS_NBODY.md, "Training budget"); raised for every family alike.
    steps: int = 20000
    batch_size: int = 200
    weight_decay: float = 0.0


@dataclass
class ThreeBodyConfig(NBodyConfig):
    """Paper settings: 5000 orbits x 20 points over [0, 5], radius U[0.9, 1.2]."""

    n_bodies: int = 3
    init: str = "2019"
    n_orbits: int = 5000
    t_end: float = 5.0
    n_points: int = 20
    radius_min: float = 0.9
    radius_max: float = 1.2
    velocity_noise: float = 0.2
    test_split: float = 0.2
    eval_t_end: float = 3.0
    eval_n_points: int = 500
    steps: int = 10000
    batch_size: int = 600
    weight_decay: float = 1e-4


# --------------------------------------------------------------------------- physics


def _split(x: np.ndarray, n_bodies: int) -> tuple[np.ndarray, np.ndarray]:
    """``(..., 4N)`` states -> positions and momenta, each ``(..., N, 2)``."""
    x = np.asarray(x, dtype=np.float64)
    if x.shape[-1] != 4 * n_bodies:
        raise ValueError(
            f"expected states with {4 * n_bodies} numbers for {n_bodies} bodies, "
            f"got shape {x.shape}"
        )
    lead = x.shape[:-1]
    q = x[..., : 2 * n_bodies].reshape(*lead, n_bodies, 2)
    p = x[..., 2 * n_bodies :].reshape(*lead, n_bodies, 2)
    return q, p


def hamiltonian(x: np.ndarray, n_bodies: int) -> np.ndarray:
    """``H`` of ``(..., 4N)`` states, shape ``(...)``."""
    q, p = _split(x, n_bodies)
    kinetic = np.sum(p**2, axis=(-1, -2)) / (2.0 * MASS)
    i, j = np.triu_indices(n_bodies, k=1)
    dist = np.linalg.norm(q[..., i, :] - q[..., j, :], axis=-1)
    potential = -G * MASS * MASS * np.sum(1.0 / dist, axis=-1)
    return kinetic + potential


def accelerations(q: np.ndarray) -> np.ndarray:
    """Gravitational accelerations ``(..., N, 2)`` of bodies at positions ``(..., N, 2)``."""
    n = q.shape[-2]
    diff = q[..., None, :, :] - q[..., :, None, :]  # [..., i, j] = q_j - q_i
    dist2 = np.sum(diff**2, axis=-1)
    dist2[..., np.arange(n), np.arange(n)] = np.inf  # no self-force
    inv_r3 = dist2**-1.5
    return G * MASS * np.sum(diff * inv_r3[..., None], axis=-2)


def vector_field(x: np.ndarray, n_bodies: int) -> np.ndarray:
    """``dx/dt = (p / m, F)`` of ``(..., 4N)`` states (F: gravitational forces), same shape."""
    q, p = _split(x, n_bodies)
    lead = q.shape[:-2]
    dq = p / MASS
    dp = MASS * accelerations(q)
    return np.concatenate(
        [dq.reshape(*lead, 2 * n_bodies), dp.reshape(*lead, 2 * n_bodies)], axis=-1
    )


def circular_speed(radius: np.ndarray, n_bodies: int) -> np.ndarray:
    """Speed of N equal masses on a uniformly rotating ring of ``radius`` (G = m = 1).

    Body 0 feels ``sum_k G m / d_k^2`` toward the centre times ``sin(pi k / N)``, with
    ``d_k = 2 r sin(pi k / N)``; equating it to ``v^2 / r`` gives ``v = sqrt(G m S / (4 r))``,
    ``S = sum_k 1 / sin(pi k / N)``.
    """
    k = np.arange(1, n_bodies)
    s = np.sum(1.0 / np.sin(np.pi * k / n_bodies))
    return np.sqrt(G * MASS * s / (4.0 * np.asarray(radius, dtype=np.float64)))


def ring_states(
    rng: np.random.Generator,
    n: int,
    n_bodies: int,
    radius_min: float,
    radius_max: float,
    velocity_noise: float,
) -> np.ndarray:
    """``(n, 4N)`` perturbed circular-ring initial states (see the module docstring)."""
    radius = rng.uniform(radius_min, radius_max, size=n)
    phase = rng.uniform(0.0, 2.0 * np.pi, size=n)
    factor = 1.0 + velocity_noise * rng.standard_normal((n, n_bodies))
    angle = phase[:, None] + 2.0 * np.pi * np.arange(n_bodies)[None, :] / n_bodies  # (n, N)
    radial = np.stack([np.cos(angle), np.sin(angle)], axis=-1)  # (n, N, 2)
    tangential = np.stack([-np.sin(angle), np.cos(angle)], axis=-1)
    q = radius[:, None, None] * radial
    speed = circular_speed(radius, n_bodies)[:, None] * factor  # (n, N)
    p = MASS * speed[..., None] * tangential
    return np.concatenate([q.reshape(n, -1), p.reshape(n, -1)], axis=1)


def _rotate(v: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """``(..., 2)`` vectors rotated counter-clockwise by ``angle`` (broadcast over ``...``)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def box_mirror_states(
    rng: np.random.Generator, n: int, box_min: float, box_max: float, velocity_noise: float
) -> np.ndarray:
    """``(n, 8)`` two-body initial states as the 2019 code drew them (``init="2019"``).

    Body 1 at ``q`` with both coordinates ``U[box_min, box_max]``, moving counter-clockwise
    (perpendicular to ``q``) at the circular speed ``1 / (2 sqrt(|q|))`` times ONE factor
    ``1 + velocity_noise * N(0, 1)``; body 2 at ``(-q, -v)``. The centre of mass is at the
    origin and at rest.
    """
    q1 = rng.uniform(box_min, box_max, size=(n, 2))
    factor = 1.0 + velocity_noise * rng.standard_normal(n)
    r = np.linalg.norm(q1, axis=1)
    speed = circular_speed(r, 2) * factor
    v1 = _rotate(q1, np.pi / 2) * (speed / r)[:, None]
    q = np.stack([q1, -q1], axis=1)  # (n, 2, 2)
    p = MASS * np.stack([v1, -v1], axis=1)
    return np.concatenate([q.reshape(n, -1), p.reshape(n, -1)], axis=1)


def triangle_states(
    rng: np.random.Generator,
    n: int,
    radius_min: float,
    radius_max: float,
    velocity_noise: float,
) -> np.ndarray:
    """``(n, 12)`` three-body initial states as the 2019 code drew them (``init="2019"``).

    Body 1 at radius ``U[radius_min, radius_max]`` in the direction of a uniform point of
    the square ``[-1, 1]^2`` (so diagonal directions are twice as likely as the axes),
    bodies 2 and 3 rotated by 120 and 240 degrees; each moves counter-clockwise at the
    circular speed of the triangle, and each velocity component is then multiplied by its
    own ``1 + velocity_noise * U(-1, 1)``. Positions sum to zero; velocities need not.
    """
    u = rng.uniform(-1.0, 1.0, size=(n, 2))
    radius = rng.uniform(radius_min, radius_max, size=n)
    factor = 1.0 + velocity_noise * rng.uniform(-1.0, 1.0, size=(n, 3, 2))
    q1 = u * (radius / np.linalg.norm(u, axis=1))[:, None]
    angles = 2.0 * np.pi * np.arange(3) / 3.0
    q = _rotate(q1[:, None, :], angles[None, :])  # (n, 3, 2)
    speed = circular_speed(radius, 3)
    v = _rotate(q, np.pi / 2) * (speed / radius)[:, None, None] * factor
    p = MASS * v
    return np.concatenate([q.reshape(n, -1), p.reshape(n, -1)], axis=1)


def initial_states(
    rng: np.random.Generator,
    n: int,
    n_bodies: int,
    init: str,
    radius_min: float,
    radius_max: float,
    velocity_noise: float,
) -> np.ndarray:
    """``(n, 4N)`` initial states from the sampler ``init`` (one of :data:`INITS`)."""
    init = str(init)
    if init == "ring":
        return ring_states(rng, n, n_bodies, radius_min, radius_max, velocity_noise)
    if init == "2019" and n_bodies == 2:
        return box_mirror_states(rng, n, radius_min, radius_max, velocity_noise)
    if init == "2019" and n_bodies == 3:
        return triangle_states(rng, n, radius_min, radius_max, velocity_noise)
    raise ConfigError(
        f"system.init='{init}' with system.n_bodies={n_bodies} has no sampler: "
        "init=2019 exists for two and three bodies, init=ring for any number."
    )


# --------------------------------------------------------------------------- REBOUND


def _new_simulation() -> rebound.Simulation:
    sim = rebound.Simulation()
    sim.G = G
    sim.integrator = "ias15"
    # REBOUND 5's default step rule (PRS23) can stall on symmetric states.
    sim.integrator.adaptive_mode = "global"
    sim.exit_min_distance = ENCOUNTER_DISTANCE
    return sim


def rebound_orbits(x0: np.ndarray, t: np.ndarray, n_bodies: int) -> tuple[np.ndarray, np.ndarray]:
    """Integrate each initial state of ``x0`` ``(M, 4N)`` over ``t`` with REBOUND IAS15.

    One simulation per orbit, stopping exactly at each time of ``t`` (``t[0]`` is the time
    of ``x0``). Nothing is rejected here.

    Returns:
        ``(M, T, 4N)`` states and ``(M,)`` relative energy drifts ``max_t |E(t) - E(0)| /
        |E(0)|`` (REBOUND's ``sim.energy()``). The drift is ``inf`` where a pair came
        closer than :data:`ENCOUNTER_DISTANCE` (REBOUND stops; that orbit's states after
        the stop are NaN) or a state is not finite.
    """
    x0 = np.asarray(x0, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    m, n_t, nb = x0.shape[0], t.shape[0], n_bodies
    out = np.full((m, n_t, 4 * nb), np.nan)
    out[:, 0] = x0
    buf = np.zeros((nb, 6))  # x, y, z, vx, vy, vz of each particle
    drift = np.zeros(m)
    q0, p0 = _split(x0, nb)
    v0 = p0 / MASS
    for k in range(m):
        sim = _new_simulation()
        sim.t = float(t[0])
        for i in range(nb):
            sim.add(m=MASS, x=q0[k, i, 0], y=q0[k, i, 1], vx=v0[k, i, 0], vy=v0[k, i, 1])
        e0 = sim.energy()
        worst = 0.0
        row = out[k]
        try:
            for j in range(1, n_t):
                sim.integrate(t[j], exact_finish_time=1)
                sim.serialize_particle_data(xyzvxvyvz=buf)
                row[j, : 2 * nb] = buf[:, 0:2].reshape(-1)
                row[j, 2 * nb :] = MASS * buf[:, 3:5].reshape(-1)
                worst = max(worst, abs(sim.energy() - e0))
        except rebound.Encounter:
            worst = np.inf
        drift[k] = worst / abs(e0) if np.all(np.isfinite(row)) else np.inf
    return out, drift


def ias15_epsilon() -> float:
    """IAS15's accuracy parameter as used here (REBOUND's default)."""
    return float(_new_simulation().integrator.epsilon)


def _reference_meta() -> dict[str, Any]:
    return {
        "reference": "REBOUND IAS15",
        "rebound_version": str(rebound.__version__),
        "ias15_adaptive_mode": "global",
        "ias15_epsilon": ias15_epsilon(),
        "max_rel_energy_drift_limit": MAX_REL_ENERGY_DRIFT,
        "encounter_distance": ENCOUNTER_DISTANCE,
    }


def min_pair_distance(states: np.ndarray, n_bodies: int) -> float:
    """Smallest distance between two bodies over all ``(..., 4N)`` states."""
    q, _ = _split(states, n_bodies)
    i, j = np.triu_indices(n_bodies, k=1)
    return float(np.min(np.linalg.norm(q[..., i, :] - q[..., j, :], axis=-1)))


# --------------------------------------------------------------------------- systems


class NBody(System):
    """N equal point masses in 2-D under Newtonian gravity (G = m = 1).

    ``Config.n_bodies`` sets N; :class:`TwoBody` and :class:`ThreeBody` are the paper's
    tasks.
    """

    Config: ClassVar[type[SystemConfig]] = NBodyConfig
    cfg: NBodyConfig
    # 2: TwoBody and ThreeBody draw initial states with the 2019 code's samplers
    # (init="2019"); init="ring" reproduces version 1's data bit for bit.
    version = "2"
    description = "N bodies in 2-D under Newtonian gravity, G = m = 1 (REBOUND IAS15 data)"
    time_reversible = True
    # Every orbit turns counter-clockwise, so the momentum-flipped states the
    # reversibility test starts from (clockwise orbits) are outside the training data:
    # the test is out of distribution here (docs/SYSTEMS_NBODY.md, "Reversibility").
    reversal_in_distribution = False
    profiles: ClassVar[dict[str, dict[str, Any]]] = {
        "quick": {"n_orbits": 100, "steps": 300, "eval_n_orbits": 5, "eval_n_points": 100}
    }

    @property
    def n_bodies(self) -> int:
        return int(self.cfg.n_bodies)

    @property
    def dof(self) -> int:
        return 2 * self.n_bodies

    def energy(self, x: np.ndarray) -> np.ndarray:
        return hamiltonian(x, self.n_bodies)

    def vector_field(self, x: np.ndarray) -> np.ndarray:
        return vector_field(x, self.n_bodies)

    def kinematics(self) -> Kinematics:
        """``q̇ = p / m``."""
        return LinearKinematics(1.0 / MASS)

    def initial_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``(n, 4N)`` initial states drawn from the protocol's distribution."""
        c = self.cfg
        return initial_states(
            rng, n, self.n_bodies, c.init, c.radius_min, c.radius_max, c.velocity_noise
        )

    @property
    def data_dt(self) -> float:
        """Sampling interval of the training data."""
        return float(self.cfg.t_end) / (self.cfg.n_points - 1)

    def ground_truth(
        self, rng: np.random.Generator, n: int, t: np.ndarray
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """``n`` REBOUND orbits over ``t`` from fresh initial states, and their metadata.

        An orbit whose relative energy drift exceeds :data:`MAX_REL_ENERGY_DRIFT` (in
        practice: a near-collision, closer than ~1e-4) is replaced by a new draw from
        ``rng``, so the result is deterministic given the generator's state. Raises
        :class:`DataError` if more than :func:`max_rejections` orbits are replaced.
        """
        nb = self.n_bodies
        states, drift = rebound_orbits(self.initial_states(rng, n), t, nb)
        bad = np.flatnonzero(~(drift <= MAX_REL_ENERGY_DRIFT))
        n_rejected = 0
        limit = max_rejections(n)
        while bad.size:
            n_rejected += int(bad.size)
            if n_rejected > limit:
                raise DataError(
                    f"{self.name}: {n_rejected} of {n} REBOUND IAS15 orbits broke the "
                    f"energy-drift limit {MAX_REL_ENERGY_DRIFT:g} (near-collisions), more "
                    f"than the {limit} allowed: lower system.velocity_noise or "
                    "system.t_end, or raise system.radius_min."
                )
            new_states, new_drift = rebound_orbits(self.initial_states(rng, bad.size), t, nb)
            states[bad], drift[bad] = new_states, new_drift
            bad = bad[~(new_drift <= MAX_REL_ENERGY_DRIFT)]
        worst = int(np.argmax(drift))
        if not drift[worst] <= MAX_REL_ENERGY_DRIFT:  # unreachable; a last guard
            raise DataError(
                f"{self.name}: REBOUND ground truth drifted in energy by {drift[worst]:.3g}, "
                f"above {MAX_REL_ENERGY_DRIFT:g}."
            )
        info = {
            "init": str(self.cfg.init),
            **_reference_meta(),
            "max_rel_energy_drift": float(drift[worst]),
            "n_rejected_orbits": n_rejected,
            "min_pair_distance": min_pair_distance(states, nb),
        }
        return states, info

    def dataset(self, seed: int) -> Dataset:
        c = self.cfg
        rng = seed_stream(seed, DATA_STREAM)  # initial states (and redraws), then the noise
        t = np.linspace(0.0, c.t_end, c.n_points)
        states, info = self.ground_truth(rng, c.n_orbits, t)  # (n_orbits, T, 4N)
        dxdt = self.vector_field(states)
        x = states
        if c.noise_std > 0:
            x = states + rng.normal(0.0, c.noise_std, size=states.shape)
        split = c.trajectory_split()
        n_train, n_test = split.sizes(c.n_orbits)
        return trajectory_dataset(
            x,
            dxdt,
            t,
            split,
            extras={CLEAN_INPUTS: states} if c.noise_std > 0 else None,
            meta={
                "dt": self.data_dt,
                "n_bodies": self.n_bodies,
                "n_train_traj": n_train,
                "n_test_traj": n_test,
                "test_orbits": split.test_from,
                **info,
            },
        )

    def evaluation(self, seed: int) -> Trajectories:
        c = self.cfg
        rng = seed_stream(seed, EVAL_STREAM)
        t = np.linspace(0.0, c.eval_t_end, c.eval_n_points)
        states, info = self.ground_truth(rng, c.eval_n_orbits, t)
        return Trajectories(
            t=t,
            states=states,
            dt=self.data_dt,
            meta={
                "horizon": float(c.eval_t_end),
                "n_traj": int(c.eval_n_orbits),
                "n_bodies": self.n_bodies,
                **info,
            },
        )


def max_rejections(n: int) -> int:
    """How many of ``n`` orbits may be redrawn before generation gives up (5%, at least 3)."""
    return max(3, int(np.ceil(0.05 * n)))


class TwoBody(NBody):
    """Two bodies on perturbed circular orbits; the paper's task 4."""

    order = 40
    Config = TwoBodyConfig
    cfg: TwoBodyConfig
    description = "Two bodies in 2-D, Newtonian gravity G = m = 1 (HNN paper, task 4; REBOUND)"
    profiles = {"quick": {"n_orbits": 100, "steps": 300, "eval_n_orbits": 5, "eval_n_points": 100}}


class ThreeBody(NBody):
    """Three bodies from a perturbed rotating triangle; the paper's three-body task."""

    order = 50
    Config = ThreeBodyConfig
    cfg: ThreeBodyConfig
    description = "Three bodies in 2-D, Newtonian gravity G = m = 1 (HNN repo README; REBOUND)"
    profiles = {"quick": {"n_orbits": 100, "steps": 300, "eval_n_orbits": 5, "eval_n_points": 100}}
