"""A third-party metric as an outside author would write it: the squared distance
between the model's rollout and the truth at the end of the evaluation horizon."""

from __future__ import annotations

import numpy as np

from hnnbench import CheckRule, Metric


def _final_state_error(ctx):
    """(M,) |x_hat(T) - x(T)|^2 of each evaluation trajectory."""
    return np.sum((ctx.states_hat()[:, -1] - ctx.traj.states[:, -1]) ** 2, axis=-1)


FINAL_STATE_ERROR = Metric(
    name="final_state_error",
    description="Squared state error at the end of the evaluation horizon",
    compute=_final_state_error,
    better="lower",
    check=CheckRule(factor=10.0, floor=1e-12),
    order=45,
)
