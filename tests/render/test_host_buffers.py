"""A CPU device reads the scene's arrays where they are (device/host_memory.py): no second copy
of a scene of millions of triangles (issue 35).  The kernels' vector loads (a float8 of the wide
BVH is an aligned 32-byte AVX load) fault on a misaligned array, as numpy's large arrays are: so
every such array must start on the page boundary that aligned() gives."""
from pathlib import Path

import numpy as np
import pyopencl as cl
import pytest

import pyopencl_rt as rt
from pyopencl_rt.device.host_memory import ALIGN, aligned, aligned_empty
from pyopencl_rt.render.film import Film
from pyopencl_rt.render.wavefront import Wavefront


@pytest.mark.parametrize("shape, dtype", [((7, 12), np.float32), ((1 << 20,), np.uint8), ((5, 3), np.int32)])
def test_aligned_arrays(shape, dtype):
    a = aligned_empty(shape, dtype)
    assert a.shape == shape and a.dtype == dtype and a.ctypes.data % ALIGN == 0 and a.flags.c_contiguous
    b = np.arange(int(np.prod(shape)), dtype=dtype).reshape(shape)
    c = aligned(b)
    assert c.ctypes.data % ALIGN == 0 and np.array_equal(c, b)
    assert aligned(c) is c  # an aligned array is used as it is


def test_cpu_scene_buffers_are_the_aligned_host_arrays(device):
    """Every scene buffer of a render on a CPU device is a host array (CL_MEM_USE_HOST_PTR) on an
    ALIGN boundary; the render runs (a misaligned wide BVH blob faulted)."""
    if not device.type & cl.device_type.CPU:
        pytest.skip("a GPU gets its own copy of the scene")
    cbox = rt.load_scene(Path(__file__).resolve().parents[2] / "scenes" / "mitsuba-cbox.toml")
    wf = Wavefront(cbox, device, width=16, height=16, seed=3)
    buffers = [v for v in wf.args.values.values() if isinstance(v, cl.Buffer) and v.flags & cl.mem_flags.USE_HOST_PTR]
    assert len(buffers) >= 10  # nodes, tris, materials, lights, ...: every const scene buffer
    hosts = {a.ctypes.data: a for a in wf._host_arrays}
    for buf in buffers:
        address = buf.get_host_array((buf.size,), np.uint8).ctypes.data  # CL_MEM_HOST_PTR
        assert address % ALIGN == 0 and address in hosts
    film = Film(16, 16)
    wf.run(film, passes=2)
    assert np.isfinite(film.sum).all() and film.sum.sum() > 0


_HEAP_KEPT = """
import ctypes, ctypes.util, sys
from pyopencl_rt.device.host_memory import return_freed_memory

class MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in
                ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks",
                 "keepcost")]

libc = ctypes.CDLL(ctypes.util.find_library("c"))
libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, (ctypes.c_size_t,)
libc.free.argtypes = (ctypes.c_void_p,)
libc.mallinfo2.restype = MallInfo2
if sys.argv[1] == "1":
    assert return_freed_memory()
libc.free(libc.malloc(24 << 20))  # its own mapping either way; glibc's default then maps from 24 MB up
mapped = libc.mallinfo2().hblkhd
block = libc.malloc(16 << 20)
print("mapped" if libc.mallinfo2().hblkhd - mapped >= 16 << 20 else "heap")  # a mapping goes back when freed
libc.free(block)
"""


def test_the_cli_returns_freed_arrays_to_the_system():
    """return_freed_memory() (which the CLI calls): a 16 MB block allocated after a 24 MB one was
    freed is a mapping of its own (returned to the system when freed); glibc's default serves it
    from the heap, which it keeps (issue 35: 60-80 MB at 2M triangles)."""
    import subprocess
    import sys

    if not sys.platform.startswith("linux"):
        pytest.skip("glibc's mallopt")

    def where(call):
        return subprocess.run([sys.executable, "-c", _HEAP_KEPT, call], capture_output=True, text=True,
                              check=True).stdout.strip()

    if where("0") != "heap":  # seen once in the parallel suite, never reproduced alone
        pytest.skip("this process's malloc maps the block without the call: nothing for it to change")
    assert where("1") == "mapped"
