"""Deprecated: ``hnnbench.integrate`` is now private (``hnnbench._integrate``); import the
public names from :mod:`hnnbench`. To be removed in hnnbench 0.5."""

from hnnbench._deprecated import forward

__getattr__ = forward("hnnbench.integrate", "hnnbench._integrate")
