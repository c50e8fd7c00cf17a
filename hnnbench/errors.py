"""Deprecated: ``hnnbench.errors`` is now private (``hnnbench._errors``); import the
public names from :mod:`hnnbench`. To be removed in hnnbench 0.5."""

from hnnbench._deprecated import forward

__getattr__ = forward("hnnbench.errors", "hnnbench._errors")
