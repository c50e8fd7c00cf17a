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

_SHARE_ENV = (
    "CUDA_VISIBLE_DEVICES",
    "XLA_PYTHON_CLIENT_MEM_FRACTION",
    "XLA_PYTHON_CLIENT_PREALLOCATE",
)


@pytest.fixture
def share_env(monkeypatch):
    """The variables device_share sets, restored after the test (set first, so that
    monkeypatch records them), and a process that holds no GPU slot yet."""
    for var in _SHARE_ENV:
        monkeypatch.setenv(var, "x")
        monkeypatch.delenv(var)
    monkeypatch.setattr(device_share, "_held", {})
    return monkeypatch


@pytest.mark.parametrize(
    ("listed", "ids"),
    [
        ("0", ["0"]),
        ("0,1", ["0", "1"]),
        ("", []),
        ("-1", []),
        ("0,-1,1", ["0"]),
        (" 2 , 3 ", ["2", "3"]),
        ("GPU-ab12", ["GPU-ab12"]),
    ],
)
def test_visible_gpus_reads_cuda_visible_devices_as_cuda_does(share_env, listed, ids):
    share_env.setenv("CUDA_VISIBLE_DEVICES", listed)
    assert device_share.visible_gpus() == ids


def test_visible_gpus_without_the_variable_counts_the_driver_s_gpus(share_env, tmp_path):
    share_env.setattr(device_share, "_NVIDIA_GPUS", tmp_path / "absent")
    assert device_share.visible_gpus() == []
    (tmp_path / "gpus" / "0000:01:00.0").mkdir(parents=True)
    (tmp_path / "gpus" / "0000:02:00.0").mkdir()
    share_env.setattr(device_share, "_NVIDIA_GPUS", tmp_path / "gpus")
    assert device_share.visible_gpus() == ["0", "1"]


def test_slots_fill_the_least_held_gpu_first_and_free_on_close(tmp_path):
    """Real file locks: each claim holds its slot (an open file description) until it is
    closed, as a launcher's worker process would for its life."""
    claims = [device_share.claim_slot(tmp_path, ["2", "3"], share=2) for _ in range(4)]
    assert [gpu for gpu, _ in claims] == ["2", "3", "2", "3"]
    assert all(handle is not None for _, handle in claims)
    gpu, handle = device_share.claim_slot(tmp_path, ["2", "3"], share=2)  # all four held
    assert handle is None and gpu in ("2", "3")
    claims[1][1].close()  # GPU 3 loses a holder: the next claim goes there
    again = device_share.claim_slot(tmp_path, ["2", "3"], share=2)
    assert again[0] == "3"
    # another sweep on the same host that sees other GPUs takes its own slots
    other = device_share.claim_slot(tmp_path, ["0", "1"], share=2)
    assert other[0] == "0" and other[1] is not None
    for _, h in [*claims, again, other]:
        if h is not None:
            h.close()


def test_device_share_leaves_cpus_single_jobs_and_gpu_less_machines_alone(share_env, tmp_path):
    share_env.setenv("CUDA_VISIBLE_DEVICES", "0,1")
    assert device_share.apply_device_share("cpu", 4, tmp_path) is None
    assert device_share.apply_device_share("auto", 1, tmp_path) is None
    assert "XLA_PYTHON_CLIENT_MEM_FRACTION" not in os.environ
    share_env.setenv("CUDA_VISIBLE_DEVICES", "")
    assert device_share.apply_device_share("auto", 4, tmp_path) is None
    assert os.environ["CUDA_VISIBLE_DEVICES"] == ""


def test_device_share_shows_the_job_one_gpu_and_caps_jax_memory(share_env, tmp_path, caplog):
    share_env.setenv("CUDA_VISIBLE_DEVICES", "0,1")
    share_env.setenv("XLA_PYTHON_CLIENT_PREALLOCATE", "true")  # the user's: kept
    share_env.setattr(device_share, "gpu_backend_started", lambda: False)
    other = device_share.claim_slot(tmp_path, ["0", "1"], share=4)  # another worker
    assert other[0] == "0"
    with caplog.at_level("WARNING", logger="hnnbench"):
        assert device_share.apply_device_share("auto", 4, tmp_path) == "1"
        assert os.environ["CUDA_VISIBLE_DEVICES"] == "1"  # device=auto: that GPU, or the CPU
        assert device_share.apply_device_share("cuda", 4, tmp_path) == "1"  # held for life
    assert os.environ["XLA_PYTHON_CLIENT_MEM_FRACTION"] == "0.2250"
    assert os.environ["XLA_PYTHON_CLIENT_PREALLOCATE"] == "true"
    assert not caplog.records  # set before any backend started: no warning
    assert other[1] is not None
    other[1].close()


def test_device_share_with_a_named_gpu_keeps_every_gpu_visible(share_env, tmp_path):
    share_env.setenv("CUDA_VISIBLE_DEVICES", "0,1")
    share_env.setattr(device_share, "gpu_backend_started", lambda: False)
    assert device_share.apply_device_share("cuda:1", 2, tmp_path) is None
    assert os.environ["CUDA_VISIBLE_DEVICES"] == "0,1"
    assert os.environ["XLA_PYTHON_CLIENT_MEM_FRACTION"] == "0.4500"


def test_device_share_after_a_backend_started_says_so_once(share_env, tmp_path, caplog):
    share_env.setenv("CUDA_VISIBLE_DEVICES", "0")
    share_env.setattr(device_share, "gpu_backend_started", lambda: True)
    with caplog.at_level("WARNING", logger="hnnbench"):
        device_share.apply_device_share("auto", 2, tmp_path)
        device_share.apply_device_share("auto", 2, tmp_path)  # the worker's next job
    warnings = [r.getMessage() for r in caplog.records]
    assert len(warnings) == 1 and "had started" in warnings[0]
    assert "\n" not in warnings[0]


def test_a_job_keeps_the_gpu_its_worker_was_given(share_env):
    """isolated() restores the environment after a job, but not what device_share set:
    the worker's backends read it once and keep it."""
    from hnnbench._running.isolation import isolated

    with isolated():
        os.environ["CUDA_VISIBLE_DEVICES"] = "1"
        os.environ["XLA_PYTHON_CLIENT_MEM_FRACTION"] = "0.4500"
        os.environ["HNNBENCH_SOME_PLUGIN_VARIABLE"] = "1"
    assert os.environ["CUDA_VISIBLE_DEVICES"] == "1"
    assert os.environ["XLA_PYTHON_CLIENT_MEM_FRACTION"] == "0.4500"
    assert "HNNBENCH_SOME_PLUGIN_VARIABLE" not in os.environ
