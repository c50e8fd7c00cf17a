"""The ``device`` setting of a job: one grammar, read by the job's validation
(:func:`hnnbench._running.config.validate_run`) and by both backends' ``resolve_device``, which
name a GPU ``cuda:N`` alike (docs/SCALING.md, "GPUs"). Imports nothing but the
standard library, so validating a config loads no backend and no neural code."""

from __future__ import annotations

import re

from hnnbench._contracts.errors import ConfigError

__all__ = ["device_request", "gpu_device"]

_DEVICE = re.compile(r"(auto|cpu|cuda(?::(\d+))?)", re.ASCII)


def device_request(requested: str) -> tuple[str, int]:
    """A job's ``device`` setting, read the same way by the job's validation and by both
    backends: ``auto`` -> ``("auto", 0)``, ``cpu`` -> ``("cpu", 0)``, ``cuda`` ->
    ``("cuda", 0)``, ``cuda:N`` -> ``("cuda", N)``. Anything else is a
    :class:`ConfigError` saying what is accepted."""
    match = _DEVICE.fullmatch(str(requested))
    if match is None:
        raise ConfigError(f"device={requested} is invalid: expected auto, cpu, cuda or cuda:N.")
    text, index = match.group(1), match.group(2)
    if text in ("auto", "cpu"):
        return text, 0
    return "cuda", int(index or 0)


def gpu_device(requested: str, index: int, count: int, backend: str, install: str) -> None:
    """Raise a :class:`ConfigError` unless GPU ``index`` is one of the ``count`` GPUs
    ``backend`` sees (``install``: how to get a CUDA build of it)."""
    if count == 0:
        raise ConfigError(
            f"device={requested} was requested but {backend} sees no CUDA GPU: use device=cpu "
            f"or device=auto (or install a CUDA build of {backend}: {install})."
        )
    if index >= count:
        raise ConfigError(
            f"device={requested} was requested but {backend} sees only {count} GPU(s): "
            f"use device=cuda:0..{count - 1}."
        )
