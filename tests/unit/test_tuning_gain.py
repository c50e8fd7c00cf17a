"""The tuning gain on the selection criterion itself, read on the seeds no trial trained
(``hnnbench._results.report.tuning.tuning_gain``, its ``criterion_unseen_seeds`` row)."""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from hnnbench._results.families import Families
from hnnbench._results.leaderboard import records_frame
from hnnbench._results.report.tuning import UNSEEN_CRITERION, tuning_gain


def _rec(seed: int, track: str, criterion: float, trial_seeds: tuple[int, ...] = ()) -> dict:
    rec: dict[str, Any] = {
        "system": "spring",
        "model": "hnn_jax",
        "family": "hnn",
        "backend": "jax",
        "seed": seed,
        "profile": "paper",
        "status": "ok",
        "ranked": True,
        "track": track,
        "metrics": {"test_loss": {"mean": 1.0, "sem": 0.0}},
        "selection": {"criterion": "field_mse_clean", "validation_loss": criterion},
    }
    if track == "tuned":
        rec["tuning"] = {"selected_on": "validation", "trial_seeds": list(trial_seeds)}
    return rec


def test_the_criterion_gain_reads_only_the_seeds_no_trial_trained():
    """Seeds 0 and 1 trained the trials and look 100x better tuned (the selection's
    luck); on seeds 2-9 the tuned criterion is 2x better: the row says x2 on 8 seeds,
    and the test-loss row (unchanged) says x1 on all ten."""
    protocol = [_rec(s, "protocol", 1.0) for s in range(10)]
    tuned = [_rec(s, "tuned", 0.01 if s < 2 else 0.5, trial_seeds=(0, 1)) for s in range(10)]
    runs = records_frame([*protocol, *tuned])
    gain = tuning_gain(Families(pd.DataFrame({"family": ["hnn"]}), runs=runs))
    row = gain[gain["metric"] == UNSEEN_CRITERION].iloc[0]
    assert row["n"] == 8 and row["scale"] == "log"
    assert math.isclose(row["gain"], math.log10(2)) and math.isclose(row["low"], row["high"])
    loss = gain[gain["metric"] == "test_loss"].iloc[0]
    assert loss["n"] == 10 and loss["gain"] == 0.0
    # a measured system's fold study trains its fold's own final seeds: no unseen seed
    folds = [_rec(s, "tuned", 0.5, trial_seeds=(s % 5, s % 5 + 5)) for s in range(10)]
    gain = tuning_gain(
        Families(pd.DataFrame({"family": ["hnn"]}), runs=records_frame([*protocol, *folds]))
    )
    assert UNSEEN_CRITERION not in set(gain["metric"])
