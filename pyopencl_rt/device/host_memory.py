"""Host arrays that a CPU device reads where they are.

On a CPU device (PoCL, Intel's CPU runtime) a buffer made with CL_MEM_USE_HOST_PTR is the host
array itself: no second copy of a scene of millions of triangles and no time spent copying it
(issue 35).  The kernels' vector loads assume their type's alignment (a float8 is 32 bytes, and
LLVM emits aligned AVX loads for it), which PoCL's own allocations give and numpy's do not (a large
numpy array starts 16 bytes into a page), so such an array must start on an aligned address:
:data:`ALIGN` is a page, which also lets Intel's runtime use it without a copy.
"""
from __future__ import annotations

import ctypes
import ctypes.util

import numpy as np

ALIGN = 4096

__all__ = ["ALIGN", "aligned_empty", "aligned", "return_freed_memory"]

# glibc's mallopt parameter and the size from which every allocation is its own mapping
_M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 1 << 20


def aligned_empty(shape, dtype, zeros: bool = False) -> np.ndarray:
    """np.empty(shape, dtype) starting on an :data:`ALIGN`-byte boundary (``zeros``: np.zeros'
    calloc, whose pages nothing has written stay out of memory)."""
    dtype = np.dtype(dtype)
    nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    raw = (np.zeros if zeros else np.empty)(nbytes + ALIGN, np.uint8)
    start = -raw.ctypes.data % ALIGN
    return raw[start:start + nbytes].view(dtype).reshape(shape)


def aligned(a) -> np.ndarray:
    """``a`` C-contiguous on an :data:`ALIGN`-byte boundary: itself where it is, else a copy."""
    a = np.ascontiguousarray(a)
    if a.ctypes.data % ALIGN == 0:
        return a
    out = aligned_empty(a.shape, a.dtype)
    out[...] = a
    return out


def return_freed_memory() -> bool:
    """Make every allocation of :data:`MMAP_THRESHOLD` bytes or more its own mapping, returned to
    the system when freed (glibc's ``mallopt(M_MMAP_THRESHOLD)``); False where the C library has no
    such call.  glibc raises that threshold to the size of each mapped block freed, so that a
    process which frees a large array serves the next ones of that size from its heap, which it
    keeps: after a big mesh's passes (numba's own arrays among them) that heap held 60-80 MB at 2M
    triangles (issue 35).  The CLI sets it for its process; a program using the API decides for its
    own."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD))
