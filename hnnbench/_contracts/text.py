"""Text that stays data where it ends up (docs/LEADERBOARD.md, "Threat model"): a CSV
cell that a spreadsheet would run as a formula is neutralised, and control characters
(ANSI and OSC terminal escapes, other C0/C1 codes) are stripped from what is printed or
written to Markdown and HTML.
"""

from __future__ import annotations

import re
from typing import Any

__all__ = ["FORMULA_START", "csv_cell", "csv_text", "neutral_frame", "printable"]

#: The characters that make a spreadsheet read a cell as a formula (or a command), at
#: the start of a text cell (OWASP's CSV injection list).
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
#: C0 controls but tab and newline, DEL, C1 controls; ESC starts every ANSI/OSC escape.
_CONTROL = re.compile(
    r"\x1b\[[0-?]*[ -/]*[@-~]|\x1b\][^\x07\x1b]*(\x07|\x1b\\)?|[\x00-\x08\x0b-\x1f\x7f-\x9f]"
)


def printable(text: Any) -> str:
    """``text`` (as ``str``) without control characters: terminal escape sequences
    (ANSI CSI, OSC) are removed whole, any other control character but tab and newline
    dropped."""
    return _CONTROL.sub("", str(text))


def csv_cell(value: Any) -> Any:
    """A CSV cell that stays data: a text cell starting with a formula character
    (:data:`FORMULA_START`) gets a leading apostrophe, and its control characters are
    stripped; numbers (negative ones too) and every other value are unchanged."""
    if not isinstance(value, str):
        return value
    value = printable(value) if value[:1] not in ("\t", "\r") else value
    return "'" + value if value.startswith(FORMULA_START) else value


def neutral_frame(frame: Any) -> Any:
    """A copy of the DataFrame ``frame`` whose text cells (and column names) are
    :func:`csv_cell`'s."""
    out = frame.copy()
    for column in out.columns:
        if out[column].dtype.kind not in "biufcmM":  # text (object or string dtype)
            out[column] = out[column].map(csv_cell)
    out.columns = [csv_cell(c) for c in out.columns]
    return out


def csv_text(frame: Any, **kwargs: Any) -> str:
    """``frame.to_csv(index=False)`` of :func:`neutral_frame`: every CSV hnnbench
    writes."""
    kwargs.setdefault("index", False)
    return str(neutral_frame(frame).to_csv(**kwargs))
