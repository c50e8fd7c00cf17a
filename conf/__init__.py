"""hnnbench's Hydra config (conf/ in the repository), shipped as package data."""
