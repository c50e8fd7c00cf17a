"""scripts/maintainer/publish_results.py, imported for the publishing tests
(tests/unit/test_publish_script.py, test_publish_tuned.py,
tests/integration/test_publish_script_pages.py; their ``tree`` fixture is in
conftest.py), and what a tuned study leaves for them to publish."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from conftest import REPO
from report_fixtures import write_run

sys.path.insert(0, str(REPO / "scripts" / "maintainer"))
import publish_results  # noqa: E402

__all__ = ["TRIALS", "publish_results", "publish_spring_protocol", "write_study"]

TRIALS = 16


def write_study(
    out: Path,
    system: str,
    model: str,
    seeds: tuple[int, ...] = (0, 1),
    done: int | None = None,
    lr: float = 0.003,
    budget: int = TRIALS,
    fold: int | None = None,
    rollouts: tuple[int, ...] = (0,),
    **change: Any,
) -> Path:
    """What ``hnnbench tune system=S model=M out=OUT`` leaves of a study of ``done``
    (default: all) of its ``budget`` trials: its summary and, when it is finished, its
    final records (the selected ``model.lr`` on ``seeds``, those of ``rollouts`` with a
    rollout; its trials trained seeds 0 and 1).
    ``change`` overrides fields of the summary. Returns the summary's path."""
    done = budget if done is None else done
    study = f"{system}/{model}" + ("" if fold is None else f"/fold{fold}")
    selected = {"number": 3, "value": 1e-3 / 4, "settings": {"model.lr": lr}}
    trials = [
        {
            "number": n,
            "state": "complete" if n < 4 else "pruned",
            "value": 1e-3 / (n + 1),
            "settings": {"model.lr": 0.001 if n == 0 else lr},
            "protocol": n == 0,
            "cpu_s": 10.0,
            "last_step": 2000 if n < 4 else 230,
            "seed_values": [1e-3 / (n + 1)] * 2,
        }
        for n in range(done)
    ]
    summary = {
        "system": system, "model": model, "study": study, "profile": "paper",
        "trials_budget": budget, "steps": 2000, "criterion": "field_mse_clean",
        "seeds_per_trial": 2, "trial_seeds": [0, 1], "fold": fold,
        "final_seeds": list(seeds), "protocol_trial": 0, "protocol_value": 1e-3,
        "selected": selected if done >= budget else None, "trials": trials, **change,
    }  # fmt: skip
    path = out / "tuning" / system / publish_results.summary_name(model, fold)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(summary))
    if done < budget:
        return path
    for seed in seeds:
        job = write_run(
            out / "final", system, model, seed, profile="paper", rollout=seed in rollouts
        )
        record = json.loads((job / "result.json").read_text())
        record["track"] = record["config"]["track"] = "tuned"
        record["config"]["model"]["lr"] = lr
        record["config"]["model"]["steps"] = 2000
        record["tuning"] = {
            "selected_on": "validation", "criterion": "field_mse_clean",
            "seeds_per_trial": 2, "trial_seeds": [0, 1], "protocol_trial": 0,
            "trials": budget, "steps": 2000, "space": {}, "selected": {"model.lr": lr},
            "selected_trial": 3, "study": study, "cpu_s": 100.0,
        }  # fmt: skip
        (job / "result.json").write_text(json.dumps(record))
    return path


def publish_spring_protocol(tree: Path, tmp_path: Path) -> Path:
    """Publishes spring's protocol track into the ``tree`` fixture's repository (the
    MLP, the HNN and the oracle, which has no tuned track, on seeds 0 and 1); returns
    its results folder."""
    protocol = tmp_path / "protocol"
    for model in ("mlp_jax", "hnn_jax", "oracle"):
        for seed in (0, 1):
            write_run(protocol, "spring", model, seed, profile="paper", rollout=False)
    publish_results.copy_records([protocol])
    return tree / "results"
