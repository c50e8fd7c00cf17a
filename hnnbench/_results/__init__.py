"""From records to results: the statistics of a verdict, the leaderboard, one competitor
per family, the aggregate across systems, what a record's provenance says, the
regression gate (``check/``) and the report (``report/``) (docs/ARCHITECTURE.md,
"Layers"; docs/STATISTICS.md).
"""
