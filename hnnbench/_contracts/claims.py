"""Claims from the literature, evaluated on a leaderboard and reported whatever they come
to: a :class:`Claim` compares two model families on one system and metric, per backend;
a :class:`ClaimSet` groups one source's claims with the values it published
(docs/PLUGINS.md, "5. Claim sets"). This module names no model or family.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Literal, Optional

__all__ = [
    "NOT_REPRODUCED",
    "NOT_RUN",
    "NOT_TRAINED",
    "REPRODUCED",
    "Claim",
    "ClaimResult",
    "ClaimSet",
    "Lookup",
    "Published",
    "evaluate_claims",
    "fmt_ratio",
]

REPRODUCED = "reproduced"
NOT_REPRODUCED = "not reproduced"
NOT_RUN = "not run"
NOT_TRAINED = "did not train"


@dataclass(frozen=True)
class Claim:
    """One statement about two families on a (system, metric).

    ``relation="lower"``: the family ``lower`` has a value at least ``factor`` times
    below the other's (strictly below when ``factor`` is 1). ``relation="similar"``: the
    two values are within a factor ``factor`` of each other. ``labels`` name the two
    families in sentences (e.g. ``("baseline", "HNN")``). ``recipe``: where the source
    trained a family by a recipe of its own (architecture, loss, schedule), what it was;
    a leaderboard under the shared protocol does not run it, and results say so.
    """

    id: str
    system: str
    metric: str
    relation: Literal["lower", "similar"]
    families: tuple[str, str]
    text: str
    source: str
    lower: Optional[str] = None
    factor: float = 1.0
    labels: Optional[tuple[str, str]] = None
    recipe: Optional[str] = None

    def label(self, family: str) -> str:
        labels = self.labels or self.families
        return labels[self.families.index(family)]

    def requirement(self) -> str:
        """``baseline / HNN >= 100x``, ``max / min <= 2x``, ..."""
        if self.relation == "similar":
            return f"max / min <= {self.factor:g}x"
        assert self.lower is not None
        other = next(f for f in self.families if f != self.lower)
        ratio = f"{self.label(other)} / {self.label(self.lower)}"
        return f"{ratio} >= {self.factor:g}x" if self.factor > 1 else f"{ratio} > 1x"

    def judge(self, a: Optional[float], b: Optional[float]) -> tuple[str, float, str]:
        """``(outcome, ratio, note)`` for the values of ``families[0]`` and
        ``families[1]`` (``None``/NaN: not run)."""
        if a is None or b is None or math.isnan(a) or math.isnan(b):
            return NOT_RUN, math.nan, "no finite result"
        if self.relation == "similar":
            lo, hi = sorted((a, b))
            if math.isinf(hi):
                return NOT_REPRODUCED, math.inf, "a value is infinite (diverged)"
            ratio = hi / lo if lo > 0 else (1.0 if hi == 0 else math.inf)
            return (REPRODUCED if ratio <= self.factor else NOT_REPRODUCED), ratio, ""
        low, high = (a, b) if self.lower == self.families[0] else (b, a)
        if math.isinf(low):
            return NOT_REPRODUCED, math.nan, "the expected-lower value is infinite (diverged)"
        ratio = (math.inf if high > 0 else math.nan) if low <= 0 else high / low
        if math.isnan(ratio):
            return NOT_REPRODUCED, ratio, "both values are zero"
        ok = ratio >= self.factor and ratio > 1.0
        return (REPRODUCED if ok else NOT_REPRODUCED), ratio, ""


@dataclass(frozen=True)
class Published:
    """One published value, in natural units, as printed (``printed_value`` at
    ``printed_scale``: the paper printed ``value * printed_scale``)."""

    system: str
    task: str
    family: str
    role: str
    metric: str
    value: float
    pm: float
    printed_value: str
    printed_pm: str
    printed_scale: str
    source: str


@dataclass(frozen=True)
class ClaimSet:
    """The claims of one source and, optionally, the values it published."""

    name: str
    title: str
    claims: tuple[Claim, ...]
    published: tuple[Published, ...] = ()
    note: str = ""
    #: ``(system, metric, how)``: where hnnbench's definition of a published metric
    #: differs from the source's, so that side-by-side magnitudes are read as what they
    #: are (``metric`` ``"*"``: every metric of the system).
    definitions: tuple[tuple[str, str, str], ...] = ()

    def definition(self, system: str, metric: str) -> str:
        """How our ``metric`` on ``system`` differs from the source's (``""``: the same
        definition)."""
        return "; ".join(
            how for s, m, how in self.definitions if s == system and m in (metric, "*")
        )


@dataclass(frozen=True)
class ClaimResult:
    claim: Claim
    backend: str  # a backend name, "published", or "-" (not run on any backend)
    outcome: str
    a: float
    b: float
    ratio: float
    note: str = ""

    def numbers(self) -> str:
        """``baseline 4.5e-03 / HNN 2.1e-05 = 214x (need >= 100x)``."""
        if self.outcome in (NOT_RUN, NOT_TRAINED):
            return self.note or "no run"
        c = self.claim
        fa, fb = c.families
        va, vb = _fmt(self.a), _fmt(self.b)
        if c.relation == "similar":
            expr = f"{c.label(fa)} {va}, {c.label(fb)} {vb}: max / min = {fmt_ratio(self.ratio)}"
        elif c.lower == fb:
            expr = f"{c.label(fa)} {va} / {c.label(fb)} {vb} = {fmt_ratio(self.ratio)}"
        else:
            expr = f"{c.label(fb)} {vb} / {c.label(fa)} {va} = {fmt_ratio(self.ratio)}"
        need = c.requirement().split()[-2:]
        return f"{expr} (need {' '.join(need)})" + (f"; {self.note}" if self.note else "")


def _fmt(x: float) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "—"
    if math.isinf(x):
        return "inf"
    return f"{x:.2e}"


def fmt_ratio(r: float) -> str:
    """``214x``, ``inf``, ``n/a``."""
    if math.isnan(r):
        return "n/a"
    if math.isinf(r):
        return "inf"
    return f"{r:.3g}x"


#: value(system, model, metric) -> mean (NaN if absent / no finite result), or None if
#: there is no such (system, model) at all.
Lookup = Callable[[str, str, str], Optional[float]]
#: backend -> {family -> model name}
Pairs = Mapping[str, Mapping[str, str]]
#: untrained(system, model) -> why the pair counts as "did not train", else None.
Untrained = Callable[[str, str], Optional[str]]


def evaluate_claims(
    lookup: Lookup, claims: Iterable[Claim], pairs: Pairs, untrained: Optional[Untrained] = None
) -> list[ClaimResult]:
    """Evaluate each claim per backend that has both families' models (``pairs``:
    ``{backend: {family: model}}``, e.g. :func:`hnnbench._registry.groups.family_models`); a
    claim with no run anywhere gives one ``not run`` result with backend ``"-"``. Where
    ``untrained`` says one of the two models did not train, the result is ``did not
    train`` (not tested), with the reason."""
    out: list[ClaimResult] = []
    for claim in claims:
        found = False
        for backend, models in pairs.items():
            names = [models.get(f) for f in claim.families]
            if None in names:
                continue
            a = lookup(claim.system, str(names[0]), claim.metric)
            b = lookup(claim.system, str(names[1]), claim.metric)
            if a is None or b is None:
                continue
            found = True
            why = next(
                (
                    w
                    for w in (untrained(claim.system, str(n)) if untrained else None for n in names)
                    if w
                ),
                None,
            )
            if why is not None:
                outcome, ratio, note = NOT_TRAINED, math.nan, why
            else:
                outcome, ratio, note = claim.judge(a, b)
            if claim.recipe:
                note = "; ".join(x for x in (note, f"protocol track: {claim.recipe} not run") if x)
            out.append(ClaimResult(claim, backend, outcome, a, b, ratio, note))
        if not found:
            out.append(
                ClaimResult(
                    claim,
                    "-",
                    NOT_RUN,
                    math.nan,
                    math.nan,
                    math.nan,
                    "no run of this system with both models",
                )
            )
    return out


def published_results(claim_set: ClaimSet) -> list[ClaimResult]:
    """``claim_set``'s claims evaluated on its own published values."""
    index = {(p.system, p.family, p.metric): p.value for p in claim_set.published}

    def lookup(system: str, family: str, metric: str) -> Optional[float]:
        return index.get((system, family, metric))

    families = {f for c in claim_set.claims for f in c.families}
    results = evaluate_claims(
        lookup, claim_set.claims, pairs={"published": {f: f for f in families}}
    )
    return [r for r in results if r.backend == "published"]
