"""JSON read strictly: an object that names one key twice is refused (a reader would
take either value: the last, as Python's ``json`` does, or the first), wherever
hnnbench reads JSON it did not just write itself (docs/LEADERBOARD.md, "Threat model").
"""

from __future__ import annotations

import json
from typing import Any

__all__ = ["DuplicateKeyError", "loads", "unique_object"]


class DuplicateKeyError(ValueError):
    """A JSON object names one key twice."""


def unique_object(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``json``'s ``object_pairs_hook``: the object, or :class:`DuplicateKeyError` naming
    the first key given twice."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            shown = key if len(key) <= 64 else key[:61] + "..."
            raise DuplicateKeyError(
                f"duplicate key {shown!r} in one JSON object (each key once: a reader "
                "would take either value)"
            )
        out[key] = value
    return out


def loads(text: str | bytes) -> Any:
    """``json.loads`` refusing duplicate keys (:class:`DuplicateKeyError`, a
    ``ValueError``)."""
    return json.loads(text, object_pairs_hook=unique_object)
