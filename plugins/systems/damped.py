"""Linearly damped versions of the paper's spring and pendulum (non-conservative systems).

With the undamped Hamiltonian ``H`` (spring ``H = q² + p²``, pendulum
``H = 3 (1 - cos q) + p²``, the paper's units) and a damping rate ``γ`` (config
``damping``), the dynamics are

    dq/dt = ∂H/∂p = 2 p,        dp/dt = -∂H/∂q - γ p,

so ``dH/dt = -2 γ p² <= 0``: the mechanical energy ``H`` (what :meth:`energy` returns)
decays. As a second-order equation (``q̇ = 2 p``), the spring is ``q̈ + γ q̇ + 4 q = 0``:
an underdamped oscillator (``ω0 = 2``) whose amplitude decays like ``e^{-γ t / 2}`` and
whose energy, averaged over a period, decays like ``e^{-γ t}``. The default
``γ = 0.07`` halves the spring's energy every ``ln 2 / γ = 9.9`` time units; the
pendulum (mostly large swings, where less of the energy is kinetic) decays a little
more slowly (docs/SYSTEMS_DAMPED.md gives measured figures).

The data and evaluation protocols are the toy systems' (:mod:`.toy`), with the damped
field: ``n_traj`` noisy trajectories over ``[0, t_end]`` with clean dx/dt targets, and 15
evaluation trajectories over ``[0, 20]`` (about two energy half-lives: the energy ends
at about a quarter of its initial value, so the decay is visible but not complete).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hnnbench import check_positive, solve_batch
from hnnbench_plugins.systems.pendulum import Pendulum, PendulumConfig
from hnnbench_plugins.systems.spring import Spring, SpringConfig
from hnnbench_plugins.systems.toy import ToySystem

__all__ = [
    "DEFAULT_DAMPING",
    "DampedPendulum",
    "DampedPendulumConfig",
    "DampedSpring",
    "DampedSpringConfig",
    "damped_spring_solution",
    "energy_half_lives",
]

#: Default damping rate γ: the spring's energy halves every ln(2) / γ = 9.9 time units.
DEFAULT_DAMPING = 0.07


@dataclass
class DampedSpringConfig(SpringConfig):
    """The spring's paper protocol plus the damping rate ``γ`` (1 / time units)."""

    damping: float = DEFAULT_DAMPING

    def validate(self) -> None:
        super().validate()
        check_positive("system", damping=self.damping)


@dataclass
class DampedPendulumConfig(PendulumConfig):
    """The pendulum's paper protocol plus the damping rate ``γ`` (1 / time units)."""

    damping: float = DEFAULT_DAMPING

    def validate(self) -> None:
        super().validate()
        check_positive("system", damping=self.damping)


class Damped(ToySystem):
    """Mixin for a toy system: adds ``-γ p`` to ``dp/dt`` (the config's ``damping``)."""

    cfg: DampedSpringConfig | DampedPendulumConfig
    time_reversible = False
    conservative = False

    def vector_field(self, x: np.ndarray) -> np.ndarray:
        """``(2 p, -∂H/∂q - γ p)`` of states ``(..., 2)``, same shape."""
        x = np.asarray(x, dtype=np.float64)
        p = x[..., 1]
        dh_dq, dh_dp = self.grad_h(x[..., 0], p)
        return np.stack([dh_dp, -dh_dq - self.cfg.damping * p], axis=-1)


class DampedSpring(Damped, Spring):
    """Damped mass-spring: ``H = q² + p²`` decaying under ``dp/dt = -2 q - γ p``."""

    order = 70
    Config = DampedSpringConfig
    cfg: DampedSpringConfig
    version = "2"  # 2: the dataset keeps the clean inputs behind the noisy ones
    description = "Damped mass-spring, H = q^2 + p^2, dp/dt = -2q - gamma p (gamma = 0.07)"
    profiles = {"quick": {"steps": 300, "eval_n_traj": 5}}


class DampedPendulum(Damped, Pendulum):
    """Damped pendulum: ``H = 3 (1 - cos q) + p²`` decaying under
    ``dp/dt = -3 sin q - γ p``."""

    order = 80
    Config = DampedPendulumConfig
    cfg: DampedPendulumConfig
    version = "2"  # 2: the dataset keeps the clean inputs behind the noisy ones
    description = (
        "Damped pendulum, H = 3(1 - cos q) + p^2, dp/dt = -3 sin q - gamma p (gamma = 0.07)"
    )
    profiles = {"quick": {"steps": 300, "eval_n_traj": 5}}


def damped_spring_solution(x0: np.ndarray, t: np.ndarray, damping: float) -> np.ndarray:
    """Closed-form solution of the damped spring from states ``x0`` ``(M, 2)`` over
    ``t`` ``(T,)``, shape ``(M, T, 2)`` (underdamped: ``damping < 4``).

    ``q̈ + γ q̇ + 4 q = 0`` gives ``q(t) = e^{-γ t / 2} (A cos ω t + B sin ω t)`` with
    ``ω = sqrt(4 - γ² / 4)``, ``A = q0``, ``B = (q̇0 + γ q0 / 2) / ω``, ``q̇0 = 2 p0``;
    then ``p = q̇ / 2``.
    """
    x0 = np.asarray(x0, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)[None, :]
    gamma = float(damping)
    omega = np.sqrt(4.0 - gamma**2 / 4.0)
    q0, qdot0 = x0[:, :1], 2.0 * x0[:, 1:]
    a, b = q0, (qdot0 + 0.5 * gamma * q0) / omega
    decay = np.exp(-0.5 * gamma * t)
    cos, sin = np.cos(omega * t), np.sin(omega * t)
    q = decay * (a * cos + b * sin)
    qdot = -0.5 * gamma * q + decay * omega * (-a * sin + b * cos)
    return np.stack([q, 0.5 * qdot], axis=-1)


def energy_half_lives(
    system: DampedSpring | DampedPendulum, draw: str, n: int = 200, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Per trajectory: the first time ``H`` falls to half its initial value, and
    ``H(20) / H(0)``, for ``n`` initial states from the training (``draw="train"``) or
    the evaluation box (``"box"``) distribution (DOP853, rtol = atol = 1e-10, samples
    every 0.01 over [0, 40]). ``H`` never increases (``dH/dt = -2 γ p²``), so the first
    crossing is the only one.
    """
    rng = np.random.default_rng(seed)
    x0 = system.initial_states(rng, n) if draw == "train" else system.box_initial_states(rng, n)
    t = np.linspace(0.0, 40.0, 4001)
    energy = system.energy(solve_batch(system.vector_field, x0, t, rtol=1e-10, atol=1e-10))
    half = t[np.argmax(energy <= 0.5 * energy[:, :1], axis=1)]
    return half, energy[:, 2000] / energy[:, 0]


def _main() -> None:
    """Print the decay figures of docs/SYSTEMS_DAMPED.md."""
    for cls in (DampedSpring, DampedPendulum):
        system = cls(cls.Config(name=cls.__name__))
        for draw in ("train", "box"):
            half, ratio = energy_half_lives(system, draw)
            print(
                f"{cls.__name__} ({draw} draw): energy half-life median {np.median(half):.2f} "
                f"(range {half.min():.2f}-{half.max():.2f}); H(20)/H(0) median "
                f"{np.median(ratio):.3f} (range {ratio.min():.3f}-{ratio.max():.3f})"
            )


if __name__ == "__main__":
    _main()
