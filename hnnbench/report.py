"""``hnnbench report DIR [--out OUT]``: tables and figures from a sweep's run records.

Writes into OUT (default DIR):

- ``leaderboard.csv``: one row per (system, model), and per variant where runs differ in
  other overrides (:func:`hnnbench.table.variant_labels`); status counts, mean and std over
  seeds of every metric (``<metric>_mean``, ``<metric>_std``), mean wall times. This is
  also the reference format of ``hnnbench check``.
- ``leaderboard.md``: the same table, ``mean ± std``, for a README.
- ``paper_comparison.md``: our values next to Table 1 of Greydanus et al. (2019), and
  the paper's qualitative claims (:mod:`hnnbench.claims`) evaluated on our runs.
- ``figures/<system>_{phase,energy,learned_energy,loss}.png``: rollouts of the lowest
  seed, true energy along each rollout, the learned conserved quantity, loss curves
  (``<system>__<variant>_...`` for each variant).
- ``leaderboard.html``: one self-contained page with all of the above.

:func:`on_sweep_end` is called by the end-of-sweep Hydra callback.
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import html
import logging
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Optional

import numpy as np
import pandas as pd
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from hnnbench import claims as C
from hnnbench import records as R
from hnnbench.errors import HnnbenchError
from hnnbench.table import (
    MODEL_ORDER,
    SYSTEM_ORDER,
    display_frame,
    format_value,
    leaderboard,
    order_key,
    variant_labels,
)

log = logging.getLogger("hnnbench")

__all__ = [
    "ReportError",
    "Report",
    "board_lookup",
    "claim_results",
    "load_sweep",
    "main",
    "on_sweep_end",
    "paper_table",
    "provenance",
    "write_report",
]

PAPER_TABLE = "paper_table1.csv"
PAPER_METRICS = ("train_loss", "test_loss", "energy_mse")
FIGURE_KINDS = ("phase", "energy", "learned_energy", "loss")
#: How many evaluation trajectories the rollout figures show.
N_TRAJ_SHOWN = 3

_COLORS = {"mlp_torch": "#1f77b4", "hnn_torch": "#d62728", "mlp_jax": "#17becf",
           "hnn_jax": "#ff7f0e", "oracle": "#2ca02c"}
_SPARE_COLORS = ("#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#7f7f7f")
_TRAJ_COLORS = ("#1f77b4", "#ff7f0e", "#2ca02c")


class ReportError(HnnbenchError):
    """A sweep directory that cannot be reported on."""


@dataclass
class Report:
    out: Path
    board: pd.DataFrame
    files: dict[str, Path] = field(default_factory=dict)
    figures: list[tuple[str, str, Path]] = field(default_factory=list)  # (system, kind, path)


# --------------------------------------------------------------------------- inputs


def load_sweep(directory: Path | str) -> list[dict[str, Any]]:
    """The run records under ``directory``; :class:`ReportError` if there are none."""
    directory = Path(directory)
    if not directory.exists():
        raise ReportError(f"Sweep directory {directory} does not exist")
    if not directory.is_dir():
        raise ReportError(f"{directory} is not a directory (expected a sweep directory)")
    recs = R.load_records(directory)
    if not recs:
        raise ReportError(
            f"No run records ({R.RECORD_NAME}) under {directory}; "
            "run a sweep first, e.g. hnnbench -m system=spring model=all profile=quick"
        )
    return recs


def paper_table() -> pd.DataFrame:
    """Table 1 of the paper (and the README's three-body numbers), natural units."""
    ref = resources.files("hnnbench").joinpath("resources").joinpath(PAPER_TABLE)
    with ref.open("r", encoding="utf-8") as fh:
        frame = pd.read_csv(fh, dtype={"printed_value": str, "printed_pm": str,
                                       "printed_scale": str})
    return frame


def _plain_rows(board: pd.DataFrame) -> pd.DataFrame:
    """The rows without a variant: the comparison with the paper is made on those only
    (a variant row is a setting the sweep varied away from the others)."""
    if "variant" not in board:
        return board
    return board[board["variant"].fillna("").astype(str) == ""]


def board_lookup(board: pd.DataFrame, profile: Optional[str] = None) -> C.Lookup:
    """A :data:`hnnbench.claims.Lookup` on a leaderboard (one profile), over the rows
    without a variant (:func:`_plain_rows`)."""
    if profile is not None and "profile" in board:
        board = board[board["profile"].astype(str) == str(profile)]
    board = _plain_rows(board)
    index = {(r["system"], r["model"]): r for _, r in board.iterrows()}

    def lookup(system: str, model: str, metric: str) -> Optional[float]:
        row = index.get((system, model))
        if row is None:
            return None
        value = row.get(f"{metric}_mean", math.nan)
        return math.nan if value is None or pd.isna(value) else float(value)

    return lookup


def paper_lookup() -> C.Lookup:
    table = paper_table()
    index = {(r.system, r.model, r.metric): float(r.value) for r in table.itertuples()}
    roles = {"baseline": "baseline", "hnn": "hnn"}

    def lookup(system: str, model: str, metric: str) -> Optional[float]:
        return index.get((system, roles.get(model, model), metric))

    return lookup


def claim_results(board: pd.DataFrame, profile: Optional[str] = None) -> list[C.ClaimResult]:
    """The paper's claims evaluated on a leaderboard, per backend pair."""
    return C.evaluate_claims(board_lookup(board, profile))


def paper_claim_ratios() -> dict[str, C.ClaimResult]:
    """Each claim evaluated on the paper's own numbers (all reproduced)."""
    pairs = {"paper": {"baseline": "baseline", "hnn": "hnn"}}
    return {r.claim.id: r for r in C.evaluate_claims(paper_lookup(), pairs=pairs)}


def _profiles(board: pd.DataFrame) -> list[str]:
    return list(dict.fromkeys(str(p) for p in board["profile"])) if not board.empty else []


def _main_profile(board: pd.DataFrame) -> Optional[str]:
    profiles = _profiles(board)
    if not profiles:
        return None
    return "paper" if "paper" in profiles else profiles[0]


# --------------------------------------------------------------------------- tables


def _md_table(frame: pd.DataFrame) -> str:
    from tabulate import tabulate

    return tabulate(frame, headers="keys", tablefmt="github", showindex=False,
                    disable_numparse=True)


def _seed_line(board: pd.DataFrame) -> str:
    profiles = ", ".join(f"`{p}`" for p in _profiles(board)) or "?"
    seeds = sorted({s for v in board["seeds"].astype(str) for s in v.split(";") if s != ""},
                   key=lambda s: (len(s), s))
    n = board["n_seeds"].astype(int)
    counts = f"{n.min()}" if n.min() == n.max() else f"{n.min()}–{n.max()}"
    return (f"Profile {profiles}; {counts} seed(s) per pair (seeds {', '.join(seeds)}). "
            "Cells are mean ± std over seeds (std omitted for one seed), over the `ok` runs "
            "of a pair (its `diverged` runs if none is ok; `inf` = rollout diverged; "
            "`—` = no value).")


def provenance(recs: Sequence[dict[str, Any]]) -> dict[str, list[str]]:
    """Where the records came from: distinct commands, git commits, devices, dates.

    Each list is sorted and deduplicated; a sweep resumed under another command or
    commit shows all of them.
    """
    def distinct(values: Any) -> list[str]:
        return sorted({str(v) for v in values if v not in (None, "")})

    return {
        "command": distinct(r.get("command") for r in recs),
        "commit": distinct((r.get("environment") or {}).get("git_commit") for r in recs),
        "device": distinct(r.get("device") for r in recs),
        "hnnbench": distinct((r.get("environment") or {}).get("hnnbench") for r in recs),
        "date": distinct(str(r.get("created_at") or "")[:10] for r in recs),
    }


def provenance_lines(prov: dict[str, list[str]]) -> list[str]:
    """Markdown bullet lines for :func:`provenance`."""
    def join(key: str, code: bool = True) -> str:
        vals = prov.get(key) or ["unknown"]
        return ", ".join(f"`{v}`" if code else v for v in vals)

    return [
        f"- Command: {join('command')}",
        f"- Git commit: {join('commit')}; hnnbench {join('hnnbench', code=False)}",
        f"- Device: {join('device', code=False)}; run on {join('date', code=False)}",
    ]


def leaderboard_markdown(board: pd.DataFrame,
                         prov: Optional[dict[str, list[str]]] = None) -> str:
    lines = ["# Leaderboard", "", _seed_line(board), ""]
    if prov is not None:
        lines += [*provenance_lines(prov), ""]
    lines.append(_md_table(display_frame(board)))
    lines += ["", "Machine-readable: `leaderboard.csv`. Built by `hnnbench report` from the "
              "run records; do not edit by hand.", ""]
    return "\n".join(lines)


def _ours_cell(board: pd.DataFrame, profile: Optional[str], system: str, model: str,
               metric: str) -> str:
    sel = _plain_rows(board)
    sel = sel[(sel["system"] == system) & (sel["model"] == model)]
    if profile is not None:
        sel = sel[sel["profile"].astype(str) == profile]
    if sel.empty or f"{metric}_mean" not in sel:
        return "—"
    row = sel.iloc[0]
    return format_value(row[f"{metric}_mean"], row[f"{metric}_std"])


def _backends_shown(board: pd.DataFrame) -> list[str]:
    shown = [b for b, pair in C.BACKEND_PAIRS.items()
             if board["model"].isin(list(pair.values())).any()]
    return shown or ["torch"]


def comparison_frame(board: pd.DataFrame) -> pd.DataFrame:
    """Every Table 1 cell (and the README's three-body numbers) next to ours."""
    profile = _main_profile(board)
    paper = paper_table()
    backends = _backends_shown(board)
    rows = []
    systems = sorted(paper["system"].unique(), key=lambda s: order_key(s, SYSTEM_ORDER))
    for system in systems:
        for metric in PAPER_METRICS:
            cells = paper[(paper["system"] == system) & (paper["metric"] == metric)]
            if cells.empty:
                continue
            by_role = {r.model: r for r in cells.itertuples()}
            any_row = cells.iloc[0]
            row: dict[str, Any] = {"task": f"{any_row['task']} ({system})", "metric": metric}
            for role in ("baseline", "hnn"):
                r = by_role.get(role)
                row[f"paper {C._LABEL[role]}"] = "—" if r is None else _paper_cell(r)
            b, h = by_role.get("baseline"), by_role.get("hnn")
            scale = str(any_row["printed_scale"])
            printed = f"{b.printed_value} / {h.printed_value}" if b is not None and h is not None \
                else "—"
            row["paper printed (B / HNN)"] = printed + ("" if scale in ("1", "1.0")
                                                       else f" ×{_pow10(scale)}")
            for backend in backends:
                pair = C.BACKEND_PAIRS[backend]
                for role in ("baseline", "hnn"):
                    row[f"ours {C._LABEL[role]} ({backend})"] = _ours_cell(
                        board, profile, system, pair[role], metric)
            row["source"] = str(any_row["source"]).split(" (")[0]  # "Table 1" / "README"
            rows.append(row)
    return pd.DataFrame(rows)


def _pow10(scale: str) -> str:
    exp = int(round(math.log10(float(scale))))
    sup = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")
    return f"10{str(exp).translate(sup)}"


def _paper_cell(r: Any) -> str:
    value = f"{float(r.value):.2e}"
    if isinstance(r.pm, float) and math.isnan(r.pm):
        return value
    return f"{value} ± {float(r.pm):.1e}"


def claims_frame(board: pd.DataFrame) -> pd.DataFrame:
    results = claim_results(board, _main_profile(board))
    paper = paper_claim_ratios()
    rows = []
    for res in results:
        p = paper.get(res.claim.id)
        rows.append({
            "claim": res.claim.text,
            "backend": res.backend,
            "result": res.outcome,
            "our numbers": res.numbers(),
            "paper": f"{C._fmt_ratio(p.ratio)} ({res.claim.source.split(' (')[0]})" if p else "—",
        })
    return pd.DataFrame(rows)


def comparison_markdown(board: pd.DataFrame) -> str:
    profile = _main_profile(board)
    claims = claims_frame(board)
    counts = claims["result"].value_counts().to_dict()
    lines = [
        "# Comparison with Greydanus et al. (2019), Table 1",
        "",
        _seed_line(board),
        "",
    ]
    if profile != "paper":
        lines += [f"Note: profile `{profile}` is not the paper's settings (profile `paper`); "
                  "this comparison is indicative only.", ""]
    lines += [
        "Values are in natural units: the paper printed them scaled (×10³; two-body losses "
        "×10⁶; pixel-pendulum losses ×10⁵), column *paper printed* shows them as printed. "
        "The paper's ± is a standard error over test points or evaluation splits, not over "
        "training seeds; ours is the std over seeds. Three-body numbers are from the "
        "authors' README (not in Table 1). Baseline = `mlp_torch` / `mlp_jax`, "
        "HNN = `hnn_torch` / `hnn_jax`. `—` = no run.",
        "",
        _md_table(comparison_frame(board)),
        "",
        "## Qualitative claims",
        "",
        "Declared in `hnnbench/claims.py`; evaluated per backend on the means above. "
        "Column *paper* is the same ratio on the paper's numbers.",
        "",
        _md_table(claims),
        "",
        ", ".join(f"{n} {k}" for k, n in sorted(counts.items())) + ".",
        "",
    ]
    return "\n".join(lines)


# --------------------------------------------------------------------------- figures


@dataclass(eq=False)  # compared by identity: the arrays make field equality ambiguous
class _Run:
    model: str
    seed: int
    status: str
    arrays: dict[str, np.ndarray]


def _color(model: str, models: Sequence[str]) -> str:
    if model in _COLORS:
        return _COLORS[model]
    others = [m for m in models if m not in _COLORS]
    return _SPARE_COLORS[others.index(model) % len(_SPARE_COLORS)]


def _line(model: str, models: Sequence[str]) -> dict[str, Any]:
    """Line style of a model in the shared-axes figures: JAX models dashed and thin on
    top of a wide solid line for the others, so that a torch model and its JAX twin,
    which often coincide (same seed, same initial weights), both stay visible."""
    if model.endswith("_jax"):
        return {"color": _color(model, models), "lw": 1.3, "ls": (0, (4, 2)), "zorder": 3}
    return {"color": _color(model, models), "lw": 2.4, "ls": "-", "alpha": 0.85, "zorder": 2}


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as z:
            return {k: np.asarray(z[k]) for k in z.files}
    except (OSError, ValueError) as err:
        log.warning("cannot read %s: %s", path, err)
        return {}


def _runs_for_figures(recs: list[dict[str, Any]]) -> tuple[Optional[int], list[_Run]]:
    """The lowest seed with rollout arrays, and each model's run for that seed."""
    with_arrays = [r for r in recs if r.get("path") and (Path(r["path"]) / "rollout.npz").exists()]
    if not with_arrays:
        return None, []
    seed = min(int(r.get("seed") or 0) for r in with_arrays)
    runs = []
    for rec in with_arrays:
        if int(rec.get("seed") or 0) != seed:
            continue
        arrays = _load_npz(Path(rec["path"]) / "rollout.npz")
        if arrays:
            runs.append(_Run(rec["model"], seed, rec["status"], arrays))
    runs.sort(key=lambda r: order_key(r.model, MODEL_ORDER))
    return seed, runs


def _new_figure(n_panels: int, width: float = 4.2, height: float = 3.6) -> Any:

    fig = Figure(figsize=(max(width * n_panels, 5.0), height), layout="constrained")
    axes = fig.subplots(1, n_panels, squeeze=False)[0]
    return fig, list(axes)


def _save(fig: Any, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.tmp.png")
    fig.savefig(tmp, dpi=100, format="png")
    tmp.replace(path)
    return path


def _phase_figure(system: str, seed: int, runs: list[_Run], models: list[str]) -> Any:
    shown = [r for r in runs if "states_hat" in r.arrays and "states_true" in r.arrays]
    if not shown:
        return None
    n_traj = min(N_TRAJ_SHOWN, shown[0].arrays["states_true"].shape[0])
    fig, axes = _new_figure(len(shown), width=3.8)
    for ax, run in zip(axes, shown, strict=True):
        true, hat = run.arrays["states_true"], run.arrays["states_hat"]
        n = true.shape[-1] // 2
        for k in range(min(n_traj, true.shape[0])):
            c = _TRAJ_COLORS[k % len(_TRAJ_COLORS)]
            ax.plot(hat[k, :, 0], hat[k, :, n], "-", color=c, lw=2.0, alpha=0.75, zorder=2)
            ax.plot(true[k, :, 0], true[k, :, n], "--", color="k", lw=0.9, zorder=3)
            ax.plot(true[k, 0, 0], true[k, 0, n], "o", color=c, ms=5, mec="k", zorder=4)
        ax.set_title(f"{run.model}", color=_color(run.model, models))
        ax.set_xlabel("q1")
        ax.set_ylabel("p1")
        ax.grid(alpha=0.3)
    handles = [Line2D([], [], color="k", ls="--", lw=0.9, label="true")]
    handles += [Line2D([], [], color=_TRAJ_COLORS[k], lw=2.0, label=f"rollout, trajectory {k + 1}")
                for k in range(n_traj)]
    handles.append(Line2D([], [], color="w", marker="o", mec="k", mfc="0.6", label="start"))
    fig.legend(handles=handles, loc="outside right upper", fontsize=8)
    fig.suptitle(f"{system}: phase portraits (q1, p1) of evaluation trajectories 1–{n_traj}, "
                 f"true vs model rollout (seed {seed})")
    return fig


def _energy_figure(system: str, seed: int, runs: list[_Run], models: list[str]) -> Any:
    shown = [r for r in runs if "energy_hat" in r.arrays]
    if not shown:
        return None
    ref = shown[0].arrays
    t, e_true = ref["t"], ref["energy_true"]
    n_traj = min(N_TRAJ_SHOWN, e_true.shape[0])
    fig, axes = _new_figure(n_traj)
    for k, ax in enumerate(axes):
        ax.plot(t, e_true[k], "k--", lw=2.0, label="ground truth")
        for run in shown:
            ax.plot(run.arrays["t"], run.arrays["energy_hat"][k], label=run.model,
                    **_line(run.model, models))
        ax.set_title(f"trajectory {k + 1}")
        ax.set_xlabel("time")
        ax.set_ylabel("true energy E(x̂(t))")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize=8)
    missing = [r.model for r in runs if r not in shown]
    note = f"; no rollout: {', '.join(missing)}" if missing else ""
    fig.suptitle(f"{system}: true energy along each model's rollout (seed {seed}){note}")
    return fig


def _learned_energy_figure(system: str, seed: int, runs: list[_Run], models: list[str]) -> Any:
    shown = [r for r in runs if "learned_energy" in r.arrays]
    if not shown:
        return None
    n_traj = min(N_TRAJ_SHOWN, shown[0].arrays["learned_energy"].shape[0])
    fig, axes = _new_figure(n_traj)
    for k, ax in enumerate(axes):
        for run in shown:
            h = run.arrays["learned_energy"][k]
            ax.plot(run.arrays["t"], h - h[0], label=run.model, **_line(run.model, models))
        ax.axhline(0.0, color="k", lw=0.8, ls=":")
        ax.set_title(f"trajectory {k + 1}")
        ax.set_xlabel("time")
        ax.set_ylabel("H(x̂(t)) − H(x̂(0))")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right upper", fontsize=8)
    fig.suptitle(f"{system}: learned conserved quantity along its own rollout, shifted to "
                 f"start at 0 (seed {seed})")
    return fig


def _loss_figure(system: str, seed: int, runs: list[_Run], models: list[str]) -> Any:
    shown = [r for r in runs if "history.step" in r.arrays and r.arrays["history.step"].size]
    if not shown:
        return None
    fig, axes = _new_figure(1, width=7.0, height=4.2)
    ax = axes[0]
    for run in shown:
        step = run.arrays["history.step"]
        color = _color(run.model, models)
        for key, style, label in (("history.train_loss", "-", "train"),
                                  ("history.test_loss", "--", "test")):
            if key in run.arrays and run.arrays[key].size == step.size:
                y = np.where(run.arrays[key] > 0, run.arrays[key], np.nan)
                ax.plot(step, y, style, color=color, lw=1.3, label=f"{run.model} {label}")
    ax.set_yscale("log")
    ax.set_xlabel("training step")
    ax.set_ylabel("loss")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best", fontsize=8, ncol=2)
    ax.set_title(f"{system}: training and test loss (seed {seed})")
    return fig


_FIGURES = {"phase": _phase_figure, "energy": _energy_figure,
            "learned_energy": _learned_energy_figure, "loss": _loss_figure}


def _variant_slug(variant: str, limit: int = 80) -> str:
    """A file-name form of a variant; a long one is cut and given a hash of the whole,
    so two variants never share a name."""
    slug = re.sub(r"[^A-Za-z0-9._-]+", "_", variant.replace("=", "-"))
    if len(slug) <= limit:
        return slug
    return f"{slug[:limit]}-{hashlib.sha1(variant.encode()).hexdigest()[:10]}"


def make_figures(recs: list[dict[str, Any]], directory: Path) -> list[tuple[str, str, Path]]:
    """Figures per system into ``directory``; ``[(system, kind, path)]``."""
    directory = Path(directory)
    out: list[tuple[str, str, Path]] = []
    profiles = sorted({str(r.get("profile")) for r in recs})
    groups: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    variants = variant_labels([rec.get("overrides") for rec in recs])
    for rec, variant in zip(recs, variants, strict=True):
        key = (str(rec.get("profile")), str(rec.get("system")), variant)
        groups.setdefault(key, []).append(rec)
    keys = sorted(groups, key=lambda k: (k[0], order_key(k[1], SYSTEM_ORDER), k[2]))
    for profile, system, variant in keys:
        seed, runs = _runs_for_figures(groups[(profile, system, variant)])
        if seed is None:
            continue
        models = [r.model for r in runs]
        stem = system if len(profiles) == 1 else f"{profile}_{system}"
        if variant:  # one figure set per variant, named after it
            stem += "__" + _variant_slug(variant)
        for kind, make in _FIGURES.items():
            try:
                fig = make(f"{system} [{variant}]" if variant else system, seed, runs, models)
            except Exception as err:  # one broken array must not stop the report
                log.warning("figure %s/%s failed: %s", system, kind, err)
                continue
            if fig is not None:
                label = system if len(profiles) == 1 else f"{system} ({profile})"
                label += f" [{variant}]" if variant else ""
                out.append((label, kind, _save(fig, directory / f"{stem}_{kind}.png")))
    return out


# --------------------------------------------------------------------------- html

_CSS = """
body{font-family:-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:24px auto;
max-width:1500px;padding:0 16px;color:#222}
h1{font-size:1.6em}h2{margin-top:1.6em;border-bottom:1px solid #ddd;padding-bottom:4px}
table{border-collapse:collapse;font-size:13px;margin:8px 0}
th,td{border:1px solid #ccc;padding:3px 8px;text-align:right;white-space:nowrap}
th{background:#f3f3f3}td.txt,th.txt{text-align:left}
tr:nth-child(even) td{background:#fafafa}
.wrap{overflow-x:auto}
td.diverged,td.inf{color:#b00}td.reproduced{color:#070}td.notrep{color:#b00}
td.notrun{color:#888}
.claims td.txt{white-space:normal}
img{max-width:100%;border:1px solid #eee;margin:6px 0}
.note{color:#555;font-size:13px}
"""


_TEXT_COLUMNS = {"system", "model", "status", "task", "metric", "source", "claim", "backend",
                 "result", "our numbers"}


def _html_table(frame: pd.DataFrame, cls: str = "", status_col: Optional[str] = None) -> str:
    txt = ' class="txt"'
    head = "".join(f"<th{txt if c in _TEXT_COLUMNS else ''}>{html.escape(str(c))}</th>"
                   for c in frame.columns)
    body = []
    for _, row in frame.iterrows():
        cells = []
        for col in frame.columns:
            value = str(row[col])
            classes = ["txt"] if col in _TEXT_COLUMNS else []
            if col == status_col:
                outcome = {"reproduced": "reproduced", "not reproduced": "notrep",
                           "not run": "notrun"}.get(value)
                if outcome:
                    classes.append(outcome)
                elif "diverged" in value or "failed" in value:
                    classes.append("diverged")
            elif value == "inf":
                classes.append("inf")
            attr = f' class="{" ".join(classes)}"' if classes else ""
            cells.append(f"<td{attr}>{html.escape(value)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return (f'<div class="wrap"><table class="{cls}"><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(body)}</tbody></table></div>")


def _inline_code(markdown: str) -> str:
    """Escape ``markdown`` for HTML, turning its `code` spans into <code> elements."""
    parts = markdown.split("`")
    return "".join(f"<code>{html.escape(p)}</code>" if i % 2 else html.escape(p)
                   for i, p in enumerate(parts))


def _img(path: Path, alt: str) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def report_html(board: pd.DataFrame, figures: list[tuple[str, str, Path]],
                prov: Optional[dict[str, list[str]]] = None) -> str:
    titles = {"phase": "Phase portraits (q1 vs p1)", "energy": "True energy along rollouts",
              "learned_energy": "Learned conserved quantity", "loss": "Loss curves"}
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        "<title>hnnbench leaderboard</title>", f"<style>{_CSS}</style></head><body>",
        "<h1>hnnbench leaderboard</h1>",
        f'<p class="note">{_inline_code(_seed_line(board))}</p>',
        *([f'<p class="note">{_inline_code(line[2:])}</p>' for line in provenance_lines(prov)]
          if prov is not None else []),
        _html_table(display_frame(board), "board", status_col="status"),
        "<h2>Comparison with Greydanus et al. (2019), Table 1</h2>",
        '<p class="note">Natural units (the paper printed ×10³, two-body losses ×10⁶, '
        "pixel losses ×10⁵); paper ± = standard error, ours = std over seeds. "
        "Details in paper_comparison.md.</p>",
        _html_table(comparison_frame(board), "paper"),
        "<h2>Qualitative claims of the paper</h2>",
        _html_table(claims_frame(board), "claims", status_col="result"),
    ]
    systems: dict[str, list[tuple[str, Path]]] = {}
    for system, kind, path in figures:
        systems.setdefault(system, []).append((kind, path))
    for system, figs in systems.items():
        parts.append(f'<h2 id="{html.escape(system)}">{html.escape(system)}</h2>')
        for kind, path in figs:
            parts.append(f"<h3>{html.escape(titles.get(kind, kind))}</h3>")
            parts.append(_img(path, f"{system} {kind}"))
    parts.append('<p class="note">Generated by <code>hnnbench report</code> from the run '
                 "records.</p></body></html>")
    return "\n".join(parts) + "\n"


# --------------------------------------------------------------------------- entry points


def write_report(sweep_dir: Path | str, out: Path | str | None = None,
                 figures: bool = True) -> Report:
    """Build every table and figure of ``sweep_dir`` into ``out`` (default: the sweep);
    ``figures=False`` skips the figures (the HTML page then has none)."""
    sweep_dir = Path(sweep_dir)
    recs = load_sweep(sweep_dir)
    out = Path(out) if out is not None else sweep_dir
    if out.exists() and not out.is_dir():
        raise ReportError(f"--out {out} exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ReportError(f"Cannot create output directory {out}: {err.strerror}") from None
    board = leaderboard(recs)
    report = Report(out=out, board=board)
    csv_path = out / "leaderboard.csv"
    R.atomic_write_text(csv_path, board.to_csv(index=False))
    report.files["csv"] = csv_path
    report.files["md"] = out / "leaderboard.md"
    prov = provenance(recs)
    R.atomic_write_text(report.files["md"], leaderboard_markdown(board, prov))
    report.files["paper"] = out / "paper_comparison.md"
    R.atomic_write_text(report.files["paper"], comparison_markdown(board))
    report.figures = make_figures(recs, out / "figures") if figures else []
    report.files["html"] = out / "leaderboard.html"
    R.atomic_write_text(report.files["html"], report_html(board, report.figures, prov))
    return report


class _Parser(argparse.ArgumentParser):
    """argparse that raises a one-line :class:`HnnbenchError` instead of exiting."""

    def error(self, message: str) -> Any:  # type: ignore[override]
        usage = " ".join(self.format_usage().split()[1:])
        raise HnnbenchError(f"{message} (usage: {usage})")


def _parser() -> _Parser:
    p = _Parser(prog="hnnbench report",
                description="Tables (CSV, Markdown, HTML) and figures from a sweep's records.")
    p.add_argument("dir", metavar="DIR", help="sweep directory (searched for result.json)")
    p.add_argument("--out", metavar="OUT", default=None, help="output directory (default DIR)")
    p.add_argument("--no-figures", action="store_true", help="tables only (faster)")
    return p


def main(args: Sequence[str]) -> int:
    ns = _parser().parse_args(list(args))
    report = write_report(Path(ns.dir), ns.out, figures=not ns.no_figures)
    print(_md_table(display_frame(report.board)))
    print()
    print(f"wrote {report.files['csv']}, {report.files['md'].name}, "
          f"{report.files['paper'].name}, {report.files['html'].name} and "
          f"{len(report.figures)} figure(s) in {report.out / 'figures'}")
    return 0


def on_sweep_end(sweep_dir: Path | str) -> None:
    """End-of-multirun hook: write the report into the sweep directory."""
    try:
        report = write_report(sweep_dir)
    except ReportError as err:
        log.warning("no report: %s", err)
        return
    print(f"report: {report.files['html']} (leaderboard.csv/.md, paper_comparison.md, "
          f"{len(report.figures)} figures)")
