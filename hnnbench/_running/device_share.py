"""Several jobs on one GPU (``device_share=N``): the paper-sized networks use a small part
of a GPU, so a launcher runs ``N × GPUs`` job processes and each takes one of ``N``
slots of a GPU (a ``flock`` per slot, the least-held GPU first, as
:mod:`hnnbench._running.affinity` does for CPU cores) and at most ``0.9 / N`` of its
memory (JAX preallocates 75 % of a GPU by default; torch's allocator grows on demand).
docs/SCALING.md, "Several jobs per GPU". Linux only; elsewhere a job keeps its device.
"""

from __future__ import annotations

import logging
import os
import sys
import tempfile
from pathlib import Path
from typing import IO, Optional

from hnnbench._contracts.device import device_request
from hnnbench._running.slots import claim_least_held

__all__ = ["MEMORY_SHARE", "claim_gpu", "memory_fraction", "share_device", "visible_gpus"]

#: The part of a GPU's memory that ``N`` sharing jobs divide among them.
MEMORY_SHARE = 0.9
_NVIDIA_GPUS = Path("/proc/driver/nvidia/gpus")
_held: dict[str, object] = {}
log = logging.getLogger("hnnbench")


def visible_gpus() -> int:
    """The NVIDIA GPUs this process may use, without starting a backend:
    ``CUDA_VISIBLE_DEVICES`` when set (``""`` or ``-1``: none), else the GPUs the driver
    lists under ``/proc/driver/nvidia/gpus``; 0 without a driver."""
    listed = os.environ.get("CUDA_VISIBLE_DEVICES")
    if listed is not None:
        ids = [part.strip() for part in listed.split(",") if part.strip()]
        # CUDA stops at the first invalid id; "-1" is the usual way to hide every GPU.
        count = 0
        for part in ids:
            if part.startswith("-"):
                break
            count += 1
        return count
    try:
        return sum(1 for entry in _NVIDIA_GPUS.iterdir() if entry.is_dir())
    except OSError:
        return 0


def memory_fraction(share: int) -> float:
    """The part of a GPU's memory each of ``share`` jobs may take: ``0.9 / share``."""
    return MEMORY_SHARE / share


def _lock_dir() -> Path:
    uid = os.getuid() if hasattr(os, "getuid") else 0
    path = Path(tempfile.gettempdir()) / f"hnnbench-gpus-{uid}"
    path.mkdir(parents=True, exist_ok=True)
    return path


def claim_slot(directory: Path, gpus: int, share: int) -> tuple[int, Optional[IO[str]]]:
    """Take a free slot (``gpu<i>.<slot>.lock``, ``slot < share``) of the GPU whose slots
    are least held (the lowest index on a tie; :mod:`hnnbench._running.slots`): ``(gpu,
    the open lock file)``, which holds the slot until it is closed. Every slot taken:
    ``(pid mod gpus, None)``, the GPU shared beyond ``share``."""
    slots = {gpu: [f"gpu{gpu}.{slot}.lock" for slot in range(share)] for gpu in range(gpus)}
    gpu, handle = claim_least_held(directory, slots)
    return (os.getpid() % gpus, None) if gpu is None else (gpu, handle)


def claim_gpu(gpus: int, share: int, lock_dir: Optional[Path] = None) -> int:
    """This process's GPU among ``gpus`` shared by ``share`` jobs each; the slot is held
    for the life of the process (a launcher's worker runs its jobs on one GPU).
    Idempotent. Without file locks (not POSIX, an unwritable temporary directory): the
    process id modulo ``gpus``, with a warning."""
    if "gpu" in _held:
        return int(_held["gpu"])  # type: ignore[call-overload]
    try:
        gpu, handle = claim_slot(lock_dir or _lock_dir(), gpus, share)
    except (OSError, ImportError) as err:
        gpu, handle = os.getpid() % gpus, None
        log.warning("hnnbench: no GPU slot could be claimed (%s); using GPU %d", err, gpu)
    _held.update(gpu=gpu, handle=handle)
    return gpu


def share_device(requested: str, share: int, lock_dir: Optional[Path] = None) -> str:
    """The device a job passes to its model when ``share`` jobs share each GPU.

    ``share == 1``, ``device=cpu`` or no GPU visible: ``requested`` as it is. Otherwise
    JAX is told to take at most :func:`memory_fraction` of the GPU and not to
    preallocate (``XLA_PYTHON_CLIENT_MEM_FRACTION``, ``XLA_PYTHON_CLIENT_PREALLOCATE``;
    values already set are kept; they take effect only before JAX starts its GPU
    backend, so a warning says when it had), and ``auto`` or ``cuda`` becomes
    ``cuda:<the claimed slot's GPU>``; ``cuda:N`` stays on GPU ``N``.
    """
    kind, _ = device_request(requested)
    if share <= 1 or kind == "cpu":
        return requested
    gpus = visible_gpus()
    if gpus == 0:
        return requested
    os.environ.setdefault("XLA_PYTHON_CLIENT_MEM_FRACTION", f"{memory_fraction(share):.4f}")
    os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")
    bridge = sys.modules.get("jax._src.xla_bridge")
    if getattr(bridge, "_backends", None) and "gpu_warned" not in _held:
        _held["gpu_warned"] = True
        log.warning(
            "JAX had started before device_share=%d applied: its GPU memory limit is the "
            "one it started with; run from the hnnbench command for the shared limit",
            share,
        )
    if ":" in requested:
        return requested
    return f"cuda:{claim_gpu(gpus, share, lock_dir)}"
