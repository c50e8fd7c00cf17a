"""A command line's jobs: its overrides parsed and checked into a plan, the plan run
through Hydra and any launcher with hnnbench's sweeper (the sweep directory's lock, the
ETA, every job's outcomes collected), and the end-of-sweep summary
(docs/ARCHITECTURE.md, "The path of one job").
"""
