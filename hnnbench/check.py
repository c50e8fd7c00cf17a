"""``hnnbench check DIR --reference CSV``: the leaderboard regression gate.

The leaderboard of DIR (:func:`hnnbench.table.leaderboard`) is compared with a
reference in the same format (a ``leaderboard.csv``), row by row on (profile, system,
model, variant) (the variant is empty where the runs vary in nothing but seeds;
:func:`hnnbench.table.variant_labels`):

- metrics: each ``<metric>_mean`` by the rules of ``resources/check_rules.yaml``
  (direction, tolerated factor in log space, noise floor), overridable with ``--rules``;
- statuses: a pair whose share of ``ok`` runs fell (ok -> diverged / failed / skipped);
- coverage: a reference pair with no run in DIR (``--allow-missing`` accepts that);
- the paper's claims (:mod:`hnnbench.claims`): one reproduced in the reference must still
  be reproduced; the others are reported as information.

Exit status: 0 when nothing regressed, 1 on a regression (with a table of what and by
how much); user errors raise :class:`~hnnbench.errors.HnnbenchError` (the CLI exits 2).
``--update`` rewrites the reference from DIR instead, on purpose.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Optional

import pandas as pd

from hnnbench import claims as C
from hnnbench import records as R
from hnnbench.errors import HnnbenchError
from hnnbench.table import leaderboard

__all__ = [
    "REQUIRED_COLUMNS",
    "CheckError",
    "CheckResult",
    "Finding",
    "Rule",
    "compare",
    "load_rules",
    "main",
    "read_reference",
]

RULES_FILE = "check_rules.yaml"
KEY = ("profile", "system", "model")
REQUIRED_COLUMNS = (*KEY, "n_seeds", "n_ok", "n_diverged", "n_failed", "n_skipped")
RULE_KEYS = {"better", "factor", "floor", "gate"}


class CheckError(HnnbenchError):
    """Bad input to ``hnnbench check``."""


@dataclass(frozen=True)
class Rule:
    better: str = "lower"
    factor: float = 10.0
    floor: float = 0.0
    gate: bool = True

    def worsening(self, reference: float, current: float) -> float:
        """How many times worse ``current`` is than ``reference`` (< 1: better)."""
        ref, cur = max(reference, self.floor), max(current, self.floor)
        worse, base = (cur, ref) if self.better == "lower" else (ref, cur)
        if math.isinf(worse) and math.isinf(base):
            return 1.0
        if base <= 0:
            return 1.0 if worse <= 0 else math.inf
        return worse / base

    def limit_text(self) -> str:
        op = "<=" if self.better == "lower" else ">="
        side = f"ref x {self.factor:g}" if self.better == "lower" else f"ref / {self.factor:g}"
        return f"{op} {side}"


@dataclass
class Finding:
    check: str  # "metric" | "status" | "missing" | "claim" | "new" | ...
    metric: str
    system: str
    model: str
    reference: str
    current: str
    factor: str = ""
    limit: str = ""

    def row(self) -> list[str]:
        return [self.check, self.metric, self.system, self.model, self.reference,
                self.current, self.factor, self.limit]


@dataclass
class CheckResult:
    regressions: list[Finding] = field(default_factory=list)
    info: list[Finding] = field(default_factory=list)
    n_pairs: int = 0
    n_metrics: int = 0
    n_claims: int = 0

    @property
    def ok(self) -> bool:
        return not self.regressions


# --------------------------------------------------------------------------- rules


def _parse_rule(raw: Any, where: str, base: Rule) -> Rule:
    if not isinstance(raw, dict):
        raise CheckError(f"{where}: expected a mapping like {{better: lower, factor: 10}}, "
                         f"got {raw!r}")
    unknown = sorted(set(raw) - RULE_KEYS)
    if unknown:
        raise CheckError(f"{where}: unknown key(s) {', '.join(map(str, unknown))}; "
                         f"allowed: {', '.join(sorted(RULE_KEYS))}")
    values = {**base.__dict__, **raw}
    if values["better"] not in ("lower", "higher"):
        raise CheckError(f"{where}: better must be 'lower' or 'higher', got {values['better']!r}")
    try:
        factor, floor = float(values["factor"]), float(values["floor"])
    except (TypeError, ValueError):
        raise CheckError(f"{where}: factor and floor must be numbers") from None
    if not factor >= 1.0:
        raise CheckError(f"{where}: factor must be >= 1 (a tolerated worsening), got {factor}")
    if not floor >= 0.0:
        raise CheckError(f"{where}: floor must be >= 0, got {floor}")
    if not isinstance(values["gate"], bool):
        raise CheckError(f"{where}: gate must be true or false, got {values['gate']!r}")
    return Rule(better=values["better"], factor=factor, floor=floor, gate=values["gate"])


def _read_yaml(text: str, source: str) -> dict[str, Any]:
    import yaml

    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        first = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise CheckError(f"rules file {source} is not valid YAML: {first}") from None
    if data is None:
        return {}
    if not isinstance(data, dict) or set(data) - {"default", "metrics"}:
        raise CheckError(f"rules file {source}: expected top-level keys 'default' and/or "
                         "'metrics'")
    return data


def _apply(data: dict[str, Any], source: str, default: Rule,
           metrics: dict[str, Rule]) -> tuple[Rule, dict[str, Rule]]:
    if "default" in data:
        default = _parse_rule(data["default"], f"{source}: default", default)
    raw_metrics = data.get("metrics") or {}
    if not isinstance(raw_metrics, dict):
        raise CheckError(f"{source}: 'metrics' must map metric names to rules")
    metrics = dict(metrics)
    for name, raw in raw_metrics.items():
        metrics[str(name)] = _parse_rule(raw, f"{source}: metrics.{name}",
                                         metrics.get(str(name), default))
    return default, metrics


def load_rules(path: Optional[Path | str] = None) -> tuple[Rule, dict[str, Rule]]:
    """The built-in rules, with those of ``path`` (a YAML file) on top."""
    text = resources.files("hnnbench").joinpath("resources").joinpath(RULES_FILE).read_text("utf-8")
    default, metrics = _apply(_read_yaml(text, RULES_FILE), RULES_FILE, Rule(), {})
    if path is not None:
        path = Path(path)
        try:
            user = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise CheckError(f"rules file {path} does not exist") from None
        except (OSError, UnicodeDecodeError) as err:
            raise CheckError(f"cannot read rules file {path}: {err}") from None
        default, metrics = _apply(_read_yaml(user, str(path)), str(path), default, metrics)
    return default, metrics


# --------------------------------------------------------------------------- reference


def read_reference(path: Path | str) -> pd.DataFrame:
    """A reference leaderboard CSV, validated; :class:`CheckError` if unusable."""
    path = Path(path)
    if not path.exists():
        raise CheckError(f"Reference {path} does not exist; create it from a sweep with "
                         f"hnnbench check DIR --reference {path} --update")
    if path.is_dir():
        raise CheckError(f"Reference {path} is a directory; expected a leaderboard CSV file")
    try:
        frame = pd.read_csv(path, dtype={"profile": str, "system": str, "model": str,
                                         "seeds": str})
    except pd.errors.EmptyDataError:
        raise CheckError(f"Reference {path} is empty; expected a leaderboard.csv") from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise CheckError(f"Reference {path} is not a readable CSV: {first}") from None
    missing = [c for c in REQUIRED_COLUMNS if c not in frame.columns]
    if missing:
        raise CheckError(
            f"Reference {path} lacks column(s) {', '.join(missing)}; expected a leaderboard.csv "
            "(from hnnbench report, or hnnbench check --update)")
    if not any(c.endswith("_mean") for c in frame.columns):
        raise CheckError(f"Reference {path} has no metric columns (<metric>_mean); expected "
                         "a leaderboard.csv")
    for col in ("n_seeds", "n_ok", "n_diverged", "n_failed", "n_skipped"):
        values = pd.to_numeric(frame[col], errors="coerce")
        if values.isna().any():
            raise CheckError(f"Reference {path}: column {col} must hold integers")
        frame[col] = values.astype(int)
    for col in frame.columns:
        if col.endswith("_mean") or col.endswith("_std"):
            values = pd.to_numeric(frame[col], errors="coerce")
            bad = values.isna() & frame[col].notna()
            if bad.any():
                raise CheckError(f"Reference {path}: column {col} holds a non-number "
                                 f"({frame[col][bad].iloc[0]!r})")
            frame[col] = values.astype(float)
    dupes = frame.duplicated(list(_keys(frame)))
    if dupes.any():
        r = frame[dupes].iloc[0]
        raise CheckError(f"Reference {path} has duplicate rows for {r['system']} x "
                         f"{r['model']} (profile {r['profile']})")
    return frame


# --------------------------------------------------------------------------- compare


def _fmt(x: float) -> str:
    if x is None or pd.isna(x):
        return "—"
    if math.isinf(x):
        return "inf"
    return f"{x:.3g}"


def _seeds(row: Any) -> Optional[frozenset[str]]:
    value = row.get("seeds")
    if value is None or pd.isna(value):
        return None
    return frozenset(s.strip() for s in str(value).split(";") if s.strip())


def _seed_text(seeds: Optional[frozenset[str]]) -> str:
    return "?" if seeds is None else "seeds " + ",".join(sorted(seeds, key=lambda s: (len(s), s)))


def _ok_share(row: Any) -> float:
    n = int(row["n_seeds"])
    return int(row["n_ok"]) / n if n else 0.0


def _status_text(row: Any) -> str:
    parts = [f"{int(row[f'n_{s}'])} {s}" for s in R.STATUSES if int(row.get(f"n_{s}", 0))]
    return ", ".join(parts) or "no runs"


def _claims_by_key(board: pd.DataFrame) -> dict[tuple[str, str], C.ClaimResult]:
    from hnnbench.report import board_lookup

    out = {}
    for profile in dict.fromkeys(board["profile"].astype(str)):
        for res in C.evaluate_claims(board_lookup(board, profile)):
            out[(profile, res.claim.id, res.backend)] = res
    return out  # type: ignore[return-value]


def _keys(frame: pd.DataFrame) -> tuple[str, ...]:
    """The columns that identify a row: :data:`KEY`, plus ``variant`` where present."""
    return (*KEY, "variant") if "variant" in frame.columns else KEY


def _row_key(row: Any) -> tuple[str, str, str, str]:
    """``(profile, system, model, variant)`` of a leaderboard row (variant ``""`` if none)."""
    variant = row.get("variant", "")
    variant = "" if variant is None or pd.isna(variant) else str(variant)
    return (str(row["profile"]), str(row["system"]), str(row["model"]), variant)


def _model_text(model: str, variant: str) -> str:
    return f"{model} [{variant}]" if variant else model


def compare(reference: pd.DataFrame, current: pd.DataFrame,
            rules: Optional[tuple[Rule, dict[str, Rule]]] = None,
            allow_missing: bool = False) -> CheckResult:
    """Compare two leaderboards; see the module docstring."""
    default, by_metric = rules if rules is not None else load_rules()
    result = CheckResult()
    ref = reference.copy()
    cur = current.copy()
    ref_keys = {_row_key(r): r for _, r in ref.iterrows()}
    cur_keys = {_row_key(r): r for _, r in cur.iterrows()}
    if ref_keys and cur_keys and not set(ref_keys) & set(cur_keys):
        ref_prof = sorted({k[0] for k in ref_keys})
        cur_prof = sorted({k[0] for k in cur_keys})
        if ref_prof != cur_prof:
            raise CheckError(f"The reference is for profile {', '.join(ref_prof)} but the sweep "
                             f"ran profile {', '.join(cur_prof)}; compare like with like")
    metrics = [c[: -len("_mean")] for c in ref.columns if c.endswith("_mean")]

    for key, r in ref_keys.items():
        system, model = key[1], _model_text(key[2], key[3])
        c = cur_keys.get(key)
        if c is None:
            finding = Finding("missing", "-", system, model, _status_text(r), "no runs")
            (result.info if allow_missing else result.regressions).append(finding)
            continue
        result.n_pairs += 1
        ref_seeds, cur_seeds = _seeds(r), _seeds(c)
        if ref_seeds != cur_seeds:
            result.info.append(Finding("seeds", "-", system, model, _seed_text(ref_seeds),
                                       _seed_text(cur_seeds), "", "same seeds expected"))
        if _ok_share(c) < _ok_share(r):
            result.regressions.append(Finding(
                "status", "status", system, model, _status_text(r), _status_text(c),
                f"ok {int(c['n_ok'])}/{int(c['n_seeds'])}",
                f"ok >= {int(r['n_ok'])}/{int(r['n_seeds'])}"))
        for metric in metrics:
            rule = by_metric.get(metric, default)
            ref_value = float(r[f"{metric}_mean"])
            if math.isnan(ref_value):
                continue  # not applicable, or no result in the reference
            cur_value = c.get(f"{metric}_mean", math.nan)
            cur_value = math.nan if cur_value is None or pd.isna(cur_value) else float(cur_value)
            result.n_metrics += rule.gate
            if math.isnan(cur_value):
                finding = Finding("metric", metric, system, model, _fmt(ref_value), "no value",
                                  "", rule.limit_text())
                (result.regressions if rule.gate else result.info).append(finding)
                continue
            factor = rule.worsening(ref_value, cur_value)
            if factor > rule.factor:
                finding = Finding("metric" if rule.gate else "info", metric, system, model,
                                  _fmt(ref_value), _fmt(cur_value),
                                  "inf worse" if math.isinf(factor) else f"{_fmt(factor)}x worse",
                                  rule.limit_text())
                (result.regressions if rule.gate else result.info).append(finding)
    for key, c in cur_keys.items():
        if key not in ref_keys:
            result.info.append(Finding("new", "-", key[1], _model_text(key[2], key[3]),
                                       "not in reference",
                                       _status_text(c)))

    ref_claims, cur_claims = _claims_by_key(ref), _claims_by_key(cur)
    for (profile, claim_id, backend), rc in ref_claims.items():
        cc = cur_claims.get((profile, claim_id, backend))
        claim = rc.claim
        pair = f"{backend} pair" if backend != "-" else "-"
        now = cc.outcome if cc is not None else C.NOT_RUN
        finding = Finding("claim", claim.metric, claim.system, pair,
                          f"{rc.outcome} ({C._fmt_ratio(rc.ratio)})",
                          f"{now} ({C._fmt_ratio(cc.ratio) if cc is not None else 'n/a'})",
                          "", claim.requirement())
        if rc.outcome == C.REPRODUCED:
            result.n_claims += 1
            if now == C.NOT_RUN and allow_missing:
                result.info.append(finding)
            elif now != C.REPRODUCED:
                result.regressions.append(finding)
        elif not (rc.outcome == C.NOT_RUN and now == C.NOT_RUN):
            result.info.append(finding)
    return result


# --------------------------------------------------------------------------- cli

HEADERS = ["check", "metric", "system", "model", "reference", "current", "factor", "limit"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> Any:  # type: ignore[override]
        usage = " ".join(self.format_usage().split()[1:])
        raise CheckError(f"{message} (usage: {usage})")


def _parser() -> _Parser:
    p = _Parser(prog="hnnbench check",
                description="Compare a sweep's leaderboard with a reference leaderboard.csv; "
                            "exit 1 on a regression.")
    p.add_argument("dir", metavar="DIR", help="sweep directory with run records")
    p.add_argument("--reference", metavar="CSV", required=True,
                   help="reference leaderboard.csv (e.g. results/reference/quick.csv)")
    p.add_argument("--update", action="store_true",
                   help="rewrite the reference from DIR instead of checking")
    p.add_argument("--rules", metavar="FILE", default=None,
                   help="YAML tolerances overriding the built-in check_rules.yaml")
    p.add_argument("--allow-missing", action="store_true",
                   help="a reference pair with no run in DIR is information, not a regression")
    return p


def main(args: Sequence[str]) -> int:
    from tabulate import tabulate

    from hnnbench.report import load_sweep

    ns = _parser().parse_args(list(args))
    board = leaderboard(load_sweep(Path(ns.dir)))
    rules = load_rules(ns.rules)
    reference = Path(ns.reference)
    if ns.update:
        if reference.is_dir():
            raise CheckError(f"Reference {reference} is a directory; give a CSV file path")
        try:
            R.atomic_write_text(reference, board.to_csv(index=False))
        except OSError as err:
            raise CheckError(f"Cannot write reference {reference}: {err.strerror}") from None
        print(f"hnnbench check: wrote reference {reference} from {ns.dir} "
              f"({len(board)} system x model pairs)")
        return 0
    result = compare(read_reference(reference), board, rules, allow_missing=ns.allow_missing)
    print(f"hnnbench check: {ns.dir} vs {reference}"
          + (f" (rules: built-in + {ns.rules})" if ns.rules else " (rules: built-in)"))
    print(f"compared {result.n_pairs} pair(s), {result.n_metrics} gated metric value(s), "
          f"{result.n_claims} claim(s) reproduced in the reference")
    if result.info:
        print()
        print("information (not failing):")
        print(tabulate([f.row() for f in result.info], headers=HEADERS, tablefmt="simple",
                       disable_numparse=True))
    if result.regressions:
        print()
        print(f"REGRESSIONS ({len(result.regressions)}):")
        print(tabulate([f.row() for f in result.regressions], headers=HEADERS,
                       tablefmt="simple", disable_numparse=True))
        print()
        print(f"hnnbench check: FAILED, {len(result.regressions)} regression(s). If a change "
              "is intended, rewrite the reference with --update.")
        return 1
    print()
    print("hnnbench check: OK, no regressions")
    return 0
