"""Where Intel MKL lives, and the few MKL entry points facecap calls directly.

pypardiso (the sparse factorisation) already installs MKL's single dynamic
library, ``libmkl_rt``, from PyPI. Two more of its routines pay for
themselves in the thin-shell hot path: ``cblas_sgemm`` (float32 GEMM, about
1.3x OpenBLAS here) and ``cblas_gemm_s16s16s32`` (int16 GEMM with int32
accumulation, which runs on the AVX-512 VNNI units at about 1.8x the float32
rate). numpy and scipy do not expose MKL, so they are called through ctypes.
Everything here returns ``None`` where MKL is absent (non-x86 machines) and
callers fall back to numpy.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
import site
import sys

__all__ = ["locate_mkl_runtime", "mkl_blas"]

CBLAS_ROW_MAJOR = 101
CBLAS_NO_TRANS = 111
CBLAS_FIX_OFFSET = 173


def locate_mkl_runtime() -> str | None:
    """Path of ``libmkl_rt`` as the ``mkl`` wheel installs it, also told to pypardiso.

    pypardiso looks for the library by a recursive glob of the Python prefix
    when it is imported and on every solver construction (1-3 s each,
    measured here) unless ``PYPARDISO_MKL_RT`` names it; the wheel puts it in
    ``<prefix>/lib``, so look there first and set the variable.
    """
    if "PYPARDISO_MKL_RT" in os.environ:
        return os.environ["PYPARDISO_MKL_RT"]
    for folder in (sys.prefix, site.USER_BASE or ""):
        found = sorted(glob.glob(os.path.join(folder, "lib", "libmkl_rt.*")), key=len)
        if found:
            os.environ["PYPARDISO_MKL_RT"] = found[0]
            return found[0]
    return None


class MklBlas:
    """ctypes bindings of the MKL routines the basis product uses (LP64 interface)."""

    def __init__(self, library: ctypes.CDLL) -> None:
        i, p, f = ctypes.c_int, ctypes.c_void_p, ctypes.c_float
        self.sgemm = library.cblas_sgemm
        self.sgemm.restype = None
        self.sgemm.argtypes = [i, i, i, i, i, i, f, p, i, p, i, f, p, i]
        self.gemm_s16s16s32 = library.cblas_gemm_s16s16s32
        self.gemm_s16s16s32.restype = None
        self.gemm_s16s16s32.argtypes = [i, i, i, i, i, i, i, f, p, i, ctypes.c_short, p, i, ctypes.c_short, f, p, i, p]
        self.set_num_threads_local = library.MKL_Set_Num_Threads_Local
        self.set_num_threads_local.restype = i
        self.set_num_threads_local.argtypes = [i]


@functools.lru_cache(maxsize=1)
def mkl_blas() -> MklBlas | None:
    """The MKL bindings, or ``None`` where MKL cannot be loaded."""
    path = locate_mkl_runtime()
    # The bindings are LP64 (32-bit MKL_INT); this variable switches libmkl_rt to 64-bit.
    if path is None or "ILP64" in os.environ.get("MKL_INTERFACE_LAYER", "").upper():
        return None
    try:
        return MklBlas(ctypes.CDLL(path))
    except (OSError, AttributeError):
        return None
