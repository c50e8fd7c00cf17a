"""The time-reversal test measures the model, not the solver: the true field passes it.

For every installed system whose true dynamics are time-reversible and known, the oracle
(the true field through the core's evaluation) scores ``reversibility_error <= 1e-8`` at
the paper profile's rollout tolerance (rtol = atol = 1e-9). The data are the quick
profile's, which the metric does not depend on. Issue 18's check; the old RK4 round trip
gave the oracle ~1e3 on the n-body systems.
"""

from __future__ import annotations

import pytest

from hnnbench import registry
from hnnbench.config import compose
from hnnbench.job import run_job

#: Built-in systems the test must reach, so that it cannot pass by checking nothing.
EXPECTED = {"spring", "pendulum", "two_body", "three_body", "double_pendulum", "spring_chain"}


def _reversible_systems() -> list[str]:
    return [
        n for n in registry.available("system") if registry.get_class("system", n).time_reversible
    ]


@pytest.mark.slow
def test_the_oracle_passes_the_time_reversal_test(tmp_path):
    checked = {}
    for name in _reversible_systems():
        overrides = [
            f"system={name}",
            "model=oracle",
            "profile=quick",
            "evaluation.rtol=1e-9",
            "evaluation.atol=1e-9",
        ]
        record = run_job(compose(overrides), tmp_path / name, overrides=overrides)
        if record["status"] == "skipped":  # no known field (measured data, pixels)
            assert record["error"], name
            continue
        assert record["status"] == "ok", (name, record["error"])
        checked[name] = record["metrics"]["reversibility_error"]["mean"]
    assert EXPECTED <= set(checked), f"not checked: {EXPECTED - set(checked)}"
    worst = {n: v for n, v in checked.items() if not v <= 1e-8}
    assert not worst, f"oracle reversibility_error above 1e-8: {worst}"
