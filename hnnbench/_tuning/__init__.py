"""The tuned track, ``hnnbench tune``: the request (:mod:`~hnnbench._tuning.request`), the
studies and their jobs (:mod:`~hnnbench._tuning.tuner`) and the command
(:mod:`~hnnbench._tuning.command`) (docs/TUNING.md).
"""
