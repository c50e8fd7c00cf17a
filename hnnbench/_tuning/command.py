"""``hnnbench tune ...``: the command (docs/TUNING.md, "Running the tuned track")."""

from __future__ import annotations

import logging
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    pass
from hnnbench._tuning.request import USAGE, parse
from hnnbench._tuning.tuner import run_tuning

__all__ = ["main"]


def main(args: Sequence[str]) -> int:
    """``hnnbench tune ...``: exit 0 when every model was tuned (or skipped), 1 when a
    final run failed."""
    if any(a in ("-h", "--help", "help") for a in args):
        print(USAGE)
        return 0
    if not logging.getLogger().handlers:
        logging.basicConfig(
            level=logging.INFO,
            stream=sys.stderr,
            format="[%(asctime)s] %(message)s",
            datefmt="%H:%M:%S",
        )
    studies = run_tuning(parse(args))
    failed = [
        f"{s.model} seed {r.get('seed')}"
        for s in studies
        for r in s.finals
        if r.get("status") in ("failed", "timeout")
    ]
    for study in studies:
        statuses = ", ".join(str(r.get("status")) for r in study.finals) or "no final runs"
        fold = "" if study.group.fold is None else f" fold {study.group.fold}"
        print(
            f"{study.model}{fold}: {len(study.trials)} trial(s) of "
            f"{len(study.group.trial_seeds)} seed(s), tuning CPU {study.cpu_s:.0f} s, "
            f"final: {statuses}",
            file=sys.stderr,
        )
    if failed:
        print(
            f"hnnbench tune: {len(failed)} final run(s) failed: {', '.join(failed)}",
            file=sys.stderr,
        )
        return 1
    return 0
