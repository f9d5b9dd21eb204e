"""Samples/s of the Cornell box (256x256, 8 spp, median of 3, interleaved) with the extend and
shadow stages on our OpenCL traversal against embreex on the host (render --intersector embree).

    python tools/bench_intersector.py
"""
import statistics
from pyopencl_rt import load_scene
from pyopencl_rt.device.devices import select_device
from pyopencl_rt.render.api import render_full
from pyopencl_rt.render.wavefront import Wavefront
from pyopencl_rt.render.embree_wavefront import EmbreeWavefront
s = load_scene("scenes/cornell-box.toml"); dev = select_device("cpu")
wfs = {"opencl (wide BVH)": Wavefront(s, dev, width=256, height=256), "embree": EmbreeWavefront(s, dev, width=256, height=256)}
for wf in wfs.values(): render_full(s, spp=1, wavefront=wf)
rates = {k: [] for k in wfs}
for _ in range(3):
    for k, wf in wfs.items():
        rates[k].append(render_full(s, spp=8, wavefront=wf).info["samples_per_second"])
for k, v in rates.items(): print(f"{k}: {statistics.median(v)/1e6:.3f} Msamples/s {[round(x/1e6,3) for x in v]}")
