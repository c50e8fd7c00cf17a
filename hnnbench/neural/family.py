"""Deprecated: ``hnnbench.neural.family`` is now private; import the public names
from :mod:`hnnbench.neural`. To be removed in hnnbench 0.5."""

from hnnbench._deprecated import forward

__getattr__ = forward("hnnbench.neural.family", "hnnbench.neural._family")
