"""The recipe track's pieces: the training loop's loss choice and learning-rate
schedule (the same in both backends), a family's declared recipe applied under
``track=recipe``, and the LNN paper's initialisation."""

from __future__ import annotations

import numpy as np
import pytest

from hnnbench import ConfigError
from hnnbench._contracts.plugin import TrainSettings
from hnnbench._registry.groups import config_defaults
from hnnbench._running.compose import compose, track_of_overrides
from hnnbench.neural._loop import ONE_CYCLE_FLOOR, ONE_CYCLE_START, lr_factors
from hnnbench_plugins.models.lnn import RECIPE, paper_init_arrays


def test_one_cycle_shape():
    steps = 8000
    f = lr_factors("one_cycle", steps)
    assert f.shape == (steps,)
    np.testing.assert_allclose(
        f[0], ONE_CYCLE_FLOOR + (1 - ONE_CYCLE_FLOOR) * np.sin(np.pi * ONE_CYCLE_START) ** 2
    )
    peak = int(np.argmax(f))
    assert abs(peak / steps - (0.5 - ONE_CYCLE_START) / (1 - ONE_CYCLE_START)) < 1e-3
    assert f.max() == pytest.approx(1.0, abs=1e-6)
    assert np.all(np.diff(f[:peak]) > 0) and np.all(np.diff(f[peak + 1 :]) < 0)
    assert f[-1] < 1e-3 and f.min() >= ONE_CYCLE_FLOOR
    np.testing.assert_array_equal(lr_factors("constant", 5), np.ones(5))


def test_recipe_is_the_defaults_on_the_recipe_track_only():
    lnn = config_defaults("model", "lnn_jax", "paper", "recipe")
    for key, value in RECIPE.items():
        assert getattr(lnn, key) == value, key
    protocol = config_defaults("model", "lnn_jax", "paper")
    assert (protocol.loss, protocol.lr_schedule, protocol.init, protocol.hidden) == (
        "mse",
        "constant",
        "shared",
        200,
    )
    # the smoke profile still shrinks a recipe run
    assert config_defaults("model", "lnn_jax", "quick", "recipe").hidden == 32
    # a model without a recipe keeps its defaults
    assert config_defaults("model", "mlp_jax", "paper", "recipe").loss == "mse"


def test_compose_applies_the_recipe_and_lets_the_command_line_win():
    cfg = compose(["system=pendulum", "model=lnn_torch", "track=recipe", "model.hidden=64"])
    assert cfg.track == "recipe"
    assert (cfg.model.hidden, cfg.model.loss, cfg.model.lr_schedule, cfg.model.init) == (
        64,
        "l1",
        "one_cycle",
        "paper",
    )
    assert compose(["system=pendulum", "model=lnn_torch"]).model.loss == "mse"


def test_one_track_per_sweep():
    with pytest.raises(ConfigError, match="a sweep runs one track"):
        track_of_overrides(["track=protocol,recipe"])
    with pytest.raises(ConfigError, match="expected one of protocol, tuned, recipe"):
        track_of_overrides(["track=recipes"])


def test_loss_choice_is_refused_where_the_family_has_its_own_objective():
    from hnnbench_plugins.models.srnn import SRNNJax
    from hnnbench_plugins.systems.spring import Spring, SpringConfig

    pytest.importorskip("jax")
    cfg = SRNNJax.Config(name="srnn_jax", loss="l1")
    with pytest.raises(ConfigError, match="trains on trajectory windows"):
        SRNNJax(cfg, Spring(SpringConfig(name="spring")), "cpu")
    with pytest.raises(ConfigError, match="model.loss='l2' is invalid"):
        SRNNJax.Config(name="srnn_jax", loss="l2").validate()


def test_paper_init_scales():
    shapes = {
        "linears.0.weight": (600, 4),
        "linears.0.bias": (600,),
        "linears.1.weight": (600, 600),
        "linears.1.bias": (600,),
        "linears.2.weight": (600, 600),
        "linears.2.bias": (600,),
        "linears.3.weight": (1, 600),
    }
    arrays = paper_init_arrays(3, shapes)
    assert all(np.all(arrays[k] == 0) for k in shapes if k.endswith("bias"))
    # std = scale / sqrt(n): 2.2, 0.58 * i in the middle, n for the last layer
    expected = {
        0: 2.2 / np.sqrt(600),
        1: 0.58 / np.sqrt(600),
        2: 1.16 / np.sqrt(600),
        3: np.sqrt(600),
    }
    for i, std in expected.items():
        assert np.std(arrays[f"linears.{i}.weight"]) == pytest.approx(std, rel=0.1)
    np.testing.assert_array_equal(
        paper_init_arrays(3, shapes)["linears.1.weight"], arrays["linears.1.weight"]
    )
    assert not np.array_equal(
        paper_init_arrays(4, shapes)["linears.1.weight"], arrays["linears.1.weight"]
    )


@pytest.mark.parametrize("family", ["mlp", "hnn", "lnn"])
def test_twins_agree_under_l1_and_one_cycle(family: str):
    """The loss choice and the schedule are the same arithmetic in both backends: equal
    curves (float64), and the schedule changes the curve."""
    pytest.importorskip("torch")
    pytest.importorskip("jax")
    import importlib

    from hnnbench_plugins.systems.spring import Spring, SpringConfig

    module = importlib.import_module(f"hnnbench_plugins.models.{family}")
    classes = [
        getattr(module, name)
        for name in dir(module)
        if name.endswith(("Torch", "Jax")) and hasattr(getattr(module, name), "family")
    ]
    torch_cls = next(c for c in classes if c.backend == "torch")
    jax_cls = next(c for c in classes if c.backend == "jax")
    system = Spring(SpringConfig(name="spring"))
    data = system.dataset(0)
    extra = {"init": "paper", "kinetic_prior": 0.0} if family == "lnn" else {}
    train = TrainSettings(steps=12, batch_size=100, lr=1e-3, weight_decay=1e-4)
    curves = {}
    for schedule in ("one_cycle", "constant"):
        cfg = torch_cls.Config(
            name="twin",
            dtype="float64",
            log_every=1,
            hidden=32,
            loss="l1",
            lr_schedule=schedule,
            **extra,
        )
        for cls in (torch_cls, jax_cls):
            model = cls(cfg, system, "cpu")
            curves[cls.backend, schedule] = model.fit(data, train, 0, lambda *_: None).history
    for key in ("train_loss", "val_loss"):
        np.testing.assert_allclose(
            curves["jax", "one_cycle"][key], curves["torch", "one_cycle"][key], rtol=1e-7
        )
    assert curves["torch", "one_cycle"]["train_loss"][0] == pytest.approx(
        curves["torch", "constant"]["train_loss"][0], rel=1e-12
    )  # the same start
    assert curves["torch", "one_cycle"]["val_loss"][-1] != pytest.approx(
        curves["torch", "constant"]["val_loss"][-1], rel=1e-6
    )


def test_a_third_party_recipe_is_checked_and_listed():
    import contextlib
    import io
    import json

    from stub_models import Unrun

    import hnnbench
    from hnnbench import _registry as registry
    from hnnbench._entry.command import cmd_list

    class WithRecipe(Unrun):
        recipe = {"lr": 3e-3, "steps": 500}

    class UnknownSetting(WithRecipe):
        recipe = {"hidden": 600}  # not a ModelConfig field

    class Invalid(WithRecipe):
        recipe = {"lr": -1.0}

    try:
        hnnbench.register("model", "recipe_model", WithRecipe)
        assert registry.discover("model")["recipe_model"].recipe == WithRecipe.recipe
        assert config_defaults("model", "recipe_model", "paper", "recipe").steps == 500
        with pytest.raises(ConfigError, match=r"recipe for unknown config fields \['hidden'\]"):
            hnnbench.register("model", "unknown_recipe_model", UnknownSetting)
        with pytest.raises(
            ConfigError, match=r"\.recipe \(track=recipe\): model\.lr=-1\.0 is invalid"
        ):
            hnnbench.register("model", "invalid_recipe_model", Invalid)
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            cmd_list(["--json"])
        listed = {m["name"]: m for m in json.loads(out.getvalue())["model"]}
        assert listed["recipe_model"]["recipe"] == {"lr": 3e-3, "steps": 500}
        assert listed["lnn_jax"]["recipe"] == RECIPE
        assert listed["hnn_jax"]["recipe"] is None
    finally:
        for name in ("recipe_model", "unknown_recipe_model", "invalid_recipe_model"):
            registry.MODELS._registered.pop(name, None)
        registry.refresh()


def test_a_recipe_record_is_the_main_row_of_its_track_and_passes_check(tmp_path):
    """A recipe job's settings are its track's defaults: no variant, nothing undeclared
    (``hnnbench check`` and the publish script compare a record with its track's
    defaults)."""
    import hnnbench
    from hnnbench._results.provenance import config_variant

    pytest.importorskip("jax")
    rec = hnnbench.run(
        "damped_spring",
        "dhnn_jax",
        seed=0,
        profile="quick",
        out=tmp_path / "recipe",
        track="recipe",
        model__hidden=16,
        system__n_traj=6,
    )
    assert rec["track"] == "recipe" and rec["status"] == "ok", rec.get("error")
    assert rec["config"]["model"]["batch_size"] == 128  # the recipe's
    assert rec["steps"] == 300  # the quick profile's steps, not the recipe's 5000
    variant = config_variant(rec)
    assert variant.label == "model.hidden=16 system.n_traj=6", variant
    assert variant.undeclared == ()


def test_quick_leaves_a_recipes_steps_out_and_the_command_line_wins():
    assert config_defaults("model", "dhnn_jax", "paper", "recipe").steps == 5000
    assert config_defaults("model", "dhnn_jax", "quick", "recipe").steps is None
    cfg = compose(["system=spring", "model=dhnn_jax", "track=recipe", "model.steps=700"])
    assert cfg.model.steps == 700 and cfg.model.batch_size == 128


def test_the_schedule_is_the_same_whatever_the_chunking_and_in_a_seed_batch():
    """The per-step rates are sliced per chunk by the shared loop: the chunk length
    (``log_every``) changes nothing, and seeds trained as one batch get what each gets
    alone."""
    pytest.importorskip("jax")
    from hnnbench_plugins.models.hnn import HNNJax
    from hnnbench_plugins.systems.spring import Spring, SpringConfig

    system = Spring(SpringConfig(name="spring"))
    data = [system.dataset(s) for s in (0, 1)]
    train = TrainSettings(steps=60, batch_size=100, lr=3e-3, weight_decay=0.0)

    def fit(log_every: int) -> list[float]:
        cfg = HNNJax.Config(
            name="hnn_jax",
            dtype="float64",
            hidden=16,
            log_every=log_every,
            lr_schedule="one_cycle",
            loss="l1",
        )
        return [
            HNNJax(cfg, system, "cpu").fit(d, train, s, lambda *_: None).history["val_loss"][-1]
            for s, d in zip((0, 1), data, strict=True)
        ]

    alone = fit(7)
    np.testing.assert_allclose(fit(60), alone, rtol=1e-12)
    cfg = HNNJax.Config(
        name="hnn_jax", dtype="float64", hidden=16, log_every=7, lr_schedule="one_cycle", loss="l1"
    )
    batched = HNNJax(cfg, system, "cpu").fit_seeds(data, train, [0, 1], lambda *_: None)
    np.testing.assert_allclose([f.history["val_loss"][-1] for _, f in batched], alone, rtol=1e-10)
