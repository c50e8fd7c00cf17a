"""The data files a job's config generates, by hash, on this CPU or as another CPU's
numerical libraries would make them.

Data generation integrates in float64 with BLAS (OpenBLAS picks a kernel per CPU) and
numpy's vectorised functions (numpy dispatches to the CPU's widest SIMD target); both
set the last bits of the results. One config and seed therefore give byte-different
data files, with other SHA-256, on CPUs of another class (measured: spring's data agree
to about 1e-16 relative). Both choices can be forced in a fresh process
(``OPENBLAS_CORETYPE``, ``NPY_DISABLE_CPU_FEATURES``), so ``hnnbench check --rerun``
tells a record made on another CPU (its hashes come back as that CPU would make them)
from a record made from other data (they come back under none).

Run as ``python -m hnnbench._running.data_hashes CONFIG.json CACHE_DIR``: the child
process a forced dispatch needs (both variables are read when the libraries load).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Optional

from omegaconf import DictConfig, OmegaConf

from hnnbench._contracts import paths
from hnnbench._record.environment import blas_kernel, numpy_simd
from hnnbench._running import dataset_cache
from hnnbench._running.config import prepare_job

__all__ = ["DATA_HASHES", "KNOWN_CPUS", "X86_64", "CpuDispatch", "generate_hashes", "hashes_on"]

#: The record's ``data`` fields that name its data files, by SHA-256 of their bytes.
DATA_HASHES = ("dataset_sha256", "evaluation_sha256")

_HEX64 = re.compile(r"[0-9a-f]{64}")
#: A kernel's or a SIMD target's name (the record schema holds them to lists of these).
_NAME = re.compile(r"[A-Za-z0-9_]{1,32}")
#: The machines whose CPU classes :data:`KNOWN_CPUS` names.
X86_64 = ("x86_64", "AMD64")


@dataclass(frozen=True)
class CpuDispatch:
    """What a CPU's numerical libraries chose: the OpenBLAS kernel (``None``: not
    OpenBLAS) and numpy's SIMD targets beyond its baseline, comma-separated (``""``:
    none; ``None``: not known). A record names its own in ``environment``."""

    blas_kernel: Optional[str]
    numpy_simd: Optional[str]

    @classmethod
    def here(cls) -> CpuDispatch:
        return cls(blas_kernel(), numpy_simd())

    @classmethod
    def of_record(cls, environment: Any) -> Optional[CpuDispatch]:
        """The dispatch a record's ``environment`` names (``null`` fields kept: no
        OpenBLAS, targets not known), ``None`` where it lacks the fields (records made
        before them)."""
        env = environment if isinstance(environment, Mapping) else {}
        if "blas_kernel" not in env or "numpy_simd" not in env:
            return None
        kernel, simd = env["blas_kernel"], env["numpy_simd"]
        return cls(
            kernel if isinstance(kernel, str) else None, simd if isinstance(simd, str) else None
        )

    def describe(self) -> str:
        simd = "targets unknown" if self.numpy_simd is None else self.numpy_simd or "baseline"
        return f"OpenBLAS {self.blas_kernel or 'none'}, numpy {simd}"

    def forcing(self, here: CpuDispatch) -> dict[str, str] | str:
        """The environment variables that make a process on this CPU (``here``) choose
        this dispatch, or one line saying why this CPU cannot: a SIMD target it lacks,
        or no OpenBLAS to force."""
        if not self.blas_kernel or here.blas_kernel is None:
            return f"{self.describe()}: no OpenBLAS kernel to force here"
        if self.numpy_simd is None or here.numpy_simd is None:
            return f"{self.describe()}: numpy's SIMD targets are not known"
        want = [t for t in self.numpy_simd.split(",") if t]
        have = [t for t in here.numpy_simd.split(",") if t]
        missing = [t for t in want if t not in have]
        if missing:
            return f"{self.describe()}: this CPU lacks {', '.join(missing)}"
        if not all(map(_NAME.fullmatch, [*self.blas_kernel.split(","), *want])):
            return f"{self.describe()}: not the names of a kernel and of SIMD targets"
        return {
            "OPENBLAS_CORETYPE": self.blas_kernel.split(",")[0],
            "NPY_DISABLE_CPU_FEATURES": ",".join(t for t in have if t not in want),
        }


#: The dispatches tried, most common first, for a record that names none: x86-64 CPU
#: classes whose float64 results differ in their last bits (numpy 2.4's target names).
KNOWN_CPUS = (
    CpuDispatch("Haswell", "X86_V3"),  # AVX2
    CpuDispatch("SkylakeX", "X86_V3,X86_V4,AVX512_ICL,AVX512_SPR"),  # AVX-512, newest targets
    CpuDispatch("SkylakeX", "X86_V3,X86_V4,AVX512_ICL"),  # AVX-512, Ice Lake's targets
    CpuDispatch("SkylakeX", "X86_V3,X86_V4"),  # AVX-512, Skylake-X's targets
    CpuDispatch("SandyBridge", ""),  # AVX
    CpuDispatch("Nehalem", ""),  # SSE4.2
)


def generate_hashes(cfg: DictConfig, cache_dir: Path) -> dict[str, str]:
    """Generate the dataset and evaluation files of ``cfg`` (its system and ``seed``)
    into ``cache_dir`` (a fresh one: a cached entry would be read back, not made) and
    return their SHA-256 by :data:`DATA_HASHES` field."""
    job = prepare_job(cfg)
    system = job.system_cls(job.system_cfg)
    (_, data_path, _), (_, traj_path, _) = dataset_cache.system_data(
        system, int(cfg.seed), cache_dir
    )
    return {
        "dataset_sha256": paths.sha256_file(data_path),
        "evaluation_sha256": paths.sha256_file(traj_path),
    }


def hashes_on(
    config: Mapping[str, Any], target: CpuDispatch, *, timeout_s: float = 900.0
) -> dict[str, str] | str:
    """:func:`generate_hashes` of ``config`` (a resolved job config) as a CPU of
    ``target``'s dispatch makes them: in a child process that forces it, in a
    temporary cache.

    Returns:
        the hashes by field and, as ``"dispatch"``, what the child ran
        (:meth:`CpuDispatch.describe`); or one line saying why there are none.
    """
    forcing = target.forcing(CpuDispatch.here())
    if isinstance(forcing, str):
        return forcing
    with tempfile.TemporaryDirectory(prefix="hnnbench-dispatch-") as tmp:
        config_file = Path(tmp) / "config.json"
        config_file.write_text(json.dumps(dict(config)), encoding="utf-8")
        # -P and cwd: the child imports the installed hnnbench and its dependencies,
        # never a module of the same name in the directory the check was started from.
        command = [sys.executable, "-P", "-m", __name__, str(config_file), "cache"]
        env = {k: v for k, v in os.environ.items() if k != "NPY_ENABLE_CPU_FEATURES"}
        try:
            child = subprocess.run(
                command,
                cwd=tmp,
                env={**env, **forcing},
                capture_output=True,
                text=True,
                timeout=timeout_s,
            )
        except subprocess.TimeoutExpired:
            return f"{target.describe()}: no data within {timeout_s:g} s"
        except (OSError, ValueError) as err:  # an environment the OS refuses
            return f"{target.describe()}: the child could not start ({err})"
        lines = child.stdout.strip().splitlines()
        if child.returncode != 0 or not lines:
            why = (child.stderr.strip().splitlines() or [f"exit status {child.returncode}"])[-1]
            return f"{target.describe()}: the data could not be made ({why})"
        try:
            answer = json.loads(lines[-1])
        except json.JSONDecodeError:
            return f"{target.describe()}: unreadable answer {lines[-1][:80]!r}"
    hashes = {k: answer.get(k) for k in DATA_HASHES} if isinstance(answer, dict) else {}
    if not hashes or not all(isinstance(v, str) and _HEX64.fullmatch(v) for v in hashes.values()):
        return f"{target.describe()}: the answer holds no SHA-256 of each data file"
    return {**{k: str(v) for k, v in hashes.items()}, "dispatch": str(answer.get("dispatch"))}


def _main(argv: list[str]) -> int:
    config_file, cache_dir = argv
    config = json.loads(Path(config_file).read_text(encoding="utf-8"))
    hashes = generate_hashes(OmegaConf.create(config), Path(cache_dir))
    print(json.dumps({**hashes, "dispatch": CpuDispatch.here().describe()}))
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
