"""Compare the angle embeddings (``model.angle_embedding``) side by side, on validation.

Reads one sweep directory per embedding, each the same sweep with one value of
``model.angle_embedding``, and prints a Markdown table of the validation loss of every
(system, model) pair under each embedding, plus each embedding's geometric-mean ratio
to ``none`` over the pairs that ran ``ok`` under all of them. Only validation is read:
the test set never chooses. ``--write`` puts the table into docs/MODELS.md
between its ``embedding`` markers.

    for e in cos_sin wrap none; do
      hnnbench -m system=pendulum,real_pendulum,double_pendulum,real_double_pendulum \\
        model=mlp_jax,hnn_jax,dhnn_jax,lnn_jax,so_mlp_jax seed=0 model.angle_embedding=$e \\
        hydra/launcher=joblib hydra.launcher.n_jobs=2 hydra.sweep.dir=runs/embedding/$e
    done
    python scripts/analysis/embedding_comparison.py runs/embedding [--write]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "MODELS.md"
BEGIN, END = "<!-- embedding:begin -->", "<!-- embedding:end -->"
EMBEDDINGS = ("cos_sin", "wrap", "none")


def _value(rec: dict, metric: str) -> float:
    value = (rec.get("metrics") or {}).get(metric, {}).get("mean")
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def table(root: Path) -> str:
    from hnnbench._record.loader import load

    found: dict[tuple[str, str], dict[str, dict]] = {}
    for embedding in EMBEDDINGS:
        recs, _ = load(root / embedding)
        for rec in recs:
            found.setdefault((rec["system"], rec["model"]), {})[embedding] = rec
    lines = [
        "| system | model | "
        + " | ".join(f"val_loss {e}" for e in EMBEDDINGS)
        + " | lowest | status "
        + " / ".join(EMBEDDINGS)
        + " |",
        "|---|---|" + "---|" * (len(EMBEDDINGS) + 2),
    ]
    ratios: dict[str, list[float]] = {e: [] for e in EMBEDDINGS}
    wins: dict[str, int] = {e: 0 for e in EMBEDDINGS}
    for (system, model), by in sorted(found.items()):
        if set(by) != set(EMBEDDINGS):
            continue
        val = {e: _value(by[e], "val_loss") for e in EMBEDDINGS}
        ok = all(by[e].get("status") == "ok" and math.isfinite(val[e]) for e in EMBEDDINGS)
        best = min(EMBEDDINGS, key=lambda e: val[e] if math.isfinite(val[e]) else math.inf)
        if ok:
            wins[best] += 1
            for e in EMBEDDINGS:
                ratios[e].append(math.log(val[e] / val["none"]))
        lines.append(
            f"| {system} | {model} | "
            + " | ".join(f"{val[e]:.3g}" for e in EMBEDDINGS)
            + f" | {best} | "
            + " / ".join(str(by[e].get("status")) for e in EMBEDDINGS)
            + " |"
        )
    n = len(ratios["none"])
    summary = (
        ", ".join(
            f"`{e}` {math.exp(sum(r) / n):.3g}× (lowest on {wins[e]} of {n})"
            for e, r in ratios.items()
        )
        if n
        else "no pair trained under every embedding"
    )
    return "\n".join(lines) + (
        f"\n\nGeometric mean of the validation loss relative to `none`, over the {n} pairs "
        f"that trained under all three: {summary}."
    )


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="directory holding cos_sin/, wrap/, none/")
    parser.add_argument("--write", action="store_true", help="update docs/MODELS.md")
    args = parser.parse_args(argv)
    missing = [e for e in EMBEDDINGS if not (args.root / e).is_dir()]
    if missing:
        print(
            f"embedding_comparison: {args.root} has no {', '.join(missing)}/: run the "
            "sweeps of the module docstring first",
            file=sys.stderr,
        )
        return 2
    text = table(args.root)
    print(text)
    if args.write:
        doc = DOC.read_text("utf-8")
        head, _, rest = doc.partition(BEGIN + "\n")
        _, _, tail = rest.partition(END)
        DOC.write_text(head + BEGIN + "\n" + text + "\n" + END + tail, "utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
