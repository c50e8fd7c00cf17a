"""One job cannot leak into the next: the process-global state a plugin could change
(the environment, the working directory and :data:`GLOBALS`) is restored after each
job's plugin calls, except the harness's own settings (:data:`HARNESS_ENV`, the thread
pools' size, JAX's 64-bit floats once ``hnnbench.neural.jax`` set them)
(docs/ARCHITECTURE.md, "Decisions").
"""

from __future__ import annotations

import contextlib
import os
import random
import sys
import warnings
from collections.abc import Iterator
from typing import Any

__all__ = ["GLOBALS", "HARNESS_ENV", "isolated"]

#: The process-global settings restored after a job (besides the environment and the
#: working directory).
GLOBALS = (
    "sys.path",
    "warnings filters",
    "random state",
    "numpy global random state",
    "torch default dtype",
    "torch random state",
    "JAX x64",
)
#: Environment variables the harness itself sets for a job (one thread per job; under
#: ``device_share``, the GPU a worker process sees and JAX's share of its memory, read
#: once, when a backend starts): kept.
HARNESS_ENV = (
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "CUDA_VISIBLE_DEVICES",
    "XLA_PYTHON_CLIENT_MEM_FRACTION",
    "XLA_PYTHON_CLIENT_PREALLOCATE",
)


def _snapshot() -> dict[str, Any]:
    import numpy as np

    snap: dict[str, Any] = {
        "environ": dict(os.environ),
        "cwd": os.getcwd(),
        "path": list(sys.path),
        "warnings": list(warnings.filters),
        "random": random.getstate(),
        "numpy": np.random.get_state(),
    }
    torch = sys.modules.get("torch")
    if torch is not None:
        snap["torch_dtype"] = torch.get_default_dtype()
        snap["torch_rng"] = torch.random.get_rng_state()
    jax = sys.modules.get("jax")
    if jax is not None:
        snap["x64"] = bool(jax.config.read("jax_enable_x64"))
    return snap


def _restore(snap: dict[str, Any]) -> None:
    import numpy as np

    kept = {k: os.environ[k] for k in HARNESS_ENV if k in os.environ}
    if dict(os.environ) != {**snap["environ"], **kept}:
        for key in [k for k in os.environ if k not in snap["environ"] and k not in kept]:
            del os.environ[key]
        os.environ.update({**snap["environ"], **kept})
    with contextlib.suppress(OSError):
        if os.getcwd() != snap["cwd"]:
            os.chdir(snap["cwd"])
    sys.path[:] = snap["path"]
    warnings.filters[:] = snap["warnings"]  # type: ignore[index]
    warnings._filters_mutated()  # type: ignore[attr-defined]
    random.setstate(snap["random"])
    np.random.set_state(snap["numpy"])
    torch = sys.modules.get("torch")
    if torch is not None and "torch_dtype" in snap:
        torch.set_default_dtype(snap["torch_dtype"])
        torch.random.set_rng_state(snap["torch_rng"])
    jax = sys.modules.get("jax")
    if jax is not None:
        harness = sys.modules.get("hnnbench.neural.jax") is not None
        want = True if harness else snap.get("x64", False)
        if bool(jax.config.read("jax_enable_x64")) != want:
            jax.config.update("jax_enable_x64", want)


@contextlib.contextmanager
def isolated() -> Iterator[None]:
    """Run the block (a job's plugin calls), then restore what it changed of the
    process's global state (see the module docstring)."""
    snap = _snapshot()
    try:
        yield
    finally:
        _restore(snap)
