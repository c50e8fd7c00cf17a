"""``hnnbench report``: leaderboard tables, figures, the HTML page, the paper comparison
and the paper's claims, on synthetic sweeps with the real record schema."""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
import pytest
from conftest import assert_one_line_error, hnnbench
from report_fixtures import INF, make_sweep, seed_metrics, set_status, write_run

from hnnbench import _record as records
from hnnbench import _registry as registry
from hnnbench._contracts import claims
from hnnbench._results import report
from hnnbench._results.leaderboard import format_value, leaderboard

METRICS = (
    "train_loss",
    "test_loss",
    "energy_mse",
    "rollout_mse",
    "reversibility_error",
    "time_reversal_error",
    "valid_prediction_time",
)


@pytest.fixture()
def sweep(tmp_path):
    return make_sweep(tmp_path / "sweep")


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """A synthetic sweep (spring, pendulum; 2 seeds) with its report in ``out``."""
    root = tmp_path_factory.mktemp("built")
    sweep = make_sweep(root / "sweep")
    out = root / "out"
    assert report.main([str(sweep), "--out", str(out)]) == 0
    return out


def _board(out):
    return pd.read_csv(out / "leaderboard.csv")


def _row(board, system, model):
    sel = board[(board["system"] == system) & (board["model"] == model)]
    assert len(sel) == 1, (system, model, board[["system", "model"]])
    return sel.iloc[0]


def test_leaderboard_csv_has_one_row_per_pair_with_mean_std_status_and_timings(built):
    board = _board(built)
    assert len(board) == 5
    expected = {
        "profile",
        "system",
        "model",
        "backend",
        "n_seeds",
        "seeds",
        "n_ok",
        "n_diverged",
        "n_failed",
        "n_skipped",
        "status",
        "reason",
        "fit_s_mean",
        "eval_s_mean",
        "total_s_mean",
        "cpu_s_mean",
    }
    expected |= {f"{m}_{s}" for m in METRICS for s in ("mean", "std", "ci_low", "ci_high")}
    assert expected <= set(board.columns), expected - set(board.columns)
    row = _row(board, "spring", "hnn_torch")
    assert row["n_seeds"] == 2 and row["n_ok"] == 2 and row["status"] == "ok"
    values = [seed_metrics("spring", "hnn_torch", s)["energy_mse"] for s in (0, 1)]
    assert row["energy_mse_mean"] == pytest.approx(np.mean(values))
    assert row["energy_mse_std"] == pytest.approx(np.std(values, ddof=1))
    # Two seeds: every bootstrap resample's mean lies between them, and the 95% interval
    # reaches both (a quarter of the resamples are each value twice).
    assert (row["energy_mse_ci_low"], row["energy_mse_ci_high"]) == pytest.approx(
        (min(values), max(values))
    )
    assert row["fit_s_mean"] == pytest.approx(2.5)
    assert row["cpu_s_mean"] == pytest.approx(2.6)  # the fixture's cpu_s: 2.1 + seed
    assert board["reason"].isna().all()  # every run ok: no reason
    # Canonical order: spring before pendulum, baseline before HNN before oracle.
    assert list(zip(board["system"], board["model"], strict=True))[:3] == [
        ("spring", "mlp_torch"),
        ("spring", "hnn_torch"),
        ("spring", "oracle"),
    ]


def test_default_out_is_the_sweep_dir_and_markdown_is_compact(sweep):
    assert report.main([str(sweep), "--no-figures"]) == 0
    assert not (sweep / "figures").exists()
    md = (sweep / "leaderboard.md").read_text()
    assert "Profile `quick`" in md and "2 seed(s)" in md
    values = [seed_metrics("spring", "mlp_torch", s)["energy_mse"] for s in (0, 1)]
    assert f"{np.mean(values):.1e} [{min(values):.1e}, {max(values):.1e}]" in md
    assert "BCa bootstrap interval" in md and "sign test" in md  # the rules, stated
    header = next(line for line in md.splitlines() if line.startswith("| system"))
    for column in (
        "family",
        "seeds_from",
        "status",
        "energy_mse",
        "test_loss",
        "valid_prediction_time",
        "cpu_s",
    ):
        assert column in header
    assert "total_s" not in header  # CPU time, not wall time on a shared machine


def test_markdown_and_html_name_the_commands_commit_and_device(sweep):
    report.main([str(sweep), "--no-figures"])
    md = (sweep / "leaderboard.md").read_text()
    page = (sweep / "leaderboard.html").read_text()
    commit = records.git_commit() or "unknown"
    for text in (md, page):
        assert "hnnbench -m system=spring seed=0" in text
        assert "hnnbench -m system=pendulum seed=1" in text
        assert commit in text and "cpu" in text
    assert "<code>hnnbench -m system=spring seed=0</code>" in page and "`" not in page


def test_figures_per_system_and_html_links_every_one(built):
    out = built
    pngs = sorted(p.name for p in (out / "figures").glob("*.png"))
    for system in ("spring", "pendulum"):
        for kind in ("phase", "energy", "learned_energy", "loss"):
            assert f"{system}_{kind}.png" in pngs
    for name in pngs:
        assert (out / "figures" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = (out / "leaderboard.html").read_text()
    assert {"heatmap_energy_mse.png", "heatmap_rollout_mse.png", "performance_profile.png"} <= set(
        pngs
    )
    # 4 kinds x 2 systems, 2 heatmaps, the performance profiles: each linked, lazily
    assert page.count("<img") == len(pngs) == 8 + 2 + 1
    linked = re.findall(
        r'<img loading="lazy" alt="[^"]*" width="\d+" height="\d+" '
        r'src="figures/([^"]+)">',
        page,
    )
    assert sorted(linked) == pngs
    assert "data:image" not in page and "<link" not in page and "http" not in page
    assert "<table" in page and "hnn_torch" in page and "Qualitative claims" in page


def test_the_page_leads_with_contents_and_the_headline_and_folds_provenance(built):
    page = (built / "leaderboard.html").read_text()
    body = page.split("<body>", 1)[1]
    toc = re.search(r'<nav class="toc">(.*?)</nav>', body, re.S)
    assert toc and body.index("<nav") < body.index("<h2")  # contents before any section
    for anchor in re.findall(r'href="#([^"]+)"', toc.group(1)):
        assert f'id="{anchor}"' in body, anchor  # every entry leads somewhere
    assert {"spring", "pendulum"} <= set(re.findall(r'href="#fig-([^"]+)"', toc.group(1)))
    # the headline table is the first table; the provenance lines are folded away
    first_table = body.index("<table")
    assert body.index('<h2 id="across">') < first_table < body.index('<h2 id="families">')
    details = re.search(r"<details>(.*?)</details>", body, re.S).group(1)
    assert "hnnbench -m system=spring" in details and body.index("<details>") < first_table
    assert "hnnbench -m system=spring" not in body[: body.index("<details>")]
    # every metric column says which way is better, in HTML and in Markdown
    heads = re.findall(r"<th[^>]*>([^<]*)</th>", body)
    assert "energy_mse \u2193" in heads and "valid_prediction_time \u2191" in heads
    assert "energy_mse IQM \u2191" in heads and "energy_mse" not in heads
    md = (built / "leaderboard.md").read_text()
    header = next(line for line in md.splitlines() if line.startswith("| system"))
    assert "energy_mse \u2193" in header and "valid_prediction_time \u2191" in header


def test_embed_figures_gives_one_self_contained_file(sweep, tmp_path):
    out = tmp_path / "embedded"
    assert report.main([str(sweep), "--out", str(out), "--embed-figures"]) == 0
    page = (out / "leaderboard.html").read_text()
    pngs = list((out / "figures").glob("*.png"))
    assert pngs and page.count('src="data:image/png;base64,') == len(pngs)
    assert 'src="figures/' not in page and 'loading="lazy"' not in page


@pytest.mark.skipif(
    not hasattr(__import__("os"), "sched_getaffinity"),
    reason="no CPU affinity: figures are drawn in one process",
)
def test_figures_drawn_in_several_processes_are_the_serial_ones(tmp_path, monkeypatch, caplog):
    """The system figures drawn by forked processes (the end of a sweep on several
    cores) are the ones one process draws: the same files, byte for byte, in the same
    order; and the pool did draw them (no fallback to one process)."""
    from hnnbench._results.report import figures

    sweep = make_sweep(tmp_path / "sweep")
    recs = report.load_sweep(sweep)
    board = leaderboard(recs)
    drawn = {}
    for processes in (1, 2):
        monkeypatch.setattr(figures, "drawing_processes", lambda p=processes: p)
        made = figures.make_figures(recs, board, tmp_path / f"figures{processes}")
        drawn[processes] = [(m.label, m.kind, m.path.name, m.path.read_bytes()) for m in made]
    systems = {label for label, kind, *_ in drawn[1] if label != "all systems"}
    assert len(systems) >= 2 and drawn[2] == drawn[1], systems
    assert "figures drawn in one process" not in caplog.text


def test_no_fork_for_figures_once_jax_has_started(monkeypatch):
    """XLA's threads do not survive a fork: a process that started a JAX backend (a
    notebook that trained in-process) draws its figures itself."""
    import sys as _sys
    import types

    from hnnbench._results.report import figures

    monkeypatch.delitem(_sys.modules, "jax", raising=False)
    assert not figures._jax_started()
    monkeypatch.setitem(_sys.modules, "jax", types.ModuleType("jax"))
    started = types.SimpleNamespace(backends_are_initialized=lambda: True)
    monkeypatch.setitem(_sys.modules, "jax._src.xla_bridge", started)
    monkeypatch.setitem(_sys.modules, "jax._src", types.SimpleNamespace(xla_bridge=started))
    assert figures._jax_started() and figures.drawing_processes() == 1


def test_no_learned_energy_figure_without_a_model_that_has_one(tmp_path):
    sweep = make_sweep(tmp_path / "s", pairs=(("spring", "mlp_torch"),), seeds=(3, 1))
    report.main([str(sweep)])
    names = {p.name for p in (sweep / "figures").glob("*.png")}
    assert names == {"spring_phase.png", "spring_energy.png", "spring_loss.png"}
    assert report.runs_for_figures(report.load_sweep(sweep))[0] == 1  # the lowest seed
    # tuned runs whose study's trials trained seed 1: no row reads them, no figure draws
    # them while another seed has a rollout
    recs = report.load_sweep(sweep)
    for rec in recs:
        rec.update(track="tuned", tuning={"trial_seeds": [1]})
    assert report.runs_for_figures(recs)[0] == 3
    for rec in recs:
        rec["tuning"]["trial_seeds"] = [1, 3]
    assert report.runs_for_figures(recs)[0] == 1  # none other: the lowest


def test_diverged_pair_is_shown_as_diverged_with_inf_never_dropped(tmp_path):
    sweep = make_sweep(
        tmp_path / "s",
        pairs=(("spring", "mlp_torch"), ("spring", "hnn_torch"), ("pendulum", "hnn_torch")),
    )
    for seed in (0, 1):
        set_status(sweep, "spring", "mlp_torch", seed, "diverged")
    set_status(sweep, "pendulum", "hnn_torch", 1, "diverged")  # one of two seeds
    write_run(sweep, "spring", "mlp_jax", 0, status="failed")
    report.main([str(sweep)])
    board = _board(sweep)
    row = _row(board, "spring", "mlp_torch")
    assert row["status"] == "diverged" and row["n_diverged"] == 2 and row["n_ok"] == 0
    assert math.isinf(row["energy_mse_mean"]) and row["energy_mse_mean"] > 0
    assert np.isfinite(row["train_loss_mean"])  # the losses of a diverged rollout are kept
    mixed = _row(board, "pendulum", "hnn_torch")
    assert mixed["status"] == "1 ok, 1 diverged" and np.isfinite(mixed["energy_mse_mean"])
    failed = _row(board, "spring", "mlp_jax")
    assert failed["status"] == "failed" and math.isnan(failed["energy_mse_mean"])
    md = (sweep / "leaderboard.md").read_text()
    every_model = md.split("## Every model", 1)[1]
    line = next(ln for ln in every_model.splitlines() if "| spring" in ln and "mlp_torch" in ln)
    assert "diverged" in line and re.search(r"\|\s*inf\s*\|", line)
    # Figures still build: the diverged model has no rollout, others do.
    assert (sweep / "figures" / "spring_energy.png").exists()
    page = (sweep / "leaderboard.html").read_text()
    assert '<td class="txt diverged">diverged</td>' in page and '<td class="inf">inf</td>' in page


def test_a_training_set_size_sweep_draws_the_data_efficiency_figure(tmp_path):
    """`system.n_traj=10,25,50` gives one figure per system: each declared data-efficiency
    metric against n_traj, one line per model, one point per size."""
    from hnnbench._results.report.figures import sweep_figures

    sweep = tmp_path / "s"
    for n in (10, 25, 50):
        for model in ("mlp_torch", "hnn_torch"):
            for seed in (0, 1):
                write_run(
                    sweep,
                    "spring",
                    model,
                    seed,
                    overrides=(f"system.n_traj={n}",),
                    metrics={k: v * 10 / n for k, v in seed_metrics("spring", model, seed).items()},
                )
    assert report.main([str(sweep)]) == 0
    assert (sweep / "figures" / "spring_sweep_system.n_traj.png").is_file()
    recs = records.load(sweep).records
    figs = sweep_figures(leaderboard(recs), recs)
    (fig,) = figs.values()
    panels = [ax for ax in fig.axes if ax.get_ylabel()]
    assert [ax.get_ylabel() for ax in panels] == ["test_loss", "energy_mse", "rollout_mse"]
    for ax in panels:
        assert ax.get_xlabel() == "system.n_traj" and len(ax.get_lines()) >= 2
        xs = sorted({float(x) for line in ax.get_lines() for x in line.get_xdata()})
        assert xs == [10.0, 25.0, 50.0]


def test_the_family_table_marks_best_only_when_separated(tmp_path):
    """Ten paired seeds, each better: bold, with its effect over the runner-up; two: too
    few seeds to separate, nothing marked. The oracle is shown, never marked."""
    pairs = (("spring", "mlp_torch"), ("spring", "hnn_torch"), ("spring", "oracle"))
    for seeds, wrap in ((tuple(range(10)), "**"), ((0, 1), "")):
        sweep = make_sweep(tmp_path / str(len(seeds)), pairs=pairs, seeds=seeds, rollout=False)
        assert report.main([str(sweep), "--no-figures"]) == 0
        md = (sweep / "leaderboard.md").read_text()
        hnn = next(ln for ln in md.splitlines() if ln.startswith("| spring") and "| hnn " in ln)
        values = [seed_metrics("spring", "hnn_torch", s)["energy_mse"] for s in seeds]
        assert f"| {wrap}{np.mean(values):.1e} [" in hnn, hnn
        oracle = next(ln for ln in md.splitlines() if "| oracle " in ln)
        assert "*" not in oracle
        families = pd.read_csv(sweep / "families.csv").set_index("family")
        assert families.loc["hnn", "energy_mse_mark"] == (
            "best" if wrap == "**" else "too_few_seeds"
        )
        if wrap:  # the median paired effect over the runner-up, beside the leader
            assert "** ×" in hnn and families.loc["hnn", "energy_mse_effect_vs"] == "mlp"
            assert (
                families.loc["hnn", "energy_mse_effect_low"]
                <= families.loc["hnn", "energy_mse_effect"]
            )


def test_reasons_and_cpu_seconds_are_in_every_table(tmp_path):
    sweep = make_sweep(
        tmp_path / "s", pairs=(("spring", "hnn_torch"),), seeds=(0, 1), rollout=False
    )
    write_run(sweep, "spring", "mlp_torch", 0, status="skipped", rollout=False)
    set_status(sweep, "spring", "hnn_torch", 1, "diverged")
    assert report.main([str(sweep), "--no-figures"]) == 0
    board = _board(sweep)
    assert _row(board, "spring", "mlp_torch")["reason"] == "skipped (seed 0): synthetic skipped"
    assert _row(board, "spring", "hnn_torch")["reason"] == "diverged (seed 1): synthetic diverged"
    md = (sweep / "leaderboard.md").read_text()
    tables = [t for t in md.split("\n\n") if t.startswith("| system")]
    families = next(t for t in tables if "| family" in t.splitlines()[0])
    models = next(t for t in tables if "| model" in t.splitlines()[0])
    assert "cpu_s" in families.splitlines()[0] and "cpu_s" in models.splitlines()[0]
    # every model's table has the column; the family table, a note per reason instead
    assert "| reason" in models.splitlines()[0] and "synthetic diverged" in models
    assert "reason" not in families.splitlines()[0] and "synthetic" not in families
    number = re.search(r"\| 1 ok, 1 diverged \[(\d)\]", families).group(1)
    notes = md.split(families, 1)[1].split("## ", 1)[0]
    assert f"{number}. diverged (seed 1): synthetic diverged" in notes
    page = (sweep / "leaderboard.html").read_text()
    assert page.count("synthetic skipped") >= 2  # the family table's notes and every model's
    assert f'<li value="{number}">diverged (seed 1): synthetic diverged' in page


def test_format_value():
    assert format_value(0.037, 0.0011) == "3.7e-02 ± 1.1e-03"
    assert format_value(0.037) == "3.7e-02"
    assert format_value(INF, math.nan) == "inf"
    assert format_value(math.nan, math.nan) == "—"
    assert format_value(3.14159, 0.5, linear=True) == "3.14 ± 0.5"


# --------------------------------------------------------------------------- paper


def test_paper_table_is_in_natural_units_and_complete():
    table = report.paper_table("greydanus2019")
    assert set(table["system"]) == {
        "spring",
        "pendulum",
        "real_pendulum",
        "two_body",
        "three_body",
        "pixel_pendulum",
    }
    assert len(table) == 6 * 3 * 2
    for r in table.itertuples():
        assert r.value == pytest.approx(float(r.printed_value) / float(r.printed_scale))
    spring = table[(table.system == "spring") & (table.metric == "energy_mse")]
    assert spring.set_index("model")["value"].to_dict() == pytest.approx(
        {"baseline": 0.17, "hnn": 3.8e-4}
    )
    two_body = table[(table.system == "two_body") & (table.metric == "test_loss")]
    assert set(two_body["printed_scale"].astype(float)) == {1e6}
    assert two_body.set_index("model")["value"]["hnn"] == pytest.approx(2.8e-6)


def test_every_claim_holds_on_the_papers_own_numbers():
    results = report.paper_claim_ratios()
    assert {c.id for c in registry.all_claims() if c.id in results} == set(results)
    assert {c.id for cs in registry.claim_sets() if cs.published for c in cs.claims} == set(results)
    for res in results.values():
        assert res.outcome == claims.REPRODUCED, (res.claim.text, res.ratio)


def test_paper_comparison_shows_every_table1_cell(built):
    text = (built / "paper_comparison.md").read_text()
    table = [ln for ln in text.splitlines() if ln.startswith("| ") and "(" in ln.split("|")[1]]
    tasks = [
        ln
        for ln in table
        if re.search(
            r"\((spring|pendulum|real_pendulum|two_body|"
            r"three_body|pixel_pendulum)\)",
            ln,
        )
    ]
    assert len(tasks) == 18
    real = [ln for ln in tasks if "(real_pendulum)" in ln]
    assert len(real) == 3 and all(ln.count("—") >= 2 for ln in real)
    assert "6.3e4 / 39 ×10⁶" in text and "×10⁶" in text
    ours = next(ln for ln in tasks if "(spring)" in ln and "energy_mse" in ln)
    assert "4.2e-03 ± 2.8e-04" in ours  # seeds 0 and 1: 4.0e-3 and 4.4e-3
    assert "## Qualitative claims" in text
    assert "spring: HNN energy MSE >= 100x below baseline" in text


def _lookup(values):
    def lookup(system, model, metric):
        return values.get((system, model, metric))

    return lookup


def test_claims_are_evaluated_per_backend_pair():
    values = {
        ("spring", "mlp_torch", "energy_mse"): 1e-2,
        ("spring", "hnn_torch", "energy_mse"): 1e-5,
        ("spring", "mlp_jax", "energy_mse"): 1e-2,
        ("spring", "hnn_jax", "energy_mse"): 1e-3,
    }
    claim = next(c for c in registry.all_claims() if c.id == "spring.energy_mse.hnn_100x_lower")
    res = {
        r.backend: r
        for r in claims.evaluate_claims(_lookup(values), [claim], registry.family_models())
    }
    assert res["torch"].outcome == claims.REPRODUCED and res["torch"].ratio == pytest.approx(1000)
    assert res["jax"].outcome == claims.NOT_REPRODUCED and res["jax"].ratio == pytest.approx(10)
    assert "need >= 100x" in res["jax"].numbers()
    # No pair at all: one "not run" entry.
    (none,) = claims.evaluate_claims(_lookup({}), [claim], registry.family_models())
    assert none.outcome == claims.NOT_RUN and none.backend == "-"


@pytest.mark.parametrize(
    "claim_id, baseline, hnn, outcome",
    [
        ("spring.energy_mse.hnn_100x_lower", INF, 1e-5, claims.REPRODUCED),  # baseline diverged
        ("spring.energy_mse.hnn_100x_lower", 1e-2, INF, claims.NOT_REPRODUCED),
        ("spring.energy_mse.hnn_100x_lower", math.nan, 1e-5, claims.NOT_RUN),  # all failed
        ("spring.test_loss.similar", 0.037, 0.07, claims.REPRODUCED),
        ("spring.test_loss.similar", 0.037, 0.08, claims.NOT_REPRODUCED),
        ("spring.test_loss.similar", INF, 0.037, claims.NOT_REPRODUCED),
        ("real_pendulum.test_loss.baseline_lower", 2e-3, 6e-3, claims.REPRODUCED),
        ("real_pendulum.test_loss.baseline_lower", 6e-3, 6e-3, claims.NOT_REPRODUCED),
        ("pendulum.energy_mse.hnn_lower", 4e-2, 2.5e-2, claims.REPRODUCED),
        ("pendulum.energy_mse.hnn_lower", 2e-2, 2.5e-2, claims.NOT_REPRODUCED),
    ],
)
def test_claim_judgement(claim_id, baseline, hnn, outcome):
    claim = next(c for c in registry.all_claims() if c.id == claim_id)
    assert claim.judge(baseline, hnn)[0] == outcome


def test_claims_on_a_leaderboard(sweep):
    board = leaderboard(report.load_sweep(sweep))
    results = {r.claim.id: r for r in report.claim_results(board) if r.backend == "torch"}
    assert results["spring.energy_mse.hnn_100x_lower"].outcome == claims.REPRODUCED
    assert results["spring.test_loss.similar"].outcome == claims.REPRODUCED
    assert results["pendulum.energy_mse.hnn_lower"].outcome == claims.REPRODUCED
    everything = report.claim_results(board)
    assert {r.outcome for r in everything if r.claim.system == "two_body"} == {claims.NOT_RUN}


def test_on_sweep_end_writes_the_report_into_the_sweep(tmp_path, capsys):
    sweep = make_sweep(tmp_path / "s", pairs=(("spring", "hnn_torch"),), seeds=(0,))
    report.on_sweep_end(sweep)
    assert (sweep / "leaderboard.html").exists() and (sweep / "paper_comparison.md").exists()
    assert "leaderboard.html" in capsys.readouterr().out
    empty = tmp_path / "empty"
    empty.mkdir()
    report.on_sweep_end(empty)  # no records: a warning, no exception
    assert not (empty / "leaderboard.csv").exists()


def test_a_running_sweep_gets_a_leaderboard_of_its_finished_pairs(tmp_path):
    """The sweeper's rewrite while jobs finish (hnnbench._sweeping.sweeper._partial_report): the
    tables of the records so far, no figures (those come at the end)."""
    from hnnbench._sweeping import sweeper

    sweep = make_sweep(tmp_path / "s", pairs=(("spring", "hnn_torch"),), seeds=(0,))
    sweeper._partial_report(sweep)
    board = pd.read_csv(sweep / "leaderboard.csv")
    assert list(board["model"]) == ["hnn_torch"]
    assert (sweep / "leaderboard.md").exists() and not (sweep / "figures").exists()


# --------------------------------------------------------------------------- CLI


def test_report_cli(tmp_path):
    sweep = make_sweep(tmp_path / "s", pairs=(("spring", "hnn_torch"),), seeds=(0,))
    out = tmp_path / "cli-out"
    proc = hnnbench("report", str(sweep), "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    assert "hnn_torch" in proc.stdout and (out / "leaderboard.html").exists()


@pytest.mark.parametrize("case", ["missing", "empty", "no-arg", "bad-flag", "corrupt", "twice"])
def test_report_bad_input_is_one_line(case, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    corrupt = tmp_path / "corrupt" / "spring" / "mlp_torch" / "seed0"
    corrupt.mkdir(parents=True)
    (corrupt / records.RECORD_NAME).write_text("{")
    for part in ("a", "b"):  # one job in two sweeps: the mean would count it twice
        write_run(tmp_path / part, "spring", "hnn_torch", 0)
    args = {
        "missing": [str(tmp_path / "nope")],
        "empty": [str(empty)],
        "no-arg": [],
        "bad-flag": [str(empty), "--bogus"],
        "corrupt": [str(tmp_path / "corrupt")],
        "twice": [str(tmp_path / "a"), str(tmp_path / "b"), "--out", str(empty)],
    }[case]
    needle = {
        "missing": "does not exist",
        "empty": "No run records",
        "no-arg": "DIR",
        "bad-flag": "--bogus",
        "corrupt": str(corrupt / records.RECORD_NAME),
        "twice": "seed 0 (quick profile) is recorded twice",
    }[case]
    assert_one_line_error(hnnbench("report", *args), needle)


def test_a_claim_on_a_model_that_did_not_train_is_not_tested_and_a_recipe_is_named():
    """A claim is about a trained model: where most seeds of one side kept their first
    evaluation's weights, the result is "did not train" (not "not reproduced"); a claim
    whose source used its own recipe says the protocol track did not run it."""
    import pandas as pd

    from hnnbench._results.report.published import board_untrained

    claim = claims.Claim(
        id="c",
        system="spring",
        metric="energy_mse",
        relation="lower",
        families=("mlp", "hnn"),
        lower="hnn",
        factor=10,
        text="t",
        source="s",
        recipe="the paper's recipe",
    )
    values = {("spring", "mlp_jax", "energy_mse"): 1e-1, ("spring", "hnn_jax", "energy_mse"): 1.0}
    board = pd.DataFrame(
        [
            {
                "profile": "paper",
                "system": "spring",
                "model": "hnn_jax",
                "n_seeds": 5,
                "n_untrained": 3,
            },
            {
                "profile": "paper",
                "system": "spring",
                "model": "mlp_jax",
                "n_seeds": 5,
                "n_untrained": 2,
            },
        ]
    )
    pairs = {"jax": {"mlp": "mlp_jax", "hnn": "hnn_jax"}}
    (res,) = claims.evaluate_claims(_lookup(values), [claim], pairs, board_untrained(board))
    assert res.outcome == claims.NOT_TRAINED
    assert "hnn_jax did not train on 3 of 5 seeds" in res.numbers()
    assert "the paper's recipe not run" in res.note
    board.loc[0, "n_untrained"] = 2  # 2 of 5: trained; judged on the values
    (res,) = claims.evaluate_claims(_lookup(values), [claim], pairs, board_untrained(board))
    assert res.outcome == claims.NOT_REPRODUCED and "recipe not run" in res.note


def test_figures_of_many_panels_wrap_into_rows():
    from hnnbench._results.report.figures import MAX_COLUMNS, _new_figure

    fig, axes = _new_figure(13, width=3.8, height=3.4)
    assert len(axes) == 13 and MAX_COLUMNS == 4
    assert fig.get_figwidth() == pytest.approx(4 * 3.8)  # four panels a row, not 13
    assert fig.get_figheight() == pytest.approx(4 * 3.4)
    assert sum(ax.get_visible() for ax in fig.axes) == 13
    fig, axes = _new_figure(3)
    assert len(axes) == 3 and fig.get_figheight() == pytest.approx(3.6)


def test_colours_are_the_familys_shaded_per_twin_and_stable():
    """One colour per family, from the registry's order, whatever rows a figure holds;
    its twins in shades of it; colour-blind-safe hues; no red-green rank scale."""
    from hnnbench._results.report import figures, style

    families = {"mlp_torch": "mlp", "mlp_jax": "mlp", "hnn_torch": "hnn", "hnn_jax": "hnn"}
    alone = style.color("hnn_jax", {"hnn_jax": "hnn"}, ["hnn_jax"])
    beside = style.color("hnn_jax", families, list(families))
    assert alone == beside  # the rows present do not move it
    assert style.family_color("hnn") == style.color("hnn_torch", families)
    assert style.color("hnn_jax", families) != style.color("hnn_torch", families)
    assert style.family_color("mlp") != style.family_color("hnn")
    assert style.family_color("mlp") in style.PALETTE[:6]  # Okabe & Ito's
    assert style.family_color("oracle") in style.REFERENCE_COLORS
    import subprocess
    import sys

    code = (
        "from hnnbench._results.report import style; "
        "print(style.family_color('a_family_not_installed'))"
    )
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert other.stdout.strip() == style.family_color("a_family_not_installed")  # stable
    torch, jax = (style.line(m, "", families, [m]) for m in ("hnn_torch", "hnn_jax"))
    assert torch["ls"] != jax["ls"] and torch["lw"] > jax["lw"]
    assert "RdYlGn" not in figures.RANK_CMAP and "viridis" in figures.RANK_CMAP
    # a figure that names models only (study summaries) colours them by their family
    assert style.model_color("hnn_jax") == style.color("hnn_jax", families)
    assert style.model_color("a_model_not_installed") == style.family_color("a_model_not_installed")


def test_log_axes_label_a_narrow_range_with_plain_numbers_and_no_minor_labels():
    """An axis spanning about one decade (a system's tuning CPU, 164 to 2249 s) is
    labelled at 1, 2 and 5 per decade in plain numbers, its minor ticks unlabelled (the
    overlapping ``2×10^2 3×10^2 4×10^2`` labels before); a wide one at decades only."""
    from matplotlib.figure import Figure

    from hnnbench._results.report.style import log_axes

    fig = Figure()
    ax = fig.subplots()
    ax.scatter([164, 2249], [1e-6, 1e-2])
    log_axes(ax)
    fig.canvas.draw()
    xs = [t.get_text() for t in ax.get_xticklabels() if t.get_text()]
    assert {"200", "500", "1000", "2000"} <= set(xs) and not any("times" in x for x in xs)
    assert not [t.get_text() for t in ax.xaxis.get_minorticklabels() if t.get_text()]
    ys = {t.get_text() for t in ax.get_yticklabels() if t.get_text()}
    assert "0.0001" in ys and "0.0002" not in ys


def test_a_long_figure_title_is_wrapped_to_the_figure_width():
    from matplotlib.figure import Figure

    from hnnbench._results.report.figures import _fit_suptitle

    fig = Figure(figsize=(5.0, 3.0))
    fig.subplots(1, 1)
    fig.suptitle("word " * 60)
    _fit_suptitle(fig)
    lines = fig._suptitle.get_text().splitlines()
    assert len(lines) > 1 and max(map(len, lines)) <= 5.0 * 72 / (0.55 * 12)
    fig.suptitle("short")
    _fit_suptitle(fig)
    assert fig._suptitle.get_text() == "short"


def test_the_pages_across_systems_section_leads_with_the_mean_ranks(sweep):
    """The HTML page's headline is aggregate.md's: the mean ranks (no normalisation)
    before the IQM of normalised scores, which is labelled a second view."""
    report.main([str(sweep), "--no-figures"])
    page = (sweep / "leaderboard.html").read_text()
    section = page.split('id="across"')[1].split("<h2")[0]
    assert "mean rank" in section
    if "second view" in section:
        assert section.index("mean rank") < section.index("second view")
    md = (sweep / "aggregate.md").read_text()
    assert ("second view" in md) == ("second view" in section)
