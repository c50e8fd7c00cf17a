"""Entry-point discovery, helpful errors, and broken plugins (with fake dist-infos)."""

from __future__ import annotations

from pathlib import Path

import pytest

from hnnbench import _registry as registry
from hnnbench._contracts.errors import HnnbenchError, UnknownNameError


def test_builtins_are_entry_points():
    systems = registry.discover("system")
    models = registry.discover("model")
    for name in ("spring", "pendulum"):
        assert systems[name].ok and systems[name].distribution == "hnnbench"
    for name in ("mlp_torch", "hnn_torch", "oracle"):
        assert models[name].ok, models[name].error
    assert models["hnn_torch"].backend == "torch"


def test_unknown_name_suggests_closest():
    with pytest.raises(UnknownNameError) as err:
        registry.get_class("system", "sprng")
    msg = str(err.value)
    assert msg.startswith("Unknown system 'sprng'. Did you mean 'spring'? Available: ")
    assert "pendulum" in msg and "\n" not in msg
    with pytest.raises(UnknownNameError, match="Did you mean 'hnn_torch'"):
        registry.get_class("model", "hnn_trch")
    with pytest.raises(UnknownNameError, match="Unknown profile 'quik'. Did you mean 'quick'"):
        registry.validate_profile("quik")


def _fake_dist(root: Path, name: str, entry_points: str) -> None:
    info = root / f"{name}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(entry_points)


def test_broken_plugin_is_reported_and_others_work(tmp_path, monkeypatch):
    _fake_dist(
        tmp_path,
        "broken_plugin",
        "[hnnbench.models]\nbroken = no_such_module_xyz:Thing\nnotamodel = json:JSONDecoder\n",
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    registry.refresh()
    try:
        models = registry.discover("model")
        assert not models["broken"].ok
        assert "No module named 'no_such_module_xyz'" in models["broken"].error
        assert "not a subclass of hnnbench.Model" in models["notamodel"].error
        assert "broken" not in registry.available("model")
        assert models["hnn_torch"].ok
        with pytest.raises(HnnbenchError, match="installed but unusable"):
            registry.get_class("model", "broken")
    finally:
        monkeypatch.undo()
        registry.refresh()
    assert "broken" not in registry.discover("model")


@pytest.mark.parametrize(
    "name, why",
    [
        ("status", "is a leaderboard column"),
        ("n_ok", "is a leaderboard column"),
        ("decay_s", "ends in '_s'"),
        ("drift_mean", "ends in '_mean'"),
        ("Energy MSE", "is not a metric name"),
    ],
)
def test_a_metric_cannot_take_a_table_column_name(name, why, monkeypatch):
    """Metrics share the records frame and the leaderboard with identity, status and
    timing columns: a colliding name is refused at registration, with the reason."""
    from hnnbench._contracts.errors import ConfigError
    from hnnbench._contracts.metric import Metric

    monkeypatch.setattr(registry.METRICS, "_registered", {})
    metric = Metric(name, "a test metric", lambda ctx: None)
    with pytest.raises(ConfigError, match=f"register: .*{why}"):
        registry.register("metric", name, metric)
    assert name not in registry.discover("metric")
    ok = Metric("decay_rate", "a test metric", lambda ctx: None)
    registry.register("metric", "decay_rate", ok)
    assert registry.discover("metric")["decay_rate"].ok
    registry.refresh()
