"""A record as strict JSON: non-finite numbers encoded as strings and ``null`` and
decoded back, and the deepest nesting a record may have.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["MAX_DEPTH", "decode", "decode_number", "encode"]


#: The deepest nesting of objects and arrays in a record (a record nests 4 to 6 levels;
#: its stored config a few more); deeper JSON is refused before the schema sees it.
MAX_DEPTH = 32


def encode(value: Any) -> Any:
    """``value`` as strict JSON data: numpy types as Python ones, ``inf`` as ``"inf"``,
    NaN as ``None``, recursively."""
    if isinstance(value, dict):
        return {str(k): encode(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [encode(v) for v in value]
    if hasattr(value, "item") and getattr(value, "ndim", None) == 0:
        value = value.item()
    elif hasattr(value, "tolist"):
        return encode(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    return str(value)


def decode_number(value: Any) -> Any:
    """A number as :func:`encode` wrote it: ``None`` as NaN, ``"inf"`` (and the other
    spellings of a non-finite float) as the float; anything else as it is."""
    if value is None:
        return math.nan
    if value in ("inf", "-inf", "Infinity", "-Infinity", "NaN", "nan"):
        return float(value)
    return value


def decode(record: dict[str, Any]) -> dict[str, Any]:
    """Turn the encoded non-finite values of ``metrics`` and ``history`` back into
    floats (in place; returns ``record``)."""
    for metric in (record.get("metrics") or {}).values():
        if isinstance(metric, dict):
            for key in ("mean", "sem"):
                if key in metric:
                    metric[key] = decode_number(metric[key])
    history = record.get("history")
    if isinstance(history, dict):
        for key, values in history.items():
            if isinstance(values, list):
                history[key] = [decode_number(v) for v in values]
    return record


def depth_problems(data: Any, limit: int = MAX_DEPTH) -> list[str]:
    """``["nested deeper than ..."]`` when objects and arrays in ``data`` nest more than
    ``limit`` levels (checked without recursion), else ``[]``."""
    level: list[tuple[Any, int]] = [(data, 1)]
    while level:
        value, depth = level.pop()
        children = (
            value.values()
            if isinstance(value, dict)
            else value
            if isinstance(value, list)
            else None
        )
        if children is None:
            continue
        if depth > limit:
            return [f"JSON nested deeper than {limit} levels"]
        level.extend((child, depth + 1) for child in children if isinstance(child, (dict, list)))
    return []
