"""Each host stage's memory of one `pyopencl-rt` command: resident MB at the stage's start and end,
and its peak (the kernel's high-water mark, reset at the stage's start through
/proc/self/clear_refs; Linux only), as docs/BENCHMARKS.md's issue 35 tables give them.

    python tools/stage_memory.py render /tmp/bench-scale/heightfield_8000000.xml -o /tmp/out.exr -q

The command's own process peak is the largest stage peak (the reset makes `/usr/bin/time`'s figure
for this process meaningless: use `bench scale` for that)."""
import sys
import time
from contextlib import contextmanager

import pyopencl_rt.host_stages as stages


def _resident_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def _peak_mb():
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) / 1024 for line in f if line.startswith("VmHWM"))


_stage = stages.host_stage


@contextmanager
def _traced(name):
    start = _resident_mb()
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # the high-water mark from here
    t0 = time.perf_counter()
    with _stage(name):
        yield
    print(f"{name:14s} start {start:7.0f}  end {_resident_mb():7.0f}  peak {_peak_mb():7.0f} MB"
          f"  {time.perf_counter() - t0:6.2f} s", file=sys.stderr, flush=True)


stages.host_stage = _traced  # before the modules that import it are loaded

from pyopencl_rt import cli  # noqa: E402

if __name__ == "__main__":
    cli.main(sys.argv[1:])
