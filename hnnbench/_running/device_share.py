"""Several jobs on one GPU (``device_share=N``): the paper-sized networks use a small part
of a GPU, so a launcher runs ``N × GPUs`` job processes and each takes one of ``N``
slots of a GPU (a ``flock`` per slot, the least-held GPU first:
:mod:`hnnbench._running.slots`), sees only that GPU (``CUDA_VISIBLE_DEVICES``, so
``device=auto`` still falls back to the CPU in a backend without CUDA) and lets JAX take
at most ``0.9 / N`` of its memory (JAX preallocates 75 % of a GPU by default; torch's
allocator grows on demand). docs/SCALING.md, "Several jobs per GPU". The slots need
POSIX file locks; without them a job takes GPU ``pid mod GPUs``.
"""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path
from typing import IO, Optional

from hnnbench._contracts.device import device_request
from hnnbench._running.slots import claim_least_held, slots_dir

__all__ = [
    "MAX_SHARE",
    "MEMORY_SHARE",
    "apply_device_share",
    "claim_gpu",
    "claim_slot",
    "gpu_backend_started",
    "jax_started",
    "memory_fraction",
    "visible_gpus",
]

#: The part of a GPU's memory that ``N`` sharing jobs divide among them.
MEMORY_SHARE = 0.9
#: The most jobs that may share one GPU.
MAX_SHARE = 64
_NVIDIA_GPUS = Path("/proc/driver/nvidia/gpus")
_held: dict[str, object] = {}
log = logging.getLogger("hnnbench")


def visible_gpus() -> list[str]:
    """The NVIDIA GPUs this process may use, named as ``CUDA_VISIBLE_DEVICES`` names
    them, found without starting a backend: its entries when it is set (up to the first
    invalid one, as CUDA reads it: ``""`` or ``-1`` hide every GPU), else ``0..n-1``
    for the ``n`` GPUs the driver lists under ``/proc/driver/nvidia/gpus``; ``[]``
    without a driver."""
    listed = os.environ.get("CUDA_VISIBLE_DEVICES")
    if listed is not None:
        ids: list[str] = []
        for part in (p.strip() for p in listed.split(",")):
            if not part or part.startswith("-"):
                break
            ids.append(part)
        return ids
    try:
        count = sum(1 for entry in _NVIDIA_GPUS.iterdir() if entry.is_dir())
    except OSError:
        return []
    return [str(i) for i in range(count)]


def memory_fraction(share: int) -> float:
    """The part of a GPU's memory each of ``share`` jobs may take: ``0.9 / share``."""
    return MEMORY_SHARE / share


def jax_started() -> bool:
    """Whether JAX has started its backends in this process (they keep the settings
    they started with: XLA's thread pool, the GPUs it sees, its memory limit). Reads
    JAX's private backend table; ``False`` when that is not there."""
    bridge = sys.modules.get("jax._src.xla_bridge")
    return bool(getattr(bridge, "_backends", None))


def gpu_backend_started() -> bool:
    """Whether JAX's backends or torch's CUDA have started in this process (then they
    keep the GPUs and memory limit they started with)."""
    torch = sys.modules.get("torch")
    cuda = getattr(torch, "cuda", None)
    return jax_started() or bool(cuda is not None and cuda.is_initialized())


def _lock_name(gpu: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in gpu)[:80]


def claim_slot(directory: Path, gpus: list[str], share: int) -> tuple[str, Optional[IO[str]]]:
    """Take a free slot (``gpu-<id>.<slot>.lock``, ``slot < share``: named by the GPU's
    id, so sweeps that see different GPUs of one host do not collide) of the GPU among
    ``gpus`` whose slots are least held: ``(its id, the open lock file)``, which holds
    the slot until it is closed. Every slot taken: ``(gpus[pid mod len], None)``."""
    slots = {
        i: [f"gpu-{_lock_name(gpu)}.{slot}.lock" for slot in range(share)]
        for i, gpu in enumerate(gpus)
    }
    index, handle = claim_least_held(directory, slots)
    return (gpus[os.getpid() % len(gpus)], None) if index is None else (gpus[index], handle)


def claim_gpu(gpus: list[str], share: int, lock_dir: Optional[Path] = None) -> str:
    """This process's GPU (an id of ``gpus``) when ``share`` jobs share each; the slot is
    held for the life of the process (a launcher's worker runs its jobs on one GPU).
    Idempotent. Without file locks (not POSIX, an unwritable temporary directory): GPU
    ``pid mod len(gpus)``, with a warning."""
    if "gpu" in _held:
        return str(_held["gpu"])
    try:
        gpu, handle = claim_slot(lock_dir or slots_dir("gpus"), gpus, share)
    except (OSError, ImportError) as err:
        gpu, handle = gpus[os.getpid() % len(gpus)], None
        log.warning("hnnbench: no GPU slot could be claimed (%s); using GPU %s", err, gpu)
    _held.update(gpu=gpu, handle=handle)
    return gpu


def apply_device_share(
    requested: str, share: int, lock_dir: Optional[Path] = None
) -> Optional[str]:
    """Give this job process its part of a GPU when ``share`` jobs share each; call it
    before the job's backend starts. Returns the GPU it was given (its
    ``CUDA_VISIBLE_DEVICES`` id), or ``None`` where nothing applies: ``share == 1``,
    ``device=cpu``, no GPU visible.

    JAX may take at most :func:`memory_fraction` of the GPU, allocated as it goes
    (``XLA_PYTHON_CLIENT_MEM_FRACTION``, ``XLA_PYTHON_CLIENT_PREALLOCATE``; values the
    user set are kept). With ``device=auto`` or ``cuda`` the process takes a slot of
    the least-held GPU and sees only it (``CUDA_VISIBLE_DEVICES``), so the job's
    device is that GPU as ``cuda:0``, or the CPU in a backend without CUDA;
    ``device=cuda:N`` keeps every GPU visible and runs on ``N``. A backend that started
    before any of this keeps what it started with: a warning says so, once.
    """
    kind, _ = device_request(requested)
    if share <= 1 or kind == "cpu":
        return None
    if "gpu" in _held:  # a later job of this worker: set up by its first
        return None if _held["gpu"] is None else str(_held["gpu"])
    gpus = visible_gpus()
    if not gpus:
        return None
    late = gpu_backend_started()
    os.environ.setdefault("XLA_PYTHON_CLIENT_MEM_FRACTION", f"{memory_fraction(share):.4f}")
    os.environ.setdefault("XLA_PYTHON_CLIENT_PREALLOCATE", "false")
    gpu: Optional[str] = None
    if ":" not in requested:
        gpu = claim_gpu(gpus, share, lock_dir)
        os.environ["CUDA_VISIBLE_DEVICES"] = gpu
        log.info("hnnbench: device_share=%d: this process uses GPU %s", share, gpu)
    else:
        _held["gpu"] = None
    if late:
        log.warning(
            "a GPU backend had started in this process before device_share=%d applied: "
            "it keeps the GPUs and memory limit it started with; run jobs from the "
            "hnnbench command for the shared setting",
            share,
        )
    return gpu
