"""Built-in systems. Each module is one system; see the entry points in pyproject.toml."""
