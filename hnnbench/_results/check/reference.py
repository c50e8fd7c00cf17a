"""The reference leaderboard (a ``leaderboard.csv``), read and validated, and the key
of its rows (profile, system, model, variant, track).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from hnnbench._contracts.names import BOARD_KEY, DEFAULT_TRACK, STATUSES
from hnnbench._results.check.findings import CheckError
from hnnbench._results.leaderboard import (
    INTERVAL_SUFFIXES,
)

__all__ = ["COUNT_COLUMNS", "KEY", "REQUIRED_COLUMNS", "read_reference"]


KEY = BOARD_KEY
#: Status counts a reference must have (``n_timeout``, new in 0.3, reads 0 where absent).
COUNT_COLUMNS = ("n_seeds", *(f"n_{s}" for s in STATUSES if s != "timeout"))
REQUIRED_COLUMNS = (*KEY, *COUNT_COLUMNS)


def read_reference(path: Path | str) -> pd.DataFrame:
    """A reference leaderboard CSV, validated; :class:`CheckError` if unusable."""
    path = Path(path)
    if not path.exists():
        raise CheckError(
            f"Reference {path} does not exist; create it from a sweep with "
            f"hnnbench check DIR --reference {path} --update"
        )
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
            "(from hnnbench report, or hnnbench check --update)"
        )
    if not any(c.endswith("_mean") for c in frame.columns):
        raise CheckError(
            f"Reference {path} has no metric columns (<metric>_mean); expected a leaderboard.csv"
        )
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
                raise CheckError(
                    f"Reference {path}: column {col} holds a non-number "
                    f"({frame[col][bad].iloc[0]!r})"
                )
            frame[col] = values.astype(float)
    dupes = frame.duplicated(list(key_columns(frame)))
    if dupes.any():
        r = frame[dupes].iloc[0]
        raise CheckError(
            f"Reference {path} has duplicate rows for {r['system']} x "
            f"{r['model']} (profile {r['profile']})"
        )
    return frame


def key_columns(frame: pd.DataFrame) -> tuple[str, ...]:
    """The columns that identify a row: :data:`KEY`, plus ``variant`` and ``track``
    where present."""
    return (*KEY, *(c for c in ("variant", "track") if c in frame.columns))


def row_key(row: Any) -> tuple[str, str, str, str, str]:
    """``(profile, system, model, variant, track)`` of a leaderboard row (variant ``""``
    if none; track ``protocol`` if none: a tuned or recipe row is never compared with
    a protocol one)."""
    variant = row.get("variant", "")
    variant = "" if variant is None or pd.isna(variant) else str(variant)
    track = row.get("track", DEFAULT_TRACK)
    track = DEFAULT_TRACK if track is None or pd.isna(track) or track == "" else str(track)
    return (str(row["profile"]), str(row["system"]), str(row["model"]), variant, track)


def model_text(model: str, variant: str, track: str = DEFAULT_TRACK) -> str:
    text = f"{model} [{variant}]" if variant else model
    return text if track == DEFAULT_TRACK else f"{text} ({track} track)"
