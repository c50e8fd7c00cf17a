"""A plugin module that calls sys.exit() when it is imported."""

import sys

sys.exit("hnnbench_bad_plugins.exits: refusing to load")


class ExitingSystem:  # never reached
    pass
