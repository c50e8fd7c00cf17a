"""The torch backend flushes subnormal floats while it trains and infers, as XLA does for
the JAX twin, and gives the caller's setting back."""

from __future__ import annotations

import pytest

pytest.importorskip("torch")


def test_the_decorated_work_flushes_and_the_callers_setting_comes_back():
    import torch

    from hnnbench.neural.torch import _flushing_subnormals, _keeps_subnormals

    assert _keeps_subnormals()  # torch's default
    assert _flushing_subnormals(_keeps_subnormals)() is False  # flushed inside
    assert _keeps_subnormals()  # given back
    torch.set_flush_denormal(True)  # a caller that flushes keeps flushing
    try:
        assert _flushing_subnormals(_keeps_subnormals)() is False
        assert not _keeps_subnormals()
    finally:
        torch.set_flush_denormal(False)
