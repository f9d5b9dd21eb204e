"""Two processes that need the same new program compile it once (device/kernels.py MachineLock):
the lock is exclusive across processes, released when its holder ends however it ends, and a
kernel's launches after its first take no lock."""
import subprocess
import sys
import time

import numpy as np

from pyopencl_rt.device.kernels import MachineLock

_HOLD = """
import sys, time
from pyopencl_rt.device.kernels import MachineLock
with MachineLock(sys.argv[1]) as lock:
    assert lock.held
    print("held", flush=True)
    time.sleep(float(sys.argv[2]))
    print(repr(time.time()), flush=True)
"""

_DIE = """
import os, sys
from pyopencl_rt.device.kernels import MachineLock
lock = MachineLock(sys.argv[1]).__enter__()
print("held", flush=True)
os._exit(3)  # no __exit__: the lock must go with the process
"""


def _name():
    return f"test-{time.time_ns()}"


def test_a_second_process_waits_for_the_holder():
    name = _name()
    holder = subprocess.Popen([sys.executable, "-c", _HOLD, name, "1.0"], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    with MachineLock(name) as lock:
        acquired = time.time()
        assert lock.held
    released = float(holder.stdout.readline())
    holder.wait(30)
    assert acquired >= released  # not before the holder let go (after its 1 s)


def test_the_lock_goes_with_a_process_that_dies():
    name = _name()
    dead = subprocess.run([sys.executable, "-c", _DIE, name], capture_output=True, text=True, timeout=60)
    assert dead.returncode == 3 and dead.stdout.strip() == "held"
    started = time.perf_counter()
    with MachineLock(name) as lock:
        assert lock.held
    assert time.perf_counter() - started < 5


def test_only_a_kernels_first_launch_is_locked(runtime):
    import pyopencl as cl

    source = "__kernel void machine_lock_probe(__global int *out) { out[get_global_id(0)] = 7; }"
    kernel = runtime.new_kernels((), ("machine_lock_probe",), extra=source)["machine_lock_probe"]
    out = cl.Buffer(runtime.context, cl.mem_flags.WRITE_ONLY, 16)
    kernel.set_args(out)
    held = []
    for _ in range(2):
        with runtime.first_launch(kernel) as launch:
            held.append(getattr(launch, "held", False))
            event = cl.enqueue_nd_range_kernel(runtime.queue, kernel, (4,), None)
            launch.done(event)
    result = np.zeros(4, np.int32)
    cl.enqueue_copy(runtime.queue, result, out)
    assert held == [True, False] and (result == 7).all()
