"""Built-in hnnbench plugins (installed as ``hnnbench_plugins``).

They are registered through the same entry points as third-party plugins; see
``[project.entry-points]`` in pyproject.toml.
"""
