"""Benchmarks: OpenCL traversal against embreex on identical rays, and BVH build time.

Timing rules (the machine is shared and noisy): every figure is the median of ``repeat`` runs,
and the OpenCL and Embree timings of one ray set are taken alternately in the same loop, so a
burst of background load hits both.
"""
from __future__ import annotations

import json
import platform
import statistics
import time

import numpy as np


def parse_sizes(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        part = part.strip().lower()
        if not part:
            continue
        mult = 1
        if part.endswith("k"):
            mult, part = 1_000, part[:-1]
        elif part.endswith("m"):
            mult, part = 1_000_000, part[:-1]
        out.append(int(float(part) * mult))
    return out


def bench_mesh(n_triangles: int):
    """A torus with about ``n_triangles`` triangles (2 * major * minor), slightly bumpy so that
    triangles are not all alike; deterministic."""
    import trimesh

    minor = max(3, int(round(np.sqrt(n_triangles / 8.0))))
    major = max(3, int(round(n_triangles / (2 * minor))))
    mesh = trimesh.creation.torus(major_radius=1.0, minor_radius=0.35, major_sections=major, minor_sections=minor)
    v = np.asarray(mesh.vertices, np.float64)
    ang = np.arctan2(v[:, 1], v[:, 0])
    v *= (1.0 + 0.03 * np.sin(7 * ang))[:, None]
    return v.astype(np.float32), np.asarray(mesh.faces, np.int32)


def primary_rays(bounds, n: int):
    """Pinhole camera rays (coherent: neighbouring rays are neighbouring pixels) framing ``bounds``."""
    side = int(np.sqrt(n))
    center = bounds.mean(axis=0)
    radius = float(np.linalg.norm(bounds[1] - bounds[0])) / 2
    eye = center + np.array([0.3, -0.8, 0.6]) * (2.2 * radius / np.linalg.norm([0.3, -0.8, 0.6]))
    forward = center - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    s = (np.arange(side) + 0.5) / side * 2 - 1
    x, y = np.meshgrid(s * 0.5, -s * 0.5)
    d = forward + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(eye, d.shape)
    return np.ascontiguousarray(o, np.float32), np.ascontiguousarray(d, np.float32)


def diffuse_rays(hits, o, d, rng):
    """Incoherent rays: from each primary hit point, a cosine-distributed direction about the
    normal facing the incoming ray."""
    hit = hits["prim_id"] >= 0
    p = o[hit] + hits["t"][hit, None] * d[hit]
    n = hits["normal"][hit]
    n = np.where((np.sum(n * d[hit], axis=1) > 0)[:, None], -n, n)
    u1, u2 = rng.random(len(p)), rng.random(len(p))
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)], axis=1)
    a = np.where(np.abs(n[:, :1]) > 0.9, [[0, 1.0, 0]], [[1.0, 0, 0]])
    t1 = np.cross(n, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    dirs = local[:, :1] * t1 + local[:, 1:2] * t2 + local[:, 2:3] * n
    scale = np.abs(p).max(axis=1, keepdims=True) + 1.0
    origins = p + n * (scale * 1e-4)
    return np.ascontiguousarray(origins, np.float32), np.ascontiguousarray(dirs, np.float32)


def _median_time(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def run_ray_bench(devices=None, sizes=(10_000, 100_000, 1_000_000), n_rays=1_000_000, repeat=3,
                  embree=True, json_path=None, echo=print, layouts=None) -> dict:
    """``layouts``: BVH layouts to time on each device (e.g. ``("binary", "wide")``; their rows are
    labelled "<layout>: <device>"); None times each device's default layout under its plain label."""
    from ..device import devices as dv
    from ..accel.bvh import build_bvh
    from ..accel.device_bvh import bvh_layout
    from ..accel.embree import embree_scene
    from ..trace import trace

    chosen = dv.resolve(devices)
    # (row label, device, layout) of every OpenCL configuration timed
    configs = [(dv.device_label(dev), dev, bvh_layout(dev)) for dev in chosen] if not layouts else \
        [(f"{lay}: {dv.device_label(dev)}", dev, bvh_layout(dev, lay)) for dev in chosen for lay in layouts]
    rng = np.random.default_rng(7)
    results = {
        "machine": {"platform": platform.platform(), "processor": platform.processor(), "python": platform.python_version()},
        "devices": [dv.device_label(d) for d in chosen],
        "repeat": repeat,
        "meshes": [],
    }
    header = f"{'mesh':>10} {'rays':>10} {'set':>8} {'backend':<40} {'Mrays/s':>9} {'vs embree':>9}"
    echo(header)
    for size in sizes:
        v, f = bench_mesh(size)
        build_times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            bvh = build_bvh(v, f)
            build_times.append(time.perf_counter() - t0)
        entry = {"triangles": int(len(f)), "bvh_build_seconds": statistics.median(build_times),
                 "bvh_stats": {k: val for k, val in bvh.stats.items() if k != "leaf_size_histogram"}, "sets": []}
        if embree:
            t0 = time.perf_counter()
            embree_scene(bvh)
            entry["embree_build_seconds"] = time.perf_counter() - t0
        echo(f"{len(f):>10} triangles: BVH build {entry['bvh_build_seconds']:.3f} s (median of {repeat}), "
             f"SAH cost {bvh.stats['sah_cost']:.2f}"
             + (f"; embree build {entry['embree_build_seconds']:.3f} s" if embree else ""))
        o, d = primary_rays(bvh.bounds.astype(np.float64), n_rays)
        ref = trace(bvh, o, d, backend="embree")
        o2, d2 = diffuse_rays(ref, o, d, rng)
        for set_name, (ro, rd) in (("primary", (o, d)), ("diffuse", (o2, d2))):
            n = len(ro)
            row = {"set": set_name, "rays": n, "backends": {}}
            for _name, dev, lay in configs:  # warm-up: kernel build, BVH collapse and upload are not timed
                trace(bvh, ro[:1024], rd[:1024], device=dev, layout=lay)
            timings = {name: [] for name, _dev, _lay in configs}
            if embree:
                timings["embree"] = []
            for _ in range(repeat):
                for name, dev, lay in configs:
                    t0 = time.perf_counter()
                    trace(bvh, ro, rd, device=dev, layout=lay)
                    timings[name].append(time.perf_counter() - t0)
                if embree:  # embreex's own call alone, so Embree is not charged for our wrapper
                    scene = embree_scene(bvh)
                    t0 = time.perf_counter()
                    scene.run(ro, rd, output=1)
                    timings["embree"].append(time.perf_counter() - t0)
            emb = statistics.median(timings["embree"]) if embree else None
            for name, ts in timings.items():
                med = statistics.median(ts)
                rate = n / med
                row["backends"][name] = {"seconds_median": med, "rays_per_second": rate,
                                         "ratio_to_embree": (emb / med) if emb else None}
                lay = next((c[2] for c in configs if c[0] == name), None)
                if lay:
                    row["backends"][name]["layout"] = lay
                ratio = f"{emb / med:9.2f}" if emb else f"{'-':>9}"
                echo(f"{len(f):>10} {n:>10} {set_name:>8} {name[:40]:<40} {rate / 1e6:9.3f} {ratio}")
            entry["sets"].append(row)
        results["meshes"].append(entry)
    if json_path:
        with open(json_path, "w") as fh:
            json.dump(results, fh, indent=2)
        echo(f"wrote {json_path}")
    return results


def run_render_bench(scene_path, devices=None, width=512, height=512, spp=16, max_depth=8, repeat=3,
                     wave_size=None, json_path=None, echo=print) -> dict:
    """Samples/s of the path tracer on each device: one warm-up render (kernel build, BVH upload,
    not timed), then ``repeat`` timed renders of ``spp`` passes; the median is reported, and the
    devices are interleaved within each repetition so background load hits them alike."""
    from ..device import devices as dv
    from ..render.api import render_full
    from ..scene.scenefile import load_scene
    from ..render.wavefront import Wavefront

    scene = load_scene(scene_path)
    chosen = dv.resolve(devices)
    wfs = {}
    results = {"scene": str(scene_path), "width": width, "height": height, "spp": spp, "max_depth": max_depth,
               "repeat": repeat, "machine": {"platform": platform.platform(), "python": platform.python_version()},
               "devices": {}}
    for dev in chosen:
        t0 = time.perf_counter()
        wf = Wavefront(scene, dev, width=width, height=height, max_depth=max_depth, wave_size=wave_size)
        setup = time.perf_counter() - t0
        render_full(scene, spp=1, wavefront=wf)  # warm-up
        wfs[dv.device_label(dev)] = (wf, setup)
    rates = {name: [] for name in wfs}
    stages = {}
    for _ in range(repeat):
        for name, (wf, _setup) in wfs.items():
            r = render_full(scene, spp=spp, wavefront=wf, profile=True)
            rates[name].append(r.info["samples_per_second"])
            stages[name] = r.info
    echo(f"{'device':<60} {'Msamples/s':>10} {'rays/sample':>11} {'setup s':>8}")
    for name, (wf, setup) in wfs.items():
        info = stages[name]
        med = statistics.median(rates[name])
        rays = (info["rays_extend"] + info["rays_shadow"]) / max(info["samples"], 1)
        results["devices"][name] = {
            "samples_per_second_median": med, "samples_per_second_all": rates[name],
            "setup_seconds": setup, "kernel_build_seconds": wf.timings.get("build_seconds"),
            "bvh_seconds": wf.timings.get("bvh_seconds"), "wave_size": wf.wave_size,
            "rays_per_sample": rays, "stage_seconds": info.get("stage_seconds"), "features": info["features"],
        }
        echo(f"{name[:60]:<60} {med / 1e6:10.3f} {rays:11.2f} {setup:8.2f}")
    if json_path:
        with open(json_path, "w") as fh:
            json.dump(results, fh, indent=2)
        echo(f"wrote {json_path}")
    return results
