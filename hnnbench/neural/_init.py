"""Seeded initial weights and minibatch streams, drawn with numpy for every backend.

Initial weights and minibatch indices are drawn with numpy from the run's seed, so a
torch model and its JAX twin with the same seed start from the same weights (cast to
the training dtype) and see the same minibatches: a backend comparison at one seed
compares backends, not random draws. Several seeds trained as one batch draw exactly
what each would draw alone.
"""

from __future__ import annotations

import numpy as np
import threadpoolctl

from hnnbench.neural._config import NeuralConfig

__all__ = [
    "AE_LAYERS",
    "BatchStream",
    "autoencoder_init_arrays",
    "init_arrays",
    "mlp_shapes",
    "network_init_arrays",
    "orthogonal",
]

#: Seed-stream tags: ``np.random.default_rng([seed, stream])``.
INIT_STREAM, BATCH_STREAM, AE_STREAM = 0, 1, 2
#: Linear layers of each half of the pixel autoencoder (``d -> h -> h -> h -> latent``).
AE_LAYERS = 4


def orthogonal(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    """A ``(rows, cols)`` matrix with orthonormal rows or columns (whichever are fewer):
    QR of a standard-normal draw, signs fixed so the draw is unique (the algorithm of
    ``torch.nn.init.orthogonal_``).

    The QR runs on one BLAS thread whatever the caller's thread setting: OpenBLAS's
    multi-threaded QR differs from its one-thread QR in the last bits, and a sensitive
    training run (pixel pendulum) carries that difference into another basin.
    """
    rows, cols = shape
    a = rng.standard_normal((rows, cols))
    if rows < cols:
        a = a.T
    with threadpoolctl.threadpool_limits(limits=1, user_api="blas"):
        q, r = np.linalg.qr(a)
    q = q * np.sign(np.diag(r))
    return q.T if rows < cols else q


def mlp_shapes(d_in: int, d_out: int, cfg: NeuralConfig) -> dict[str, tuple[int, ...]]:
    """Parameter name -> shape of the MLP ``cfg`` describes (no bias on the last layer).

    Names and ``(out, in)`` weight shapes follow torch's ``nn.Linear`` convention; both
    backends use the same names.
    """
    dims = [d_in] + [cfg.hidden] * (cfg.layers - 1) + [d_out]
    shapes: dict[str, tuple[int, ...]] = {}
    for i, (a, b) in enumerate(zip(dims[:-1], dims[1:], strict=True)):
        shapes[f"linears.{i}.weight"] = (b, a)
        if i < cfg.layers - 1:
            shapes[f"linears.{i}.bias"] = (b,)
    return shapes


def init_arrays(
    seed: int, d_in: int, d_out: int, cfg: NeuralConfig, network: int = 0
) -> dict[str, np.ndarray]:
    """The seeded initial weights of an MLP, float64, keyed as :func:`mlp_shapes`.

    Orthogonal weights; biases ``U(-1/sqrt(fan_in), 1/sqrt(fan_in))`` (torch's
    ``nn.Linear`` default). Every backend builds its network from these arrays.
    ``network`` numbers the networks of a model (a model with one network uses 0); each
    draws from its own stream, ``[seed, INIT_STREAM]`` for the first and
    ``[seed, INIT_STREAM, k]`` for the k-th after it.
    """
    stream = [seed, INIT_STREAM] if network == 0 else [seed, INIT_STREAM, network]
    rng = np.random.default_rng(stream)
    arrays: dict[str, np.ndarray] = {}
    for name, shape in mlp_shapes(d_in, d_out, cfg).items():
        if name.endswith("weight"):
            arrays[name] = orthogonal(rng, shape)  # type: ignore[arg-type]
        else:
            bound = 1.0 / np.sqrt(arrays[name.replace("bias", "weight")].shape[1])
            arrays[name] = rng.uniform(-bound, bound, size=shape)
    return arrays


def network_init_arrays(
    seed: int, shapes: dict[str, tuple[int, int]], cfg: NeuralConfig
) -> dict[str, dict[str, np.ndarray]]:
    """Initial weights of every network of a model: ``{net: {param: array}}`` for
    ``shapes = {net: (d_in, d_out)}``, the k-th network (in ``shapes``' order) drawn with
    ``init_arrays(..., network=k)``."""
    return {
        name: init_arrays(seed, d_in, d_out, cfg, network=k)
        for k, (name, (d_in, d_out)) in enumerate(shapes.items())
    }


def autoencoder_init_arrays(
    seed: int, d_obs: int, d_latent: int, hidden: int
) -> dict[str, np.ndarray]:
    """Seeded initial weights of the pixel autoencoder, float64: orthogonal weights and
    zero biases for the encoder ``d_obs -> hidden (x3) -> d_latent`` and its mirror,
    keyed ``encoder.<i>.weight`` / ``decoder.<i>.bias`` (torch ``state_dict`` names)."""
    rng = np.random.default_rng([seed, AE_STREAM])
    arrays: dict[str, np.ndarray] = {}
    for prefix, d_in, d_out in (("encoder", d_obs, d_latent), ("decoder", d_latent, d_obs)):
        dims = [d_in] + [hidden] * (AE_LAYERS - 1) + [d_out]
        for i, (a, b) in enumerate(zip(dims[:-1], dims[1:], strict=True)):
            arrays[f"{prefix}.{i}.weight"] = orthogonal(rng, (b, a))
            arrays[f"{prefix}.{i}.bias"] = np.zeros(b)
    return arrays


class BatchStream:
    """The minibatch indices of one training run: step after step, ``batch`` distinct
    indices out of ``n`` (``Generator.choice`` without replacement, the distribution of
    torch's ``randperm(n)[:batch]``), drawn from ``[seed, BATCH_STREAM]``."""

    def __init__(self, seed: int, n: int, batch: int) -> None:
        self.rng = np.random.default_rng([seed, BATCH_STREAM])
        self.n, self.batch = n, batch

    def next(self) -> np.ndarray:
        """``(batch,)`` int64 indices of the next step."""
        return self.rng.choice(self.n, self.batch, replace=False)

    def block(self, steps: int) -> np.ndarray:
        """``(steps, batch)`` indices of the next ``steps`` steps (same draws as calling
        :meth:`next` ``steps`` times)."""
        return np.stack([self.next() for _ in range(steps)])
