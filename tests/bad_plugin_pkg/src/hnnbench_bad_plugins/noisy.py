"""A working system whose module prints to stdout when it is imported."""

from hnnbench_plugins.systems.spring import Spring

print("hello from a noisy plugin")
print("{ not json")


class NoisySpring(Spring):
    """The spring, from a module that prints at import."""

    description = "Spring, printed at import (test plugin)"
