"""Experiment (docs/BENCHMARKS.md, "Packets of rays"): packet traversal (cl/accel/bvh_packet.h) against the
single-ray 8-wide traversal on the Cornell box, for random, shadow, diffuse and camera ray sets; checks the
results are equal bit for bit.  Usage: python tools/packet_rays_experiment.py [8|16]"""
import sys, time, statistics, numpy as np
from pathlib import Path; ROOT = Path(__file__).resolve().parents[1]; sys.path.insert(0, str(ROOT)); sys.path.insert(0, str(ROOT / 'tests'))
import pyopencl as cl
from pyopencl_rt.scene.loaders import load_scene
from pyopencl_rt.accel.bvh import build_bvh
from pyopencl_rt.accel.device_bvh import device_bvh
from pyopencl_rt.trace import _opencl, _rays
from pyopencl_rt.device import devices as reg
from pyopencl_rt.device.kernels import runtime
import harness
W = int(sys.argv[1]) if len(sys.argv) > 1 else 16
SRC = r'''
#include "accel/bvh_packet.h"
__kernel void pk_closest(__global const float8 *bvh, __global const float *o, __global const float *d, int n,
                         __global float *out_t, __global int *out_prim, __global float *out_u, __global float *out_v)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    PacketRay r;
    pfloat t = PFLOAT(INFINITY);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const int i = min(base + k, n - 1);
        packet_set_ray(&r, k, load3(o, i), load3(d, i));
        if (base + k >= n) PLANE(t, k) = -1.0f;
    }
    pint prim = PINT(PRIM_MISS); pfloat u, v;
    packet_closest_hit(bvh, &r, PFLOAT(0.0f), &t, &prim, &u, &v);
    for (int k = 0; k < PACKET_WIDTH && base + k < n; ++k) {
        out_t[base + k] = PLANE(t, k); out_prim[base + k] = PLANE_I(prim, k);
        out_u[base + k] = PLANE(u, k); out_v[base + k] = PLANE(v, k);
    }
}
__kernel void pk_any(__global const float8 *bvh, __global const float *o, __global const float *d, int n,
                     __global int *out_hit)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    PacketRay r;
    pfloat tmax = PFLOAT(INFINITY);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const int i = min(base + k, n - 1);
        packet_set_ray(&r, k, load3(o, i), load3(d, i));
        if (base + k >= n) PLANE(tmax, k) = -1.0f;
    }
    const pint h = packet_any_hit(bvh, &r, PFLOAT(0.0f), tmax);
    for (int k = 0; k < PACKET_WIDTH && base + k < n; ++k) out_hit[base + k] = PLANE_I(h, k);
}
'''
K = harness.Kernels(SRC, defines={"BVH_WIDE8": True, "PACKET_WIDTH": W})
s = load_scene(str(ROOT / 'scenes/mitsuba-cbox.toml'))
bvh = build_bvh(s.vertices, s.faces)
n = 1_000_000
rng = np.random.default_rng(1)
lo, hi = bvh.bounds[0].astype(np.float64), bvh.bounds[1].astype(np.float64)
o = (lo + (hi - lo) * (0.05 + 0.9 * rng.random((n, 3)))).astype(np.float32)
d = rng.normal(size=(n, 3)); d /= np.linalg.norm(d, axis=1, keepdims=True); d = d.astype(np.float32)
O, D, T0, T1 = _rays(o, d, 0.0, np.inf)
dev = reg.resolve(['cpu'])[0]
rt = runtime(dev)
db = device_bvh(bvh, rt, 'wide8')
ref = _opencl(bvh, O, D, T0, T1, dev, any_hit=False, layout='wide8')
refany = _opencl(bvh, O, D, T0, T1, dev, any_hit=True, layout='wide8')

mf = cl.mem_flags; ctx, q = rt.context, rt.queue
bo = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=O); bd = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=D)
outs = [np.zeros(n, np.float32), np.zeros(n, np.int32), np.zeros(n, np.float32), np.zeros(n, np.float32)]
bouts = [cl.Buffer(ctx, mf.READ_WRITE, a.nbytes) for a in outs]
bany = cl.Buffer(ctx, mf.READ_WRITE, 4 * n)
kc = K.kernel(rt, 'pk_closest'); ka = K.kernel(rt, 'pk_any')
groups = (n + W - 1) // W
gs = ((groups + 63) // 64 * 64,)
def run_c():
    kc(q, gs, (64,), db.nodes, bo, bd, np.int32(n), *bouts); q.finish()
def run_a():
    ka(q, gs, (64,), db.nodes, bo, bd, np.int32(n), bany); q.finish()
run_c(); run_a()
for a, b in zip(outs, bouts): cl.enqueue_copy(q, a, b)
hit_any = np.zeros(n, np.int32); cl.enqueue_copy(q, hit_any, bany); q.finish()
prim = np.where(outs[1] >= 0, db_prim := np.asarray(bvh.prim_ids)[np.maximum(outs[1], 0)], -1)
print('t equal', np.mean(outs[0] == ref['t']), 'prim equal', np.mean(prim == ref['prim_id']),
      'u equal', np.mean((outs[2] == ref['u']) | (ref['prim_id'] < 0)), 'any equal', np.mean((hit_any != 0) == refany))
for name, f, g in (('closest', run_c, lambda: _opencl(bvh, O, D, T0, T1, dev, any_hit=False, layout='wide8')),
                   ('any', run_a, lambda: _opencl(bvh, O, D, T0, T1, dev, any_hit=True, layout='wide8'))):
    a, b = [], []
    for _ in range(5):
        t = time.perf_counter(); f(); a.append(time.perf_counter() - t)
        t = time.perf_counter(); g(); b.append(time.perf_counter() - t)
    print(name, 'packet%d %.2f Mrays/s  single %.2f Mrays/s' % (W, n / statistics.median(a) / 1e6, n / statistics.median(b) / 1e6))
# realistic sets: surface points (hits of the volume rays), shadow rays to the light, diffuse bounces
from pyopencl_rt.bench.workloads import diffuse_rays
hit = ref['prim_id'] >= 0
P = (o[hit] + ref['t'][hit, None] * d[hit])
emissive = [i for i, m in enumerate(s.materials) if np.max(getattr(m, 'emission', 0) or 0) > 0]
lf = np.isin(s.face_materials, emissive)
lv = s.vertices[s.faces[lf]].reshape(-1, 3)
llo, lhi = lv.min(0), lv.max(0)
print('light box', llo, lhi)
m = len(P)
L = llo + (lhi - llo) * rng.random((m, 3))
sets = {}
sd = (L - P).astype(np.float32)
sets['shadow'] = (P.astype(np.float32), sd, 0.0001, 0.9999)
bo_, bd_ = diffuse_rays(ref, o, d, rng)
sets['diffuse'] = (bo_.astype(np.float32), bd_.astype(np.float32), 1e-4, np.inf)
# camera rays (pixel order: 16 consecutive rays = 16 pixels of a row)
side = 1000
cam = np.array([0, 0, 3.9], np.float32)
ys, xs = np.mgrid[0:side, 0:side]
dirs = np.stack([(xs + 0.5) / side * 2 - 1, 1 - (ys + 0.5) / side * 2, -np.full(xs.shape, 2.6)], -1).reshape(-1, 3)
dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
sets['camera'] = (np.repeat(cam[None], len(dirs), 0), dirs.astype(np.float32), 0.0, np.inf)
for name, (so, sdir, a, b) in sets.items():
    nn = len(so)
    O2, D2, T02, T12 = _rays(so, sdir, a, b)
    bo2 = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=O2); bd2 = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=D2)
    gs2 = (((nn + W - 1) // W + 63) // 64 * 64,)
    for any_hit in (False, True):
        kk = ka if any_hit else kc
        args = (bany,) if any_hit else tuple(bouts)
        def f():
            kk(q, gs2, (64,), db.nodes, bo2, bd2, np.int32(nn), *args); q.finish()
        g = lambda: _opencl(bvh, O2, D2, T02, T12, dev, any_hit=any_hit, layout='wide8')
        f(); g()
        a_, b_ = [], []
        for _ in range(5):
            t = time.perf_counter(); f(); a_.append(time.perf_counter() - t)
            t = time.perf_counter(); g(); b_.append(time.perf_counter() - t)
        print(name, 'any' if any_hit else 'closest', 'packet%d %.2f  single %.2f Mrays/s' % (W, nn / statistics.median(a_) / 1e6, nn / statistics.median(b_) / 1e6))
