"""What ``hnnbench check`` finds: a :class:`Finding` (regression or information), the
result of a comparison, and the lines that say what to do about them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from hnnbench._contracts.errors import HnnbenchError
from hnnbench._contracts.text import printable

__all__ = [
    "CheckError",
    "CheckResult",
    "Finding",
    "HEADERS",
    "missing_line",
    "published_reference",
    "update_hint",
]


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
        """The table's cells, control characters stripped (they are printed)."""
        return [
            printable(cell)
            for cell in (
                self.check,
                self.metric,
                self.system,
                self.model,
                self.reference,
                self.current,
                self.factor,
                self.limit,
            )
        ]


@dataclass
class CheckResult:
    regressions: list[Finding] = field(default_factory=list)
    info: list[Finding] = field(default_factory=list)
    n_pairs: int = 0
    n_metrics: int = 0
    n_claims: int = 0
    #: every gated (system, model, metric) value compared (``len`` is ``n_metrics``)
    gated: list[tuple[str, str, str]] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.regressions


HEADERS = ["check", "metric", "system", "model", "reference", "current", "factor", "limit"]


def missing_line(
    missing: Sequence[Finding], unrun: Sequence[Finding] = (), failing: bool = False
) -> str:
    """One line for the reference pairs a sweep did not run (``failing``: they are
    regressions, without ``--allow-missing``), and the reference's claims left
    unevaluated because of them."""
    parts = []
    if missing:
        systems = list(dict.fromkeys(f.system for f in missing))
        models = list(dict.fromkeys(f.model for f in missing))
        example = ", ".join(f"{f.system} x {f.model}" for f in missing[:2])
        parts.append(
            f"{len(missing)} reference pair(s) not in this sweep ({len(systems)} "
            f"system(s) x {len(models)} model(s), e.g. {example})"
        )
    if unrun:
        parts.append(
            f"{len(unrun)} claim(s) of the reference not evaluated (their pairs were not run)"
        )
    tail = (
        " (regressions: pass --allow-missing for a sweep of only some pairs)"
        if failing
        else " (information: --allow-missing)"
    )
    return "missing: " + "; ".join(parts) + tail


def published_reference(reference: Path) -> bool:
    """Whether ``reference`` is a published leaderboard (a ``leaderboard.csv`` next to a
    ``records/`` directory), which only publishing rebuilds."""
    return reference.name == "leaderboard.csv" and (reference.parent / "records").is_dir()


def update_hint(result: CheckResult, reference: Path) -> str:
    """What to do about the regressions: ``--allow-missing`` where every one is a pair
    the sweep did not run; ``--update`` only where it is safe, i.e. the sweep covers
    every pair of the reference and its records are valid (it would otherwise drop
    rows, or write bad ones); never for a published leaderboard (a ``leaderboard.csv``
    next to a ``records/`` directory: scripts/maintainer/publish_results.py rebuilds that)."""
    kinds = {f.check for f in result.regressions}
    if kinds == {"missing"}:
        return (
            " Every regression is a reference pair this sweep did not run: pass "
            "--allow-missing to compare the pairs it ran."
        )
    if published_reference(reference):
        return (
            " The reference is a published leaderboard: it is rebuilt from records by "
            "scripts/maintainer/publish_results.py (docs/LEADERBOARD.md), never by --update."
        )
    missing = sum(f.check == "missing" for f in result.regressions)
    if missing:
        return (
            f" Rewriting the reference from this sweep would not be safe: it would drop "
            f"the {missing} reference pair(s) the sweep did not run."
        )
    if kinds & {"invalid", "unreadable", "provenance", "version", "variant", "rerun"}:
        return (
            " Rewriting the reference from these records would not be safe: fix the "
            "records that fail validation first."
        )
    return " If the change is intended, rewrite the reference with --update."
