"""scripts/maintainer/publish_results.py, imported for the publishing tests
(tests/unit/test_publish_script.py, tests/integration/test_publish_script_pages.py; their
``tree`` fixture is in conftest.py)."""

from __future__ import annotations

import sys

from conftest import REPO

sys.path.insert(0, str(REPO / "scripts" / "maintainer"))
import publish_results  # noqa: E402

__all__ = ["publish_results"]
