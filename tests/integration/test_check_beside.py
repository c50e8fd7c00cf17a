"""A rank for any submission (docs/STATISTICS.md, "A new model in hnnbench check"): a
real plugin system (``quartic``, tests/plugin_pkg, pip-installed) that the published
leaderboard has no rows for is ranked against the families run beside it in the same
sweep, with the leader test over their paired seeds; alone, it gets one line saying why
it has no rank and what to run. Records are synthetic (the real schema, the installed
plugins' configs and provenance), so the test takes seconds."""

from __future__ import annotations

import importlib
import json
import sys

import pytest
from conftest import REPO, install_test_package
from report_fixtures import seed_metrics, write_run

from hnnbench import _registry as registry
from hnnbench._results import check, stats

LEADERBOARD = REPO / "results" / "leaderboard.csv"
BESIDE = ("mlp_jax", "hnn_jax")


@pytest.fixture(scope="module")
def plugin(tmp_path_factory: pytest.TempPathFactory):
    """tests/plugin_pkg installed and importable in this process."""
    site, _ = install_test_package("plugin_pkg", tmp_path_factory)
    sys.path.insert(0, str(site))
    importlib.invalidate_caches()
    registry.refresh()
    assert "quartic" in registry.available("system")
    yield
    sys.path.remove(str(site))
    importlib.invalidate_caches()
    registry.refresh()


def _sweep(root, seeds, beside=BESIDE):
    """quartic x the plugin's model (better than the others on every seed) and
    ``beside``, paper profile, ``seeds``."""
    for seed in seeds:
        for model in beside:
            write_run(root, "quartic", model, seed, profile="paper", rollout=False)
        better = {k: v * 0.3 for k, v in seed_metrics("quartic", "hnn_jax", seed).items()}
        write_run(
            root, "quartic", "linear_lstsq", seed, profile="paper", rollout=False, metrics=better
        )
    return root


def _check(sweep, capsys, *extra: str) -> tuple[int, str]:
    capsys.readouterr()
    status = check.main([str(sweep), "--reference", str(LEADERBOARD), "--allow-missing", *extra])
    return status, capsys.readouterr().out


def test_a_new_system_ranks_against_the_families_run_beside_it(plugin, tmp_path, capsys):
    n = stats.min_separable_seeds(comparisons=len(BESIDE))  # 7: a leader vs 2 others
    status, out = _check(_sweep(tmp_path / "sweep", range(n)), capsys)
    assert status == 0, out
    lines = [line.strip() for line in out.splitlines()]
    assert (
        "quartic: the reference has no rows for system quartic; linear_lstsq ranked "
        "against the families run beside it: mlp_jax, hnn_jax"
    ) in lines
    energy = next(ln for ln in lines if ln.startswith("quartic energy_mse: linear_lstsq"))
    assert energy.startswith("quartic energy_mse: linear_lstsq ranks 1 of 3 families [1]: ")
    assert f"over {n} seeds; leader test: best (paired sign test" in energy
    # the rollout metrics are marked only where the leader beats standing still
    rollout = next(ln for ln in lines if ln.startswith("quartic rollout_mse: linear_lstsq"))
    assert "leader test: not applied (marked only where the leader beats" in rollout
    assert any(ln.startswith("verdict: linear_lstsq ranks first on 3 ") for ln in lines)
    assert "has no value on a headline metric" not in out
    # the comparators are not ranked themselves
    assert not any(
        ln.startswith(("quartic energy_mse: mlp_jax", "verdict: mlp_jax")) for ln in lines
    )


def test_too_few_seeds_is_said_and_never_marked_best(plugin, tmp_path, capsys):
    status, out = _check(_sweep(tmp_path / "sweep", range(stats.MIN_SEPARABLE_SEEDS)), capsys)
    assert status == 0, out
    energy = next(
        ln.strip() for ln in out.splitlines() if ln.strip().startswith("quartic energy_mse:")
    )
    assert "ranks 1 of 3 families [1]" in energy
    assert (
        "leader test: too few seeds to separate (6 seeds; the sign test needs 7 paired "
        "seeds against 2 other families): no best"
    ) in energy
    assert "best (paired" not in out


def test_json_says_what_a_rank_is_against(plugin, tmp_path, capsys):
    sweep = _sweep(tmp_path / "sweep", range(3))
    status, out = _check(sweep, capsys, "--format", "json")
    assert status == 0
    data = json.loads(out)
    ranks = [r for r in data["ranks"] if r["system"] == "quartic"]
    assert {r["metric"] for r in ranks} == {"test_loss", "energy_mse", "rollout_mse"}
    energy = next(r for r in ranks if r["metric"] == "energy_mse")
    assert energy["basis"] == "beside" and energy["against"] == ["mlp_jax", "hnn_jax"]
    assert (energy["rank"], energy["of"], energy["n_seeds"]) == (1, 3, 3)
    assert energy["leader_test"].startswith("too few seeds to separate")
    assert data["rank_notes"] and data["unranked"] == []


def test_alone_on_a_new_system_it_says_why_it_has_no_rank(plugin, tmp_path, capsys):
    sweep = _sweep(tmp_path / "sweep", range(2), beside=())
    status, out = _check(sweep, capsys)
    assert status == 0, out
    (line,) = [ln.strip() for ln in out.splitlines() if "no rank for" in ln]
    assert line == (
        "no rank for linear_lstsq on quartic: the reference has no rows for system quartic "
        "and no other family ran beside it on quartic; run e.g. -m system=quartic "
        "model=linear_lstsq,mlp_jax,hnn_jax seed=0,1,2,3,4,5,6 (7 paired seeds: the fewest "
        "with which the sign test can separate a leader from 2 other families)"
    )
    assert "has no value on a headline metric" not in out
