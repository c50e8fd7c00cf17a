"""The Python API (hnnbench.run / sweep / load / leaderboard) is the CLI's twin, and the
HTML leaderboard ranks at a glance (structure checked without a browser)."""

from __future__ import annotations

import json
import math
import os
import re

import pytest
from conftest import hnnbench as cli
from report_fixtures import make_sweep

import hnnbench
from hnnbench._results.report import write_report

QUICK = dict(profile="quick", device="cpu", system__eval_n_traj=3, system__steps=40)


def _metrics(record: dict) -> dict[str, float]:
    return {k: v["mean"] for k, v in record["metrics"].items()}


def _same(a: dict[str, float], b: dict[str, float]) -> bool:
    return a.keys() == b.keys() and all(
        (math.isnan(a[k]) and math.isnan(b[k])) or a[k] == b[k] for k in a
    )


@pytest.mark.slow
def test_run_writes_the_record_the_cli_writes(tmp_path):
    """In a fresh interpreter, as in a notebook: this process may have started JAX
    unpinned already (another test), and then gets other bits than the CLI
    (:func:`test_a_run_after_jax_started_unpinned_warns`)."""
    import subprocess
    import sys

    script = "\n".join(
        [
            "import json, sys, hnnbench",
            f"rec = hnnbench.run('spring', 'hnn_jax', seed=1, out=sys.argv[1], **{QUICK!r})",
            "print('RECORD ' + json.dumps(hnnbench._record.codec.encode(rec)))",
        ]
    )
    api = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path / "api")],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert api.returncode == 0, api.stderr[-2000:]
    line = next(ln for ln in api.stdout.splitlines() if ln.startswith("RECORD "))
    rec = hnnbench._record.codec.decode(json.loads(line.removeprefix("RECORD ")))
    assert rec["status"] == "ok"
    proc = cli(
        "system=spring",
        "model=hnn_jax",
        "seed=1",
        "profile=quick",
        "device=cpu",
        "system.eval_n_traj=3",
        "system.steps=40",
        f"hydra.run.dir={tmp_path / 'cli'}",
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    on_disk = [json.loads((tmp_path / d / "result.json").read_text()) for d in ("api", "cli")]
    assert _same(_metrics(rec), _metrics(hnnbench._record.codec.decode(on_disk[0])))
    assert _same(*(_metrics(hnnbench._record.codec.decode(r)) for r in on_disk))
    assert on_disk[0]["config"] == on_disk[1]["config"]
    assert on_disk[0]["command"].startswith("hnnbench system=spring model=hnn_jax seed=1")


def test_sweep_with_a_bad_model_raises_the_typed_one_line_error(tmp_path):
    with pytest.raises(hnnbench.UnknownNameError) as err:
        hnnbench.sweep("spring", ["mlp_torch", "hnn_jx"], out=tmp_path / "s")
    assert "Did you mean 'hnn_jax'?" in str(err.value) and "\n" not in str(err.value)
    with pytest.raises(hnnbench.ConfigError, match="model.hiden is not a setting"):
        hnnbench.run("spring", "hnn_torch", out=tmp_path / "r", model__hiden=5)
    assert not (tmp_path / "s").exists()


def test_overrides_become_hydra_values():
    from hnnbench._entry.api import _settings
    from hnnbench._sweeping.overrides import hydra_value

    typed, raw = _settings(
        {
            "model__steps": 5,
            "device": "cpu",
            "save_model": False,
            "cache_dir": None,
            "model__hidden": "100,200",
        }
    )
    assert typed == {"model.steps": 5, "save_model": False, "cache_dir": None}
    assert raw == {"device": "cpu", "model.hidden": "100,200"}  # strings as written
    assert [hydra_value(v) for v in (5, False, None, 1e-3, [1, 2], "cpu")] == [
        "5",
        "false",
        "null",
        "0.001",
        "[1,2]",
        "cpu",
    ]
    # Paths reach Hydra as the same string, whatever they hold.
    assert hydra_value("/tmp/a b/it's #1 [x]=y,z") == "'/tmp/a b/it\\'s #1 [x]=y,z'"


def test_load_and_leaderboard_read_records_back(tmp_path):
    sweep = make_sweep(tmp_path / "s")
    frame = hnnbench.load(sweep)
    assert len(frame) == 10 and {"system", "model", "seed", "energy_mse"} <= set(frame.columns)
    board = hnnbench.leaderboard(frame)
    assert len(board) == 5 and (board["n_seeds"] == 2).all()
    assert board.equals(hnnbench.leaderboard(hnnbench._record.loader.load(sweep).records))
    with pytest.raises(hnnbench.HnnbenchError, match="does not exist"):
        hnnbench.load(tmp_path / "nope")


def test_the_page_ranks_at_a_glance(tmp_path):
    sweep = make_sweep(tmp_path / "s", seeds=(0, 1, 2, 3, 4, 5))  # 6: the sign test can separate
    report = write_report(sweep)
    page = (sweep / "leaderboard.html").read_text()
    # the aggregate first, then the family table, then the family heatmaps (linked)
    assert (
        page.index('<h2 id="across">')
        < page.index('<h2 id="families">')
        < page.index('<h2 id="heatmaps">')
        < page.index('<h2 id="models">')
    )
    assert page.count('alt="heatmap_') == 2 and page.count('alt="performance_profile') == 1
    # the family table sorts on click, with numeric keys, by a few lines of JS
    table = re.search(r'<table class="board sortable">.*?</table>', page, re.S).group(0)
    assert "<script>" in page and "localeCompare" in page and "sortable" in page
    assert "http" not in page.split("<script>")[1]  # no CDN: self-contained
    assert re.search(r'data-v="[0-9.e+-]+"', table)
    # spring energy_mse: hnn beats mlp on each of 6 paired seeds -> best; never the oracle
    rows = re.findall(r"<tr>(.*?)</tr>", table, re.S)
    best = [r for r in rows if 'class="best"' in r]
    assert best and not any(">oracle<" in r for r in best)
    spring_hnn = next(r for r in rows if ">spring<" in r and ">hnn<" in r)
    header = re.findall(r"<th[^>]*>(.*?)</th>", table)
    cells = re.findall(r"<td([^>]*)>(.*?)</td>", spring_hnn)
    energy = cells[header.index("energy_mse \u2193")]  # lower is better
    assert "best" in energy[0]
    # the Markdown marks the same cell in bold
    md = (sweep / "leaderboard.md").read_text()
    assert re.search(r"\| spring\s+\| hnn\s+\| hnn_torch .*\*\*2\.\de-05", md)
    assert report.figures and all(m.path.exists() for m in report.figures)


@pytest.mark.slow
@pytest.mark.parametrize("jax_first", [False, True])
def test_a_run_after_jax_started_unpinned_warns(tmp_path, jax_first):
    """XLA sizes its thread pool when JAX starts; a process that started JAX on several
    cores and then pins itself for a run gets other bits than the CLI: it is told so."""
    import subprocess
    import sys

    script = "\n".join(
        [
            "import jax.numpy as jnp; jnp.ones(2).block_until_ready()" if jax_first else "",
            "import hnnbench",
            f"rec = hnnbench.run('spring', 'mlp_jax', out={str(tmp_path / 'r')!r}, profile='quick',"
            " device='cpu', system__steps=20, system__eval_n_traj=2)",
            "assert rec['status'] == 'ok', rec['error']",
        ]
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    warned = "JAX was started in this process before the job pinned it" in proc.stderr + proc.stdout
    assert warned == jax_first, proc.stderr[-2000:]


@pytest.mark.parametrize("model", ["mlp_jax", "mlp_torch"])
def test_device_share_on_a_machine_whose_backends_see_no_gpu_keeps_auto_s_cpu(tmp_path, model):
    """``device_share`` on a host that lists a GPU (``CUDA_VISIBLE_DEVICES=0``) with CPU
    builds of the backends: the job takes the GPU's slot, sees only it, and
    ``device=auto`` still falls back to the CPU; the record is ok and says ``cpu``."""
    import subprocess
    import sys

    script = "\n".join(
        [
            "import os, hnnbench",
            f"rec = hnnbench.run('spring', {model!r}, out={str(tmp_path / 'r')!r}, "
            "profile='quick', device_share=3, system__steps=20, system__eval_n_traj=2)",
            "assert rec['status'] == 'ok', rec['error']",
            "assert rec['device'] == 'cpu', rec['device']",
            "assert rec['config']['device_share'] == 3",
            "assert os.environ['CUDA_VISIBLE_DEVICES'] == '0'",
            "assert os.environ['XLA_PYTHON_CLIENT_MEM_FRACTION'] == '0.3000'",
        ]
    )
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("XLA_PYTHON_CLIENT_MEM_FRACTION", "XLA_PYTHON_CLIENT_PREALLOCATE")
    }
    proc = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=600,
        env={**env, "CUDA_VISIBLE_DEVICES": "0", "TMPDIR": str(tmp_path)},
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
