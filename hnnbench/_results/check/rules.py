"""The gate's rules: each metric's declared :class:`~hnnbench.CheckRule`, overridable
by a YAML file (``--rules``; docs/LEADERBOARD.md).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Optional

from hnnbench import _registry as registry
from hnnbench._contracts.metric import CheckRule
from hnnbench._contracts.names import TIMINGS
from hnnbench._results.check.findings import CheckError

__all__ = ["RULE_KEYS", "TIMING_RULE", "declared_rules", "load_rules"]


#: Wall times depend on the machine: shown, never gating.
TIMING_RULE = CheckRule(factor=3.0, floor=1.0, gate=False, better="lower")
RULE_KEYS = {"better", "factor", "floor", "gate"}


def _parse_rule(raw: Any, where: str, base: CheckRule) -> CheckRule:
    if not isinstance(raw, dict):
        raise CheckError(
            f"{where}: expected a mapping like {{better: lower, factor: 10}}, got {raw!r}"
        )
    unknown = sorted(set(raw) - RULE_KEYS)
    if unknown:
        raise CheckError(
            f"{where}: unknown key(s) {', '.join(map(str, unknown))}; "
            f"allowed: {', '.join(sorted(RULE_KEYS))}"
        )
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
        raise CheckError(f"rules file {source}: expected top-level keys 'default' and/or 'metrics'")
    return data


def _apply(
    data: dict[str, Any], source: str, default: CheckRule, metrics: dict[str, CheckRule]
) -> tuple[CheckRule, dict[str, CheckRule]]:
    if "default" in data:
        default = _parse_rule(data["default"], f"{source}: default", default)
    raw_metrics = data.get("metrics") or {}
    if not isinstance(raw_metrics, dict):
        raise CheckError(f"{source}: 'metrics' must map metric names to rules")
    metrics = dict(metrics)
    for name, raw in raw_metrics.items():
        metrics[str(name)] = _parse_rule(
            raw, f"{source}: metrics.{name}", metrics.get(str(name), default)
        )
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
