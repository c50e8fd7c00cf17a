"""``hnnbench check`` verifies what a record says about itself instead of reading it
(hnnbench._results.provenance, issue #28): the variant comes from the stored config against the
profile's defaults, ``--rerun`` ignores the record's run-only settings and compares the
data hashes with the canonical ones, plugin versions and packages are compared with the
installed ones (null is a mismatch), and metric or timing keys named like a table column
are refused. Every record here is a real quick job's, crafted where a test says so."""

from __future__ import annotations

import copy
import json
import os
import shutil
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from hnnbench import _record as records
from hnnbench import _registry as registry
from hnnbench._contracts.errors import HnnbenchError
from hnnbench._contracts.paths import sha256_file
from hnnbench._contracts.plugin import Dataset
from hnnbench._record.codec import encode
from hnnbench._results import check
from hnnbench._results.check.rerun import rerun_config
from hnnbench._running.compose import compose
from hnnbench._running.config import prepare_job
from hnnbench._running.data_hashes import (
    DATA_HASHES,
    KNOWN_CPUS,
    CpuDispatch,
    generate_hashes,
    hashes_on,
)
from hnnbench._running.dataset_cache import cached
from hnnbench._running.fresh_job import run_fresh
from hnnbench._running.job import run_job
from tests.conftest import hnnbench as hnnbench_cli

JOB = ["system=spring", "model=oracle", "profile=quick"]


def _run(directory: Path, *extra: str) -> dict:
    overrides = [*JOB, "pin_cpu=false", *extra]
    record = run_job(compose(overrides), directory, overrides=overrides)[0].record
    assert record["status"] == "ok", record.get("error")
    return record


@pytest.fixture(scope="module")
def honest(tmp_path_factory) -> Path:
    """A sweep directory holding one real quick job (spring x oracle, seed 0)."""
    sweep = tmp_path_factory.mktemp("honest")
    _run(sweep / "spring" / "oracle" / "seed0")
    return sweep


def _copy(sweep: Path, tmp_path: Path, name: str = "sweep") -> Path:
    return Path(shutil.copytree(sweep, tmp_path / name))


def _edit(sweep: Path, change) -> Path:
    """Rewrite the sweep's one record through ``change(record)``; returns its file."""
    (path,) = sweep.rglob(records.RECORD_NAME)
    record = json.loads(path.read_text())
    change(record)
    path.write_text(json.dumps(record, indent=2))
    return path


def _reference(sweep: Path, tmp_path: Path) -> Path:
    reference = tmp_path / "reference.csv"
    assert check.main([str(sweep), "--reference", str(reference), "--update"]) == 0
    return reference


def _lines(out: str, needle: str) -> list[str]:
    return [line for line in out.splitlines() if needle in line]


# --------------------------------------------------------------------------- records


def test_a_real_record_names_its_plugins_and_passes(honest, tmp_path, capsys):
    (path,) = honest.rglob(records.RECORD_NAME)
    record = json.loads(path.read_text())
    assert records.validate(record) == []
    oracle = registry.discover("model")["oracle"]
    assert record["plugins"]["model"] == {
        "name": "oracle",
        "version": oracle.version,
        "distribution": oracle.distribution,
        "distribution_version": oracle.dist_version,
    }
    assert record["plugins"]["system"]["name"] == "spring"
    variants = check.record_variants(records.load_records(honest))
    assert [(v.label, v.undeclared, v.problem) for v in variants] == [("", (), None)]
    reference = _reference(honest, tmp_path)
    capsys.readouterr()
    assert check.main([str(honest), "--reference", str(reference)]) == 0, capsys.readouterr().out


# --------------------------------------------------------------------------- variants


def test_a_setting_changed_without_its_override_is_not_the_main_row(honest, tmp_path, capsys):
    """A record trained with other data settings, its overrides stripped, must not pass
    as the main row: check derives the variant from the config and says why."""
    reference = _reference(honest, tmp_path)
    sweep = _copy(honest, tmp_path)

    def other_data(record):
        record["config"]["system"]["n_traj"] = 20
        record["overrides"] = list(JOB)  # says nothing about n_traj

    path = _edit(sweep, other_data)
    capsys.readouterr()
    assert check.main([str(sweep), "--reference", str(reference)]) == 1
    out = capsys.readouterr().out
    (line,) = _lines(out, "is not the main row") or _lines(out, "not the main row")
    assert str(path) in line
    assert (
        "config.system.n_traj is 20 but the quick profile's default is 50, and the "
        "record's overrides do not set it: a variant (system.n_traj=20)"
    ) in line
    # its row is a variant of its own: the main row lost its seed
    assert _lines(out, "missing") and _lines(out, "[system.n_traj=20]")

    # The same setting, declared by an override: a variant, named, and not a failure.
    def declared(record):
        record["overrides"] = [*JOB, "system.n_traj=20"]

    _edit(sweep, declared)
    variants = check.record_variants(records.load_records(sweep))
    assert [(v.label, v.undeclared) for v in variants] == [("system.n_traj=20", ())]
    assert check.main([str(sweep), "--reference", str(reference), "--allow-missing"]) == 0


def test_a_config_of_another_job_or_none_is_refused(honest, tmp_path, capsys):
    reference = _reference(honest, tmp_path)
    sweep = _copy(honest, tmp_path)
    path = _edit(sweep, lambda r: r["config"]["model"].update(name="mlp_torch"))
    capsys.readouterr()
    assert check.main([str(sweep), "--reference", str(reference)]) == 1
    (line,) = _lines(capsys.readouterr().out, "config is of another job")
    assert str(path) in line and "model: record oracle, config mlp_torch" in line

    _edit(sweep, lambda r: r.update(config={"seed": 0}))
    assert check.main([str(sweep), "--reference", str(reference)]) == 1
    (line,) = _lines(capsys.readouterr().out, "holds no resolved config")
    assert str(path) in line


@pytest.mark.slow
def test_a_trained_model_of_another_width_is_not_the_main_row(tmp_path, capsys):
    """The issue's case on a trained model: config.model.hidden changed, no override."""
    job = ["system=spring", "model=mlp_torch", "profile=quick", "pin_cpu=false"]
    directory = tmp_path / "sweep" / "spring" / "mlp_torch" / "seed0"
    assert run_job(compose(job), directory, overrides=job)[0].record["status"] == "ok"
    reference = _reference(tmp_path / "sweep", tmp_path)
    path = _edit(tmp_path / "sweep", lambda r: r["config"]["model"].update(hidden=32))
    capsys.readouterr()
    assert check.main([str(tmp_path / "sweep"), "--reference", str(reference)]) == 1
    (line,) = _lines(capsys.readouterr().out, "not the main row")
    # the quick profile's default width is 64 (NeuralModel.profiles)
    assert str(path) in line and "config.model.hidden is 32" in line and "default is 64" in line


# --------------------------------------------------------------------------- --rerun


def test_rerun_of_an_honest_record_passes_with_a_table(honest, tmp_path, capsys):
    reference = _reference(honest, tmp_path)
    capsys.readouterr()
    assert (
        check.main([str(honest), "--reference", str(reference), "--rerun", "spring/oracle/0"]) == 0
    )
    out = capsys.readouterr().out
    assert "--rerun spring/oracle/0 (fresh cache" in out
    header = _lines(out, "re-run")[1]
    assert header.split()[:5] == ["metric", "record", "re-run", "apart", "allowed"]
    for name in (
        "status",
        "data.dataset_sha256",
        "data.evaluation_sha256",
        "train_loss",
        "rollout_mse",
    ):
        (row,) = [line for line in out.splitlines() if line.split()[:1] == [name]]
        assert row.rstrip().endswith("ok"), row


def test_rerun_ignores_a_cache_of_altered_data_and_writes_nothing_the_record_names(
    honest, tmp_path, capsys
):
    """A record made from altered cached data (train and test swapped, its recorded
    hash rewritten to match), whose config
    points at that cache: re-run from its own settings it would reproduce itself. The
    re-run uses a fresh cache instead, so its canonical data hashes differ, and fails;
    the record's cache, data directory and job directory are left as they were."""
    evil, data_dir = tmp_path / "evil-cache", tmp_path / "evil-data"
    data_dir.mkdir()
    job = prepare_job(compose(JOB))
    system = job.system_cls(job.system_cfg)
    _, entry, _ = cached(system, 0, "dataset", lambda: system.dataset(0), Dataset.load, root=evil)
    honest_data = Dataset.load(entry)
    Dataset(train=honest_data.test, test=honest_data.train, meta=honest_data.meta).save(entry)
    altered = sha256_file(entry)
    # the hash recorded beside the entry rewritten too, so that the job takes the entry
    # (without it, the job rebuilds an altered entry: test_records_round_two.py)
    entry.with_name(entry.name + ".sha256").write_text(altered + "\n", encoding="ascii")

    sweep = tmp_path / "sweep"
    directory = sweep / "spring" / "oracle" / "seed0"
    record = _run(directory, f"cache_dir={evil}", f"data_dir={data_dir}")
    assert record["data"]["dataset_sha256"] == altered and record["data"]["cache_hit"]
    assert record["config"]["cache_dir"] == str(evil)
    reference = _reference(sweep, tmp_path)

    def listing(*roots):
        return {p: p.stat().st_mtime_ns for root in roots for p in root.rglob("*")}

    before = listing(evil, data_dir, sweep)
    capsys.readouterr()
    assert (
        check.main([str(sweep), "--reference", str(reference), "--rerun", "spring/oracle/0"]) == 1
    )
    out = capsys.readouterr().out
    (line,) = [ln for ln in _lines(out, "data.dataset_sha256") if ln.startswith("rerun")]
    assert altered[:12] in line and "canonical" in line and str(directory) in line
    assert listing(evil, data_dir, sweep) == before
    # the honest record's hash is the canonical one
    assert (
        altered
        != json.loads(next(honest.rglob(records.RECORD_NAME)).read_text())["data"]["dataset_sha256"]
    )

    # A record that names no BLAS kernel (made before the field) is tried under the known
    # ones too; altered data come back under none of them, and the line names each.
    _edit(sweep, _unnamed_dispatch)
    capsys.readouterr()
    assert (
        check.main([str(sweep), "--reference", str(reference), "--rerun", "spring/oracle/0"]) == 1
    )
    out = capsys.readouterr().out
    (line,) = [ln for ln in _lines(out, "data.dataset_sha256") if ln.startswith("rerun")]
    tried = [cpu.describe() for cpu in KNOWN_CPUS if cpu != CpuDispatch.here()]
    assert "made as other CPUs make them" in line and all(cpu in line for cpu in tried)
    assert listing(evil, data_dir, sweep) == {**before, **listing(sweep)}


def _unnamed_dispatch(record: dict) -> None:
    """As a record made before ``environment`` named its CPU dispatch."""
    del record["environment"]["blas_kernel"], record["environment"]["numpy_simd"]


def test_rerun_reproduces_a_record_made_on_another_class_of_cpu(tmp_path, capsys):
    """A record made on a CPU whose OpenBLAS kernel and numpy SIMD targets differ (an
    SSE4.2 one, forced here in a child process) holds data files whose bytes this CPU
    does not make (float64's last bits differ). ``--rerun`` makes them again as the CPU
    the record names would, or as each known class of CPU would for a record that names
    none, and passes with a row saying which dispatch reproduced them."""
    here = CpuDispatch.here()
    target = next(cpu for cpu in reversed(KNOWN_CPUS) if cpu != here)
    forcing = target.forcing(here)
    if isinstance(forcing, str):
        pytest.skip(forcing)  # no OpenBLAS or numpy dispatch to force on this machine
    sweep = tmp_path / "sweep"
    directory = sweep / "spring" / "oracle" / "seed0"
    child = hnnbench_cli(
        *JOB,
        "seed=0",
        f"hydra.run.dir={directory}",
        env={**forcing, "HNNBENCH_CACHE_DIR": str(tmp_path / "c")},
        timeout=300,
    )
    assert child.returncode == 0, child.stderr[-2000:]
    record = json.loads((directory / records.RECORD_NAME).read_text())
    assert CpuDispatch.of_record(record["environment"]) == target
    # this CPU's kernel makes other bytes of the same config and seed
    canonical = generate_hashes(compose([*JOB, "seed=0"]), tmp_path / "fresh")
    assert canonical["dataset_sha256"] != record["data"]["dataset_sha256"]
    reference = _reference(sweep, tmp_path)
    for named in (target, None):  # the dispatch the record names; none (an older record)
        if named is None:
            _edit(sweep, _unnamed_dispatch)
        capsys.readouterr()
        assert (
            check.main([str(sweep), "--reference", str(reference), "--rerun", "spring/oracle/0"])
            == 0
        )
        out = capsys.readouterr().out
        (row,) = [ln for ln in out.splitlines() if ln.split()[:1] == ["cpu_dispatch"]]
        assert f"{target.describe()} (forced)" in row and canonical["dataset_sha256"][:12] in row
        assert row.split()[1:3] == (["OpenBLAS", "Nehalem,"] if named else ["not", "recorded"])
        assert row.rstrip().endswith("ok")
        for name in ("data.dataset_sha256", "data.evaluation_sha256"):
            (line,) = [ln for ln in out.splitlines() if ln.split()[:1] == [name]]
            assert record["data"][name.split(".")[1]][:12] in line and line.rstrip().endswith("ok")


def test_rerun_config_takes_no_run_only_setting_from_the_record(honest, tmp_path):
    (rec,) = records.load_records(honest)
    rec = copy.deepcopy(rec)
    rec["config"].update(
        cache_dir="/elsewhere/cache",
        data_dir="/elsewhere/data",
        device="cuda:7",
        threads=64,
        pin_cpu=True,
        save_model=True,
        seeds_per_job=4,
        seed_batch=[0, 1, 2, 3],
    )
    cfg = check.rerun_config(rec, tmp_path / "fresh")
    assert cfg["cache_dir"] == str(tmp_path / "fresh") and cfg["data_dir"] is None
    assert (
        cfg["device"],
        cfg["threads"],
        cfg["pin_cpu"],
        cfg["save_model"],
        cfg["rerun"],
        cfg["seeds_per_job"],
        cfg["seed_batch"],
    ) == ("auto", 1, None, False, True, 1, None)
    assert cfg["system"] == rec["config"]["system"] and cfg["model"] == rec["config"]["model"]


# --------------------------------------------------------------------------- plugins


@pytest.mark.parametrize(
    ("change", "field", "gating"),
    [
        (lambda r: r.update(model_version=None), "model_version", True),
        (lambda r: r["plugins"]["model"].update(version=None), "plugins.model.version", True),
        (
            lambda r: r["plugins"]["system"].update(distribution="someone-else"),
            "plugins.system.distribution",
            True,
        ),
        (
            lambda r: r["plugins"]["model"].update(distribution_version=None),
            "plugins.model.distribution_version",
            True,
        ),
        (
            lambda r: r["plugins"]["model"].update(distribution_version="0.0.1"),
            "plugins.model.distribution_version",
            False,
        ),
        # no plugins field: unverifiable, failing unless --allow-unverified (issue 48)
        (lambda r: r.pop("plugins"), None, True),
    ],
)
def test_plugin_versions_are_compared_and_null_is_a_mismatch(
    honest, tmp_path, capsys, change, field, gating
):
    reference = _reference(honest, tmp_path)
    sweep = _copy(honest, tmp_path)
    _edit(sweep, change)
    capsys.readouterr()
    code = check.main([str(sweep), "--reference", str(reference)])
    out = capsys.readouterr().out
    assert code == (1 if gating else 0), out
    if field is not None:
        (line,) = _lines(out, field)
        assert line.startswith("version")
        section = out.split("REGRESSIONS")[-1] if gating else out.split("information")[1]
        assert field in section


# --------------------------------------------------------------------------- names


@pytest.mark.parametrize(
    ("change", "key"),
    [
        (lambda r: r["timings"].update(seed=3), "timings key 'seed'"),
        (lambda r: r["timings"].update(n_ok=1.0), "timings key 'n_ok'"),
        (lambda r: r["metrics"].update(status={"mean": 0.0, "sem": 0.0}), "metrics key 'status'"),
        (lambda r: r["metrics"].update(ranked={"mean": 1.0, "sem": 0.0}), "metrics key 'ranked'"),
    ],
)
def test_a_key_named_like_a_table_column_is_refused(honest, tmp_path, change, key):
    sweep = _copy(honest, tmp_path)
    path = _edit(sweep, change)
    with pytest.raises(HnnbenchError) as err:
        check.main([str(sweep), "--reference", str(tmp_path / "ref.csv"), "--update"])
    message = str(err.value)
    assert message.startswith(f"{path}: {key}") and "refused" in message
    assert "\n" not in message and not os.path.exists(tmp_path / "ref.csv")


def test_the_remade_data_come_from_the_installed_code_not_the_working_directory(
    tmp_path, monkeypatch
):
    """``check --rerun`` runs in a submission's folder: modules there named like those
    the child process imports (hnnbench itself, omegaconf, numpy) are never imported by
    it, so they cannot answer with the record's hashes."""
    here = CpuDispatch.here()
    if isinstance(here.forcing(here), str):
        pytest.skip(here.forcing(here))
    (tmp_path / "hnnbench").mkdir()
    for name in ("omegaconf.py", "numpy.py", "hnnbench/__init__.py"):
        (tmp_path / name).write_text("raise SystemExit('a module of the working directory')\n")
    monkeypatch.chdir(tmp_path)
    cfg = compose([*JOB, "seed=0"])
    answer = hashes_on(OmegaConf.to_container(cfg, resolve=True), here)
    assert isinstance(answer, dict), answer
    assert {k: answer[k] for k in DATA_HASHES} == generate_hashes(cfg, tmp_path / "fresh")


def test_a_rerun_in_a_fresh_pinned_process_gives_a_jax_records_numbers_exactly(tmp_path):
    """The command pins each job to one core before JAX starts, which sizes XLA's thread
    pool; ``check --rerun`` runs its job the same way, in a fresh process
    (``_running/fresh_job.py``), so a JAX record re-run on this machine gives its numbers
    to the last bit, not within tolerance."""
    directory = tmp_path / "sweep" / "spring" / "mlp_jax" / "seed0"
    overrides = ["system=spring", "model=mlp_jax", "profile=quick", "seed=0"]
    child = hnnbench_cli(
        *overrides, f"hydra.run.dir={directory}", env={"HNNBENCH_CACHE_DIR": str(tmp_path / "c")}
    )
    assert child.returncode == 0, child.stderr[-2000:]
    record = json.loads((directory / records.RECORD_NAME).read_text())
    assert record["status"] == "ok" and record["cpu_pin"] is not None
    config = {**rerun_config(record, tmp_path / "fresh-cache"), "pin_cpu": True}
    again = run_fresh(config, tmp_path / "again", overrides=record["overrides"])
    assert isinstance(again, dict), again
    assert again["cpu_pin"] is not None and again["status"] == "ok"
    # the file's JSON, as a record writes it (NaN as null)
    assert encode(again["metrics"]) == record["metrics"]
    assert encode(again["selection"]) == record["selection"]
