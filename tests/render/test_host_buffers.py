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
import sys
import numpy as np
from pyopencl_rt.device.host_memory import return_freed_memory

def rss_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20

if sys.argv[1] == "1":
    assert return_freed_memory()
a = np.ones(24 << 20, np.uint8)  # a mapping of its own either way; freeing it raises glibc's threshold
del a                            # (up to its 32 MB bound) to 24 MB
before = rss_mb()
b = np.ones(16 << 20, np.uint8)  # without the call: from the heap, which keeps it once freed
del b
print(rss_mb() - before)
"""


def test_the_cli_returns_freed_arrays_to_the_system():
    """return_freed_memory() (which the CLI calls): a large array freed after a larger one leaves
    the process; glibc's default keeps it in the heap (issue 35: 60-80 MB at 2M triangles)."""
    import subprocess
    import sys

    if not sys.platform.startswith("linux"):
        pytest.skip("glibc's mallopt")

    def kept(call):
        out = subprocess.run([sys.executable, "-c", _HEAP_KEPT, call], capture_output=True, text=True, check=True)
        return float(out.stdout)

    assert kept("1") < 4
    assert kept("0") > 12  # the default's behaviour, which the call changes (a test that can fail)
