"""Benchmark the host BVH builder: build time and SAH quality.

    python tools/bench_bvh.py [--json out.json] [--sizes 10000,100000,1000000] [--no-sweep]

For each size, binned SAH is built (median of 3 runs) on a subdivided icosphere, a torus, a random
triangle soup and a soup of long thin slivers of about that many triangles; on the meshes of
``sweep_size`` triangles the full-sweep builder is run too and the binned/sweep SAH ratio is
reported.  ``run(...)`` returns the same data as a dict (for a CLI).
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pyopencl_rt.accel.bvh import build_bvh, validate

KINDS = ("sphere", "torus", "soup", "slivers")


def make_mesh(kind: str, n: int, seed: int = 0):
    """(vertices, faces) of about n triangles (exactly n for the soups)."""
    rng = np.random.default_rng(seed)
    if kind == "sphere":
        import trimesh
        sub = max(0, int(round(np.log(max(n, 20) / 20) / np.log(4))))
        m = trimesh.creation.icosphere(subdivisions=sub)
        return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32)
    if kind == "torus":
        import trimesh
        minor = max(3, int(np.sqrt(n / 2 / 4)))
        major = max(3, int(n / 2 / minor))
        m = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=major,
                                   minor_sections=minor)
        return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32)
    if kind == "soup":
        size = 2.0 / np.cbrt(n)
        c = rng.random((n, 1, 3))
        v = c + (rng.random((n, 3, 3)) - 0.5) * size
    elif kind == "slivers":
        c = rng.random((n, 1, 3))
        d = rng.normal(size=(n, 1, 3))
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        t = np.array([-0.15, 0.15, 0.0])[None, :, None]
        v = c + d * t + rng.normal(size=(n, 3, 3)) * 1e-3
    else:
        raise ValueError(kind)
    return v.reshape(-1, 3).astype(np.float32), np.arange(3 * n, dtype=np.int32).reshape(n, 3)


def _one(v, f, method, repeat):
    times, bvh = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        bvh = build_bvh(v, f, method=method)
        times.append(time.perf_counter() - t)
    s = dict(bvh.stats)
    s["build_seconds"] = statistics.median(times)
    s["build_seconds_all"] = times
    return bvh, s


def run(sizes=(10_000, 100_000, 1_000_000), kinds=KINDS, sweep_size=100_000, repeat=3,
        check=False, log=None) -> dict:
    """Build every (kind, size) with binned SAH, and with sweep at sweep_size; return results."""
    out = {"results": []}
    for n in sizes:
        for kind in kinds:
            v, f = make_mesh(kind, n)
            bvh, s = _one(v, f, "binned", repeat)
            if check:
                validate(bvh)
            row = {"kind": kind, "size": int(n), "triangles": int(len(f)), "binned": s}
            if sweep_size and n == sweep_size:
                sw, ss = _one(v, f, "sweep", 1)
                if check:
                    validate(sw)
                row["sweep"] = ss
                row["sah_ratio"] = s["sah_cost"] / ss["sah_cost"]
            out["results"].append(row)
            if log:
                log(_fmt(row))
    return out


def _fmt(row):
    b = row["binned"]
    txt = (f"{row['kind']:8s} {row['triangles']:>9d}  binned {b['build_seconds']:7.3f}s "
           f"SAH {b['sah_cost']:8.2f}  nodes {b['node_count']:>8d} depth {b['depth']:>2d}")
    if "sweep" in row:
        s = row["sweep"]
        txt += f" | sweep {s['build_seconds']:7.2f}s SAH {s['sah_cost']:8.2f}  ratio {row['sah_ratio']:.4f}"
    hist = b["leaf_size_histogram"]
    txt += "  leaves " + " ".join(f"{k}:{v}" for k, v in sorted(hist.items())[:8])
    if len(hist) > 8:
        txt += f" ... (max {max(hist)})"
    return txt


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", help="write the results to this file")
    ap.add_argument("--sizes", default="10000,100000,1000000")
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--sweep-size", type=int, default=100_000, help="0 = no sweep builds")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--check", action="store_true", help="validate() every BVH")
    a = ap.parse_args(argv)
    res = run(sizes=[int(x) for x in a.sizes.split(",")], kinds=a.kinds.split(","),
              sweep_size=a.sweep_size, repeat=a.repeat, check=a.check,
              log=lambda s: print(s, flush=True))
    text = json.dumps(res, indent=1)
    if a.json:
        Path(a.json).write_text(text)
    else:
        print(text)


if __name__ == "__main__":
    main()
