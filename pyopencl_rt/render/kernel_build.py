"""A Wavefront's kernels built on a thread of their own (issue 35): PoCL's compiler releases the
GIL, so the build, or its load from PoCL's cache, runs while the thread that renders collapses the
BVH into the device's layout and makes the buffers (render/wavefront.py); the host stage
``kernel_wait`` is what of it was not hidden."""
from __future__ import annotations

import time

from ..host_stages import host_stage


class KernelBuild:
    """The build of a Wavefront's kernels on a thread (the lane width's choice, the kernels, the
    defines they were built with); :meth:`join` sets them on the Wavefront, or raises what the
    build raised.  A lane kernel that fails falls back to one path per work-item, with a warning."""

    def __init__(self, wf, device, sources, stages):
        """``sources``, ``stages``: the wavefront program's files and stage names (one path per
        work-item, where the megakernel does not run).  The thread only builds (clBuildProgram,
        clCreateKernel): no command of it goes to a queue."""
        import threading

        from . import megakernel

        self._wf, self._device, self._sources, self._stages = wf, device, sources, stages
        # the width's choice runs the ISA probe, a kernel on the device's queue: here, on the
        # calling thread, so that the build thread never uses the queue the caller fills
        self._lanes = megakernel.lane_choice(wf.kernel_mode, device, dict(wf.features))
        self._result = self._error = None
        self._thread = threading.Thread(target=self._run, name="pyopencl-rt kernel build", daemon=True)
        self._thread.start()

    def _run(self):
        try:
            t0 = time.perf_counter()
            with host_stage("kernel_build"):
                self._result = self._build()
            self._result["build_seconds"] = time.perf_counter() - t0
        except BaseException as exc:  # re-raised by join(), in the thread that renders
            self._error = exc

    def _build(self) -> dict:
        import pyopencl as cl

        from . import megakernel

        wf, device = self._wf, self._device
        features, kernel_mode, rt = dict(wf.features), wf.kernel_mode, wf.rt
        lane_width, lane_reason = self._lanes
        kernels = None
        if lane_width:
            try:
                # the scene's defines last: a benchmark variant (tools/kernel_ab.py) may set LANE_GROUP
                lane_features = {**megakernel.lane_features(lane_width), **features}
                kernels = {"path": rt.new_kernels(megakernel.SOURCES, ("mk_path",), lane_features)["mk_path"]}
                features = lane_features
            except cl.Error as exc:  # a kernel of ours that fails never ends the render
                import warnings

                failure = f"the {lane_width}-lane kernel failed ({str(exc).splitlines()[0]})"
                warnings.warn(f"{failure}: rendering with one path per work-item", stacklevel=2)
                lane_width, lane_reason = 0, f"one path per work-item: {failure}"
        if not lane_width and kernel_mode == "megakernel":
            features = {**megakernel.group_features(device, 0), **features}
            kernels = {"path": rt.new_kernels(megakernel.SOURCES, ("mk_path",), features)["mk_path"]}
        elif not lane_width:
            built = rt.new_kernels(self._sources, [f"wf_{s}" for s in self._stages], features)
            kernels = {s: built[f"wf_{s}"] for s in self._stages}
        return {"lane_width": lane_width, "lane_reason": lane_reason, "kernels": kernels, "features": features}

    def wait(self) -> None:
        """Until the build has ended (whatever its outcome): a render that fails before join()
        does not leave PoCL compiling while the process exits."""
        self._thread.join()

    def join(self) -> None:
        self._thread.join()
        if self._error is not None:
            raise self._error
        wf, r = self._wf, self._result
        wf.lane_width, wf.lane_reason, wf.kernels, wf.features = (r["lane_width"], r["lane_reason"],
                                                                  r["kernels"], r["features"])
        wf.timings["build_seconds"] = r["build_seconds"]
