"""Samples/s of Mitsuba 3 on its own Cornell box (mi.cornell_box()), for scale beside ours.

Run with an interpreter that has mitsuba; llvm_ad_rgb needs a system libLLVM (Debian's
libllvm19 works; LLVM 15 fails with "Cannot select: fminimum"):

    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 python tools/mitsuba_cbox.py

The first render includes the JIT compilation; later ones reuse the compiled kernels.
"""
import time

import drjit as dr
import mitsuba as mi

mi.set_variant("llvm_ad_rgb")
scene = mi.load_dict(mi.cornell_box())
res = scene.sensors()[0].film().crop_size()
for spp in (16, 64, 256):
    t0 = time.time()
    img = mi.render(scene, spp=spp)
    dr.eval(img)
    img.numpy()
    dt = time.time() - t0
    print(f"{spp:4d} spp at {res[0]}x{res[1]}: {dt:6.2f} s, {res[0] * res[1] * spp / dt / 1e6:.2f} Msamples/s")
