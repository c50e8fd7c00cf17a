"""One bad plugin cannot stop the harness (issue #28): a plugin's failure at import,
registration, configuration, fit or evaluation is recorded against it and everything
else goes on; a per-job time limit; a sweep's exit status and last line; one sweep per
directory at a time; kept jobs reported as kept; Hydra flags that load pickles refused;
the API's paths quoted for Hydra.

The broken plugins are a real package (tests/bad_plugin_pkg), pip-installed into a
temporary site directory, or registered in-process where importing is not the point."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest
from conftest import hnnbench, install_test_package

import hnnbench as hb
from hnnbench import _registry
from hnnbench._contracts.errors import ConfigError, HnnbenchError, JobTimeout
from hnnbench._entry import command
from hnnbench._running import job
from hnnbench._running.compose import compose
from hnnbench._sweeping.lock import LOCK_NAME, sweep_lock
from hnnbench._sweeping.plan import plan

QUICK = ("profile=quick",)


@pytest.fixture(scope="module")
def bad_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    return install_test_package("bad_plugin_pkg", tmp_path_factory)[1]


def _records(directory: Path) -> dict[str, dict]:
    return {
        f"{r['model']}/{r['seed']}": r
        for r in (json.loads(p.read_text()) for p in directory.rglob("result.json"))
    }


def _last_line(text: str) -> str:
    return [line for line in text.strip().splitlines() if line.strip()][-1]


@pytest.fixture
def registered():
    """Plugins registered in-process, forgotten afterwards."""
    names: list[tuple[str, str]] = []

    def register(kind: str, name: str, obj) -> None:
        _registry.register(kind, name, obj)  # type: ignore[arg-type]
        names.append((kind, name))

    yield register
    for kind, name in names:
        _registry.group(kind)._registered.pop(name, None)
    _registry.refresh()


# ----------------------------------------------------------------- discovery, listing


def test_list_json_survives_every_broken_plugin(bad_env):
    """sys.exit() at import, a raising requirements_missing, a non-numeric order, a
    Config whose __post_init__ calls sys.exit(): each is listed with its reason; a
    plugin that prints at import works, and its output goes to stderr, named."""
    proc = hnnbench("list", "--json", env=bad_env)
    assert proc.returncode == 0, proc.stderr
    listing = json.loads(proc.stdout)  # stdout is JSON and nothing else
    found = {i["name"]: i for kind in listing.values() for i in kind}
    expected = {
        "exits_at_import": "import failed: SystemExit: hnnbench_bad_plugins.exits: refusing",
        "requirements_raise": "requirements_missing() raised: RuntimeError: cannot tell",
        "order_not_a_number": "order must be a number (lower first), not 'first'",
        "config_raises": "config cannot be built: SystemExit: config refuses",
    }
    for name, reason in expected.items():
        assert found[name]["status"] == "error", found[name]
        assert reason in found[name]["error"], found[name]["error"]
    for name in (
        "noisy_spring",
        "exits_in_fit",
        "hangs_in_fit",
        "raising_metric",
        "spring",
        "oracle",
    ):
        assert found[name]["status"] == "ok", found[name]
    assert "hello from a noisy plugin" in proc.stderr and "noisy_spring" in proc.stderr


def test_a_broken_plugin_named_on_the_command_line_is_one_line(bad_env, tmp_path):
    proc = hnnbench("system=spring", "model=config_raises", *QUICK, cwd=tmp_path, env=bad_env)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    line = _last_line(proc.stderr)  # (the line before: the noisy plugin's output)
    assert line.startswith("hnnbench: error: ") and "config_raises" in line
    assert "SystemExit: config refuses" in line


def test_registration_refuses_each_broken_plugin_with_the_reason(registered):
    from hnnbench_plugins.models.oracle import Oracle

    class RequirementsRaise(Oracle):
        @classmethod
        def requirements_missing(cls):
            raise SystemExit(5)

    class BadOrder(Oracle):
        order = "soon"  # type: ignore[assignment]

    @dataclass
    class ExitConfig(hb.ModelConfig):
        def __post_init__(self) -> None:
            sys.exit("no")

    class BadConfig(Oracle):
        Config = ExitConfig

    for cls, reason in (
        (RequirementsRaise, "requirements_missing() raised: SystemExit: 5"),
        (BadOrder, "order must be a number"),
        (BadConfig, "config cannot be built: SystemExit: no"),
    ):
        with pytest.raises(ConfigError, match=reason.replace("(", r"\(").replace(")", r"\)")):
            registered("model", f"bad_{cls.__name__.lower()}", cls)
    # ordering never breaks on a plugin's order
    assert _registry.ordered("model", ["oracle", "hnn_torch", "nope"])[-1] == "nope"


def test_a_config_raising_at_job_start_fails_in_one_line_naming_the_plugin(registered, tmp_path):
    """A __post_init__ or validate() that raises (sys.exit too) only for some values:
    the command line is refused in one line that names the plugin; run_job records
    the job failed."""
    from hnnbench_plugins.models.oracle import Oracle

    @dataclass
    class PickyConfig(hb.ModelConfig):
        hidden: int = 1

        def validate(self) -> None:
            if self.hidden == 7:
                sys.exit("seven")

    class Picky(Oracle):
        Config = PickyConfig

    registered("model", "picky_model", Picky)
    status = command.run(
        [
            "system=spring",
            "model=picky_model",
            "model.hidden=7",
            *QUICK,
            f"hydra.run.dir={tmp_path / 'run'}",
        ]
    )
    assert status == 2
    cfg = compose(["system=spring", "model=picky_model", "model.hidden=7", *QUICK])
    record = job.run_job(cfg, tmp_path / "job")[0].record
    assert record["status"] == "failed"
    assert "picky_model" in record["error"] and "SystemExit: seven" in record["error"]


# ----------------------------------------------------------------- jobs and sweeps


@pytest.mark.slow
def test_a_sweep_survives_exit_hang_and_a_raising_metric(bad_env, tmp_path):
    """A fit that calls sys.exit() fails its job, a fit that hangs times out, a
    third-party metric that raises is recorded in metric_errors (the job is ok); the
    other jobs go on, and the sweep exits 1 saying so in its last line."""
    sweep = tmp_path / "sweep"
    proc = hnnbench(
        "-m",
        "system=noisy_spring",
        "model=oracle,exits_in_fit,hangs_in_fit",
        *QUICK,
        "timeout_s=5",
        f"hydra.sweep.dir={sweep}",
        cwd=tmp_path,
        env=bad_env,
        timeout=300,
    )
    assert proc.returncode == 1, proc.stderr[-3000:]
    recs = _records(sweep)
    assert recs["oracle/0"]["status"] == "ok"
    assert recs["oracle/0"]["metric_errors"]["raising_metric"] == (
        "RuntimeError: this metric is broken"
    )
    assert recs["exits_in_fit/0"]["status"] == "failed"
    assert recs["exits_in_fit/0"]["error"] == "SystemExit: 3"
    hung = recs["hangs_in_fit/0"]
    assert hung["status"] == "timeout" and "time limit of 5 s" in hung["error"]
    assert 4 < hung["timings"]["total_s"] < 60
    assert _last_line(proc.stderr) == (
        "hnnbench: 1 failed and 1 timed out of 3 job(s) (see the log and each record's error)"
    )
    assert "this run: 3 jobs: 1 failed, 1 ok, 1 timeout" in proc.stdout
    board = (sweep / "leaderboard.csv").read_text().splitlines()
    assert "n_timeout" in board[0].split(",")


def test_a_sweep_whose_every_job_failed_exits_nonzero(registered, tmp_path, capsys):
    from hnnbench_plugins.models.oracle import Oracle

    class Exits(Oracle):
        def fit(self, data, train, seed, progress):
            sys.exit(4)

    registered("model", "exits_inproc", Exits)
    status = command.run(
        [
            "-m",
            "system=spring",
            "model=exits_inproc",
            "seed=0,1",
            *QUICK,
            f"hydra.sweep.dir={tmp_path / 'sweep'}",
        ]
    )
    err = capsys.readouterr().err
    assert status == 1
    assert _last_line(err).startswith("hnnbench: 2 failed of 2 job(s)")
    assert {r["error"] for r in _records(tmp_path / "sweep").values()} == {"SystemExit: 4"}


def test_resumed_sweep_reports_kept_and_other_settings_fail(tmp_path, capsys):
    sweep = tmp_path / "sweep"
    args = ["-m", "system=spring", "model=oracle", "seed=0", *QUICK, f"hydra.sweep.dir={sweep}"]
    assert command.run(args) == 0
    assert _last_line(capsys.readouterr().err) == "hnnbench: 1 job(s): 1 ok"
    assert command.run([*args[:-2], "seed=0,1", *args[-2:]]) == 0
    out, err = capsys.readouterr()
    assert _last_line(err) == "hnnbench: 1 job(s): 1 ok; 1 kept from an earlier run"
    assert "this run: 1 jobs: 1 ok; 1 kept from an earlier run" in out
    # other settings into the same job directory: not the earlier record's "ok"
    paper = [a for a in args if a != "profile=quick"]
    assert command.run(paper) == 1
    out, err = capsys.readouterr()
    assert _last_line(err).startswith("hnnbench: 1 failed of 1 job(s)")
    assert "this run: 1 jobs: 1 failed; 2 records in the directory in all" in out
    # other settings in a job directory of their own: the earlier ones are not this run's
    assert command.run([*args, "system.eval_n_traj=3"]) == 0
    out, err = capsys.readouterr()
    assert "this run: 1 jobs: 1 ok; 3 records in the directory in all" in out


def test_timeout_in_data_generation_inprocess(tmp_path):
    """The basic launcher runs the job in this process: the limit holds there too,
    here in data generation (t_end=1e300 would integrate forever)."""
    start = time.monotonic()
    record = hb.run(
        "spring", "oracle", profile="quick", out=tmp_path / "run", system__t_end=1e300, timeout_s=2
    )
    assert time.monotonic() - start < 60
    assert record["status"] == "timeout", record.get("error")
    assert "timeout_s" in record["error"]
    assert json.loads((tmp_path / "run" / "result.json").read_text())["status"] == "timeout"


def test_time_limit_restores_an_outer_timer():
    fired: list[int] = []
    previous = signal.signal(signal.SIGALRM, lambda *a: fired.append(1))
    try:
        signal.setitimer(signal.ITIMER_REAL, 30.0)
        with pytest.raises(JobTimeout), job.time_limit(0.2):
            while True:
                pass
        remaining, _ = signal.getitimer(signal.ITIMER_REAL)
        assert 25 < remaining <= 30
        assert signal.getsignal(signal.SIGALRM) is not None and not fired
        with job.time_limit(0) as limited:
            assert not limited
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def test_timeout_s_is_validated():
    with pytest.raises(ConfigError, match=r"timeout_s=-1(\.0)? is invalid"):
        plan(["system=spring", "model=oracle", "timeout_s=-1"])
    cfg = compose(["system=spring", "model=oracle"])
    assert cfg.timeout_s == 21600
    assert compose(["system=spring", "model=oracle", *QUICK]).timeout_s == 1200


def test_a_metric_that_raises(registered, tmp_path, monkeypatch):
    """A metric (required by default) that raises: NaN and its message in metric_errors,
    the job goes on; one whose declaration sets errors_fail_job (as hnnbench's own
    required metrics do) fails the job."""

    def boom(ctx):
        raise SystemExit("metric exits")

    registered(
        "metric", "boom_metric", hb.Metric(name="boom_metric", description="x", compute=boom)
    )
    cfg = compose(["system=spring", "model=oracle", *QUICK])
    record = job.run_job(cfg, tmp_path / "a")[0].record
    assert record["status"] == "ok"
    assert record["metric_errors"] == {"boom_metric": "SystemExit: metric exits"}
    registered(
        "metric",
        "boom_fatal",
        hb.Metric(name="boom_fatal", description="x", compute=boom, errors_fail_job=True),
    )
    record = job.run_job(cfg, tmp_path / "b")[0].record
    assert record["status"] == "failed" and record["error"] == "SystemExit: metric exits"


# ----------------------------------------------------------------- the sweep lock


def test_a_second_sweep_into_a_busy_directory_fails_naming_the_holder(bad_env, tmp_path):
    sweep = tmp_path / "sweep"
    first = subprocess.Popen(
        [
            str(Path(sys.executable).parent / "hnnbench"),
            "-m",
            "system=spring",
            "model=hangs_in_fit",
            *QUICK,
            "timeout_s=120",
            f"hydra.sweep.dir={sweep}",
        ],
        cwd=tmp_path,
        env={**os.environ, **bad_env},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        lock = sweep / LOCK_NAME
        deadline = time.monotonic() + 120
        while not (lock.is_file() and lock.read_text().strip()):
            assert first.poll() is None and time.monotonic() < deadline
            time.sleep(0.2)
        proc = hnnbench(
            "-m",
            "system=spring",
            "model=oracle",
            *QUICK,
            f"hydra.sweep.dir={sweep}",
            cwd=tmp_path,
            env=bad_env,
        )
        assert proc.returncode == 2 and "Traceback" not in proc.stderr
        line = _last_line(proc.stderr)  # one line (after the noisy plugin's, the count)
        assert line.startswith(
            f"hnnbench: error: {sweep} is in use by another sweep (pid {first.pid} on "
        )
        assert "model=hangs_in_fit" in line
        assert not list(sweep.rglob("oracle"))
    finally:
        os.killpg(first.pid, signal.SIGKILL)
        first.wait()
    # the holder is gone (killed, its lock file left behind): the lock is free
    proc = hnnbench(
        "-m",
        "system=spring",
        "model=oracle",
        *QUICK,
        f"hydra.sweep.dir={sweep}",
        cwd=tmp_path,
        env=bad_env,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_the_lock_is_held_for_the_sweep_and_released(tmp_path):
    with sweep_lock(tmp_path, "hnnbench -m x"):
        holder = json.loads((tmp_path / LOCK_NAME).read_text())
        assert holder["pid"] == os.getpid() and holder["command"] == "hnnbench -m x"
        with (
            pytest.raises(HnnbenchError, match=f"pid {os.getpid()} on .*: hnnbench -m x"),
            sweep_lock(tmp_path),
        ):
            pass
    with sweep_lock(tmp_path):
        pass


# ----------------------------------------------------------------- flags and the API


def test_experimental_rerun_is_refused_and_never_unpickled(tmp_path, capsys):
    marker = tmp_path / "unpickled"
    payload = tmp_path / "config.pickle"
    import pickle

    class Evil:
        def __reduce__(self):
            return (Path.touch, (marker,))

    payload.write_bytes(pickle.dumps(Evil()))
    with pytest.raises(ConfigError, match="unpickles the file"):
        plan(["--experimental-rerun", str(payload)])
    assert command.run(["--experimental-rerun", str(payload)]) == 2
    err = capsys.readouterr().err
    assert (
        len(err.strip().splitlines()) == 1 and "hnnbench check DIR --reference CSV --rerun" in err
    )
    assert not marker.exists()


PATHS = [
    "ü ñ 日本",
    'it\'s "q"',
    "a#b",
    "~home",
    "br[a]c{e}",
    "k=v",
    "x,y",
    "back\\slash",
    "end\\",
    "$HOME %(x)s",
]


@pytest.mark.parametrize("name", PATHS)
def test_run_out_paths_reach_hydra_unchanged(name, tmp_path):
    out = tmp_path / name
    record = hb.run("spring", "oracle", profile="quick", out=out)
    assert record["status"] == "ok"
    assert (out / "result.json").is_file()


def test_sweep_out_path_with_every_special_character(tmp_path):
    out = tmp_path / "all ' \" # ~ [ ] = , \\ é"
    board = hb.sweep("spring", "oracle", seeds=[0, 1], out=out)
    assert board["n_ok"].tolist() == [2]
    assert board.attrs["sweep_dir"] == str(out)
    assert len(list(out.rglob("result.json"))) == 2


def test_out_path_with_an_interpolation_is_one_line(tmp_path):
    with pytest.raises(ConfigError, match="holds '\\$\\{'"):
        hb.run("spring", "oracle", out=tmp_path / "${x}")


@pytest.mark.parametrize(
    "value, error, needle",
    [
        ("results/x", TypeError, "not a path"),
        (Path("results/x"), TypeError, "hnnbench.load("),
        (3, TypeError, "not int"),
        ([1], TypeError, "item 0 is int"),
        ({"system": "spring"}, TypeError, "not one record"),
        ([{"a": 1}], HnnbenchError, "item 0 is not a record"),
    ],
)
def test_leaderboard_says_what_it_expects(value, error, needle):
    with pytest.raises(error, match=needle.replace("(", r"\(")) as info:
        hb.leaderboard(value)
    assert "\n" not in str(info.value)
