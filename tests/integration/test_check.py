"""``hnnbench check``: the leaderboard regression gate, on synthetic sweeps (real record
schema), through ``check.main`` and through the real console script."""

from __future__ import annotations

import shutil

import pandas as pd
import pytest
from conftest import assert_one_line_error, hnnbench
from report_fixtures import make_sweep, scale_metric, set_status

from hnnbench._results import check
from hnnbench._results.leaderboard import leaderboard
from hnnbench._results.report import load_sweep


@pytest.fixture()
def ref_sweep(tmp_path):
    """A sweep, and its leaderboard written as the reference by ``--update``."""
    sweep = make_sweep(tmp_path / "ref")
    reference = tmp_path / "reference" / "quick.csv"
    assert check.main([str(sweep), "--reference", str(reference), "--update"]) == 0
    return sweep, reference


def _copy(sweep, tmp_path, name="current"):
    return shutil.copytree(sweep, tmp_path / name)


def _compare(reference, current, **kw):
    return check.compare(check.read_reference(reference), leaderboard(load_sweep(current)), **kw)


def test_update_writes_the_leaderboard_and_identical_data_passes(ref_sweep, capsys):
    sweep, reference = ref_sweep
    written = pd.read_csv(reference)
    assert {"system", "model", "n_ok", "energy_mse_mean", "energy_mse_std"} <= set(written)
    assert len(written) == 5
    capsys.readouterr()
    assert check.main([str(sweep), "--reference", str(reference)]) == 0
    out = capsys.readouterr().out
    assert "OK, no regressions" in out and "compared 5 pair(s)" in out


def test_metric_degraded_100x_fails_naming_metric_and_factor(ref_sweep, tmp_path, capsys):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    scale_metric(current, "pendulum", "mlp_torch", "rollout_mse", 100.0)
    capsys.readouterr()
    assert check.main([str(current), "--reference", str(reference)]) == 1
    out = capsys.readouterr().out
    assert "REGRESSIONS (1)" in out
    line = next(ln for ln in out.splitlines() if ln.startswith("metric ") and "rollout_mse" in ln)
    assert "pendulum" in line and "mlp_torch" in line and "100x worse" in line
    assert "<= ref x 3" in line


def test_energy_degraded_100x_also_breaks_the_papers_claim(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    scale_metric(current, "spring", "hnn_torch", "energy_mse", 100.0)
    result = _compare(reference, current)
    kinds = {(f.check, f.metric, f.system) for f in result.regressions}
    assert ("metric", "energy_mse", "spring") in kinds
    claim = next(f for f in result.regressions if f.check == "claim")
    assert claim.system == "spring" and claim.model == "torch pair"
    assert claim.reference.startswith("reproduced") and claim.current.startswith("not reproduced")
    assert claim.limit == "baseline / HNN >= 100x"


def test_within_tolerance_passes_and_improvements_pass(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    scale_metric(current, "spring", "mlp_torch", "test_loss", 1.5)  # factor 2 allowed
    scale_metric(current, "spring", "mlp_torch", "energy_mse", 5.0)  # factor 10 allowed
    scale_metric(current, "pendulum", "hnn_torch", "energy_mse", 1e-3)  # better
    scale_metric(current, "spring", "oracle", "energy_mse", 100.0)  # 2e-16 -> 2e-14: floor
    scale_metric(current, "spring", "hnn_torch", "valid_prediction_time", 2.0)  # higher
    assert _compare(reference, current).ok


def test_losses_are_tighter_than_rollout_errors(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    scale_metric(current, "spring", "mlp_torch", "test_loss", 3.0)
    metric, claim = _compare(reference, current).regressions
    assert (metric.check, metric.metric, metric.factor) == ("metric", "test_loss", "3x worse")
    # ... and the losses are no longer "similar" (within 2x), as the paper says.
    assert (claim.check, claim.metric, claim.limit) == ("claim", "test_loss", "max / min <= 2x")


def test_same_is_two_sided_and_catches_improvements_and_status_changes(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    assert _compare(reference, sweep, same=0.0).ok  # identical records
    current = _copy(sweep, tmp_path)
    scale_metric(current, "spring", "mlp_torch", "test_loss", 1.0 + 1e-6)  # within 1e-3
    scale_metric(current, "spring", "oracle", "energy_mse", 100.0)  # below the noise floor
    assert _compare(reference, current, same=1e-3).ok
    scale_metric(current, "pendulum", "hnn_torch", "energy_mse", 0.5)  # better, but changed
    (finding,) = _compare(reference, current, same=1e-3).regressions
    assert (finding.check, finding.metric, finding.system, finding.model) == (
        "changed",
        "energy_mse",
        "pendulum",
        "hnn_torch",
    )
    assert finding.factor == "0.5 rel" and finding.limit == "within 0.001 rel"
    assert _compare(reference, current).ok  # the one-sided gate lets an improvement pass
    set_status(current, "spring", "mlp_torch", 0, "diverged")
    assert "status" in {f.check for f in _compare(reference, current, same=1.0).regressions}


def test_valid_prediction_time_is_higher_better(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    scale_metric(current, "pendulum", "hnn_torch", "valid_prediction_time", 0.2)
    (finding,) = _compare(reference, current).regressions
    assert finding.metric == "valid_prediction_time" and finding.limit == ">= ref / 3"
    assert finding.factor == "5x worse"


def test_status_regression_ok_to_diverged_fails(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    set_status(current, "spring", "hnn_torch", 1, "diverged")
    set_status(current, "pendulum", "mlp_torch", 0, "failed")
    result = _compare(reference, current)
    status = {(f.system, f.model): f for f in result.regressions if f.check == "status"}
    assert set(status) == {("spring", "hnn_torch"), ("pendulum", "mlp_torch")}
    assert status[("spring", "hnn_torch")].current == "1 ok, 1 diverged"
    assert status[("pendulum", "mlp_torch")].reference == "2 ok"


def test_all_diverged_pair_reports_infinite_metrics(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    for seed in (0, 1):
        set_status(current, "pendulum", "hnn_torch", seed, "diverged")
    result = _compare(reference, current)
    energy = next(f for f in result.regressions if f.metric == "energy_mse")
    assert energy.current == "inf" and energy.factor == "inf worse"
    # A reference that diverged itself: diverging again is no regression.
    ref2 = tmp_path / "ref2.csv"
    assert check.main([str(current), "--reference", str(ref2), "--update"]) == 0
    assert _compare(ref2, current).ok


def test_missing_pair_fails_unless_allowed(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    shutil.rmtree(current / "pendulum")
    result = _compare(reference, current)
    assert {(f.check, f.system) for f in result.regressions} >= {("missing", "pendulum")}
    allowed = _compare(reference, current, allow_missing=True)
    assert allowed.ok  # the missing pairs and their claims become information
    assert {f.check for f in allowed.info} >= {"missing", "claim"}


def test_new_pairs_and_changed_seeds_are_information(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    make_sweep(current, pairs=(("spring", "mlp_jax"), ("spring", "hnn_jax")))
    shutil.rmtree(current / "spring" / "oracle" / "seed1")
    result = _compare(reference, current)
    assert result.ok
    info = {(f.check, f.model) for f in result.info}
    assert ("new", "mlp_jax") in info and ("seeds", "oracle") in info
    # The jax pair's claims are new: not gated (they were not run in the reference).
    assert not [f for f in result.regressions if f.model == "jax pair"]


def test_claim_not_reproduced_in_reference_is_information_only(tmp_path):
    sweep = make_sweep(tmp_path / "ref")
    scale_metric(sweep, "spring", "hnn_torch", "energy_mse", 50.0)  # 4e-3 / 1e-3: 4x only
    reference = tmp_path / "ref.csv"
    check.main([str(sweep), "--reference", str(reference), "--update"])
    current = _copy(sweep, tmp_path)
    scale_metric(current, "spring", "hnn_torch", "energy_mse", 1 / 50.0)  # reproduced again
    result = _compare(reference, current)
    assert result.ok
    claim = next(f for f in result.info if f.check == "claim" and f.metric == "energy_mse")
    assert claim.reference.startswith("not reproduced")
    assert claim.current.startswith("reproduced")


def test_rules_override(ref_sweep, tmp_path, capsys):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    scale_metric(current, "pendulum", "mlp_torch", "rollout_mse", 100.0)
    rules = tmp_path / "rules.yaml"
    rules.write_text("metrics:\n  rollout_mse: {factor: 1000}\n")
    assert check.main([str(current), "--reference", str(reference), "--rules", str(rules)]) == 0
    default, metrics = check.load_rules(rules)
    assert metrics["rollout_mse"].factor == 1000
    assert metrics["rollout_mse"].floor == 1e-8  # unchanged keys keep the built-in value
    assert metrics["valid_prediction_time"].better == "higher"
    assert metrics["fit_s"].gate is False


def test_builtin_rules_cover_every_summary_metric():
    from hnnbench._contracts.names import TIMINGS
    from hnnbench._results.leaderboard import summary_metrics

    default, metrics = check.load_rules()
    assert set(summary_metrics()) | set(TIMINGS) <= set(metrics)
    assert all(r.factor >= 1 for r in metrics.values())
    assert {m for m, r in metrics.items() if r.better == "higher"} == {
        "rollout_skill",
        "valid_prediction_time",
        "vpt_censored",
        "vpt_lyapunov",
    }


def test_timings_never_gate(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    current = _copy(sweep, tmp_path)
    for path in current.rglob("result.json"):
        text = path.read_text().replace('"fit_s": 2.0', '"fit_s": 200.0')
        path.write_text(text)
    result = _compare(reference, current)
    assert result.ok and any(f.metric == "fit_s" for f in result.info)


def test_profile_mismatch_is_a_user_error(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    paper = make_sweep(tmp_path / "paper", profile="paper")
    with pytest.raises(check.CheckError, match="profile quick but the sweep ran profile paper"):
        _compare(reference, paper)


# --------------------------------------------------------------------------- CLI


def test_cli_pass_fail_and_update(ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    proc = hnnbench("check", str(sweep), "--reference", str(reference))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    current = _copy(sweep, tmp_path)
    scale_metric(current, "spring", "mlp_torch", "test_loss", 100.0)
    proc = hnnbench("check", str(current), "--reference", str(reference))
    assert proc.returncode == 1 and "test_loss" in proc.stdout and "FAILED" in proc.stdout
    assert "Traceback" not in proc.stderr
    new_ref = tmp_path / "new" / "ref.csv"
    proc = hnnbench("check", str(current), "--reference", str(new_ref), "--update")
    assert proc.returncode == 0 and new_ref.exists(), proc.stderr
    assert hnnbench("check", str(current), "--reference", str(new_ref)).returncode == 0


def _bad_inputs(tmp_path, sweep, reference):
    empty = tmp_path / "empty"
    empty.mkdir()
    wrong = tmp_path / "wrong.csv"
    pd.read_csv(reference).drop(columns=["n_ok", "system"]).to_csv(wrong, index=False)
    nometric = tmp_path / "nometric.csv"
    pd.read_csv(reference)[list(check.REQUIRED_COLUMNS)].to_csv(nometric, index=False)
    blank = tmp_path / "blank.csv"
    blank.write_text("")
    bad_rules = tmp_path / "bad.yaml"
    bad_rules.write_text("metrics:\n  energy_mse: {factr: 10}\n")
    ref = ["--reference", str(reference)]
    return {
        "missing dir": ([str(tmp_path / "nope"), *ref], ["does not exist"]),
        "no records": ([str(empty), *ref], ["No run records"]),
        "missing reference": (
            [str(sweep), "--reference", str(tmp_path / "none.csv")],
            ["none.csv does not exist", "--update"],
        ),
        "wrong columns": ([str(sweep), "--reference", str(wrong)], ["system, n_ok"]),
        "no metric columns": ([str(sweep), "--reference", str(nometric)], ["no metric"]),
        "empty reference": ([str(sweep), "--reference", str(blank)], ["is empty"]),
        "no --reference": ([str(sweep)], ["--reference"]),
        "bad rules": ([str(sweep), *ref, "--rules", str(bad_rules)], ["factr"]),
        "missing rules": (
            [str(sweep), *ref, "--rules", str(tmp_path / "r.yaml")],
            ["r.yaml does not exist"],
        ),
    }


CASES = [
    "missing dir",
    "no records",
    "missing reference",
    "wrong columns",
    "no metric columns",
    "empty reference",
    "no --reference",
    "bad rules",
    "missing rules",
]


@pytest.mark.parametrize("case", CASES)
def test_bad_input_is_one_line(case, ref_sweep, tmp_path):
    sweep, reference = ref_sweep
    args, needles = _bad_inputs(tmp_path, sweep, reference)[case]
    line = assert_one_line_error(hnnbench("check", *args), *needles)
    assert line.startswith("hnnbench: error:")


# --------------------------------------------------------------------------- real sweep


@pytest.mark.slow
def test_real_quick_sweep_passes_its_own_reference_and_catches_short_training(tmp_path):
    common = [
        "-m",
        "system=spring",
        "model=mlp_torch,hnn_torch",
        "profile=quick",
        "system.steps=50",
        "system.eval_n_traj=3",
    ]
    sweep = tmp_path / "sweep"
    proc = hnnbench(*common, f"hydra.sweep.dir={sweep}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # The end-of-sweep hook wrote the report.
    for name in ("leaderboard.csv", "leaderboard.md", "leaderboard.html", "paper_comparison.md"):
        assert (sweep / name).exists(), name
    assert (sweep / "figures" / "spring_loss.png").exists()
    reference = tmp_path / "quick.csv"
    assert hnnbench("check", str(sweep), "--reference", str(reference), "--update").returncode == 0
    proc = hnnbench("check", str(sweep), "--reference", str(reference))
    assert proc.returncode == 0, proc.stdout + proc.stderr

    degraded = tmp_path / "degraded"
    proc = hnnbench(*common, "model.steps=5", f"hydra.sweep.dir={degraded}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    proc = hnnbench("check", str(degraded), "--reference", str(reference))
    assert proc.returncode == 1, proc.stdout
    # Runs of other settings are another row (their variant comes from their config),
    # never compared as the reference's: the reference's rows went missing.
    assert "REGRESSIONS" in proc.stdout and "missing" in proc.stdout
    assert "[model.steps=5 system.eval_n_traj=3 system.steps=50]" in proc.stdout


# --------------------------------------------------------------------------- a new model


@pytest.fixture()
def family_reference(tmp_path):
    """A reference of the baseline's twins and the oracle, seeds 0-2."""
    sweep = make_sweep(
        tmp_path / "ref",
        pairs=(
            ("spring", "mlp_torch"),
            ("spring", "mlp_jax"),
            ("spring", "oracle"),
            ("pendulum", "mlp_jax"),
        ),
        seeds=(0, 1, 2),
        rollout=False,
    )
    reference = tmp_path / "ref.csv"
    assert check.main([str(sweep), "--reference", str(reference), "--update"]) == 0
    return reference


def test_a_new_model_gets_its_rank_among_the_reference_families(family_reference, tmp_path, capsys):
    new = make_sweep(
        tmp_path / "new",
        pairs=(("spring", "hnn_torch"), ("pendulum", "hnn_torch")),
        seeds=(0, 1, 2, 3, 4),
        rollout=False,
    )
    capsys.readouterr()
    assert check.main([str(new), "--reference", str(family_reference), "--allow-missing"]) == 0
    out = capsys.readouterr().out
    lines = [ln.strip() for ln in out.splitlines()]
    # The twins mlp_torch and mlp_jax are one family, the oracle is not ranked: 2 families.
    energy = next(ln for ln in lines if ln.startswith("spring energy_mse: hnn_torch"))
    assert energy.startswith("spring energy_mse: hnn_torch ranks 1 of 2 families [1]: ")
    assert energy.endswith("over 5 seeds")
    test_loss = next(ln for ln in lines if ln.startswith("spring test_loss: hnn_torch"))
    assert "ranks 2 of 2 families [1, 2]" in test_loss  # intervals overlap: either rank
    assert any(ln.startswith("verdict: hnn_torch ranks first on") for ln in lines)
    missing = [ln for ln in lines if ln.startswith("missing:")]
    assert len(missing) == 1 and "4 reference pair(s) not in this sweep" in missing[0]
    assert not any(ln.startswith("missing ") for ln in lines)  # no line per pair


def test_one_seed_has_no_interval_and_says_so(family_reference, tmp_path, capsys):
    new = make_sweep(tmp_path / "new", pairs=(("spring", "hnn_torch"),), seeds=(0,), rollout=False)
    capsys.readouterr()
    check.main([str(new), "--reference", str(family_reference), "--allow-missing"])
    out = capsys.readouterr().out
    assert "spring energy_mse: hnn_torch ranks 1 of 2 families (1 seed: no interval)" in out
    assert "no rank is backed by an interval" in out


def test_update_is_suggested_only_where_it_is_safe(family_reference, tmp_path, capsys):
    ref_sweep = tmp_path / "ref"
    partial = _copy(ref_sweep, tmp_path, "partial")
    shutil.rmtree(partial / "pendulum")
    scale_metric(partial, "spring", "mlp_jax", "rollout_mse", 100.0)
    capsys.readouterr()
    assert check.main([str(partial), "--reference", str(family_reference)]) == 1
    out = capsys.readouterr().out
    assert "--update" not in out and "would drop the 1 reference pair(s)" in out
    whole = _copy(ref_sweep, tmp_path, "whole")
    scale_metric(whole, "spring", "mlp_jax", "rollout_mse", 100.0)
    assert check.main([str(whole), "--reference", str(family_reference)]) == 1
    assert "rewrite the reference with --update" in capsys.readouterr().out
    published = tmp_path / "results"
    (published / "records").mkdir(parents=True)
    shutil.copy(family_reference, published / "leaderboard.csv")
    assert check.main([str(whole), "--reference", str(published / "leaderboard.csv")]) == 1
    out = capsys.readouterr().out
    assert "scripts/maintainer/publish_results.py" in out and "rewrite the reference" not in out


def test_a_reference_interval_column_must_hold_numbers(family_reference, tmp_path):
    frame = pd.read_csv(family_reference)
    frame["energy_mse_ci_low"] = frame["energy_mse_ci_low"].astype(object)
    frame.loc[0, "energy_mse_ci_low"] = "low"
    bad = tmp_path / "bad.csv"
    frame.to_csv(bad, index=False)
    with pytest.raises(check.CheckError, match="energy_mse_ci_low holds a non-number"):
        check.read_reference(bad)


def test_rank_intervals_count_a_diverged_family_behind_and_an_unknown_one_as_either():
    def row(model, mean, low, high, n=5):
        return {
            "profile": "paper",
            "system": "spring",
            "model": model,
            "family": model,
            "backend": "jax",
            "ranked": True,
            "n_seeds": n,
            "n_ok": n,
            "energy_mse_mean": mean,
            "energy_mse_ci_low": low,
            "energy_mse_ci_high": high,
        }

    nan, inf = float("nan"), float("inf")
    reference = pd.DataFrame(
        [
            row("a", 1e-3, 5e-4, 2e-3),
            row("b", 1e-1, 5e-2, 2e-1),
            row("c", inf, nan, nan),
            row("d", 2e-2, nan, nan, n=1),
        ]
    )
    current = pd.DataFrame([row("new", 3e-2, 1e-2, 6e-2)])
    (line, verdict) = check.rank_lines(reference, current, ["energy_mse"])
    # a is wholly better, c (diverged) wholly worse, b overlaps, d has no interval
    assert line.startswith("spring energy_mse: new ranks 3 of 5 families [2, 4]: ")
    assert verdict.startswith("verdict: new ranks first on 0 ")
