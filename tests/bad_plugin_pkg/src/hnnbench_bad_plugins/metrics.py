"""A metric (required, the default) whose compute raises for every model."""

from hnnbench import Metric


def _boom(ctx):
    raise RuntimeError("this metric is broken")


RAISING = Metric(name="raising_metric", description="Always raises (test plugin)", compute=_boom)
