"""Deprecated: ``hnnbench.data`` is now private (``hnnbench._data``); import the
public names from :mod:`hnnbench`. To be removed in hnnbench 0.5."""

from hnnbench._deprecated import forward

__getattr__ = forward("hnnbench.data", "hnnbench._data")
