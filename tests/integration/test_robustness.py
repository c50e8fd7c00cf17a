"""Robustness: bad input fails in one clean line; divergence and failures are recorded
and isolated; records and caches are written atomically; runs are reproducible;
weights load without pickle; a fuzzer finds no other kind of failure."""

from __future__ import annotations

import contextlib
import io
import json
import math
import pickle
import sys
from pathlib import Path

import _fakeplug
import numpy as np
import pytest
from conftest import QUICK_ORACLE_BOUND, assert_one_line_error, hnnbench, with_pair
from conftest import compose_job as compose
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from omegaconf import OmegaConf

from hnnbench import _record as records
from hnnbench import _registry as registry
from hnnbench._contracts.errors import HnnbenchError
from hnnbench._entry.command import run as cli_run
from hnnbench._record.fields import new_record
from hnnbench._running.config import prepare_job
from hnnbench._running.job import run_job
from hnnbench._sweeping.plan import plan

QUICK = ["profile=quick", "system.steps=20"]


def run_inprocess(argv: list[str]) -> tuple[int, str, str]:
    """``hnnbench._entry.command.run(argv)`` with stdout and stderr captured."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli_run(with_pair(argv))
    return code, out.getvalue(), err.getvalue()


def assert_clean(code: int, err: str, *needles: str) -> str:
    assert code != 0
    assert "Traceback" not in err, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("hnnbench: error: "), lines[0]
    assert "unexpected" not in lines[0], lines[0]  # the catch-all means a bug
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


@pytest.fixture(scope="module")
def fake_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _fakeplug.install(tmp_path_factory.mktemp("fakeplug"))


@pytest.fixture
def fake_plugins(fake_site: Path):
    _fakeplug.activate(fake_site)
    yield fake_site
    _fakeplug.deactivate(fake_site)


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "args, needles",
    [
        # Hydra found these itself before, and printed many lines (or a traceback).
        (["hydra/launcher=nonexistent"], ["Unknown Hydra launcher 'nonexistent'", "joblib"]),
        (["-m", "hydra/launcher=jobllib", "seed=0,1"], ["Did you mean 'joblib'"]),
        (["hydra/launcher=ray"], ["pip install hydra-ray-launcher"]),
        (["hydra.job.chdir=maybe"], ["hydra.job.chdir"]),
        (["--cfg", "job", "seed=abc"], ["seed"]),
        (["--cfg", "job", "model.hidden=0"], ["model.hidden=0 is invalid"]),
        (["~seed"], ["seed is missing"]),
        (["seed=${nope}"], ["Interpolation key 'nope' not found", "seed"]),
        (["system.steps=2", "+system.steps=3"], ["system.steps"]),
        (["--unknown-flag"], ["unrecognized arguments: --unknown-flag"]),
        (["--cfg"], ["--cfg"]),
        (["-m", "--cfg", "job"], ["cannot be combined"]),
        (["--config-name", "nope"], ["Cannot find primary config 'nope'"]),
        (["report", "/nonexistent/sweep"], ["/nonexistent/sweep"]),
        (["check", "/nonexistent/sweep"], ["--reference"]),
    ],
)
def test_bad_input_console_script(args, needles, tmp_path):
    assert_one_line_error(hnnbench(*with_pair(args), cwd=tmp_path), *needles)


@pytest.mark.parametrize(
    "args, needles",
    [
        (["system=sprng"], ["Unknown system 'sprng'", "Did you mean 'spring'"]),
        (["model=hnn_trch"], ["Unknown model 'hnn_trch'", "Did you mean 'hnn_torch'"]),
        (["profile=quik"], ["Unknown profile 'quik'", "Did you mean 'quick'"]),
        (["seed=abc"], ["seed=abc", "Integer"]),
        (["seed=1.5"], ["seed=1.5", "Integer"]),
        (["seed=-1"], ["seed=-1 is invalid"]),
        (["seed=99999999999999999999"], ["is invalid: expected an integer from 0"]),
        (["seed=true"], ["seed"]),
        (["system.steps=-5"], ["system.steps=-5 is invalid"]),
        (["system.steps=1e10"], ["system.steps"]),
        (["model.hidden=0"], ["model.hidden=0 is invalid"]),
        (["model.hidden=1.5"], ["model.hidden"]),
        (["model.lr=nan"], ["model.lr=nan is invalid"]),
        (["model.lr=inf"], ["model.lr=inf is invalid"]),
        (["system.weight_decay=nan"], ["system.weight_decay=nan is invalid"]),
        (["model=mlp_torch", "model.weight_decay=inf"], ["model.weight_decay=inf is invalid"]),
        (["evaluation.atol=inf"], ["evaluation.atol=inf is invalid"]),
        (["system.t_end=inf"], ["system.t_end=inf is invalid"]),
        (["system.noise_std=nan"], ["system.noise_std=nan is invalid", "finite"]),
        (["model.name=lnn_torch"], ["model.name", "model=lnn_torch"]),
        (["system.name=pendulum"], ["system.name", "system=pendulum"]),
        (["-m", "seed=0,1", "seeds_per_job=2", "seed_batch=[5]"], ["seed_batch", "seeds_per_job"]),
        (["system=pixel_pendulum", "system.dt=0"], ["system.dt=0"]),
        (["system=pixel_pendulum", "system.dt=-0.1"], ["system.dt=-0.1"]),
        (["system.t_end=0"], ["system.t_end=0"]),
        (["system.test_split=0"], ["system.test_split=0.0 is invalid"]),
        (["system.test_split=1"], ["system.test_split=1.0 is invalid"]),
        (["system=two_body", "system.test_split=1.5"], ["system.test_split=1.5"]),
        (["model.activation=relu6"], ["model.activation='relu6' is invalid"]),
        (
            ["system.integrator=euler"],
            ["system.integrator is not a setting of system", "Settings:"],
        ),
        (["evaluation.rtol=-1"], ["evaluation.rtol"]),
        (["evaluation=5"], ["evaluation"]),
        (["device=gpu"], ["device=gpu is invalid"]),
        (["threads=-1"], ["threads=-1 is invalid"]),
        (["device_share=0"], ["device_share=0 is invalid", "e.g. device_share=4"]),
        (["rerun=maybe"], ["rerun"]),
        (["system="], ["Unknown system ''"]),
        (["=x"], ["Cannot parse override '=x'"]),
        (["system.steps=[1"], ["Cannot parse override 'system.steps=[1'"]),
        (["++foo"], ["Cannot parse override '++foo'"]),
        (["foo=1"], ["foo is not an hnnbench setting"]),
        (["+foo=1"], ["foo is not an hnnbench setting"]),
        (["+sed=1"], ["Did you mean 'seed'"]),
        (["+system.extra=0"], ["system.extra is not a setting of system 'spring'"]),
        (["+model.hiden=5"], ["model.hiden is not a setting", "Did you mean 'hidden'"]),
        (["model=hnn_jax", "model.hiden=5"], ["not a setting of model 'hnn_jax'"]),
        (["~system"], ["no system chosen"]),
        (["system.steps=${nowhere}"], ["nowhere", "system.steps"]),
        (["cache_dir=${oc.env:HNNBENCH_SURELY_UNSET_VAR}"], ["HNNBENCH_SURELY_UNSET_VAR"]),
        (["hydra.run.dir=${oops}"], ["oops", "hydra.run.dir"]),
        (["hydra/sweeper=foo"], ["Unknown Hydra sweeper 'foo'"]),
        (["hydra/nope=x"], ["Unknown Hydra config group 'hydra/nope'"]),
        (["hydra.launcher.n_jobs=abc"], ["n_jobs"]),
        (["seed=0,1"], ["add -m"]),
        (["--cfg", "job", "seed=0,1"], ["one value per key"]),
        (["-m", "seed=abc,1"], ["seed=abc"]),
        (["-m", "seed=range(a)"], ["seed=range(a)"]),
        (["-m", "seed=interval(0,1)"], ["interval"]),
        (["-m", "system=glob(zz*)"], ["matches no registered system"]),
        (["-m", "system=spring", "model=hnn_torch,nope"], ["Unknown model 'nope'"]),
        (["-m", "model=mlp_torch", "model.hidden=10,0"], ["model.hidden=0 is invalid"]),
        (["-m", "system=spring", "profile=quick,paper"], ["one profile"]),
        (["--resolve"], ["--resolve"]),
        (["--info", "nonsense"], ["invalid choice: 'nonsense'"]),
        (["--config-path", "/nonexistent/conf"], ["no such directory"]),
        (["--cfg", "bogus"], ["invalid choice: 'bogus'"]),
        (["--c", "job"], ["ambiguous option"]),
        (["list", "--foo"], ["unknown argument"]),
    ],
)
def test_bad_input_one_line_inprocess(args, needles):
    code, _, err = run_inprocess(args)
    assert_clean(code, err, *needles)


def test_flags_and_overrides_in_any_order_and_abbreviated():
    p = plan(with_pair(["system=spring", "--mult", "seed=0,1", *QUICK]))
    assert p.multirun and p.n_jobs == 2
    assert p.argv[0] == "--multirun" and "seed=0,1" in p.argv


def test_cfg_job_shows_config():
    code, out, err = run_inprocess(["--cfg", "job", "model=mlp_torch", *QUICK])
    assert code == 0, err
    cfg = OmegaConf.create(out)
    assert cfg.model.name == "mlp_torch" and cfg.system.steps == 20


def test_missing_backend_is_one_line_with_install_hint(fake_site, tmp_path):
    env = _fakeplug.env_for(fake_site)
    proc = hnnbench(*with_pair(["model=needs_backend", *QUICK]), cwd=tmp_path, env=env)
    assert_one_line_error(proc, "needs_backend", "pip install 'hnnbench[jax]'")
    listing = hnnbench("list", "--json", cwd=tmp_path, env=env)
    assert listing.returncode == 0, listing.stderr
    broken = next(m for m in json.loads(listing.stdout)["model"] if m["name"] == "needs_backend")
    assert broken["status"] == "error" and "hnnbench[jax]" in broken["error"]


def test_missing_backend_inprocess(fake_plugins):
    assert "needs_backend" not in registry.available("model")
    code, _, err = run_inprocess(["model=needs_backend"])
    assert_clean(code, err, "pip install 'hnnbench[jax]'")
    # `all` leaves the unusable plugin out instead of failing.
    assert "needs_backend" not in plan(with_pair(["-m", "model=all", *QUICK])).overrides[1]


def test_subcommand_import_problems_are_one_line(monkeypatch):
    import importlib

    real = importlib.import_module

    def broken(name, *args, **kwargs):
        if name == "hnnbench._results.report.cli":
            raise RuntimeError("numpy.core.multiarray failed to import\nsecond line")
        if name == "hnnbench._results.check.command":
            raise ModuleNotFoundError("No module named 'pandas'", name="pandas")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(importlib, "import_module", broken)
    code, _, err = run_inprocess(["report", "somewhere"])
    assert_clean(code, err, "could not be loaded", "second line")
    code, _, err = run_inprocess(["check", "somewhere"])
    assert_clean(code, err, "needs pandas")


def test_subcommand_errors_are_one_line(monkeypatch):
    import types

    module = types.ModuleType("hnnbench._results.report.cli")

    def main(args):
        raise HnnbenchError("Sweep directory\n  nowhere does not exist")

    module.main = main  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "hnnbench._results.report.cli", module)
    code, _, err = run_inprocess(["report", "nowhere"])
    assert_clean(code, err, "Sweep directory nowhere does not exist")
    module.main = lambda args: {}["bug"]  # type: ignore[attr-defined]
    code, _, err = run_inprocess(["report", "nowhere"])
    assert code != 0 and len(err.strip().splitlines()) == 1 and "KeyError" in err


def test_hnnbench_error_is_always_one_line():
    assert str(HnnbenchError("a\n  b\tc ")) == "a b c"


# --------------------------------------------------------------------------- isolation


def _job(tmp_path: Path, name: str, *overrides: str, rerun: bool = False) -> dict:
    cfg = compose([*QUICK, *overrides] + (["rerun=true"] if rerun else []))
    return run_job(cfg, tmp_path / name, overrides=[*QUICK, *overrides])[0].record


def test_nan_model_is_diverged_with_inf_metrics(fake_plugins, tmp_path):
    rec = _job(tmp_path, "nan", "model=nan_model")
    assert rec["status"] == "diverged", rec["error"]
    assert rec["metrics"]["energy_mse"]["mean"] == math.inf
    assert rec["metrics"]["test_loss"]["mean"] == math.inf
    # strict JSON on disk: inf is the string "inf" (any parser reads it; records decode it)
    on_disk = json.loads(
        (tmp_path / "nan" / "result.json").read_text(),
        parse_constant=lambda c: pytest.fail(f"non-strict JSON: {c}"),
    )
    assert on_disk["status"] == "diverged" and on_disk["metrics"]["energy_mse"]["mean"] == "inf"


def test_torch_training_blowup_is_diverged(tmp_path):
    # Adam at lr=1e30 sends float32 weights to inf within a step: an honest divergence.
    rec = _job(tmp_path, "blowup", "model=mlp_torch", "model.lr=1e30", "model.weight_decay=0")
    assert rec["status"] == "diverged", (rec["status"], rec["error"])
    assert rec["error"].startswith("training diverged")
    metrics = rec["metrics"]
    not_applicable = ("pixel_mse", "vpt_lyapunov")  # spring: no pixels, not chaotic
    assert all(
        math.isinf(m["mean"])
        for k, m in metrics.items()
        if k not in (*not_applicable, "valid_prediction_time", "vpt_censored")
    )
    assert all(math.isnan(metrics[k]["mean"]) for k in not_applicable)
    assert metrics["valid_prediction_time"]["mean"] == 0.0  # higher is better: worst is 0
    assert metrics["vpt_censored"]["mean"] == 0.0


def test_crash_is_failed_with_message_and_traceback(fake_plugins, tmp_path):
    rec = _job(tmp_path, "crash", "model=crash_model")
    assert rec["status"] == "failed"
    assert rec["error"] == "RuntimeError: boom: the model crashed on purpose"
    assert "Traceback" in rec["traceback"]
    assert records.read_record(tmp_path / "crash" / "result.json")["status"] == "failed"


def test_a_crash_during_evaluation_is_failed_not_ok(fake_plugins, tmp_path):
    rec = _job(tmp_path, "crash", "model=rollout_crash_model")
    assert rec["status"] == "failed", rec["status"]
    assert rec["error"] == "RuntimeError: boom: the rollout crashed on purpose"
    assert "rollout" in rec["traceback"]


def test_bad_config_at_job_start_is_failed_not_raised(tmp_path):
    # A launcher hands the job its config; validation at job start records the problem.
    cfg = compose(QUICK)
    cfg.seed = -3
    rec = run_job(cfg, tmp_path / "bad")[0].record
    assert rec["status"] == "failed" and "seed=-3 is invalid" in rec["error"]
    cfg = compose(QUICK)
    OmegaConf.update(cfg, "system.t_end", "${nowhere}")
    rec = run_job(cfg, tmp_path / "interp")[0].record
    assert rec["status"] == "failed" and "nowhere" in rec["error"]


# --------------------------------------------------------------------------- nothing lost


def test_resume_skips_finished_and_rerun_redoes(tmp_path):
    first = _job(tmp_path, "job", "model=oracle")
    assert first["status"] == "ok"
    text = (tmp_path / "job" / "result.json").read_text()
    again = _job(tmp_path, "job", "model=oracle")
    assert again["created_at"] == first["created_at"]
    assert (tmp_path / "job" / "result.json").read_text() == text
    redone = _job(tmp_path, "job", "model=oracle", rerun=True)
    assert redone["status"] == "ok"
    assert json.loads((tmp_path / "job" / "result.json").read_text())["timings"] != first["timings"]


def test_resume_refuses_a_record_of_other_settings(tmp_path):
    first = _job(tmp_path, "job", "model=oracle")
    text = (tmp_path / "job" / "result.json").read_text()
    # Settings that change what the job computes: not run, the old record kept.
    for other in ("evaluation.rtol=1e-7", "profile=paper"):
        rec = _job(tmp_path, "job", "model=oracle", other)
        assert rec["status"] == "failed", other
        assert "holds a finished record of other settings" in rec["error"]
        assert other.split("=")[0] in rec["error"]
        assert (tmp_path / "job" / "result.json").read_text() == text
    # Settings that say how the job runs: the record is this job's result.
    again = _job(tmp_path, "job", "model=oracle", "threads=2", "save_model=false")
    assert again["created_at"] == first["created_at"]


def test_failed_jobs_are_redone_on_resume(fake_plugins, tmp_path):
    assert _job(tmp_path, "j", "model=crash_model")["status"] == "failed"
    assert _job(tmp_path, "j", "model=oracle")["status"] == "ok"  # same dir, now fixed


def test_torn_record_and_stale_temp_files(tmp_path):
    job = tmp_path / "job"
    job.mkdir()
    (job / "result.json").write_text('{"status": "ok", "metr')  # torn by a crash
    stale = [job / ".result.123.abc.tmp.json", job / ".rollout.9.ff.tmp.npz"]
    for path in stale:
        path.write_text("garbage")
    assert records.read_record(job / "result.json") is None
    assert records.load(tmp_path).records == []
    rec = run_job(compose([*QUICK, "model=oracle"]), job)[0].record
    assert rec["status"] == "ok"
    assert records.read_record(job / "result.json")["created_at"] == rec["created_at"]
    assert not [p for p in job.iterdir() if ".tmp" in p.name]
    assert [r["status"] for r in records.load(tmp_path).records] == ["ok"]


def test_atomic_write_keeps_old_file_on_failure(tmp_path):
    path = tmp_path / "result.json"
    records.atomic_write_text(path, '{"status": "ok"}\n')
    with pytest.raises(RuntimeError), records.atomic_path(path) as tmp:
        tmp.write_text('{"status": "fai')
        raise RuntimeError("killed mid-write")
    assert path.read_text() == '{"status": "ok"}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]


def test_records_serialise_numpy_and_non_finite(tmp_path):
    rec = {
        **new_record(
            system="spring",
            model="oracle",
            seed=0,
            profile="quick",
            config={},
            overrides=None,
            command=None,
            rerun_command=None,
            environment=records.environment(),
            created_at=records.now_iso(),
        ),
        "status": "diverged",
        "metrics": {
            "a": {"mean": np.float32(0.5), "sem": math.nan},
            "b": {"mean": math.inf, "sem": math.nan},
        },
        "n": np.int64(3),
        "arr": np.arange(2),
    }
    records.write_record(tmp_path, rec)
    back = records.read_record(tmp_path / "result.json")
    assert back["metrics"]["a"]["mean"] == 0.5 and isinstance(back["n"], int)
    assert back["metrics"]["b"]["mean"] == math.inf and back["arr"] == [0, 1]


def test_cache_write_is_atomic(tmp_path, monkeypatch):
    from hnnbench._contracts.plugin import Dataset
    from hnnbench._running import dataset_cache

    cfg = compose(QUICK)
    job = prepare_job(cfg)
    system = job.system_cls(job.system_cfg)
    calls = []

    def build():
        calls.append(1)
        return system.dataset(0)

    data, path, hit = dataset_cache.cached(system, 0, "dataset", build, Dataset.load, tmp_path)
    assert not hit and path.exists()
    path.write_bytes(path.read_bytes()[:100])  # torn entry (e.g. an old non-atomic write)
    again, path2, hit = dataset_cache.cached(system, 0, "dataset", build, Dataset.load, tmp_path)
    assert path2 == path and not hit and len(calls) == 2  # rebuilt, not fatal
    np.testing.assert_array_equal(again.train.x, data.train.x)
    assert not [p for p in path.parent.iterdir() if ".tmp" in p.name]


# --------------------------------------------------------------------------- records


def test_record_has_what_an_exact_rerun_needs(tmp_path):
    rec = _job(tmp_path, "job", "model=mlp_torch", "seed=3")
    assert rec["status"] == "ok", rec["error"]
    assert rec["config"]["seed"] == 3 and rec["config"]["system"]["steps"] == 20
    assert rec["config"]["model"]["name"] == "mlp_torch"
    assert rec["overrides"] == [*QUICK, "model=mlp_torch", "seed=3"]
    assert rec["rerun_command"].startswith("hnnbench profile=quick system.steps=20")
    env = rec["environment"]
    for key in (
        "hnnbench",
        "python",
        "numpy",
        "torch",
        "platform",
        "git_commit",
        "hydra-core",
        "omegaconf",
    ):
        assert key in env, key
    assert env["torch"] and env["numpy"]
    assert len(rec["data"]["dataset_sha256"]) == 64
    assert len(rec["data"]["evaluation_sha256"]) == 64
    assert rec["system_version"] and rec["model_version"] and rec["backend"] == "torch"
    assert rec["train"]["steps"] == 20 and rec["steps"] == 20


# --------------------------------------------------------------------------- reproducible


def _metrics(rec: dict) -> dict:
    return {k: (v["mean"], v["sem"]) for k, v in rec["metrics"].items()}


def _same(a: dict, b: dict) -> bool:
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


@pytest.mark.parametrize("model", ["mlp_torch", "hnn_torch"])
def test_torch_runs_are_bitwise_reproducible(model, tmp_path):
    a = _job(tmp_path, "a", f"model={model}", "device=cpu", "seed=1")
    b = _job(tmp_path, "b", f"model={model}", "device=cpu", "seed=1")
    assert a["status"] == b["status"] == "ok", (a["error"], b["error"])
    assert _same(_metrics(a), _metrics(b))
    assert _same(a["history"], b["history"])
    assert (tmp_path / "a" / "weights.safetensors").read_bytes() == (
        tmp_path / "b" / "weights.safetensors"
    ).read_bytes()
    c = _job(tmp_path, "c", f"model={model}", "device=cpu", "seed=2")
    assert not _same(_metrics(a), _metrics(c))  # the seed matters


def test_jax_runs_are_bitwise_reproducible(tmp_path):
    if "mlp_jax" not in registry.available("model"):
        info = registry.discover("model").get("mlp_jax")
        pytest.skip(f"mlp_jax is not usable here: {info.error if info else 'not registered'}")
    a = _job(tmp_path, "a", "model=mlp_jax", "device=cpu", "seed=1")
    b = _job(tmp_path, "b", "model=mlp_jax", "device=cpu", "seed=1")
    assert a["status"] == b["status"] == "ok", (a["error"], b["error"])
    assert _same(_metrics(a), _metrics(b))
    assert _same(a.get("history"), b.get("history"))


# --------------------------------------------------------------------------- safe weights


def test_torch_weights_are_safetensors_and_load_without_pickle(tmp_path, monkeypatch):
    import torch

    rec = _job(tmp_path, "job", "model=hnn_torch", "device=cpu")
    assert rec["status"] == "ok", rec["error"]
    path = tmp_path / "job" / "weights.safetensors"
    raw = path.read_bytes()
    assert not raw.startswith(b"PK")  # not a zip (torch.save)
    header_len = int.from_bytes(raw[:8], "little")  # safetensors: its JSON header's length
    assert raw[8:9] == b"{"  # a pickle would start with 0x80 0x02-0x05 and no JSON
    header = json.loads(raw[8 : 8 + header_len])
    assert all(v["dtype"] in ("F32", "F64") for k, v in header.items() if k != "__metadata__")

    def no_pickle(*args, **kwargs):
        raise AssertionError("weights must load without pickle")

    monkeypatch.setattr(pickle, "load", no_pickle)
    monkeypatch.setattr(pickle, "loads", no_pickle)
    monkeypatch.setattr(pickle, "Unpickler", no_pickle)
    monkeypatch.setattr(torch, "load", no_pickle)

    job = prepare_job(compose([*QUICK, "model=hnn_torch", "device=cpu"]))
    system = job.system_cls(job.system_cfg)
    fresh = job.model_cls(job.model_cfg, system, "cpu")
    fresh.load(path)
    x = np.random.default_rng(0).normal(size=(7, 2))
    trained = job.model_cls(job.model_cfg, system, "cpu")
    trained.load(path)
    np.testing.assert_array_equal(fresh.time_derivative(x), trained.time_derivative(x))
    rollout = np.load(tmp_path / "job" / "rollout.npz", allow_pickle=False)
    assert "states_hat" in rollout.files


# --------------------------------------------------------------------------- fuzzing

_DEFAULT = OmegaConf.to_container(compose(["profile=quick"]), resolve=True)


def _flat(node, prefix=""):
    for key, value in node.items():
        if isinstance(value, dict):
            yield from _flat(value, f"{prefix}{key}.")
        else:
            yield f"{prefix}{key}"


KEYS = sorted(
    set(_flat(_DEFAULT))
    | {
        "system",
        "model",
        "profile",
        "hydra/launcher",
        "hydra.job.chdir",
        "hydra.sweep.dir",
        "foo",
        "system.nope",
        "model.steps",
        "model.batch_size",
        "model.lr",
        "+foo",
        "++seed",
        "~seed",
        "~model",
        "+system.extra",
        "model.layers",
        "model.dtype",
        "model.log_every",
    }
)
NAMES = [
    "spring",
    "pendulum",
    "two_body",
    "pixel_pendulum",
    "real_pendulum",
    "mlp_torch",
    "hnn_torch",
    "oracle",
    "quick",
    "paper",
    "all",
    "basic",
    "joblib",
    "tanh",
    "cpu",
    "cuda:0",
]
JUNK = [
    "",
    "null",
    "abc",
    "[1",
    "]",
    "[1,2]",
    "{a:1}",
    "${foo}",
    "${seed}",
    "${system.name}",
    "1,2",
    "glob(*)",
    "range(3)",
    "'x y'",
    "=",
    "~",
    "\\",
    "nan",
    "inf",
    "-inf",
    "1e400",
    "-0",
    "true",
    "'a\nb'",
    "${oc.env:NOPE}",
    "${now:%Y}",
    "choice(1,a)",
    "interval(0,1)",
]

values = st.one_of(
    st.integers(-(2**40), 2**40).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.booleans().map(str),
    st.sampled_from(NAMES + JUNK),
    st.text(max_size=10),
)
overrides = st.one_of(
    st.builds(lambda k, v: f"{k}={v}", st.sampled_from(KEYS), values),
    st.builds(lambda k, v: f"{k}={v}", st.text(max_size=8), values),
    st.sampled_from(["~seed", "~system", "++foo", "=x", "system=", "-m", "--cfg"]),
)
FUZZ = settings(
    max_examples=60,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)


@FUZZ
@given(st.lists(overrides, min_size=1, max_size=4))
def test_fuzz_config_validation_fails_only_with_one_line_errors(args):
    try:
        prepare_job(compose(args))
    except HnnbenchError as err:
        message = str(err)
        assert message and "\n" not in message, message


@settings(
    max_examples=25,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
@given(st.lists(overrides, min_size=1, max_size=3))
def test_fuzz_cli_entry_prints_one_line_or_succeeds(args):
    argv = ["--cfg", "job", *[a for a in args if a not in ("-m", "--cfg")]]
    code, _, err = run_inprocess(argv)
    if code != 0:
        assert_clean(code, err)
    else:
        assert "Traceback" not in err


# --------------------------------------------------------------------------- a real sweep


def _sweep_records(root: Path) -> dict[str, dict]:
    return {r["model"]: r for r in records.load(root).records}


@pytest.mark.slow
def test_sweep_isolates_divergence_and_failure_then_resumes(fake_site, tmp_path):
    """Through the console script: one job diverges for real (torch at lr=1e30), one
    predicts NaN, one crashes; the sweep goes on, the oracle is ok, and the command
    exits 1 (a job failed) saying so. Resuming redoes only the failed job; rerun=true
    redoes everything."""
    env = _fakeplug.env_for(fake_site)
    sweep = tmp_path / "sweep"
    args = [
        "-m",
        "system=spring",
        "model=oracle,mlp_torch,crash_model,nan_model",
        "model.lr=1e30",
        "model.weight_decay=0",
        *QUICK,
        f"hydra.sweep.dir={sweep}",
    ]
    proc = hnnbench(*args, cwd=tmp_path, env=env)
    assert proc.returncode == 1, proc.stderr[-3000:]
    assert proc.stderr.strip().splitlines()[-1].startswith("hnnbench: 1 failed of 4 job(s)")
    recs = _sweep_records(sweep)
    assert {m: r["status"] for m, r in recs.items()} == {
        "oracle": "ok",
        "mlp_torch": "diverged",
        "crash_model": "failed",
        "nan_model": "diverged",
    }
    assert recs["crash_model"]["error"] == "RuntimeError: boom: the model crashed on purpose"
    for name in ("mlp_torch", "nan_model"):
        assert recs[name]["metrics"]["energy_mse"]["mean"] == math.inf
        assert recs[name]["metrics"]["test_loss"]["mean"] == math.inf
    assert recs["oracle"]["metrics"]["energy_mse"]["mean"] < QUICK_ORACLE_BOUND
    assert "this run: 4 jobs: 2 diverged, 1 failed, 1 ok" in proc.stdout
    oracle = recs["oracle"]
    assert oracle["overrides"] == [
        "system=spring",
        "model=oracle",
        "model.lr=1e+30",
        "model.weight_decay=0",
        "profile=quick",
        "system.steps=20",
    ]
    assert oracle["command"].startswith("hnnbench -m system=spring model=oracle,mlp_torch")
    assert oracle["rerun_command"] == (
        "hnnbench system=spring model=oracle model.lr=1e+30 "
        "model.weight_decay=0 profile=quick system.steps=20"
    )

    before = {m: r["created_at"] for m, r in recs.items()}
    texts = {m: (Path(r["path"]) / "result.json").read_text() for m, r in recs.items()}
    proc = hnnbench(*args, cwd=tmp_path, env=env)
    assert proc.returncode == 1, proc.stderr[-3000:]  # crash_model fails again
    assert (proc.stdout + proc.stderr).count("already finished") == 3
    again = _sweep_records(sweep)
    for name in ("oracle", "mlp_torch", "nan_model"):
        assert (Path(again[name]["path"]) / "result.json").read_text() == texts[name]
    assert again["crash_model"]["status"] == "failed"  # failed jobs are tried again

    proc = hnnbench(*args, "rerun=true", cwd=tmp_path, env=env)
    assert proc.returncode == 1, proc.stderr[-3000:]
    assert "already finished" not in proc.stdout + proc.stderr
    redone = _sweep_records(sweep)
    assert len(redone) == 4  # rerun=true is not part of the job directory name
    assert all(redone[m]["created_at"] >= before[m] for m in redone)
    assert all((Path(redone[m]["path"]) / "result.json").read_text() != texts[m] for m in redone)
