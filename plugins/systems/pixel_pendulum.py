"""Pixel pendulum: the ideal pendulum seen through 28 x 28 rendered frames (paper task 5).

The underlying dynamics are those of :class:`~hnnbench_plugins.systems.pendulum.Pendulum`,
H = 3 (1 - cos q) + p^2 (so dq/dt = 2p, dp/dt = -3 sin q; small-angle period
2 pi / sqrt(6) ~ 2.57). Models never see (q, p): they see pairs of consecutive frames.

Rendering (own numpy renderer, no gym): a grey-scale image, background 0, pendulum 1. The
pivot is at the image centre; q = 0 hangs straight down, q grows counter-clockwise as seen
on screen (the bob moves to the right for small q > 0). A thin rod joins the pivot to a
disk (the bob). Each pixel's value is the fraction of its area the pendulum covers,
approximated from the signed distance d (in pixels) of a sample point to the shape's edge
as ``clip(0.5 - d, 0, 1)`` (exact for a straight edge through an axis-aligned pixel), on a
``supersample x supersample`` grid of sample points per pixel averaged (box filter). The
frames are therefore anti-aliased: edge pixels hold intermediate grey values and move
continuously with q.

Data (the paper's protocol):

- ``n_traj`` trials of ``n_frames`` frames sampled every ``dt`` time units. Initial
  states are drawn like the pendulum task's (a random direction in (q, p) scaled to a
  radius uniform in ``[radius_min, radius_max]``), but with **small** radii by default,
  U[0.2, 0.6]: swings of up to ~0.6 rad (35 degrees), like the original, which kept gym
  resets with |theta_0| < pi/6 and |dtheta_0| <= 1 (amplitudes up to ~0.6 rad). The
  pendulum task's radii U[1.3, 2.3] give swings up to ~2.3 rad, beyond the horizontal.
  There the pixels are a strongly non-linear (even non-monotonic) function of q. Two
  latents then cannot be linear in (q, p), so the linear probe of the evaluation fails:
  the HNN's probe R^2 was 0.3 for q after 2000 steps. The energy MSE then measures the
  probe, not the dynamics. Set ``system.radius_min=1.3 system.radius_max=2.3`` to get
  those radii. Integrated with :func:`hnnbench.solve_batch` (DOP853,
  ``data_rtol``).
- ``dt = 0.1`` by default: a phase advance of sqrt(6) * 0.1 = 0.245 rad per frame (the
  original's gym frames: sqrt(15) * 0.05 = 0.19), ~26 frames per period, 103 frames cover
  four swings. The bob (10 px from the pivot) moves up to ~1.5 px between two frames. The
  anti-aliased frames register sub-pixel motion, so the motion within an input is
  visible.
- Model input x_k = (frame_k, frame_{k+1}) flattened, ``2 * side^2`` = 1568 numbers.
  The next input x_{k+1} = (frame_{k+1}, frame_{k+2}) is ``extras["x_next"]``, so a
  trial of ``n_frames`` frames gives ``n_frames - 2`` points (101 for 103 frames).
- ``dxdt = (x_next - x) / dt``: the forward-difference time derivative of the
  observation. Pixel models train on (x, x_next); since ``x_next = x + dt * dxdt`` the
  pair is recoverable from a split's ``(x, dxdt)`` alone.
- ``extras["state"]``: the true (q, p) at the time of frame_k, ``(N, 2)`` float64, for the
  linear probe of the evaluation.
- The FIRST ``test_split`` of the trials (20 %, ``round(n_traj * test_split)`` trials) are
  the test set, as in the paper (:meth:`PixelPendulumConfig.trajectory_split`).
- Pixel arrays (``x``, ``dxdt``, ``x_next``, ``observations``) are **float32**: they are
  large (three 20200 x 1568 arrays; ~380 MB instead of ~760 MB in float64) and pixel
  values carry no more precision. Everything else is float64.

Evaluation: ``eval_n_traj`` fresh trials (own seed stream) of ``eval_n_points`` frame
pairs, states integrated at ``eval_rtol``; ``Trajectories.states`` (M, T, 2) are the
true states at the first frame of each pair, ``observations`` (M, T, 1568) the pairs,
``dt`` the frame interval.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from hnnbench import (
    DATA_STREAM,
    EVAL_STREAM,
    Dataset,
    System,
    SystemConfig,
    Trajectories,
    TrajectorySplit,
    check_fraction,
    check_int_at_least,
    check_ordered,
    check_positive,
    seed_stream,
    solve_batch,
    trajectory_dataset,
)
from hnnbench_plugins.systems.pendulum import Pendulum, PendulumConfig

#: Geometry as fractions of the image side (28 px: rod 10.1 px, bob radius 3.1 px,
#: rod 1.4 px wide). Changing any of these changes the data: bump PixelPendulum.version.
ROD_LENGTH = 0.36
BOB_RADIUS = 0.11
ROD_HALF_WIDTH = 0.025


def render(q: np.ndarray, side: int = 28, supersample: int = 2) -> np.ndarray:
    """Anti-aliased frames of the pendulum at angles ``q``.

    Args:
        q: ``(N,)`` angles (0: hanging down).
        side: image side in pixels.
        supersample: sample points per pixel along each axis (box-filtered).

    Returns:
        ``(N, side, side)`` float32 frames in ``[0, 1]`` (row 0 is the top of the image).
    """
    q = np.asarray(q, dtype=np.float64).reshape(-1)
    # chunks keep the temporaries in cache (several times faster than one big batch)
    chunk = max(1, 2**14 // (side * supersample) ** 2)
    out = np.empty((q.shape[0], side, side), dtype=np.float32)
    for start in range(0, q.shape[0], chunk):
        out[start : start + chunk] = _render(q[start : start + chunk], side, supersample)
    return out


def _render(q: np.ndarray, side: int, s: int) -> np.ndarray:
    """:func:`render` of one chunk; lengths in sub-pixel units, in-place float32 ops."""
    n = side * s
    coord = np.arange(n, dtype=np.float32) + np.float32(0.5 - side * s / 2.0)
    dx = coord[None, None, :]  # sample columns (x to the right), relative to the pivot
    dy = coord[None, :, None]  # sample rows (y downwards)
    length = np.float32(ROD_LENGTH * n)
    half_width = np.float32(ROD_HALF_WIDTH * n)
    radius = np.float32(BOB_RADIUS * n)
    ux = np.sin(q).astype(np.float32)[:, None, None]  # unit vector pivot -> bob
    uy = np.cos(q).astype(np.float32)[:, None, None]
    along = dx * ux + dy * uy  # (N, n, n) coordinate along the rod
    across = dx * uy - dy * ux  # coordinate across the rod
    np.square(across, out=across)
    # distance to the rod's segment [0, length] (a capsule of radius half_width)
    rod = np.clip(along, 0.0, length)
    np.subtract(rod, along, out=rod)
    np.square(rod, out=rod)
    rod += across
    np.sqrt(rod, out=rod)
    # distance to the bob's centre (separable), shifted so both shapes share one offset
    bob = (dx - length * ux) ** 2 + (dy - length * uy) ** 2
    np.sqrt(bob, out=bob)
    bob -= radius - half_width
    np.minimum(rod, bob, out=rod)
    # coverage of the sample's box from the signed distance: clip(0.5 - (d - half_width))
    np.subtract(np.float32(0.5) + half_width, rod, out=rod)
    np.clip(rod, 0.0, 1.0, out=rod)
    if s == 1:
        return rod
    out = np.zeros((q.shape[0], side, side), dtype=np.float32)  # box filter
    for i in range(s):
        for j in range(s):
            out += rod[:, i::s, j::s]
    return out * np.float32(1.0 / (s * s))


@dataclass
class PixelPendulumConfig(SystemConfig):
    """Paper settings: 200 trials x 103 frames, 28 x 28, 20 % test; trained 10000 steps,
    batch 200, weight decay 1e-5. Small swings (radius U[0.2, 0.6]), see the module doc."""

    steps: int = 10000
    batch_size: Optional[int] = 200
    weight_decay: float = 1e-5
    n_traj: int = 200
    n_frames: int = 103
    dt: float = 0.1
    side: int = 28
    supersample: int = 2
    radius_min: float = 0.2
    radius_max: float = 0.6
    test_split: float = 0.2
    data_rtol: float = 1e-10
    eval_n_traj: int = 15
    eval_n_points: int = 100
    eval_rtol: float = 1e-12

    def validate(self) -> None:
        super().validate()
        check_positive(
            "system",
            dt=self.dt,
            radius_min=self.radius_min,
            data_rtol=self.data_rtol,
            eval_rtol=self.eval_rtol,
        )
        for key, low in (
            ("n_traj", 2),
            ("n_frames", 3),
            ("eval_n_traj", 1),
            ("eval_n_points", 2),
            ("side", 8),
            ("supersample", 1),
        ):
            check_int_at_least("system", low, **{key: getattr(self, key)})
        check_fraction("system", "test_split", self.test_split, 0.2)
        check_ordered("system", "radius_min", self.radius_min, "radius_max", self.radius_max)
        self.trajectory_split().check(self.n_traj, unit="trials")

    def trajectory_split(self) -> TrajectorySplit:
        """The FIRST ``round(n_traj * test_split)`` trials test, the rest train."""
        return TrajectorySplit(self.test_split, test_from="first")


class PixelPendulum(System):
    """The ideal pendulum observed as pairs of 28 x 28 frames (HNN paper, task 5)."""

    Config = PixelPendulumConfig
    order = 60
    cfg: PixelPendulumConfig
    version = "1"
    description = "Pendulum seen as 28x28 frame pairs, H = 3(1 - cos q) + p^2 (HNN paper, task 5)"
    observation = "pixels"
    time_reversible = True
    profiles = {
        "quick": {
            "n_traj": 40,
            "n_frames": 32,
            "steps": 300,
            "eval_n_traj": 5,
            "eval_n_points": 50,
        },
    }

    def __init__(self, cfg: PixelPendulumConfig) -> None:
        super().__init__(cfg)
        #: The state-space pendulum: its Hamiltonian, vector field and initial states.
        self.pendulum = Pendulum(
            PendulumConfig(name="pendulum", radius_min=cfg.radius_min, radius_max=cfg.radius_max)
        )

    @property
    def dof(self) -> int:
        return 1

    def energy(self, x: np.ndarray) -> np.ndarray:
        return self.pendulum.energy(x)

    def vector_field(self, x: np.ndarray) -> np.ndarray:
        """The true dynamics of the underlying state (q, p) (not of the pixels)."""
        return self.pendulum.vector_field(x)

    @property
    def angles(self) -> tuple[int, ...]:
        """The angle ``q`` of the underlying state (the probe's; models see latents)."""
        return (0,)

    def render(self, q: np.ndarray) -> np.ndarray:
        """``(N, side, side)`` float32 frames for angles ``q`` ``(N,)``."""
        return render(q, self.cfg.side, self.cfg.supersample)

    def _trials(
        self, rng: np.random.Generator, n_traj: int, n_frames: int, rtol: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """States ``(n_traj, n_frames, 2)``, frames ``(n_traj, n_frames, side^2)``, times."""
        t = np.arange(n_frames) * self.cfg.dt
        x0 = self.pendulum.initial_states(rng, n_traj)
        states = solve_batch(self.pendulum.vector_field, x0, t, rtol=rtol, atol=rtol)
        frames = self.render(states[..., 0].reshape(-1)).reshape(n_traj, n_frames, -1)
        return states, frames, t

    @staticmethod
    def pairs(frames: np.ndarray) -> np.ndarray:
        """``(M, F, P)`` frames -> ``(M, F - 1, 2P)`` consecutive pairs."""
        return np.concatenate([frames[:, :-1], frames[:, 1:]], axis=-1)

    def dataset(self, seed: int) -> Dataset:
        c = self.cfg
        rng = seed_stream(seed, DATA_STREAM)
        states, frames, t = self._trials(rng, c.n_traj, c.n_frames, c.data_rtol)
        pairs = self.pairs(frames)  # (n_traj, F - 1, 2P)
        x, x_next = pairs[:, :-1], pairs[:, 1:]  # (n_traj, F - 2, 2P) each
        n_pts = c.n_frames - 2
        split = c.trajectory_split()
        n_train, n_test = split.sizes(c.n_traj)
        return trajectory_dataset(
            x,
            (x_next - x) / np.float32(c.dt),
            t[:n_pts],
            split,
            extras={"state": states[:, :n_pts], "x_next": x_next},
            meta={
                "dt": float(c.dt),
                "side": c.side,
                "frame_shape": [c.side, c.side],
                "frames_per_input": 2,
                "n_train_traj": n_train,
                "n_test_traj": n_test,
                "points_per_traj": n_pts,
                "dxdt": "(x_next - x) / dt (forward difference of frame pairs)",
            },
        )

    def evaluation(self, seed: int) -> Trajectories:
        c = self.cfg
        rng = seed_stream(seed, EVAL_STREAM)
        n = c.eval_n_points
        states, frames, t = self._trials(rng, c.eval_n_traj, n + 1, c.eval_rtol)
        return Trajectories(
            t=t[:n],
            states=states[:, :n],
            dt=float(c.dt),
            observations=self.pairs(frames),
            meta={
                "horizon": float(t[n - 1]),
                "n_traj": c.eval_n_traj,
                "reference": "DOP853",
                "rtol": c.eval_rtol,
                "observation": "frame pairs (frame_k, frame_k+1)",
            },
        )
