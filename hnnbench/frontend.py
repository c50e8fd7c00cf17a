"""Deprecated: ``hnnbench.frontend`` is now private (``hnnbench._user_api``); import the
public names from :mod:`hnnbench`. To be removed in hnnbench 0.5."""

from hnnbench._deprecated import forward

__getattr__ = forward("hnnbench.frontend", "hnnbench._user_api")
