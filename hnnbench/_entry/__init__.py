"""The entry points, the top layer: the ``hnnbench`` command
(:mod:`~hnnbench._entry.command`, the console script) and the Python API behind
``hnnbench.run``, ``sweep``, ``tune``, ``load`` and ``leaderboard``
(:mod:`~hnnbench._entry.api`).
"""
