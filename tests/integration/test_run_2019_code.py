"""scripts/analysis/run_2019_code.py: calls the original's train.py per seed and model (each
in a fresh interpreter), parses it.

The original repository cannot be fetched in CI, so a stand-in ``train.py`` with the
original's command line and final print format takes its place; what is tested is this
repository's script (arguments passed, logs parsed and reused, the table printed).
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from conftest import load_script

ROOT = Path(__file__).resolve().parents[2]

STAND_IN = """\
import argparse
p = argparse.ArgumentParser()
p.add_argument("--seed", type=int)
p.add_argument("--save_dir")
p.add_argument("--baseline", action="store_true")
a = p.parse_args()
scale = 10.0 if a.baseline else 1.0
print("some training output")
print("Final train loss {:.4e} +/- {:.4e}".format(scale * (a.seed + 1) * 1e-6, 1e-8))
print("Final test loss {:.4e} +/- {:.4e}".format(scale * (a.seed + 2) * 1e-6, 1e-8))
"""


def _script():
    return load_script(ROOT / "scripts/analysis/run_2019_code.py", "run_2019_code")


def test_runs_each_seed_and_model_and_reuses_finished_logs(tmp_path, capsys):
    repo = tmp_path / "hamiltonian-nn"
    (repo / "experiment-2body").mkdir(parents=True)
    (repo / "experiment-2body/train.py").write_text(STAND_IN)
    work = tmp_path / "work"
    script = _script()
    argv = ["--repo", str(repo), "--seeds", "0", "1", "--workdir", str(work)]
    assert script.main(argv) == 0
    with (work / "results.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    got = {(r["seed"], r["model"]): (float(r["train_loss"]), float(r["test_loss"])) for r in rows}
    assert got == {
        ("0", "hnn"): (1e-6, 2e-6),
        ("0", "baseline"): (1e-5, 2e-5),
        ("1", "hnn"): (2e-6, 3e-6),
        ("1", "baseline"): (2e-5, 3e-5),
    }
    out = capsys.readouterr().out
    # the HNN's 2-seed mean train loss against Table 1's 3.0e-6
    assert "hnn       train_loss   1.500e-06  3.000e-06      0.50" in out

    (repo / "experiment-2body/train.py").write_text("raise SystemExit(3)\n")
    assert script.main(argv) == 0  # every log is finished: nothing is retrained
    assert "reusing" in capsys.readouterr().out


def test_a_failed_original_run_is_one_line(tmp_path):
    repo = tmp_path / "hamiltonian-nn"
    (repo / "experiment-2body").mkdir(parents=True)
    (repo / "experiment-2body/train.py").write_text("raise SystemExit(3)\n")
    with pytest.raises(SystemExit, match=r"the original script failed \(exit 3\); see "):
        _script().main(["--repo", str(repo), "--seeds", "0", "--workdir", str(tmp_path / "w")])


def test_a_wrong_repo_path_says_what_to_pass(tmp_path, capsys):
    with pytest.raises(SystemExit):
        _script().main(["--repo", str(tmp_path)])
    err = capsys.readouterr().err
    assert "must be a checkout of greydanus/hamiltonian-nn" in err
    assert "Traceback" not in err
