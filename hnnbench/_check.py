"""``hnnbench check DIR [DIR ...] --reference CSV``: the leaderboard regression gate
and the validation of submitted records.

The records of the directories are validated, then their leaderboard
(:func:`hnnbench._table.leaderboard`) is compared with a reference in the same format (a
``leaderboard.csv``), row by row on (profile, system, model, variant, track) (the variant is
empty where the runs vary in nothing but seeds, :func:`hnnbench._table.variant_labels`; the
track is ``protocol`` where a record or reference row has none, so a tuned or recipe row is
never compared with a protocol one):

- records: every ``result.json`` must be readable and valid against the record schema
  (a strict :func:`hnnbench._records.load`: bounded size and nesting, names that are
  names, ``created_at`` a date-time not in the future, each metric within its declared
  domain; one line per file left out, naming the field), carry provenance (hnnbench
  version, date, platform) and, where the plugin is installed, its current version and package
  (a missing version is a mismatch); a metric or timing key named like a table column
  is refused (:func:`hnnbench._provenance.reserved_key_problem`);
- metrics: each ``<metric>_mean`` by the metric's declared rule
  (:class:`hnnbench._metric.CheckRule`: direction, tolerated factor in log space, noise
  floor), overridable with ``--rules FILE`` (YAML: ``default:`` and ``metrics:``);
- statuses: a pair whose share of ``ok`` runs fell (ok -> diverged / failed / skipped);
- coverage: a reference pair with no run in DIR (``--allow-missing`` accepts that, for
  a sweep that ran only some systems or models);
- claims (:mod:`hnnbench._claims`): one reproduced in the reference must still be
  reproduced; the others are reported as information;
- variants: each record's variant is derived from its stored config against the
  defaults of its (system, model, profile) (:mod:`hnnbench._provenance`), not read
  from its overrides; a setting that differs from the defaults with no override saying
  so is named, and such a record is never the main row;
- ``--rerun SYSTEM/MODEL/SEED``: that job is run again from its record's config, with
  the record's run-only settings (cache, data directory, device, ...) ignored, in a
  fresh cache and a temporary directory; its data hashes must equal the canonical ones
  (those the installed system generates now), its status the record's, and its metrics
  agree with the record's by the same rules, in both directions (a table shows record
  against re-run per metric);
- ``--same RTOL``: two-sided instead. Every gated metric mean must equal the
  reference's within RTOL relative (both values at or below the metric's noise floor
  count as equal) and every pair's statuses must be the same: a reproduction check,
  which flags an improvement as loudly as a regression (tests/test_reproduction_guard.py).

Exit status: 0 when nothing regressed, 1 on a regression (with a table of what and by
how much); user errors raise :class:`~hnnbench._errors.HnnbenchError` (the CLI exits 2).
``--update`` rewrites the reference from DIR instead, on purpose.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

import pandas as pd

from hnnbench import _claims as C
from hnnbench import _provenance as P
from hnnbench import _records as R
from hnnbench import _registry as registry
from hnnbench import _stats as stats
from hnnbench._aggregate import headline_metrics
from hnnbench._errors import HnnbenchError, OneLineArgumentParser
from hnnbench._families import RANKING_KEY, ROW_KEY, key_of, primary_rows, select
from hnnbench._metric import CheckRule
from hnnbench._record_schema import (
    BOARD_KEY,
    DEFAULT_TRACK,
    PROVENANCE_FIELDS,
    STATUSES,
    TIMINGS,
    track_of,
    track_problem,
    variant_problem,
)
from hnnbench._table import (
    INTERVAL_SUFFIXES,
    format_interval,
    leaderboard,
    variant_labels,
    variant_overrides,
)

__all__ = [
    "REQUIRED_COLUMNS",
    "CheckError",
    "CheckResult",
    "Finding",
    "compare",
    "load_rules",
    "main",
    "rank_lines",
    "read_reference",
]

KEY = BOARD_KEY
#: Wall times depend on the machine: shown, never gating.
TIMING_RULE = CheckRule(factor=3.0, floor=1.0, gate=False, better="lower")
#: Status counts a reference must have (``n_timeout``, new in 0.3, reads 0 where absent).
COUNT_COLUMNS = ("n_seeds", *(f"n_{s}" for s in STATUSES if s != "timeout"))
REQUIRED_COLUMNS = (*KEY, *COUNT_COLUMNS)
RULE_KEYS = {"better", "factor", "floor", "gate"}


class CheckError(HnnbenchError):
    """Bad input to ``hnnbench check``."""


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


def _parse_rule(raw: Any, where: str, base: CheckRule) -> CheckRule:
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
    return CheckRule(better=values["better"], factor=factor, floor=floor, gate=values["gate"])


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


def _apply(data: dict[str, Any], source: str, default: CheckRule,
           metrics: dict[str, CheckRule]) -> tuple[CheckRule, dict[str, CheckRule]]:
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


def declared_rules() -> dict[str, CheckRule]:
    """The rule of every registered metric (its declaration), and of the timings."""
    rules = {m.name: m.check for m in registry.metrics()}
    rules.update({t: TIMING_RULE for t in TIMINGS})
    return rules


def load_rules(path: Optional[Path | str] = None) -> tuple[CheckRule, dict[str, CheckRule]]:
    """The declared rules (:func:`declared_rules`; metrics no installed plugin declares
    get the default), with those of ``path`` (a YAML file) on top."""
    default, metrics = CheckRule(), declared_rules()
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
        frame = pd.read_csv(path, dtype={**dict.fromkeys(KEY, str), "seeds": str})
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
    for col in COUNT_COLUMNS:
        values = pd.to_numeric(frame[col], errors="coerce")
        if values.isna().any():
            raise CheckError(f"Reference {path}: column {col} must hold integers")
        frame[col] = values.astype(int)
    for col in frame.columns:
        if col.endswith(("_mean", "_std", *INTERVAL_SUFFIXES)):
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
    parts = [f"{int(row[f'n_{s}'])} {s}" for s in STATUSES if int(row.get(f"n_{s}", 0))]
    return ", ".join(parts) or "no runs"


def _claims_by_key(board: pd.DataFrame) -> dict[tuple[str, str, str], C.ClaimResult]:
    from hnnbench._report.published import board_lookup, board_untrained

    out = {}
    claims = registry.all_claims()
    for profile in dict.fromkeys(board["profile"].astype(str)):
        for res in C.evaluate_claims(board_lookup(board, profile), claims,
                                     registry.family_models(),
                                     board_untrained(board, profile)):
            out[(profile, res.claim.id, res.backend)] = res
    return out


def _keys(frame: pd.DataFrame) -> tuple[str, ...]:
    """The columns that identify a row: :data:`KEY`, plus ``variant`` and ``track``
    where present."""
    return (*KEY, *(c for c in ("variant", "track") if c in frame.columns))


def _row_key(row: Any) -> tuple[str, str, str, str, str]:
    """``(profile, system, model, variant, track)`` of a leaderboard row (variant ``""``
    if none; track ``protocol`` if none: a tuned or recipe row is never compared with
    a protocol one)."""
    variant = row.get("variant", "")
    variant = "" if variant is None or pd.isna(variant) else str(variant)
    track = row.get("track", DEFAULT_TRACK)
    track = DEFAULT_TRACK if track is None or pd.isna(track) or track == "" else str(track)
    return (str(row["profile"]), str(row["system"]), str(row["model"]), variant, track)


def _model_text(model: str, variant: str, track: str = DEFAULT_TRACK) -> str:
    text = f"{model} [{variant}]" if variant else model
    return text if track == DEFAULT_TRACK else f"{text} ({track} track)"


def compare(reference: pd.DataFrame, current: pd.DataFrame,
            rules: Optional[tuple[CheckRule, dict[str, CheckRule]]] = None,
            allow_missing: bool = False, same: Optional[float] = None) -> CheckResult:
    """Compare two leaderboards; see the module docstring (``same``: ``--same RTOL``)."""
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
        system, model = key[1], _model_text(key[2], key[3], key[4])
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
        changed = same is not None and (int(c["n_ok"]), int(c["n_seeds"])) != (
            int(r["n_ok"]), int(r["n_seeds"]))
        if changed or _ok_share(c) < _ok_share(r):
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
            if same is not None:
                if not rule.gate:
                    continue
                diff = rule.difference(ref_value, cur_value)
                if diff > same:
                    result.regressions.append(Finding(
                        "changed", metric, system, model, _fmt(ref_value), _fmt(cur_value),
                        f"{_fmt(diff)} rel", f"within {same:g} rel"))
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
            result.info.append(Finding("new", "-", key[1], _model_text(key[2], key[3], key[4]),
                                       "not in reference",
                                       _status_text(c)))

    ref_claims, cur_claims = _claims_by_key(ref), _claims_by_key(cur)
    for (profile, claim_id, backend), rc in ref_claims.items():
        cc = cur_claims.get((profile, claim_id, backend))
        claim = rc.claim
        pair = f"{backend} pair" if backend != "-" else "-"
        now = cc.outcome if cc is not None else C.NOT_RUN
        finding = Finding("claim", claim.metric, claim.system, pair,
                          f"{rc.outcome} ({C.fmt_ratio(rc.ratio)})",
                          f"{now} ({C.fmt_ratio(cc.ratio) if cc is not None else 'n/a'})",
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


# --------------------------------------------------------------------------- ranks


def _interval_of(row: Any, metric: str) -> Optional[tuple[float, float]]:
    low, high = row.get(f"{metric}_ci_low"), row.get(f"{metric}_ci_high")
    if low is None or high is None or pd.isna(low) or pd.isna(high):
        return None
    return float(low), float(high)


def _ordinal_text(low: int, high: int) -> str:
    return f"[{low}, {high}]" if low != high else f"[{low}]"


@dataclass
class Rank:
    """One new family's rank on one (system, metric) among the reference's families."""

    name: str
    system: str
    metric: str
    rank: int
    of: int
    low: Optional[int]  # the rank interval (None: no interval)
    high: Optional[int]
    line: str


def _rank_one(name: str, row: Any, others: pd.DataFrame, metric: str, better: str,
              linear: bool) -> Optional[Rank]:
    value = pd.to_numeric(row.get(f"{metric}_mean"), errors="coerce")
    system = str(row["system"])
    if pd.isna(value):
        return None
    value = float(value)
    means = pd.to_numeric(others[f"{metric}_mean"], errors="coerce")
    others = others[means.notna()]
    means = means[means.notna()].astype(float)
    sign = -1.0 if better == "higher" else 1.0
    rank = 1 + int((sign * means < sign * value).sum())
    of = len(others) + 1
    mine = _interval_of(row, metric)
    if mine is None and math.isinf(value):
        mine = (value, value)  # a diverged mean: certainly there
    theirs = []
    for _, r in others.iterrows():
        interval, mean = _interval_of(r, metric), float(r[f"{metric}_mean"])
        theirs.append(interval if interval is not None else
                      (mean, mean) if math.isinf(mean) else None)
    n_seeds = int(row.get("n_seeds", 0) or 0)
    shown = format_interval(value, *(_interval_of(row, metric) or (math.nan, math.nan)),
                            linear=linear)
    low = high = None
    if mine is None:
        text = (f"({n_seeds} seed: no interval)" if n_seeds < 2 else
                "(fewer than 2 seeds with a value: no interval)")
    elif all(t is None for t in theirs):
        n_ref = int(pd.to_numeric(others["n_seeds"], errors="coerce").min())
        text = (f"(the reference has {n_ref} seed{'s' if n_ref != 1 else ''} and no "
                "interval: no rank interval)")
    else:
        # a reference family without an interval is separated from no one
        lo_m, hi_m = sorted((sign * mine[0], sign * mine[1]))
        ahead = behind = 0
        for t in theirs:
            if t is None:
                continue
            lo_t, hi_t = sorted((sign * t[0], sign * t[1]))
            ahead += hi_t < lo_m  # wholly better than ours
            behind += lo_t > hi_m  # wholly worse
        low, high = 1 + ahead, of - behind
        text = _ordinal_text(low, high)
    line = (f"{system} {metric}: {name} ranks {rank} of {of} families {text}: {shown} over "
            f"{n_seeds} seed{'s' if n_seeds != 1 else ''}")
    return Rank(name, system, metric, rank, of, low, high, line)


def _verdict(name: str, ranks: list[Rank]) -> str:
    if not ranks:
        return f"verdict: {name} has no value on a headline metric here"
    first = sum(r.rank == 1 for r in ranks)
    top = sum(r.rank <= (r.of + 1) // 2 for r in ranks)
    median = sorted(r.rank for r in ranks)[(len(ranks) - 1) // 2]
    of = max(r.of for r in ranks)
    text = (f"verdict: {name} ranks first on {first} and in the top half on {top} of "
            f"{len(ranks)} (system, metric) cell(s), median rank {median} of {of}")
    with_interval = [r for r in ranks if r.low is not None]
    if not with_interval:
        return (text + "; no rank is backed by an interval (an interval needs 2 seeds on "
                f"both sides; a separated best, {stats.MIN_SEPARABLE_SEEDS} paired seeds)")
    sure = sum(r.high == 1 for r in with_interval)
    maybe = sum(r.low == 1 for r in with_interval)
    return (text + f"; the intervals put it first on {sure} and possibly first on {maybe} "
            f"of the {len(with_interval)} with an interval")


def rank_lines(reference: pd.DataFrame, current: pd.DataFrame,
               metrics: Optional[Sequence[str]] = None) -> list[str]:
    """For every family of ``current`` that the reference does not hold (a new model,
    or a variant), per system and headline metric (default:
    :func:`hnnbench._aggregate.headline_metrics`): its rank among the reference's ranked
    families on that system (by mean), the rank interval their intervals allow (each
    family's 95% interval over seeds, ``<metric>_ci_low``/``_ci_high``: ranked ahead of
    it are the families whose interval lies wholly on the better side), and then one
    verdict line per new family."""
    from hnnbench._table import linear_metrics, metric_declarations

    declared = metric_declarations()
    metrics = [m for m in (headline_metrics() if metrics is None else metrics)
               if m in declared and f"{m}_mean" in current and f"{m}_mean" in reference]
    if current.empty:
        return []
    linear = linear_metrics()

    def ranked(frame: pd.DataFrame) -> pd.DataFrame:
        frame = frame[frame["ranked"].fillna(True).astype(str).str.lower() != "false"]
        return primary_rows(frame)

    ref, cur = ranked(reference), ranked(current)
    keys = {key_of(r, ROW_KEY) for _, r in ref.iterrows()}
    ranking = [k for k in RANKING_KEY if k != "variant"]
    lines: list[str] = []
    by_name: dict[str, list[Rank]] = {}
    for _, row in cur.iterrows():
        if key_of(row, ROW_KEY) in keys:
            continue
        name = str(row["seeds_from"]) + (f" [{row['variant']}]" if row["variant"] else "")
        others = select(ref, [*ranking, "variant"], (*key_of(row, ranking), ""))
        by_name.setdefault(name, [])
        if others.empty:
            continue
        for metric in metrics:
            done = _rank_one(name, row, others, metric, declared[metric].better,
                             metric in linear)
            if done is not None:
                lines.append(done.line)
                by_name[name].append(done)
    lines += [_verdict(name, ranks) for name, ranks in by_name.items()]
    return lines


# --------------------------------------------------------------------------- cli

HEADERS = ["check", "metric", "system", "model", "reference", "current", "factor", "limit"]


class _Parser(OneLineArgumentParser):
    error_type = CheckError


def _parser() -> _Parser:
    p = _Parser(prog="hnnbench check",
                description="Validate run records and compare their leaderboard with a "
                            "reference leaderboard.csv; exit 1 on a regression.")
    p.add_argument("dirs", metavar="DIR", nargs="+",
                   help="sweep or record directories (their records merge)")
    p.add_argument("--reference", metavar="CSV", required=True,
                   help="reference leaderboard.csv (e.g. results/reference/quick.csv)")
    p.add_argument("--update", action="store_true",
                   help="rewrite the reference from DIR instead of checking")
    p.add_argument("--rules", metavar="FILE", default=None,
                   help="YAML tolerances overriding the metrics' declared rules")
    p.add_argument("--allow-missing", action="store_true",
                   help="a reference pair with no run in DIR is information, not a "
                        "regression (for a sweep of only some systems or models)")
    p.add_argument("--rerun", metavar="SYSTEM/MODEL/SEED", action="append", default=[],
                   help="run this job again from its record and compare (repeatable)")
    p.add_argument("--same", metavar="RTOL", type=float, default=None,
                   help="two-sided: every gated metric within RTOL relative of the "
                        "reference and the same statuses (a reproduction check)")
    return p


def record_variants(recs: Sequence[dict[str, Any]]) -> list[P.Variant]:
    """Each record's variant, derived from its stored config and the defaults of its
    profile (:func:`hnnbench._provenance.config_variant`); where that cannot be done,
    the label its overrides claim (:func:`hnnbench._table.variant_labels`)."""
    claimed = variant_labels([variant_overrides(rec) for rec in recs])
    return [P.config_variant(rec, label) for rec, label in zip(recs, claimed, strict=True)]


def _file(rec: dict[str, Any]) -> str:
    return str(Path(rec["path"]) / R.RECORD_NAME) if rec.get("path") else "?"


def variant_findings(recs: Sequence[dict[str, Any]], variants: Sequence[P.Variant]
                     ) -> tuple[list[Finding], list[Finding]]:
    """``(regressions, information)`` about the records' variants: a setting that
    differs from the profile's defaults with no override saying so, a config of another
    job than the record's, a config that cannot be compared (no config: a regression;
    a plugin not installed here: information), a variant label that is not of safe
    ``key=value`` tokens (:data:`hnnbench._record_schema.VARIANT_TOKEN_PATTERN`)."""
    bad: list[Finding] = []
    info: list[Finding] = []
    for rec, variant in zip(recs, variants, strict=True):
        system, model, where = str(rec.get("system")), str(rec.get("model")), _file(rec)
        unsafe = variant_problem(variant.label)
        if unsafe:
            bad.append(Finding("variant", "config", system, model, where, unsafe))
        if variant.mismatch:
            bad.append(Finding("variant", "config", system, model, where,
                               f"its config is of another job ({variant.mismatch})"))
        if variant.problem:
            finding = Finding("variant", "config", system, model, where,
                              str(variant.problem))
            (bad if variant.installed else info).append(finding)
        elif variant.undeclared:
            text = variant.undeclared_text(str(rec.get("profile") or "paper"))
            bad.append(Finding("variant", variant.undeclared[0], system, model, where,
                               text))
    return bad, info


def _field(rec: dict[str, Any], name: str) -> Any:
    """The value of ``name`` in ``rec`` (``a.b``: key ``b`` of field ``a``), or ``None``."""
    value: Any = rec
    for part in name.split("."):
        value = value.get(part) if isinstance(value, dict) else None
    return value


def validate_records(recs: Sequence[dict[str, Any]], bad: Sequence[R.Unreadable]
                     ) -> list[Finding]:
    """Findings about the records themselves: unreadable files, schema violations (the
    records of a strict :func:`hnnbench._records.load`, and the files it left out),
    missing provenance, plugin versions or packages that differ from the installed ones
    (:func:`hnnbench._provenance.plugin_problems`; a missing version is a mismatch).
    The gating ones; :func:`plugin_information` has the others."""
    out = [Finding("invalid" if item.reason.startswith("invalid") else "unreadable", "-", "-",
                   str(item.path), "", item.reason) for item in bad]
    for rec in recs:
        where = str(rec.get("path", "?"))
        system, model = str(rec.get("system")), str(rec.get("model"))
        missing = [name for name in PROVENANCE_FIELDS if not _field(rec, name)]
        if missing:
            out.append(Finding("provenance", "-", system, model, where,
                               f"missing {', '.join(missing)}"))
        for key, mine, have, gate in P.plugin_problems(rec):
            if gate:
                out.append(Finding("version", key, system, model, f"record {mine}",
                                   f"installed {have}", "", f"same plugin ({where})"))
        problem = track_problem(rec)
        if problem is not None:
            out.append(Finding("track", "-", system, model, where, problem))
    return out + budget_findings(recs)


def budget_findings(recs: Sequence[dict[str, Any]]) -> list[Finding]:
    """The tuned track's promise, checked: on each (profile, system), every tuned model
    had the same number of trials, each of the same step budget (docs/TUNING.md)."""
    budgets: dict[tuple[str, str], dict[tuple[Any, Any], set[str]]] = {}
    for rec in recs:
        tuning = rec.get("tuning")
        if track_of(rec) != "tuned" or not isinstance(tuning, dict):
            continue
        pair = (str(rec.get("profile")), str(rec.get("system")))
        budget = (tuning.get("trials"), tuning.get("steps"))
        budgets.setdefault(pair, {}).setdefault(budget, set()).add(str(rec.get("model")))
    out = []
    for (profile, system), found in budgets.items():
        if len(found) > 1:
            shown = "; ".join(f"{t} trials x {s} steps: {', '.join(sorted(models))}"
                              for (t, s), models in found.items())
            out.append(Finding("budget", "-", system, "tuned track", f"{profile} profile",
                               f"unequal tuning budgets ({shown})", "",
                               "the same trials and steps for every model"))
    return out


def plugin_information(recs: Sequence[dict[str, Any]]) -> list[Finding]:
    """Plugin packages of another (non-null) version than the installed one: shown, not
    failing (the plugin's own ``version`` says when its results change)."""
    out = []
    for rec in recs:
        for key, mine, have, gate in P.plugin_problems(rec):
            if not gate:
                out.append(Finding("version", key, str(rec.get("system")),
                                   str(rec.get("model")), f"record {mine}",
                                   f"installed {have}", "", "information"))
    return out


#: The record's ``data`` hashes a re-run must reproduce.
DATA_HASHES = ("dataset_sha256", "evaluation_sha256")
RERUN_HEADERS = ["metric", "record", "re-run", "apart", "allowed", ""]


@dataclass
class Rerun:
    """One ``--rerun``: its findings (regressions) and its table, record against
    re-run per metric and data hash."""

    spec: str
    findings: list[Finding] = field(default_factory=list)
    rows: list[list[str]] = field(default_factory=list)


def rerun_config(rec: dict[str, Any], cache_dir: Path) -> dict[str, Any]:
    """The config a ``--rerun`` of ``rec`` runs: the record's stored config, with every
    run-only setting (:data:`hnnbench._records.RUN_ONLY_KEYS`: cache and data
    directories, device, threads, pinning, saving, batching) taken from the defaults of
    its (system, model, profile) instead of the record, a fresh ``cache_dir``, and no
    weights written. Nothing the record names decides where the re-run reads or writes."""
    config = rec.get("config")
    spec = f"{rec.get('system')}/{rec.get('model')}/{rec.get('seed')}"
    if not isinstance(config, dict) or not isinstance(config.get("system"), dict):
        raise CheckError(f"--rerun {spec}: the record holds no resolved config to run again")
    try:
        defaults = P.default_config(str(rec.get("system")), str(rec.get("model")),
                                    str(rec.get("profile") or "paper"), track_of(rec))
    except HnnbenchError as err:
        raise CheckError(f"--rerun {spec}: cannot compose its defaults: {err}") from None
    out = {k: v for k, v in config.items() if k not in R.RUN_ONLY_KEYS}
    out.update({k: defaults[k] for k in R.RUN_ONLY_KEYS if k in defaults})
    out.update(rerun=True, save_model=False, cache_dir=str(cache_dir))
    return out


def _short(value: Any) -> str:
    return str(value)[:12] if value else "none"


def rerun(recs: Sequence[dict[str, Any]], spec: str, rules: tuple[CheckRule, dict[str, CheckRule]]
          ) -> Rerun:
    """Run the job ``SYSTEM/MODEL/SEED`` of ``recs`` again (:func:`rerun_config`, in a
    temporary directory with a fresh dataset cache) and compare: its status, its data
    hashes (the re-run's, generated now by the installed system, are the canonical ones),
    and each metric with the record's by ``rules``, in both directions."""
    import tempfile

    from omegaconf import OmegaConf

    from hnnbench._job import run_job

    parts = spec.split("/")
    if len(parts) != 3 or not parts[2].isdigit():
        raise CheckError(f"--rerun {spec}: expected SYSTEM/MODEL/SEED, e.g. spring/hnn_jax/0")
    system, model, seed = parts[0], parts[1], int(parts[2])
    match = [r for r in recs if r.get("system") == system and r.get("model") == model
             and r.get("seed") == seed]
    if not match:
        raise CheckError(f"--rerun {spec}: no record of that job in the checked directories")
    rec = match[0]
    result = Rerun(spec)
    with tempfile.TemporaryDirectory(prefix="hnnbench-rerun-") as tmp:
        cfg = OmegaConf.create(rerun_config(rec, Path(tmp) / "cache"))
        again = run_job(cfg, Path(tmp) / "job", overrides=rec.get("overrides"))
    default, by_metric = rules
    where = _file(rec)

    def add(name: str, ref: str, cur: str, apart: str, allowed: str, ok: bool) -> None:
        result.rows.append([name, ref, cur, apart, allowed, "ok" if ok else "FAILS"])
        if not ok:
            result.findings.append(Finding("rerun", name, system, model, ref, cur, apart,
                                           allowed))

    add("status", str(rec.get("status")), str(again.get("status")), "", "same status",
        again.get("status") == rec.get("status"))
    if again.get("status") == "failed" and again.get("error"):
        result.rows.append(["error", "", str(again["error"]), "", "", ""])
    for key in DATA_HASHES:
        mine = (rec.get("data") or {}).get(key)
        canonical = (again.get("data") or {}).get(key)
        if mine is None and canonical is None and rec.get("status") == "skipped":
            continue
        add(f"data.{key}", _short(mine), _short(canonical), "",
            "the installed system's data", bool(canonical) and mine == canonical)
        if canonical and mine != canonical:
            result.findings[-1].current = (f"canonical {_short(canonical)} ({where} names "
                                           "other data)")
    for name, value in (rec.get("metrics") or {}).items():
        rule = by_metric.get(name, default)
        ref = float(value.get("mean", math.nan))
        cur = float((again.get("metrics") or {}).get(name, {}).get("mean", math.nan))
        if math.isnan(ref) and math.isnan(cur):
            continue
        # A re-run must agree with the record both ways, not merely be no worse.
        worst = max(rule.worsening(ref, cur), rule.worsening(cur, ref))
        ok = not (math.isnan(cur) or math.isnan(ref)) and worst <= rule.factor
        add(name, _fmt(ref), _fmt(cur), f"{_fmt(worst)}x", f"within {rule.factor:g}x", ok)
    return result


def main(args: Sequence[str]) -> int:
    from tabulate import tabulate

    from hnnbench._report.inputs import load_sweeps

    ns = _parser().parse_args(list(args))
    dirs = [Path(d) for d in ns.dirs]
    recs, bad = load_sweeps(dirs, strict=True, refuse=False)
    rules = load_rules(ns.rules)
    reference = Path(ns.reference)
    ref_board = None if ns.update else read_reference(reference)
    if ns.same is not None and not ns.same >= 0:
        raise CheckError(f"--same {ns.same}: expected a relative tolerance >= 0, e.g. 1e-3")
    # Each record's variant is derived from its stored config, never read from its
    # overrides (hnnbench._provenance).
    variants = record_variants(recs)
    board = leaderboard(recs, [v.label for v in variants])
    where = " ".join(ns.dirs)
    if ns.update:
        if bad:
            raise CheckError(f"{len(bad)} unreadable record(s), e.g. {bad[0]}: fix or remove "
                             "them before writing a reference")
        if reference.is_dir():
            raise CheckError(f"Reference {reference} is a directory; give a CSV file path")
        dropped = 0
        if reference.is_file():
            try:
                old = read_reference(reference)
                have = {_row_key(r) for _, r in board.iterrows()}
                dropped = sum(_row_key(r) not in have for _, r in old.iterrows())
            except CheckError:
                dropped = 0
        try:
            R.atomic_write_text(reference, board.to_csv(index=False))
        except OSError as err:
            raise CheckError(f"Cannot write reference {reference}: {err.strerror}") from None
        print(f"hnnbench check: wrote reference {reference} from {where} "
              f"({len(board)} system x model pairs)"
              + (f"; {dropped} pair(s) of the old reference are not in it" if dropped else ""))
        return 0
    assert ref_board is not None
    result = compare(ref_board, board, rules, allow_missing=ns.allow_missing,
                     same=ns.same)
    variant_bad, variant_info = variant_findings(recs, variants)
    result.regressions[:0] = validate_records(recs, bad) + variant_bad
    result.info += variant_info + plugin_information(recs)
    reruns = [rerun(recs, spec, rules) for spec in ns.rerun]
    for done in reruns:
        result.regressions += done.findings
    print(f"hnnbench check: {where} vs {reference}"
          + (f" (two-sided, within {ns.same:g} relative)" if ns.same is not None else
             f" (rules: declared + {ns.rules})" if ns.rules else " (rules: declared)"))
    print(f"validated {len(recs) + len(bad)} record(s); compared {result.n_pairs} pair(s), "
          f"{result.n_metrics} gated metric value(s), {result.n_claims} claim(s) reproduced "
          f"in the reference" + (f"; re-ran {len(ns.rerun)} job(s)" if ns.rerun else ""))
    for done in reruns:
        print()
        print(f"--rerun {done.spec} (fresh cache; the record's run-only settings ignored): "
              "record vs re-run")
        print(tabulate(done.rows, headers=RERUN_HEADERS, tablefmt="simple",
                       disable_numparse=True))
    ranks = rank_lines(ref_board, board)
    if ranks:
        print()
        print("ranks among the reference's families (headline metrics; 95% intervals over "
              "seeds):")
        for line in ranks:
            print(f"  {line}")
    missing = [f for f in result.info + result.regressions if f.check == "missing"]
    unrun = [f for f in result.info if f.check == "claim" and f.current.startswith(C.NOT_RUN)]
    new = [f for f in result.info if f.check == "new"]
    shown = [f for f in result.info if f not in missing and f not in unrun and f not in new]
    if missing or unrun or new:
        print()
    if new:
        models = list(dict.fromkeys(f.model for f in new))
        print(f"new: {len(new)} pair(s) not in the reference ({', '.join(models[:4])}"
              + (f" and {len(models) - 4} more" if len(models) > 4 else "") + ")")
    if missing or unrun:
        print(missing_line(missing, unrun, failing=not ns.allow_missing))
    if shown:
        print()
        print("information (not failing):")
        print(tabulate([f.row() for f in shown], headers=HEADERS, tablefmt="simple",
                       disable_numparse=True))
    if result.regressions:
        listed = [f for f in result.regressions if f.check != "missing"]
        print()
        print(f"REGRESSIONS ({len(result.regressions)}"
              + (f", {len(result.regressions) - len(listed)} of them missing pairs, above"
                 if len(listed) < len(result.regressions) else "") + "):")
        if listed:
            print(tabulate([f.row() for f in listed], headers=HEADERS,
                           tablefmt="simple", disable_numparse=True))
        print()
        print(f"hnnbench check: FAILED, {len(result.regressions)} regression(s)."
              f"{update_hint(result, reference)}")
        return 1
    print()
    print("hnnbench check: OK, no regressions")
    return 0


def missing_line(missing: Sequence[Finding], unrun: Sequence[Finding] = (),
                 failing: bool = False) -> str:
    """One line for the reference pairs a sweep did not run (``failing``: they are
    regressions, without ``--allow-missing``), and the reference's claims left
    unevaluated because of them."""
    parts = []
    if missing:
        systems = list(dict.fromkeys(f.system for f in missing))
        models = list(dict.fromkeys(f.model for f in missing))
        example = ", ".join(f"{f.system} x {f.model}" for f in missing[:2])
        parts.append(f"{len(missing)} reference pair(s) not in this sweep ({len(systems)} "
                     f"system(s) x {len(models)} model(s), e.g. {example})")
    if unrun:
        parts.append(f"{len(unrun)} claim(s) of the reference not evaluated (their pairs "
                     "were not run)")
    tail = " (regressions: pass --allow-missing for a sweep of only some pairs)" if failing \
        else " (information: --allow-missing)"
    return "missing: " + "; ".join(parts) + tail


def update_hint(result: CheckResult, reference: Path) -> str:
    """What to do about the regressions: ``--allow-missing`` where every one is a pair
    the sweep did not run; ``--update`` only where it is safe, i.e. the sweep covers
    every pair of the reference and its records are valid (it would otherwise drop
    rows, or write bad ones); never for a published leaderboard (a ``leaderboard.csv``
    next to a ``records/`` directory: scripts/maintainer/publish_results.py rebuilds that)."""
    kinds = {f.check for f in result.regressions}
    if kinds == {"missing"}:
        return (" Every regression is a reference pair this sweep did not run: pass "
                "--allow-missing to compare the pairs it ran.")
    published = reference.name == "leaderboard.csv" and (reference.parent / "records").is_dir()
    if published:
        return (" The reference is a published leaderboard: it is rebuilt from records by "
                "scripts/maintainer/publish_results.py (docs/LEADERBOARD.md), never by --update.")
    missing = sum(f.check == "missing" for f in result.regressions)
    if missing:
        return (f" Rewriting the reference from this sweep would not be safe: it would drop "
                f"the {missing} reference pair(s) the sweep did not run.")
    if kinds & {"invalid", "unreadable", "provenance", "version", "variant", "rerun"}:
        return (" Rewriting the reference from these records would not be safe: fix the "
                "records that fail validation first.")
    return " If the change is intended, rewrite the reference with --update."
