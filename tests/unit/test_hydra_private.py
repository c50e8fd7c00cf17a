"""Pins the private Hydra API that hnnbench/_running/hydra_private.py wraps (the only module that
touches it). A Hydra upgrade that moves or changes these fails here, by name."""

from __future__ import annotations

import json

import pytest

from hnnbench._contracts.errors import HnnbenchError
from hnnbench._running import hydra_private, launch_context


def test_args_parser_is_hydras_with_its_flags():
    parser = hydra_private.args_parser()
    ns = parser.parse_intermixed_args(["-m", "seed=0,1", "--config-dir", "/tmp", "a=b"])
    assert ns.multirun is True
    assert ns.config_dir == "/tmp"
    assert ns.overrides == ["seed=0,1", "a=b"]
    for attr in (
        "run",
        "cfg",
        "info",
        "shell_completion",
        "resolve",
        "package",
        "config_path",
        "config_name",
        "experimental_rerun",
        "hydra_help",
        "help",
    ):
        assert hasattr(ns, attr), attr


def test_run_and_report_is_the_hook_hydra_main_reports_through():
    import hydra._internal.utils as hydra_utils

    original = hydra_utils.run_and_report
    with hydra_private.one_line_errors(lambda err: f"one line: {err}"):
        assert hydra_utils.run_and_report is not original
        with pytest.raises(HnnbenchError, match="^one line: boom$"):
            hydra_utils.run_and_report(lambda: (_ for _ in ()).throw(ValueError("boom")))
        assert hydra_utils.run_and_report(lambda: 3) == 3
    assert hydra_utils.run_and_report is original
    with hydra_private.one_line_errors(str, enabled=False):
        assert hydra_utils.run_and_report is original


def test_hydra_main_reports_composition_errors_through_run_and_report(tmp_path, monkeypatch):
    """Without the hook, hydra.main prints a multi-line error and exits; with it, the
    error surfaces as one HnnbenchError."""
    import sys

    import hydra

    (tmp_path / "config.yaml").write_text("defaults:\n  - nothere\n")
    monkeypatch.setattr(sys, "argv", ["hnnbench"])
    app = hydra.main(version_base="1.3", config_path=str(tmp_path), config_name="config")(
        lambda cfg: None
    )
    with hydra_private.one_line_errors(lambda err: "composition failed"):
        with pytest.raises(HnnbenchError, match="^composition failed$"):
            app()
    with pytest.raises(SystemExit):  # Hydra's own reporting, unpatched
        app()


def test_group_lister_sees_an_extra_search_path(tmp_path):
    from hydra import initialize_config_module
    from hydra.core.global_hydra import GlobalHydra

    (tmp_path / "hydra" / "launcher").mkdir(parents=True)
    (tmp_path / "hydra" / "launcher" / "my_cluster.yaml").write_text(
        "_target_: hydra._internal.core_plugins.basic_launcher.BasicLauncher\n"
    )
    GlobalHydra.instance().clear()
    with initialize_config_module("hnnbench_conf", version_base="1.3"):
        loader = GlobalHydra.instance().config_loader()
        groups, options = hydra_private.group_lister(loader, [])
        assert "launcher" in groups("hydra")
        assert "basic" in options("hydra/launcher")
        assert "my_cluster" not in options("hydra/launcher")
        groups, options = hydra_private.group_lister(loader, [f"file://{tmp_path}"])
        assert "my_cluster" in options("hydra/launcher") and "basic" in options("hydra/launcher")
    GlobalHydra.instance().clear()


def test_launch_context_is_set_for_a_command_and_restored(monkeypatch):
    monkeypatch.delenv(launch_context.ENV, raising=False)
    assert launch_context.current() is None
    ctx = launch_context.LaunchContext(command="hnnbench -m x=1", n_jobs=3, cli_pid=42)
    with launch_context.launched(ctx):
        assert launch_context.current() == ctx
        inner = launch_context.LaunchContext(command="hnnbench y=2")
        with launch_context.launched(inner):
            assert launch_context.current() == inner
        assert launch_context.current() == ctx
    assert launch_context.current() is None
    monkeypatch.setenv(launch_context.ENV, "not json")  # set by hand: still "started by the CLI"
    assert launch_context.current() == launch_context.LaunchContext()
    monkeypatch.setenv(launch_context.ENV, json.dumps({"n_jobs": 5}))
    assert launch_context.current() == launch_context.LaunchContext(n_jobs=5)
