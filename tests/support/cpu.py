"""The arithmetic settings this CPU can run, as environment variables: what the regeneration and outcome tests
repeat their runs under, so that one machine imitates several CPUs."""
from __future__ import annotations

from pathlib import Path


def _cpu_flags() -> set[str]:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def cpu_settings() -> dict[str, dict[str, str]]:
    """The arithmetic settings this CPU can run: OpenBLAS kernels (``OPENBLAS_CORETYPE``) down to SSE3, and numpy's
    SIMD dispatch narrowed (``NPY_DISABLE_CPU_FEATURES``, named from numpy's own dispatch targets) from AVX-512 to
    AVX2 and to numpy's baseline, the latter with the SSE3 BLAS kernel too."""
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    flags = _cpu_flags()
    settings = {"default": {}, "openblas-prescott": {"OPENBLAS_CORETYPE": "Prescott"}}
    if {"avx2", "fma"} <= flags:
        settings["openblas-haswell"] = {"OPENBLAS_CORETYPE": "Haswell"}
    if "avx512f" in flags:
        settings["openblas-skylakex"] = {"OPENBLAS_CORETYPE": "SkylakeX"}
    wide = [t for t in __cpu_dispatch__ if (t.startswith("AVX512") or t == "X86_V4") and __cpu_features__.get(t)]
    if wide:
        settings["numpy-avx2"] = {"NPY_DISABLE_CPU_FEATURES": " ".join(wide)}
    if [t for t in __cpu_dispatch__ if __cpu_features__.get(t)]:
        settings["numpy-baseline+prescott"] = {"NPY_DISABLE_CPU_FEATURES": " ".join(__cpu_dispatch__),
                                               "OPENBLAS_CORETYPE": "Prescott"}
    return settings
