"""Text from records and plugins, made safe to put into Markdown.

Every Markdown table cell the report writes goes through :func:`md_cell`, every inline
code span through :func:`md_code` and every other line of text from a record or a
plugin through :func:`md_text`: whatever a name, a variant, a command line or a claim
says, it stays inside its cell or line. A line break never starts a new row or line, a
``|`` never opens a cell, a backtick never opens or closes a code span, a ``<`` never
starts raw HTML, and so no text can hold an HTML comment such as the README's
``<!-- leaderboard:begin -->`` markers (scripts/maintainer/publish_results.py).

Plain text (names, numbers, ``<=``, ``±``) is written as it is.
"""

from __future__ import annotations

import re
from typing import Any

from hnnbench._contracts.text import printable

__all__ = ["md_cell", "md_code", "md_text"]

# "<" that could open raw HTML, a comment or a processing instruction (CommonMark: a
# letter, "/", "!" or "?" follows it).
_HTML_START = re.compile(r"<(?=[A-Za-z/!?])")
_INLINE = str.maketrans({"\\": "&#92;", "`": "&#96;"})


def _one_line(value: Any) -> str:
    """``str(value)`` without control characters (terminal escapes:
    :func:`hnnbench._contracts.text.printable`), every line break and run of whitespace
    as one space."""
    return " ".join(printable(value).split())


def md_text(value: Any) -> str:
    """``value`` as one line of Markdown text: no line break, no code span, no raw HTML
    (backslashes and backticks as character references, ``<`` before a tag as
    ``&lt;``)."""
    return _HTML_START.sub("&lt;", _one_line(value).translate(_INLINE))


def md_cell(value: Any) -> str:
    """``value`` as the content of one Markdown (GitHub) table cell: :func:`md_text`,
    and ``|`` as a character reference (so it never splits the row)."""
    return md_text(value).replace("|", "&#124;")


def md_code(value: Any) -> str:
    """``value`` as an inline code span (with its backticks): one line, its backticks
    as ``'`` (a code span shows its text literally, so it cannot escape them), and
    ``<!`` as ``‹!`` (so it never holds an HTML comment marker). Not for table cells
    (use :func:`md_cell`)."""
    text = _one_line(value).replace("`", "'").replace("<!", "\u2039!")
    return f"`{text}`"
