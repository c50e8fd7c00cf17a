"""The dataset cache under a real race: two processes build and store the same entry
into one cache root at the same moment (as two launcher workers, or two cluster jobs on
a shared filesystem, do). Both must get valid, identical data, and the stored file must
load afterwards. A third process keeps loading whatever entry files it sees during the
race: with writes through a temporary file and ``os.replace`` it never sees a torn one.
No mocks: the race is forced with barriers, not simulated."""

from __future__ import annotations

import dataclasses
import hashlib
import multiprocessing as mp
import os
import queue
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hnnbench._contracts.plugin import Dataset, Trajectories
from hnnbench._running import dataset_cache

#: The entries raced for, one race each: (kind, seed).
RACES = (("dataset", 0), ("evaluation", 0), ("dataset", 1))
TIMEOUT_S = 120.0


def _spring() -> Any:
    """The spring system with its paper data settings (imported directly: loading every
    plugin would import torch and JAX in each worker for nothing)."""
    from hnnbench_plugins.systems.spring import Spring

    return Spring(Spring.Config(name="spring"))


def _digest(value: Any) -> str:
    """SHA-256 over every array, number and string of a (nested) dataclass value."""
    h = hashlib.sha256()

    def feed(obj: Any) -> None:
        if isinstance(obj, np.ndarray):
            h.update(f"{obj.dtype.str}{obj.shape}".encode())
            h.update(np.ascontiguousarray(obj).tobytes())
        elif dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            for f in dataclasses.fields(obj):
                h.update(f.name.encode())
                feed(getattr(obj, f.name))
        elif isinstance(obj, dict):
            for key in sorted(obj, key=str):
                h.update(repr(key).encode())
                feed(obj[key])
        elif isinstance(obj, (list, tuple)):
            for item in obj:
                feed(item)
        else:
            h.update(repr(obj).encode())

    feed(value)
    return h.hexdigest()


def _race_worker(root: str, start: Any, building: Any, results: Any) -> None:
    """Race the other worker for every entry of :data:`RACES`; report each outcome.

    ``start`` lines both workers up before they look the entry up; ``building`` is
    passed only once both have found it missing and are inside ``build()``, so both
    build it and both store it, whatever the scheduler does."""
    try:
        system = _spring()
        for kind, seed in RACES:
            loader = Dataset.load if kind == "dataset" else Trajectories.load

            def build(kind: str = kind, seed: int = seed) -> Any:
                building.wait(timeout=TIMEOUT_S)
                return system.dataset(seed) if kind == "dataset" else system.evaluation(seed)

            start.wait(timeout=TIMEOUT_S)
            value, path, hit = dataset_cache.cached(system, seed, kind, build, loader, Path(root))
            results.put((os.getpid(), kind, seed, hit, str(path), _digest(value)))
    except BaseException:  # noqa: BLE001 - reported to the parent, which fails the test
        results.put((os.getpid(), "error", traceback.format_exc()))
        raise


def _reader(root: str, stop: Any, results: Any) -> None:
    """Load every entry file visible under ``root`` again and again until ``stop``;
    report how many loads succeeded and every failure (a torn or partial file)."""
    loaded, failures = 0, []
    directory = Path(root) / "datasets" / "spring"
    while not stop.is_set():
        for path in sorted(directory.glob("*.npz")) if directory.is_dir() else []:
            if path.name.startswith("."):  # a writer's temporary file, never read
                continue
            loader = Dataset.load if "-dataset-" in path.name else Trajectories.load
            try:
                loader(path)
                loaded += 1
            except FileNotFoundError:  # replaced between glob and open: not torn
                continue
            except Exception as err:  # noqa: BLE001
                failures.append(f"{path.name}: {type(err).__name__}: {err}")
        time.sleep(0.001)
    results.put((loaded, failures))


@pytest.mark.slow
def test_two_processes_store_the_same_entry_at_once(tmp_path: Path) -> None:
    root = tmp_path / "cache"
    ctx = mp.get_context("spawn")
    start, building = ctx.Barrier(2), ctx.Barrier(2)
    results, reads, stop = ctx.Queue(), ctx.Queue(), ctx.Event()
    workers = [
        ctx.Process(target=_race_worker, args=(str(root), start, building, results))
        for _ in range(2)
    ]
    reader = ctx.Process(target=_reader, args=(str(root), stop, reads))
    for proc in [reader, *workers]:
        proc.start()
    outcomes = []
    try:
        for _ in range(2 * len(RACES)):
            item = results.get(timeout=TIMEOUT_S)
            assert item[1] != "error", item[2]
            outcomes.append(item)
    except queue.Empty:
        pytest.fail("a worker hung: " + repr(outcomes))
    finally:
        for proc in workers:
            proc.join(timeout=TIMEOUT_S)
        stop.set()
        loaded, failures = reads.get(timeout=TIMEOUT_S)
        for proc in [*workers, reader]:
            proc.join(timeout=TIMEOUT_S)
            if proc.is_alive():
                proc.kill()
    assert [proc.exitcode for proc in [*workers, reader]] == [0, 0, 0]
    assert not failures, failures  # never a torn entry, even mid-race
    assert loaded >= len(RACES)

    for kind, seed in RACES:
        both = [o for o in outcomes if (o[1], o[2]) == (kind, seed)]
        assert len(both) == 2 and both[0][0] != both[1][0], both
        # Both missed the cache and built the entry themselves: a real race.
        assert [o[3] for o in both] == [False, False], both
        (path,) = {o[4] for o in both}
        (digest,) = {o[5] for o in both}  # identical data in both processes
        # The stored file is complete and holds that same data.
        loader = Dataset.load if kind == "dataset" else Trajectories.load
        assert _digest(loader(Path(path))) == digest
        # A later lookup is a hit and returns it too.
        system = _spring()
        value, again, hit = dataset_cache.cached(
            system, seed, kind, lambda: pytest.fail("rebuilt"), loader, root
        )
        assert hit and str(again) == path and _digest(value) == digest

    directory = root / "datasets" / "spring"
    names = sorted(p.name for p in directory.iterdir() if p.suffix != ".sha256")
    hashes = sorted(p.name for p in directory.iterdir() if p.suffix == ".sha256")
    assert hashes == [f"{n}.sha256" for n in names], hashes  # each its recorded hash
    assert len(names) == len(RACES), names  # one file per entry ...
    assert not [n for n in names if n.startswith(".") or ".tmp" in n], names  # no leftovers
