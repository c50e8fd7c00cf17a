"""The paper profile's three-body dataset (slow: REBOUND over every trajectory;
tests/unit/test_nbody.py has the rest)."""

from __future__ import annotations

import pytest

from hnnbench_plugins.systems.nbody import (
    ThreeBody,
    ThreeBodyConfig,
)


@pytest.mark.slow
def test_paper_three_body_dataset():
    system = ThreeBody(ThreeBodyConfig(name="three_body"))
    data = system.dataset(0)
    assert len(data.train) == 4000 * 20 and len(data.test) == 1000 * 20
    assert data.meta["max_rel_energy_drift"] < 1e-10
    assert data.meta["n_rejected_orbits"] <= 5
