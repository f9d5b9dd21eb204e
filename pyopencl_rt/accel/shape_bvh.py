"""The analytic shapes' BVH (cl/scene/shapes.h traverses it): accel/bvh.h's node layout (each
node the boxes of its two children), one shape per leaf (count 1, child the shape's index in
Scene.shapes, so no reordering), built by median splits of the box centres along their widest
axis.  Shapes are few next to triangles (tens to thousands), so a balanced tree, depth
ceil(log2 S) (under BVH_STACK_SIZE for any count), is what matters, not the SAH.

Boxes are rounded outwards to float32 and grown by BOX_PAD_RELATIVE of the largest coordinate,
as the triangle BVHs' are, so that the kernels' slab test never misses a shape it would hit.
"""
from __future__ import annotations

import numpy as np

from ..device import abi


def _box32(lo, hi, pad):
    return (np.nextafter((lo - pad).astype(np.float32), np.float32(-np.inf)),
            np.nextafter((hi + pad).astype(np.float32), np.float32(np.inf)))


def build_shape_bvh(lo, hi) -> np.ndarray:
    """The abi.BVH_NODE array over the shapes whose boxes are (lo, hi) ((S, 3) float64 each; the
    types' bounds, scene/shapes/); without any, a root whose two children are absent, which a kernel
    compiled with every feature walks and leaves."""
    n = len(lo)
    nodes = np.zeros(max(1, n - 1), abi.BVH_NODE)
    if n == 0:
        nodes[0]["bmin_left"] = nodes[0]["bmin_right"] = np.inf
        nodes[0]["bmax_left"] = nodes[0]["bmax_right"] = -np.inf
        nodes[0]["count_left"] = nodes[0]["count_right"] = -1
        return nodes
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    pad = abi.BOX_PAD_RELATIVE * max(float(np.abs(lo).max()), float(np.abs(hi).max()), 1e-30)
    centres = 0.5 * (lo + hi)
    if n == 1:  # the root's left child the one shape, its right absent (count -1, an empty box)
        nodes[0]["bmin_left"], nodes[0]["bmax_left"] = _box32(lo[0], hi[0], pad)
        nodes[0]["child_left"], nodes[0]["count_left"] = 0, 1
        nodes[0]["bmin_right"], nodes[0]["bmax_right"] = np.inf, -np.inf
        nodes[0]["count_right"] = -1
        return nodes
    stack, used = [(0, np.arange(n))], 1
    while stack:
        k, idx = stack.pop()
        c = centres[idx]
        order = idx[np.argsort(c[:, int(np.argmax(c.max(axis=0) - c.min(axis=0)))], kind="stable")]
        half = len(order) // 2
        for side, part in (("left", order[:half]), ("right", order[half:])):
            nodes[k][f"bmin_{side}"], nodes[k][f"bmax_{side}"] = _box32(lo[part].min(axis=0), hi[part].max(axis=0), pad)
            if len(part) == 1:
                nodes[k][f"child_{side}"], nodes[k][f"count_{side}"] = part[0], 1
            else:
                nodes[k][f"child_{side}"], nodes[k][f"count_{side}"] = used, 0
                stack.append((used, part))
                used += 1
    return nodes
