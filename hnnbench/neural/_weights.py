"""Saving and loading neural-model weights: one safetensors file, no pickle, the same
format for every backend (written and read through safetensors' numpy API)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from hnnbench._contracts import jsonio

__all__ = ["FORMAT", "load_weights", "save_weights"]

#: Format tag written into the file's metadata.
FORMAT = "hnnbench-neural/1"


def save_weights(path: Path, weights: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
    """Write ``weights`` (``{name: array}``) and JSON-serialisable ``meta`` to ``path``
    exactly (no suffix is added)."""
    from safetensors.numpy import save_file

    arrays = {k: np.ascontiguousarray(v) for k, v in weights.items()}
    # One metadata key: safetensors writes several in no fixed order, and the same
    # weights must give the same bytes.
    header = json.dumps({"format": FORMAT, "meta": meta}, sort_keys=True)
    save_file(arrays, str(path), metadata={"hnnbench": header})


def load_weights(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """``(weights, meta)`` from a file written by :func:`save_weights`; a file of
    another format raises ``ValueError``."""
    from safetensors import safe_open

    try:
        with safe_open(str(path), framework="numpy") as fh:
            header = fh.metadata() or {}
            weights = {key: fh.get_tensor(key) for key in fh.keys()}  # noqa: SIM118
    except Exception as err:  # safetensors raises its own error types
        raise ValueError(f"{path} is not a readable weight file: {err}") from None
    try:
        info = jsonio.loads(header.get("hnnbench", "{}"))
    except ValueError:
        info = {}
    if info.get("format") != FORMAT:
        raise ValueError(f"{path} is not an {FORMAT} weight file")
    return weights, dict(info.get("meta") or {})
