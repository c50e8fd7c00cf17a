"""A CPU's dispatch (OpenBLAS kernel, numpy SIMD targets): what a record names, and the
environment variables that make this CPU choose another one (``check --rerun``)."""

from __future__ import annotations

from hnnbench._running.data_hashes import KNOWN_CPUS, CpuDispatch

HERE = CpuDispatch("SkylakeX", "X86_V3,X86_V4,AVX512_ICL,AVX512_SPR")


def test_forcing_turns_off_the_targets_the_other_cpu_lacks_and_names_its_kernel():
    assert CpuDispatch("Haswell", "X86_V3").forcing(HERE) == {
        "OPENBLAS_CORETYPE": "Haswell",
        "NPY_DISABLE_CPU_FEATURES": "X86_V4,AVX512_ICL,AVX512_SPR",
    }
    assert CpuDispatch("Nehalem", "").forcing(HERE) == {
        "OPENBLAS_CORETYPE": "Nehalem",
        "NPY_DISABLE_CPU_FEATURES": "X86_V3,X86_V4,AVX512_ICL,AVX512_SPR",
    }
    assert HERE.forcing(HERE) == {"OPENBLAS_CORETYPE": "SkylakeX", "NPY_DISABLE_CPU_FEATURES": ""}


def test_a_dispatch_this_cpu_cannot_run_is_one_line_saying_why():
    older = CpuDispatch("Haswell", "X86_V3")
    assert HERE.forcing(older) == (
        "OpenBLAS SkylakeX, numpy X86_V3,X86_V4,AVX512_ICL,AVX512_SPR: this CPU lacks "
        "X86_V4, AVX512_ICL, AVX512_SPR"
    )
    assert "no OpenBLAS kernel to force" in older.forcing(CpuDispatch(None, "X86_V3"))
    assert "not known" in older.forcing(CpuDispatch("Haswell", None))


def test_a_record_names_its_dispatch_or_none():
    assert CpuDispatch.of_record({"blas_kernel": "Haswell", "numpy_simd": ""}) == CpuDispatch(
        "Haswell", ""
    )
    for env in ({}, {"blas_kernel": "Haswell"}, None):  # made before the fields
        assert CpuDispatch.of_record(env) is None
    # named, as null: no OpenBLAS there, its targets unknown; nothing to force
    none = CpuDispatch.of_record({"blas_kernel": None, "numpy_simd": None})
    assert none == CpuDispatch(None, None)
    assert none.describe() == "OpenBLAS none, numpy targets unknown"
    assert "no OpenBLAS kernel to force" in none.forcing(HERE)
    assert CpuDispatch("Haswell", "").describe() == "OpenBLAS Haswell, numpy baseline"


def test_names_that_are_not_a_kernel_and_targets_are_never_forced():
    for odd in (CpuDispatch("Has well", "X86_V3"), CpuDispatch("Haswell", "X86_V3,=1")):
        assert "not the names" in odd.forcing(CpuDispatch("Haswell", "X86_V3,X86_V4,=1"))
    assert len(set(KNOWN_CPUS)) == len(KNOWN_CPUS)
