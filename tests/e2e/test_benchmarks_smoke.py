"""Smoke tests of the benchmark scripts in benchmarks/ (they are not part of the package).

The fast test runs ``benchmarks/eval_speed.py`` in-process with the oracle (the true
vector field, numpy only, no training) at a loose tolerance. The slow ones run the
scripts as subprocesses: eval_speed.py with briefly trained torch and JAX models (the
batched rollout and the per-trajectory scipy loop must compute the same energy MSE),
train_step.py and seed_batch.py's ratios at tiny settings, chain_scaling.py at two tiny
chains, and sweep.py --warm on two oracle jobs.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from types import ModuleType

import pytest
from conftest import REPO, load_script

EVAL_SPEED = REPO / "benchmarks" / "eval_speed.py"
HEADER = "| system | model | traj | batched ms | scipy-loop ms | speed-up |"


def load_eval_speed() -> ModuleType:
    """Import benchmarks/eval_speed.py as a module."""
    return load_script(EVAL_SPEED, "hnnbench_eval_speed")


def table_rows(output: str) -> dict[str, list[str]]:
    """The Markdown table's data rows, by model name, as lists of cell strings."""
    lines = output.splitlines()
    assert any(line.startswith(HEADER) for line in lines), output
    start = next(i for i, line in enumerate(lines) if line.startswith(HEADER)) + 2
    rows: dict[str, list[str]] = {}
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        cells = [cell.strip() for cell in line.strip("|").split("|")]
        rows[cells[1]] = cells
    return rows


def test_eval_speed_oracle_in_process(capsys: pytest.CaptureFixture[str]) -> None:
    """Both paths run and agree on the oracle, whose energy MSE is the solver's error."""
    bench = load_eval_speed()
    status = bench.main(
        ["--models", "oracle", "--repeats", "1", "--rtol", "1e-6", "--atol", "1e-6"]
    )
    out = capsys.readouterr().out
    assert status == 0, out
    row = table_rows(out)["oracle"]
    assert row[0] == "spring" and row[2] == "15"
    batched_ms, loop_ms = float(row[3]), float(row[4])
    assert batched_ms > 0 and loop_ms > 0
    assert float(row[6]) > 15 * 6  # loop RHS evals: at least one RK45 step per trajectory
    mse_batched, mse_loop = float(row[8]), float(row[9])
    # The true field at rtol = 1e-6 over 20 time units: energy errors of ~1e-5 at most
    # (measured: ~1e-10 for both MSEs); a path that compares the wrong states is O(0.1).
    assert 0 <= mse_batched < 1e-8 and 0 <= mse_loop < 1e-8, row


def test_eval_speed_rejects_pixel_systems(capsys: pytest.CaptureFixture[str]) -> None:
    bench = load_eval_speed()
    status = bench.main(["--systems", "pixel_pendulum", "--models", "oracle"])
    out = capsys.readouterr().out
    assert status == 1
    assert "FAILED" in out and "states only" in out


def test_row_relative_difference() -> None:
    bench = load_eval_speed()
    row = bench.Row(
        system="spring",
        model="m",
        n_traj=15,
        n_points=100,
        rtol=1e-9,
        atol=1e-9,
        fit_s=0.0,
        batched_ms=10.0,
        batched_min_ms=10.0,
        loop_ms=250.0,
        loop_min_ms=250.0,
        loop_nfev=1,
        batched_rhs_calls=None,
        energy_mse_batched=2.0,
        energy_mse_loop=1.0,
    )
    assert row.speedup == pytest.approx(25.0)
    assert row.rel_diff == pytest.approx(0.5)
    assert "| spring | m | 15 | 10.0 | 250.0 | 25.0x |" in bench.markdown_table([row])


@pytest.mark.slow
def test_eval_speed_trained_models_agree() -> None:
    """Briefly trained torch and JAX models at the harness tolerance: the two paths'
    energy MSEs agree to well within the solver's accuracy."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [
            sys.executable,
            str(EVAL_SPEED),
            "--models",
            "mlp_torch",
            "hnn_jax",
            "--steps",
            "100",
            "--repeats",
            "1",
        ],
        capture_output=True,
        text=True,
        timeout=900,
        env=env,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    rows = table_rows(proc.stdout)
    assert set(rows) == {"mlp_torch", "hnn_jax"}, proc.stdout
    for name, row in rows.items():
        mse_batched, mse_loop, rel = float(row[8]), float(row[9]), float(row[10])
        assert mse_batched > 0 and mse_loop > 0, row
        assert rel < 1e-4, f"{name}: energy MSEs disagree: {row}"
        assert float(row[5].rstrip("x")) > 1.0, f"{name}: batched path slower: {row}"
    assert rows["mlp_torch"][7].isdigit()  # torch: batched RHS calls counted


@pytest.mark.slow
def test_train_step_benchmark_prints_2019_and_roofline_columns():
    """benchmarks/train_step.py, tiny settings: it runs, and its tables have the 2019
    loop and roofline columns and a row per backend."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "train_step.py"),
            "--systems",
            "spring",
            "--models",
            "hnn_torch",
            "hnn_jax",
            "--steps",
            "20",
            "--repeats",
            "1",
            "--steps-2019",
            "10",
            "--rate-budget",
            "0.05",
            "--no-pin",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = proc.stdout
    assert "2019 loop" in out and "roofline" in out.lower()
    rows = [line for line in out.splitlines() if line.startswith("| spring | hnn_")]
    assert {line.split("|")[2].strip() for line in rows} >= {"hnn_torch", "hnn_jax"}


@pytest.mark.slow
def test_train_step_benchmark_times_other_families():
    """train_step.py --models takes any family: rows for so_mlp (torch) and srnn (JAX,
    trained on trajectory windows), no 2019 figure for them, a per-family table."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "train_step.py"),
            "--systems",
            "spring",
            "--models",
            "so_mlp_torch",
            "srnn_jax",
            "--steps",
            "20",
            "--repeats",
            "1",
            "--rate-budget",
            "0.05",
            "--no-pin",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = {
        line.split("|")[2].strip(): [c.strip() for c in line.split("|")[1:-1]]
        for line in proc.stdout.splitlines()
        if line.startswith("| spring | ")
    }
    assert {"so_mlp_torch", "srnn_jax", "so_mlp", "srnn"} <= set(rows), proc.stdout
    assert rows["so_mlp_torch"][6] == "— / —" and rows["srnn_jax"][6] == "— / —"
    assert float(rows["so_mlp_torch"][4].split("/")[0]) > 0
    # batch: every training window (full batch): 23 trajectories x 26 windows, the other
    # 2 of the 25 held out for validation
    assert rows["srnn_jax"][2] == "598"
    so_mlp, srnn = rows["so_mlp"], rows["srnn"]  # the family table
    assert so_mlp[3] == "—" and float(so_mlp[2].split("/")[0]) > 0  # torch only
    assert srnn[2] == "—" and float(srnn[3].split("/")[0]) > 0  # JAX only


@pytest.mark.slow
def test_torch_step_options_compute_the_same_step():
    """benchmarks/torch_step_options.py, tiny settings: every variant of the torch step
    (the a47bd0f step, direct Adam, mse_loss, hnnbench's hand-written backward passes,
    with oneDNN's tanh, with the sigmoid form of tanh, with oneDNN's fused layer and
    tanh, torch.func.grad, the
    autograd-free step, with either tanh) has the a47bd0f step's gradient (the script
    itself fails if a swapped tanh left a gradient bit for bit unchanged), the summary
    has a row per family with a JAX column, and the tanh error table bounds every
    kernel's absolute error at float32 rounding."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "torch_step_options.py"),
            "--shapes",
            "spring",
            "--steps",
            "2",
            "--repeats",
            "1",
            "--no-compile",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    import torch

    variants: tuple[str, ...] = (
        "a47bd0f",
        "+ direct Adam",
        "+ mse_loss",
        "hnnbench",
        "hnnbench + sigmoid tanh",
        "torch.func.grad",
        "no autograd",
        "no autograd + sigmoid tanh",
    )
    if torch.backends.mkldnn.is_available():  # a build without oneDNN has no such row
        variants += ("hnnbench + oneDNN tanh", "hnnbench + fused linear-tanh")
    for family in ("mlp", "hnn"):
        block = proc.stdout.split(f"{family} step: ms")[1].split("\n\n")[0]
        lines = {line.strip().split("  ")[0]: line.split() for line in block.splitlines()[1:]}
        for name in variants:
            assert name in lines, (name, block)
            assert float(lines[name][-1]) < 1e-5, (family, name, lines[name])  # gradient
    rows = [line for line in proc.stdout.splitlines() if line.startswith("| spring |")]
    assert len(rows) == 2 and "JAX" in proc.stdout
    errors = proc.stdout.split("largest relative error")[1].split("\n\n")[0]
    kernels = {line[:24].strip(): float(line.split()[-2]) for line in errors.splitlines()[1:]}
    assert {"torch.tanh", "XLA tanh", "2 sigmoid(2a) - 1"} <= set(kernels), errors
    assert all(0 <= err < 1e-6 for err in kernels.values()), kernels


@pytest.mark.slow
def test_chain_scaling_benchmark_prints_one_row_per_size_and_model():
    """benchmarks/chain_scaling.py at two tiny chains and two models: a table row per
    (N, model), the ratio 1.00x at the smallest N, a finite energy MSE everywhere."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "chain_scaling.py"),
            "--sizes",
            "2",
            "3",
            "--models",
            "hnn_torch",
            "mlp_torch",
            "--steps",
            "20",
            "--timing-steps",
            "10",
            "--repeats",
            "1",
            "--no-pin",
            "--overrides",
            "system.eval_t_end=5",
            "system.eval_n_points=11",
            "system.eval_n_traj=3",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    head = next(i for i, line in enumerate(lines) if line.startswith("| N | state dim |"))
    assert "ms/step vs N=2" in lines[head] and "energy MSE after 20 steps" in lines[head]
    rows = {}
    for line in lines[head + 2 :]:
        if not line.startswith("|"):
            break
        cells = [cell.strip() for cell in line.strip("|").split("|")]
        rows[(int(cells[0]), cells[2])] = cells
    assert set(rows) == {(n, m) for n in (2, 3) for m in ("hnn_torch", "mlp_torch")}
    for (n, _), cells in rows.items():
        assert int(cells[1]) == 2 * n and int(cells[3]) > 0  # state dim, batch
        assert float(cells[4]) > 0  # ms/step
        ratio = float(cells[5].rstrip("x"))
        assert ratio == 1.0 if n == 2 else ratio > 0
        mse = float(cells[7])  # a bare number: no divergence note
        assert 0 < mse < 100, cells  # energies are O(1) (initial radii 0.5-1.5)


@pytest.mark.slow
def test_sweep_benchmark_warm_runs_start_from_the_filled_cache(tmp_path):
    """benchmarks/sweep.py --warm: an uncompared first run fills the cache, and the timed
    run finds every dataset there (its records say cache_hit)."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "sweep.py"),
            "--warm",
            "--launchers",
            "basic",
            "--overrides",
            "system=spring,pendulum",
            "model=oracle",
            "--keep",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "[warmup]" in proc.stdout and "## Wall time" in proc.stdout
    records = sorted((tmp_path / "basic" / "sweep").rglob("result.json"))
    assert len(records) == 2
    for path in records:
        record = json.loads(path.read_text())
        assert record["status"] == "ok" and record["data"]["cache_hit"] is True
    assert not (tmp_path / "basic" / "cache").exists()  # no cache of its own


GPU_RUNS = REPO / "benchmarks" / "results" / "gpu-h100-2026-11-28"


@pytest.mark.parametrize("run", ["1-default-autotuning", "2-seeds-per-job", "3-autotune-off"])
def test_gpu_summaries_are_what_their_committed_records_give(run, tmp_path):
    """benchmarks/README.md's GPU figures: each committed summary.md is what
    ``gpu.py --summarize`` prints from the records beside it (and the published records
    it compared with, frozen beside them in published.json), and
    every GPU record validates against the record schema."""
    from hnnbench._record.validation import shape_problems

    copy = tmp_path / run
    shutil.copytree(GPU_RUNS / run, copy)
    proc = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "gpu.py"), "--summarize", str(copy)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (copy / "summary.md").read_text() == (GPU_RUNS / run / "summary.md").read_text()
    records = [json.loads(p.read_text()) for p in (GPU_RUNS / run).rglob("result.json")]
    assert records and all(r["device"].startswith("cuda") for r in records)
    assert all(shape_problems(r) == [] for r in records)


SEED_BATCH_RUNS = REPO / "benchmarks" / "results" / "gpu-h200-2026-11-29"


def test_gpu_seed_batch_summary_is_what_its_committed_records_give():
    """benchmarks/README.md's H200 figures: the committed summary.md is what
    ``gpu_seed_batch.py --summarize`` prints from the records beside it and the CPU
    records it compared with (frozen in each run's cpu_records.json), all but the
    extrapolation, which reads the job costs of the day; every record there validates
    and ran on the GPU."""
    from hnnbench._record.validation import shape_problems

    runs = [SEED_BATCH_RUNS / "1-pairs", SEED_BATCH_RUNS / "2-cheap-pairs-autotune"]
    proc = subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "gpu_seed_batch.py"), "--summarize"]
        + [str(r) for r in runs]
        + ["--cpu", str(SEED_BATCH_RUNS / "no-such-folder")],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    committed = (SEED_BATCH_RUNS / "summary.md").read_text().splitlines()
    kept = [line for line in committed if not line.startswith("Extrapolation")]
    assert proc.stdout.strip() == "\n".join(kept).strip()
    records = [json.loads(p.read_text()) for p in SEED_BATCH_RUNS.rglob("result.json")]
    assert len(records) == 140 and all(r["device"].startswith("cuda") for r in records)
    assert all(shape_problems(r) == [] for r in records)


@pytest.mark.slow
def test_gpu_benchmark_runs_its_parts_on_the_cpu(tmp_path):
    """benchmarks/gpu.py end to end with --device cpu (the GPU itself is not here) and the
    oracle (the script's logic, not a model's speed, is under test): a job per pair, the
    seed batch against separate jobs on warm caches, the host CPU part, the tables, and
    each job's exit status."""
    proc = subprocess.run(
        [
            sys.executable,
            str(REPO / "benchmarks" / "gpu.py"),
            "--out",
            str(tmp_path),
            "--device",
            "cpu",
            "--profile",
            "quick",
            "--systems",
            "spring",
            "--models",
            "oracle",
            "--batch-system",
            "spring",
            "--batch-models",
            "oracle",
            "--cpu-system",
            "spring",
            "--budget-s",
            "300",
        ],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=REPO,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    summary = (tmp_path / "summary.md").read_text()
    (row,) = [line for line in summary.splitlines() if line.startswith("| spring | oracle")]
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2:4] == ["ok", "cpu"] and float(cells[5]) > 0
    assert cells[6] != "— / —" and cells[7].endswith("×")  # part 3 ran: this host's CPU
    (batch,) = [
        line
        for line in summary.split("three separate jobs")[1].splitlines()
        if line.startswith("| oracle |")
    ]
    assert batch.endswith("| ok,ok,ok / ok,ok,ok |"), batch
    data_sep, data_batch = (float(v) for v in batch.split("|")[5].split("/"))
    assert data_sep < 1.0 and data_batch < 1.0  # the datasets were generated beforehand
    assert json.loads((tmp_path / "exits.json").read_text()) == {
        "gpu/spring-oracle": 0,
        "batch/oracle-separate": 0,
        "batch/oracle-seeds_per_job3": 0,
        "cpu/spring-oracle": 0,
    }
    assert "XLA_FLAGS" in (tmp_path / "environment.txt").read_text()


def run_seed_batch(*args: str) -> subprocess.CompletedProcess[str]:
    """benchmarks/seed_batch.py with ``args``, one thread, its output captured."""
    return subprocess.run(
        [sys.executable, str(REPO / "benchmarks" / "seed_batch.py"), *args],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=REPO,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )


@pytest.mark.slow
def test_seed_batch_counts_aten_calls_per_step():
    """benchmarks/seed_batch.py --ops: ATen calls per step of one seed's fit and of the
    batched fit, views counted apart (docs/SCALING.md, "GPUs", reads these counts)."""
    proc = run_seed_batch("--ops", "--systems", "spring", "--models", "mlp_torch", "mlp_jax")
    assert proc.returncode == 0, proc.stderr[-3000:]
    (row,) = [line for line in proc.stdout.splitlines() if line.startswith("| spring |")]
    one, batch, one_views, batch_views = (float(c) for c in row.strip("|").split("|")[2:])
    assert 0 < one_views < one < batch and 0 < batch_views < batch, row
    assert "mlp_jax" not in proc.stdout  # counted for torch models only


@pytest.mark.slow
def test_seed_batch_prints_a_ratio_per_system_and_family():
    """benchmarks/seed_batch.py in its default mode (issue 52's CPU check): for two
    systems and two JAX families, separate fits against one batched fit, one table row
    each with the ratio, and the best ratio per system."""
    proc = run_seed_batch(
        *("--seeds", "2", "--steps", "3", "--repeats", "1"),
        *("--systems", "spring", "pendulum", "--models", "mlp_jax", "hnn_jax"),
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    rows = [line for line in proc.stdout.splitlines() if line.startswith("| spring |")]
    rows += [line for line in proc.stdout.splitlines() if line.startswith("| pendulum |")]
    assert len(rows) == 4, proc.stdout
    for row in rows:
        fits, batch, ratio = (c.strip() for c in row.strip("|").split("|")[2:5])
        assert float(fits) > 0 and float(batch) > 0 and ratio.endswith("x"), row
    assert "best training ratio per system: spring" in proc.stdout, proc.stdout


@pytest.mark.slow
def test_gpu_seed_batch_runs_its_parts_on_the_cpu(tmp_path):
    """benchmarks/gpu_seed_batch.py, the prepared check for a lent GPU, end to end with
    --device cpu (the GPU itself is not here): the data part, a pair of two seeds as one
    batch with two processes sharing the device (``device_share``), the autotuning part,
    the pack, and the summary against records of the same jobs."""
    out = tmp_path / "run"
    argv = [sys.executable, str(REPO / "benchmarks" / "gpu_seed_batch.py")]
    proc = subprocess.run(
        [
            *argv,
            *("--out", str(out), "--device", "cpu", "--profile", "quick"),
            *("--systems", "spring", "--models", "mlp_jax", "--seeds", "2", "--parallel", "2"),
            *("--autotune-pair", "spring:mlp_jax", "--budget-s", "300"),
            *("--pack", str(tmp_path / "pack.tar.gz")),
        ],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=REPO,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    exits = json.loads((out / "exits.json").read_text())
    assert set(exits) == {"data-spring", "pair-spring-mlp_jax", "autotune-spring-mlp_jax"}
    assert set(exits.values()) == {0}
    records = [json.loads(p.read_text()) for p in (out / "pairs").rglob("result.json")]
    assert sorted(r["seed"] for r in records) == [0, 1]
    assert all(r["status"] == "ok" and r["device"] == "cpu" for r in records)
    assert all(r["config"]["device_share"] == 2 for r in records)
    assert (tmp_path / "pack.tar.gz").stat().st_size > 0
    summary = subprocess.run(
        [*argv, "--summarize", str(out), "--cpu", str(out / "autotune")],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=REPO,
    )
    assert summary.returncode == 0, summary.stderr[-2000:]
    (row,) = [r for r in summary.stdout.splitlines() if r.startswith("| spring | mlp_jax")]
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[2] == "2/2" and cells[-1] == "2/2 seeds", row
