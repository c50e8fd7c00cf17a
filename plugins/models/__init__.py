"""Built-in models. Each module is one model family; see the entry points in pyproject.toml."""
