"""Pixel support for the PyTorch models: an autoencoder with learned latent dynamics.

On a system with ``observation == "pixels"`` (inputs are flattened pairs of consecutive
frames, e.g. 2 x 28 x 28 = 1568 numbers) a :class:`PixelTorchModel` trains, jointly:

- an MLP autoencoder (the 2019 paper's): ``D -> h -> h -> h -> 2n`` encoder whose two
  middle layers are residual (``h <- h + relu(W h + b)``), ReLU, and a mirrored decoder
  ``2n -> h -> h -> h -> D`` (linear output). ``h`` is the model's ``hidden`` (200);
  ``2n`` latents, ``n = system.dof`` (2 for the pendulum). Orthogonal init.
- the model's own latent dynamics network (the same :class:`~.torch_base.MLP` and
  ``field`` as on state systems: the baseline outputs dz/dt, the HNN a scalar H whose
  symplectic gradient is dz/dt), on the latents ``z = (z_q, z_p)``.

The objective on a pair of consecutive inputs (x, x') with ``z = enc(x), z' = enc(x')``
(the paper's three-part loss; every term a mean over batch and coordinates):

    L = mean((dec(z) - x)^2)                      reconstruction
      + mean((z_p - (z'_q - z_q))^2)              canonical coordinates
      + 0.1 * mean((z' - (z + f(z)))^2)           latent dynamics, one Euler step, dt = 1

The canonical-coordinates term follows the original code and paper: the *latent* momentum
``z_p`` is tied to the frame-to-frame change of the latent position ``z_q``, so the latent
space looks like (position, velocity).

Time units. The latent dynamics ``f`` are trained in frame steps (dt = 1, as the paper).
Through the :class:`~hnnbench.api.Model` API they are reported in the system's time:
``time_derivative(z) = f(z) / dt_frame`` and ``rollout(z0, t)`` integrates ``f`` over
``t / dt_frame`` (the same trajectory). ``dt_frame`` is ``data.meta["dt"]``, saved with
the weights. ``energy(z)`` (HNN) is the learned H in frame units (a conserved quantity; its
scale is arbitrary).

API conventions on pixel systems (the core evaluation relies on them):
``encode(obs (N, D)) -> (N, 2n)``, ``decode(z (N, 2n)) -> (N, D)``; ``time_derivative``,
``rollout`` (float64, dopri5) and ``energy`` work in latent space. ``loss(x, dxdt)`` is the
full objective above on the pairs (x, x + dt * dxdt): the pixel systems' ``dxdt`` is
``(x_next - x) / dt``, so the next input is recovered exactly up to float rounding.
Training logs the minibatch objective as ``train_loss`` and the objective on (at most
1024 evenly spaced) test points as ``test_loss``, every ``log_interval`` steps.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Optional

import numpy as np

from hnnbench.api import Dataset, FitResult, Progress, System, TrainSettings
from hnnbench.errors import ConfigError, RolloutDiverged
from hnnbench_plugins.models.neural import (
    AE_LAYERS,
    BatchStream,
    NeuralConfig,
    autoencoder_init_arrays,
)
from hnnbench_plugins.models.torch_base import TorchModel, nn, torch

#: Weights of the objective's terms (the paper's).
CC_WEIGHT = 1.0
DYNAMICS_WEIGHT = 0.1
#: Rows per forward pass when evaluating whole splits (bounds memory).
CHUNK = 4096
#: The test loss logged during training is taken on this many evenly spaced test points
#: (the whole test set costs as much as ~10 training steps; ``loss()`` uses all points).
LOG_TEST_POINTS = 1024


class Autoencoder(nn.Module):
    """MLP autoencoder ``d -> h -> (2 residual h) -> latent`` and its mirror, ReLU."""

    def __init__(self, d_obs: int, d_latent: int, hidden: int) -> None:
        super().__init__()

        def stack(d_in: int, d_out: int) -> nn.ModuleList:
            dims = [d_in] + [hidden] * (AE_LAYERS - 1) + [d_out]
            return nn.ModuleList(nn.Linear(a, b) for a, b in zip(dims[:-1], dims[1:], strict=True))

        self.encoder = stack(d_obs, d_latent)
        self.decoder = stack(d_latent, d_obs)

    @staticmethod
    def _run(layers: nn.ModuleList, x: torch.Tensor) -> torch.Tensor:
        h = torch.relu(layers[0](x))
        for layer in layers[1:-1]:
            h = h + torch.relu(layer(h))
        return layers[-1](h)

    def encode(self, x: torch.Tensor) -> torch.Tensor:
        return self._run(self.encoder, x)

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        return self._run(self.decoder, z)


class PixelTorchModel(TorchModel):
    """A :class:`TorchModel` that also runs on pixel systems (see the module docstring).

    On state systems every method is :class:`TorchModel`'s. On pixel systems ``self.net``
    is the latent dynamics network, so the inherited float64 ``time_derivative`` and
    ``rollout`` (and the HNN's ``energy``) act on latents; this class adds the
    autoencoder, the paper's objective and the time-unit conversion.
    """

    observations = ("state", "pixels")

    def __init__(self, cfg: NeuralConfig, system: System, device: str = "auto") -> None:
        super().__init__(cfg, system, device)
        self.pixels = system.observation == "pixels"
        self.autoencoder: Optional[Autoencoder] = None
        #: System time per frame step (the latent dynamics' unit of time).
        self.frame_dt = 1.0

    @property
    def latent_dim(self) -> int:
        return 2 * self.system.dof

    # -- objective --------------------------------------------------------------------
    def objective(
        self, ae: Autoencoder, net: nn.Module, x: torch.Tensor, x_next: torch.Tensor
    ) -> torch.Tensor:
        """The paper's loss on pairs of consecutive inputs ``x -> x_next`` (scalar)."""
        n = self.system.dof
        z, z_next = ae.encode(x), ae.encode(x_next)
        reconstruction = torch.mean((ae.decode(z) - x) ** 2)
        canonical = torch.mean((z[:, n:] - (z_next[:, :n] - z[:, :n])) ** 2)
        dynamics = torch.mean((z_next - (z + self.field(net, z))) ** 2)
        return reconstruction + CC_WEIGHT * canonical + DYNAMICS_WEIGHT * dynamics

    def _objective_mean(self, x: torch.Tensor, x_next: torch.Tensor) -> float:
        """The objective over a whole split, in chunks, without gradients."""
        ae, net = self._require_autoencoder(), self._require_net()
        total = 0.0
        with torch.no_grad():
            for start in range(0, x.shape[0], CHUNK):
                xb, xnb = x[start : start + CHUNK], x_next[start : start + CHUNK]
                total += float(self.objective(ae, net, xb, xnb)) * xb.shape[0]
        return total / max(1, x.shape[0])

    # -- training ---------------------------------------------------------------------
    def fit(
        self, data: Dataset, train: TrainSettings, seed: int, progress: Progress
    ) -> FitResult:
        if not self.pixels:
            return super().fit(data, train, seed, progress)
        if "dt" not in data.meta:
            raise ConfigError(f"{self.name}: pixel datasets must record meta['dt']")
        self.frame_dt = float(data.meta["dt"])
        x, x_next = self._pairs(data.train.x, data.train.dxdt, data.train.extras)
        test = data.test
        sub = np.unique(np.linspace(0, len(test) - 1, min(len(test), LOG_TEST_POINTS)).astype(int))
        x_test, x_next_test = self._pairs(
            test.x[sub], test.dxdt[sub], {k: v[sub] for k, v in test.extras.items()}
        )
        net = self.net = self.build(self.latent_dim, seed)
        ae = self.autoencoder = self._build_autoencoder(x.shape[1], seed)
        self._net64 = None
        params = [*ae.parameters(), *net.parameters()]
        opt = torch.optim.Adam(params, lr=train.lr, weight_decay=train.weight_decay)
        n = x.shape[0]
        batch = n if train.batch_size is None else min(train.batch_size, n)
        stream = None if batch == n else BatchStream(seed, n, batch)
        every = self.cfg.log_interval(train.steps)
        history: dict[str, list[float]] = {"step": [], "train_loss": [], "test_loss": []}
        for step in range(1, train.steps + 1):
            if stream is None:
                xb, xnb = x, x_next
            else:
                idx = torch.from_numpy(stream.next()).to(self._device)
                xb, xnb = x[idx], x_next[idx]
            loss = self.objective(ae, net, xb, xnb)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            if step % every == 0 or step == train.steps:
                train_loss = float(loss.detach())
                test_loss = self._objective_mean(x_test, x_next_test)
                history["step"].append(step)
                history["train_loss"].append(train_loss)
                history["test_loss"].append(test_loss)
                progress(step, {"train_loss": train_loss, "test_loss": test_loss})
                if not (np.isfinite(train_loss) and np.isfinite(test_loss)):
                    raise RolloutDiverged(f"training loss became {train_loss} at step {step}")
        self._net64 = None
        return FitResult(history=history, steps=train.steps)

    def _pairs(
        self, x: np.ndarray, dxdt: np.ndarray, extras: dict[str, np.ndarray]
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``(x, x_next)`` tensors: ``extras["x_next"]`` if present, else x + dt * dxdt."""
        x_next = extras.get("x_next")
        if x_next is None:
            x_next = np.asarray(x) + self.frame_dt * np.asarray(dxdt)
        return self._tensor(x), self._tensor(x_next)

    def _build_autoencoder(self, d_obs: int, seed: int = 0) -> Autoencoder:
        """The seeded initial autoencoder (the same weights as the JAX twin's)."""
        ae = Autoencoder(d_obs, self.latent_dim, self.cfg.hidden)
        ae = ae.to(device=self._device, dtype=self._dtype)
        arrays = autoencoder_init_arrays(seed, d_obs, self.latent_dim, self.cfg.hidden)
        ae.load_state_dict({k: torch.from_numpy(v) for k, v in arrays.items()})  # casts
        return ae

    def _require_autoencoder(self) -> Autoencoder:
        if self.autoencoder is None:
            raise RuntimeError(f"{self.name}: call fit() or load() first")
        return self.autoencoder

    # -- inference --------------------------------------------------------------------
    def loss(self, x: np.ndarray, dxdt: np.ndarray) -> float:
        if not self.pixels:
            return super().loss(x, dxdt)
        return self._objective_mean(*self._pairs(x, dxdt, {}))

    def time_derivative(self, x: np.ndarray) -> np.ndarray:
        out = super().time_derivative(x)
        return out / self.frame_dt if self.pixels else out

    def rollout(
        self, x0: np.ndarray, t: np.ndarray, rtol: float = 1e-9, atol: float = 1e-9
    ) -> np.ndarray:
        if self.pixels:
            t = np.asarray(t, dtype=np.float64) / self.frame_dt
        return super().rollout(x0, t, rtol=rtol, atol=atol)

    def _map(self, fn: Callable[[torch.Tensor], torch.Tensor], a: np.ndarray) -> np.ndarray:
        out = []
        with torch.no_grad():
            for start in range(0, a.shape[0], CHUNK):
                out.append(fn(self._tensor(a[start : start + CHUNK])).cpu().numpy())
        return np.concatenate(out).astype(np.float64) if out else np.zeros((0, 0))

    def encode(self, obs: np.ndarray) -> np.ndarray:
        if not self.pixels:
            return super().encode(obs)
        return self._map(self._require_autoencoder().encode, np.asarray(obs))

    def decode(self, z: np.ndarray) -> Optional[np.ndarray]:
        if not self.pixels:
            return super().decode(z)
        return self._map(self._require_autoencoder().decode, np.asarray(z))

    # -- persistence ------------------------------------------------------------------
    def save(self, path: Path) -> None:
        if not self.pixels:
            return super().save(path)
        from safetensors.torch import save_file

        tensors = {}
        for prefix, module in (("dynamics.", self._require_net()),
                               ("autoencoder.", self._require_autoencoder())):
            for key, value in module.state_dict().items():
                tensors[prefix + key] = value.detach().cpu().contiguous()
        save_file(tensors, str(path), metadata={"frame_dt": repr(self.frame_dt)})

    def load(self, path: Path) -> None:
        if not self.pixels:
            return super().load(path)
        from safetensors import safe_open
        from safetensors.torch import load_file

        with safe_open(str(path), framework="pt") as fh:
            meta = fh.metadata() or {}
        state = load_file(str(path))

        def part(prefix: str) -> dict[str, torch.Tensor]:
            return {k[len(prefix):]: v for k, v in state.items() if k.startswith(prefix)}

        ae_state = part("autoencoder.")
        net = self.build(self.latent_dim, seed=0)
        net.load_state_dict(part("dynamics."))
        ae = self._build_autoencoder(ae_state["encoder.0.weight"].shape[1])
        ae.load_state_dict(ae_state)
        self.net, self._net64, self.autoencoder = net, None, ae
        self.frame_dt = float(meta.get("frame_dt", 1.0))
