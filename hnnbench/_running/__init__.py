"""Running one job: its config (schema, validation, composition through Hydra, the
ConfigStore), the job itself (data from the cache -> fit -> evaluation -> one record per
seed) and what it runs under (core pinning, progress, the launch context, the private
Hydra API). Above the record, below sweeping (docs/ARCHITECTURE.md, "The path of one
job").
"""
