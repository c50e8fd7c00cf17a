"""Checkpoint selection in the training loop written once for every backend
(hnnbench.neural._loop.train), and the validation split it selects on
(hnnbench._contracts.datasets.with_validation)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hnnbench._contracts.datasets import MIN_VALID_TRAJECTORIES, VALID_FRACTION, with_validation
from hnnbench._contracts.plugin import Dataset, Split, TrainSettings
from hnnbench.neural._loop import train

#: Per-point offsets of the scripted criterion: the same at every checkpoint, so two
#: checkpoints differ by the same amount at every point (paired standard error 0).
OFFSETS = np.linspace(-0.05, 0.05, 20)


class ScriptedTrainer:
    """A trainer whose chunk losses are scripted per seed: ``valid[s][k]`` is the mean
    of seed ``s``'s validation criterion after chunk ``k`` (20 points, ``noise[s][k]``
    times a fixed zero-mean pattern added to each chunk's points: the paired noise);
    its training losses are 1.0, or NaN where ``nan_train[s] == k``. ``kept`` is the
    chunk index each seed's kept checkpoint was taken at."""

    def __init__(
        self,
        valid: list[list[float]],
        nan_train: dict[int, int] | None = None,
        noise: list[list[float]] | None = None,
    ):
        self.valid, self.nan_train = valid, nan_train or {}
        self.noise = noise or [[0.0] * len(v) for v in valid]
        self.chunk = -1
        self.kept = [None] * len(valid)

    def run_chunk(self, indices, length, lrs=None):
        self.chunk += 1
        losses = np.ones((len(self.valid), length))
        for s, k in self.nan_train.items():
            if k == self.chunk:
                losses[s, 1] = math.nan
        pattern = np.resize([1.0, -1.0], OFFSETS.size)  # mean 0, paired with itself
        return losses, np.array(
            [
                v[self.chunk] + OFFSETS + n[self.chunk] * pattern
                for v, n in zip(self.valid, self.noise, strict=True)
            ]
        )

    def keep(self, seeds):
        for s in np.flatnonzero(seeds):
            self.kept[s] = self.chunk


def run(trainer, chunks: int, seeds=(0,)):
    settings = TrainSettings(steps=10 * chunks, batch_size=None, lr=1e-3, weight_decay=0.0)
    return train(trainer, 100, settings, list(seeds), 10, lambda step, losses: None)


def test_the_lowest_validation_loss_is_kept_and_reported():
    trainer = ScriptedTrainer([[3.0, 1.0, 2.0, 1.5]])
    (fit,) = run(trainer, 4)
    assert fit.diverged is None and fit.steps == 40
    assert fit.selection is not None
    assert (fit.selection.step, fit.selection.val_loss) == (20, 1.0)
    assert fit.selection.evaluations == 4 and fit.selection.first_step == 10
    assert fit.selection.trained and fit.selection.stopped is None
    assert trainer.kept == [1]  # the weights after chunk 1 (step 20)
    assert fit.history["val_loss"] == [3.0, 1.0, 2.0, 1.5]


def test_a_run_best_at_its_first_evaluation_did_not_train():
    (fit,) = run(ScriptedTrainer([[1.0, 2.0, 3.0]]), 3)
    assert fit.selection is not None and fit.selection.step == 10
    assert not fit.selection.trained
    assert fit.selection.as_record()["trained"] is False


def test_a_validation_loss_never_finite_is_diverged():
    (fit,) = run(ScriptedTrainer([[math.inf, math.nan, math.inf]]), 3)
    assert fit.selection is None
    assert fit.diverged == "validation loss became inf at step 10"
    assert fit.steps == 10  # training stopped at the first non-finite loss


def test_divergence_after_a_kept_checkpoint_keeps_it_and_says_why_training_stopped():
    trainer = ScriptedTrainer([[2.0, 1.0, 0.5, 0.1]], nan_train={0: 2})
    (fit,) = run(trainer, 4)
    assert fit.diverged is None and fit.steps == 30
    assert fit.selection is not None and fit.selection.step == 20
    assert fit.selection.stopped == "training loss became nan at step 22"
    assert trainer.kept == [1]


def test_the_final_checkpoint_is_scored_unless_an_earlier_one_wins_by_two_paired_se():
    # The lowest (1.0, after chunk 1) beats the final (1.1) by 0.1; paired noise of
    # amplitude a at both checkpoints gives per-point differences 0.1 ± (a_f - a_b).
    quiet = ScriptedTrainer([[3.0, 1.0, 2.0, 1.1]], noise=[[0, 0.0, 0, 0.01]])
    (fit,) = run(quiet, 4)
    assert fit.selection.step == 20 and quiet.kept == [1]  # 0.1 >> 2 SE
    noisy = ScriptedTrainer([[3.0, 1.0, 2.0, 1.1]], noise=[[0, 0.0, 0, 1.0]])
    (fit,) = run(noisy, 4)
    sel = fit.selection
    assert sel.final_se == pytest.approx(1.0 / math.sqrt(20 - 1))  # ±1 at 20 points
    assert 0.1 < 2 * sel.final_se
    assert sel.step == 40 and noisy.kept == [3]  # not resolved: the final one is scored
    assert (sel.best_step, sel.final_step) == (20, 40)
    assert sel.best_value == pytest.approx(1.0) and sel.final_value == pytest.approx(1.1)
    assert sel.as_record()["rule"].startswith("the final checkpoint")


def test_convergence_compares_the_late_checkpoint_with_the_final_one():
    # 10 chunks of 10 steps: the late checkpoint is at step 80 (80 % of 100).
    falling = ScriptedTrainer([[10 - k for k in range(10)]])
    (fit,) = run(falling, 10)
    sel = fit.selection
    assert sel.late_step == 80 and sel.late_value == pytest.approx(3.0)
    assert sel.converged is False  # fell by 2 with no paired noise
    flat = ScriptedTrainer([[5, 4, 3, 2, 1, 1, 1, 1, 1, 1]], noise=[[0.0] * 9 + [0.01]])
    (fit,) = run(flat, 10)
    assert fit.selection.converged is True and fit.selection.as_record()["converged"] is True


def test_each_seed_of_a_batch_is_selected_on_its_own_validation_loss():
    trainer = ScriptedTrainer([[3.0, 1.0, 2.0], [1.0, 2.0, 0.5], [math.nan] * 3])
    fits = run(trainer, 3, seeds=(0, 1, 2))
    assert [f.selection.step if f.selection else None for f in fits] == [20, 30, None]
    assert trainer.kept == [1, 2, None]
    assert fits[2].diverged == "validation loss became nan at step 10"


# --------------------------------------------------------------------------- the split


def _split(n_traj: int, n_points: int) -> Split:
    traj = np.repeat(np.arange(n_traj), n_points)
    t = np.tile(np.arange(n_points, dtype=float), n_traj)
    x = np.stack([traj.astype(float), t], axis=1)
    return Split(x=x, dxdt=x.copy(), traj=traj, t=t, extras={"state": x.copy()})


@pytest.mark.parametrize("seed", [0, 1])
def test_many_trajectories_hold_out_whole_ones_drawn_from_the_seed(seed):
    data = Dataset(train=_split(25, 6), test=_split(5, 6))
    out = with_validation(data, seed)
    assert out.test is data.test and out.valid is not None
    held = set(np.unique(out.valid.traj))
    assert len(held) == round(VALID_FRACTION * 25)
    assert held.isdisjoint(np.unique(out.train.traj))
    assert len(out.train) + len(out.valid) == len(data.train)
    np.testing.assert_array_equal(out.valid.extras["state"], out.valid.x)
    assert held == set(np.unique(with_validation(data, seed).valid.traj))  # reproducible


def test_different_seeds_hold_out_different_trajectories():
    data = Dataset(train=_split(40, 3), test=_split(5, 3))
    draws = {tuple(np.unique(with_validation(data, s).valid.traj)) for s in range(5)}
    assert len(draws) > 1


def test_few_trajectories_hold_out_the_tail_of_each():
    assert MIN_VALID_TRAJECTORIES > 2
    data = Dataset(train=_split(2, 50), test=_split(1, 50))
    out = with_validation(data, 0)
    assert out.valid is not None
    for traj in (0, 1):
        valid_t = out.valid.t[out.valid.traj == traj]
        train_t = out.train.t[out.train.traj == traj]
        assert len(valid_t) == 5 and valid_t.min() > train_t.max()


def test_a_dataset_with_a_validation_split_is_refused():
    data = with_validation(Dataset(train=_split(2, 10), test=_split(1, 10)), 0)
    with pytest.raises(ValueError, match="already has a validation split"):
        with_validation(data, 0)


def test_the_validation_split_survives_save_and_load(tmp_path):
    data = with_validation(Dataset(train=_split(12, 4), test=_split(2, 4)), 3)
    data.save(tmp_path / "d.npz")
    back = Dataset.load(tmp_path / "d.npz")
    assert back.valid is not None
    np.testing.assert_array_equal(back.valid.x, data.valid.x)


def _selected(step: int, best: float, final: float, late: float, *, family: str = "hnn") -> dict:
    """A record's fields the selection table reads (schema 3), on the spring."""
    return {
        "profile": "paper",
        "system": "spring",
        "family": family,
        "status": "ok",
        "selection": {
            "criterion": "field_mse_clean",
            "points": 60,
            "step": step,
            "final_step": 2000,
            "best_value": best,
            "final_value": final,
            "final_se": 0.02,
            "late_value": late,
            "late_se": 0.1,
            "converged": late - final <= 2 * 0.1,
        },
    }


def test_the_selection_table_summarises_what_selection_resolved():
    """results/selection.md: per family, the medians of the paired z of the lowest
    checkpoint over the final one and of the late fall, the seeds scored earlier and
    converged, and where in training the scored checkpoint lies; records that name no
    criterion (schema 2) or did not finish ok are left out."""
    from hnnbench._results.report.selection import selection_frame, selection_markdown

    final_scored = _selected(2000, best=0.5, final=0.5, late=1.0)  # still falling: late_z 5
    earlier = _selected(1000, best=0.4, final=0.5, late=0.52)  # gap_z 5, converged
    legacy = {**_selected(500, 0.1, 0.2, 0.3), "selection": {"step": 500}}
    diverged = {**_selected(500, 0.1, 0.2, 0.3), "status": "diverged"}
    frame = selection_frame([final_scored, earlier, legacy, diverged])
    assert len(frame) == 1
    row = frame.iloc[0]
    assert (row["family"], row["criterion"], row["runs"]) == ("hnn", "field_mse_clean", 2)
    assert row["gap_z"] == pytest.approx(2.5)  # median of 0 and 5
    assert row["late_z"] == pytest.approx(2.6)  # median of 5 and 0.2
    assert (row["earlier"], row["converged"]) == (1, 1)
    assert row["at"] == pytest.approx(0.75)  # median of 1 and 0.5
    assert row["rel_se"] == pytest.approx(0.2)  # late_se / final
    text = selection_markdown(frame)
    assert "| 1/2 " in text and "| 0.75 " in text
    assert "No record names its selection criterion" in selection_markdown(
        selection_frame([legacy])
    )
