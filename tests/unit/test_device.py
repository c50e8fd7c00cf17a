"""The ``device`` setting, read the same way by the job's validation and both backends
(hnnbench._contracts.device), and the JAX backend's GPU compilation setting. These run on a CPU;
the GPU path itself was measured with benchmarks/gpu.py (docs/SCALING.md, "GPUs")."""

from __future__ import annotations

import os

import pytest

from hnnbench._contracts.device import device_request, gpu_device
from hnnbench._contracts.errors import ConfigError
from hnnbench._running import device_share


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


# --------------------------------------------------------------------------- device_share


@pytest.mark.parametrize(
    ("listed", "count"),
    [("0", 1), ("0,1", 2), ("", 0), ("-1", 0), ("0,-1,1", 1), (" 2 , 3 ", 2), ("GPU-ab12", 1)],
)
def test_visible_gpus_reads_cuda_visible_devices_as_cuda_does(monkeypatch, listed, count):
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", listed)
    assert device_share.visible_gpus() == count


def test_visible_gpus_without_a_driver_is_zero(monkeypatch, tmp_path):
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES", raising=False)
    monkeypatch.setattr(device_share, "_NVIDIA_GPUS", tmp_path / "absent")
    assert device_share.visible_gpus() == 0
    (tmp_path / "gpus" / "0000:01:00.0").mkdir(parents=True)
    (tmp_path / "gpus" / "0000:02:00.0").mkdir()
    monkeypatch.setattr(device_share, "_NVIDIA_GPUS", tmp_path / "gpus")
    assert device_share.visible_gpus() == 2


def test_slots_fill_the_least_held_gpu_first_and_free_on_close(tmp_path):
    """Real file locks: each claim holds its slot (an open file description) until it is
    closed, as a launcher's worker process would for its life."""
    claims = [device_share.claim_slot(tmp_path, gpus=2, share=2) for _ in range(4)]
    assert [gpu for gpu, _ in claims] == [0, 1, 0, 1]
    assert all(handle is not None for _, handle in claims)
    gpu, handle = device_share.claim_slot(tmp_path, gpus=2, share=2)  # all four held
    assert handle is None and gpu in (0, 1)
    claims[1][1].close()  # GPU 1 loses a holder: the next claim goes there
    assert device_share.claim_slot(tmp_path, gpus=2, share=2)[0] == 1


def test_share_device_leaves_cpus_and_single_jobs_alone(monkeypatch, tmp_path):
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "0,1")
    for var in ("XLA_PYTHON_CLIENT_MEM_FRACTION", "XLA_PYTHON_CLIENT_PREALLOCATE"):
        monkeypatch.delenv(var, raising=False)
    assert device_share.share_device("cpu", 4, tmp_path) == "cpu"
    assert device_share.share_device("auto", 1, tmp_path) == "auto"
    assert "XLA_PYTHON_CLIENT_MEM_FRACTION" not in os.environ
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "")
    assert device_share.share_device("auto", 4, tmp_path) == "auto"  # no GPU: as asked


def test_share_device_puts_the_job_on_a_slot_and_caps_jax_memory(monkeypatch, tmp_path):
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "0,1")
    monkeypatch.delenv("XLA_PYTHON_CLIENT_MEM_FRACTION", raising=False)
    monkeypatch.setenv("XLA_PYTHON_CLIENT_PREALLOCATE", "true")  # the user's: kept
    monkeypatch.setattr(device_share, "_held", {})
    other = device_share.claim_slot(tmp_path, gpus=2, share=4)  # another worker: GPU 0
    assert other[0] == 0
    assert device_share.share_device("auto", 4, tmp_path) == "cuda:1"
    assert device_share.share_device("cuda", 4, tmp_path) == "cuda:1"  # held for life
    assert device_share.share_device("cuda:0", 4, tmp_path) == "cuda:0"  # named: kept
    assert os.environ["XLA_PYTHON_CLIENT_MEM_FRACTION"] == "0.2250"
    assert os.environ["XLA_PYTHON_CLIENT_PREALLOCATE"] == "true"
