"""Model outputs checked against the shapes and dtypes the contract documents
(:func:`checked`, before the evaluation or a loss uses them): a mismatch is a one-line
:class:`~hnnbench.ModelOutputError`, and an output already right is returned as it is
(docs/PLUGINS.md, "3. Write a model", where the shapes are listed).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Optional

import numpy as np

from hnnbench._contracts.errors import ModelOutputError

__all__ = ["checked", "checked_scalar", "shape_text"]

#: ``None`` in an expected shape: any size (e.g. an encoder's latent width).
Dim = Optional[int]


def shape_text(shape: Sequence[Any]) -> str:
    """``(3, 50, 2)``; ``(3, ?)`` where a size is free; ``(N,)`` for one dimension."""
    dims = ["?" if d is None else str(d) for d in shape]
    return "(" + ", ".join(dims) + ("," if len(dims) == 1 else "") + ")"


def _owner(model: Any) -> str:
    name = getattr(getattr(model, "cfg", None), "name", None)
    return str(name) if name else type(model).__name__


def checked(
    model: Any,
    method: str,
    value: Any,
    shape: Sequence[Dim],
    meaning: str,
    float64: bool = True,
    optional: bool = False,
) -> Any:
    """``value``, the output of ``model.<method>``, if it has ``shape`` (``None``: any
    size) and a float64 dtype (``float64=False``: any real floating dtype); raise
    :class:`ModelOutputError` otherwise. ``meaning`` spells the expected shape in the
    contract's words (``"(M, T, d)"``), shown with the numbers. ``optional``: ``None``
    is a valid output (``energy``, ``decode`` of a model without one)."""
    if value is None and optional:
        return None
    owner = f"{_owner(model)}.{method}"
    if value is None:
        raise ModelOutputError(
            f"{owner} returned None; expected an array of shape {meaning} = {shape_text(shape)}"
        )
    arr = value
    if not (hasattr(arr, "shape") and hasattr(arr, "dtype")):
        try:
            arr = np.asarray(value)
        except Exception:
            raise ModelOutputError(
                f"{owner} returned a {type(value).__name__}; expected "
                f"an array of shape {meaning} = {shape_text(shape)}"
            ) from None
    actual = tuple(int(d) for d in arr.shape)
    if len(actual) != len(shape) or any(
        e is not None and e != a for e, a in zip(shape, actual, strict=False)
    ):
        raise ModelOutputError(
            f"{owner} returned shape {shape_text(actual)}, expected {meaning} = "
            f"{shape_text(shape)} (docs/PLUGINS.md)"
        )
    dtype = np.dtype(arr.dtype)
    ok = dtype == np.float64 if float64 else np.issubdtype(dtype, np.floating)
    if not ok:
        want = "float64" if float64 else "a floating dtype"
        raise ModelOutputError(
            f"{owner} returned dtype {dtype} (shape {shape_text(actual)}), "
            f"expected {want} (docs/PLUGINS.md)"
        )
    return arr


def checked_scalar(model: Any, method: str, value: Any) -> float:
    """``value`` (the output of ``model.<method>``, e.g. ``loss``) as a float, if it is
    a real scalar; :class:`ModelOutputError` otherwise."""
    owner = f"{_owner(model)}.{method}"
    shape = getattr(value, "shape", ())
    if isinstance(value, (bool, np.bool_)) or tuple(shape) not in ((), (1,)):
        what = f"shape {shape_text(tuple(shape))}" if shape else type(value).__name__
        raise ModelOutputError(f"{owner} returned {what}, expected a scalar")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ModelOutputError(
            f"{owner} returned a {type(value).__name__}, expected a real scalar"
        ) from None
    return out
