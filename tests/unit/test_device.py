"""The ``device`` setting, read the same way by the job's validation and both backends
(hnnbench._contracts.device), and the JAX backend's GPU compilation setting. These run on a CPU;
the GPU path itself was measured with benchmarks/gpu.py (docs/SCALING.md, "GPUs")."""

from __future__ import annotations

import os

import pytest

from hnnbench._contracts.device import device_request, gpu_device
from hnnbench._contracts.errors import ConfigError


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("auto", ("auto", 0)),
        ("cpu", ("cpu", 0)),
        ("cuda", ("cuda", 0)),
        ("cuda:1", ("cuda", 1)),
        ("cuda:12", ("cuda", 12)),
    ],
)
def test_device_request_accepts_the_documented_spellings(text, expected):
    assert device_request(text) == expected


@pytest.mark.parametrize(
    "text", ["tpu", "gpu", "CUDA", " cpu", "cuda:x", "cuda:-1", "cuda:", "cuda:²", "cpu:0", ""]
)
def test_device_request_rejects_anything_else_in_one_line(text):
    """As the job's validation does (hnnbench._running.config.validate_run calls it)."""
    with pytest.raises(ConfigError, match="expected auto, cpu, cuda or cuda:N") as err:
        device_request(text)
    assert "\n" not in str(err.value)


def test_gpu_device_says_how_many_gpus_the_backend_sees():
    gpu_device("cuda:1", 1, 2, "torch", "X")  # there: no error
    with pytest.raises(ConfigError, match="torch sees no CUDA GPU.*install a CUDA build"):
        gpu_device("cuda", 0, 0, "torch", "TORCH_SPEC=torch make setup")
    with pytest.raises(ConfigError, match=r"sees only 1 GPU\(s\): use device=cuda:0..0"):
        gpu_device("cuda:3", 3, 1, "jax", "X")


def test_torch_names_a_gpu_with_its_index_as_jax_does(monkeypatch):
    """A record's ``device`` is ``cuda:0`` in both backends (the H100 run found torch's
    records saying ``cuda`` and JAX's ``cuda:0``)."""
    torch = pytest.importorskip("torch")
    from hnnbench.neural.torch import resolve_device

    assert str(resolve_device("cpu")) == "cpu"
    with pytest.raises(ConfigError, match="expected auto, cpu, cuda"):
        resolve_device("tpu")  # was torch's own RuntimeError, a traceback
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert str(resolve_device("auto")) == "cpu"
    with pytest.raises(ConfigError, match="torch sees no CUDA GPU"):
        resolve_device("cuda")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 2)
    assert [str(resolve_device(d)) for d in ("auto", "cuda", "cuda:1")] == [
        "cuda:0",
        "cuda:0",
        "cuda:1",
    ]
    with pytest.raises(ConfigError, match="sees only 2 GPU"):
        resolve_device("cuda:2")


def test_jax_gpu_autotuning_is_off_unless_the_user_sets_its_level(monkeypatch):
    """Importing the JAX backend adds the flag; a level the user set is kept."""
    backend = pytest.importorskip("hnnbench.neural.jax")
    assert "--xla_gpu_autotune_level=" in os.environ.get("XLA_FLAGS", "")  # at import
    for before, after in [
        (None, "--xla_gpu_autotune_level=0"),
        (
            "--xla_cpu_use_thunk_runtime=true",
            "--xla_cpu_use_thunk_runtime=true --xla_gpu_autotune_level=0",
        ),
        ("--xla_gpu_autotune_level=4", "--xla_gpu_autotune_level=4"),
    ]:
        if before is None:
            monkeypatch.delenv("XLA_FLAGS", raising=False)
        else:
            monkeypatch.setenv("XLA_FLAGS", before)
        backend._gpu_autotuning_off()
        assert os.environ["XLA_FLAGS"] == after
