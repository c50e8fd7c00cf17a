"""Deprecated: ``hnnbench.neural.config`` is now private; import the public names
from :mod:`hnnbench.neural`. To be removed in hnnbench 0.5."""

from hnnbench._deprecated import forward

__getattr__ = forward("hnnbench.neural.config", "hnnbench.neural._config")
