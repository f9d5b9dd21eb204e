"""The kernels build on a thread of their own while the BVH is collapsed and the buffers are made
(render/kernel_build.py, issue 35): whatever that thread raises reaches the caller as it was, and a
render that fails on the other thread first waits for the build to end (PoCL is never left compiling
under an exception that may end the process)."""
import threading

import pytest

from pyopencl_rt.render import kernel_build, wavefront
from pyopencl_rt.render.wavefront import Wavefront
from tests.scenes_small import small_scene


class BuildFailed(Exception):
    pass


def test_a_build_error_reaches_the_caller(device, monkeypatch):
    def fail(self):
        raise BuildFailed("the build thread's own error")

    monkeypatch.setattr(kernel_build.KernelBuild, "_build", fail)
    with pytest.raises(BuildFailed, match="the build thread's own error"):
        Wavefront(small_scene(width=8, height=8), device)


def test_a_failure_beside_the_build_waits_for_it(device, monkeypatch):
    """The buffers fail while the build is still running (held on an event): the exception comes
    out only once the build thread has ended."""
    release = threading.Event()
    ended = []
    real_build = kernel_build.KernelBuild._build

    def slow_build(self):
        release.wait(10)
        try:
            return real_build(self)
        finally:
            ended.append(True)

    def buffers_fail(*args, **kwargs):
        threading.Timer(0.2, release.set).start()  # the build can end only after the failure
        raise BuildFailed("the buffers' error")

    monkeypatch.setattr(kernel_build.KernelBuild, "_build", slow_build)
    monkeypatch.setattr(wavefront, "environment_buffers", buffers_fail)
    with pytest.raises(BuildFailed, match="the buffers' error"):
        Wavefront(small_scene(width=8, height=8), device)
    assert ended == [True]
    assert not any(t.name == "pyopencl-rt kernel build" for t in threading.enumerate())
