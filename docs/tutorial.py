# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # hnnbench in a notebook
#
# This tutorial trains a plain MLP and a Hamiltonian neural network (HNN) on the ideal
# mass-spring, looks at the true energy along their rollouts, loads a sweep into pandas,
# and puts a model of your own on the leaderboard. It uses the `quick` profile (seconds
# per job); `profile="paper"` gives the 2019 paper's settings. CI runs this notebook
# (`tests/unit/test_tutorial.py`), so it stays in step with the code.
#
# Everything here goes through the same machinery as the `hnnbench` command: the
# records a notebook writes are the ones the CLI writes. (The stored notebook shows each
# cell's results; the log lines the jobs print while they run are left out of it.)

# %%
import os
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import hnnbench

OUT = Path(os.environ.get("HNNBENCH_TUTORIAL_OUT", "results/runs/tutorial")).resolve()
print("hnnbench", hnnbench.__version__, "- records go to", os.path.relpath(OUT))

# %% [markdown]
# ## 1. Train an MLP and an HNN on the spring
#
# `hnnbench.run` runs one job (as `hnnbench system=spring model=... profile=quick`) and
# returns its record: metrics, timings, the resolved config, versions.

# %%
records = {}
for model in ("mlp_jax", "hnn_jax"):
    records[model] = hnnbench.run(
        "spring", model, seed=0, profile="quick", out=OUT / "spring" / model
    )
    m = records[model]["metrics"]
    print(
        f"{model:8s} status={records[model]['status']}  test_loss={m['test_loss']['mean']:.3g}"
        f"  energy_mse={m['energy_mse']['mean']:.3g}"
    )

# %% [markdown]
# ## 2. The true energy along each rollout
#
# Each job also writes `rollout.npz`: the evaluation trajectories, the model's rollouts
# from the same initial states, and the true energy `E = q² + p²` along both. An HNN
# conserves its learned energy, so the true energy along its rollout stays nearly flat;
# the MLP's drifts.

# %%
fig, axes = plt.subplots(1, 3, figsize=(12, 3.2), sharey=True)
for k, ax in enumerate(axes):
    for model, style in (("mlp_jax", "-"), ("hnn_jax", "-")):
        arrays = np.load(OUT / "spring" / model / "rollout.npz")
        ax.plot(arrays["t"], arrays["energy_hat"][k], style, label=model)
    ax.plot(arrays["t"], arrays["energy_true"][k], "k--", label="truth")
    ax.set_title(f"evaluation trajectory {k + 1}")
    ax.set_xlabel("time")
axes[0].set_ylabel("true energy along the rollout")
axes[0].legend()
plt.tight_layout()
plt.show()

# %% [markdown]
# ## 3. A sweep, loaded into pandas
#
# `hnnbench.sweep` runs a Hydra sweep (any launcher) and returns its leaderboard: one
# row per system × model, mean and std over seeds. `hnnbench.load` reads any
# directories of records back, one row per record.

# %%
board = hnnbench.sweep(
    ["spring", "pendulum"],
    ["mlp_jax", "hnn_jax", "oracle"],
    seeds=[0, 1],
    profile="quick",
    out=OUT / "sweep",
)
board[["system", "model", "n_seeds", "test_loss_mean", "energy_mse_mean", "energy_mse_std"]]

# %%
frame = hnnbench.load(OUT / "sweep")
frame.groupby(["system", "model"])["energy_mse"].describe()[["count", "mean", "min", "max"]]

# %% [markdown]
# ## 4. Your own model on the leaderboard, in ten lines
#
# A model is a `hnnbench.Model` with `fit`, `time_derivative` and `rollout`. This one
# fits a linear field `dx/dt = A x + b` by least squares. `hnnbench.register` adds it
# to this process (a package would declare an entry point instead: docs/PLUGINS.md);
# from then on it is a model like any other, with every metric computed by the core.


# %%
class Linear(hnnbench.Model):
    """dx/dt = A x + b by least squares (no training loop)."""

    def fit(self, data, train, seed, progress):
        design = np.c_[data.train.x, np.ones(len(data.train))]
        self.coef = np.linalg.lstsq(design, data.train.dxdt, rcond=None)[0]
        return hnnbench.FitResult(steps=0)

    def time_derivative(self, x):
        return x @ self.coef[:-1] + self.coef[-1]

    def rollout(self, x0, t, rtol=1e-9, atol=1e-9):
        return hnnbench.solve_batch(
            self.time_derivative, x0, t, rtol=rtol, atol=atol, method="RK45"
        )


hnnbench.register("model", "linear", Linear)

# %%
board = hnnbench.sweep(
    ["spring", "pendulum"],
    ["linear", "mlp_jax", "hnn_jax"],
    seeds=[0, 1],
    profile="quick",
    out=OUT / "sweep",
)  # resumes: only `linear` runs
board[["system", "model", "status", "test_loss_mean", "energy_mse_mean"]]

# %% [markdown]
# On the spring the true field *is* linear (`dq/dt = 2p`, `dp/dt = -2q`), so least
# squares recovers it almost exactly and conserves energy as well as the HNN; on the
# pendulum (`dp/dt = -3 sin q`) it cannot. `hnnbench report DIR` turns the same records
# into the HTML leaderboard and its figures.
