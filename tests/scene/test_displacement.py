"""pbrt-v4's displaced plymesh (scene/displacement.py, loaders/pbrt_shapes.py): refined until every
edge is shorter than "edgelength" in the world, each vertex moved along its normal by a float texture.

* Refinement alone keeps the surface: the same area, every world-space edge below the bound under a
  non-uniform scale, every inner edge shared by exactly two triangles (no crack at a split), the
  boundary's length unchanged, the orientation kept.
* A vertical ramp image (linear, clamped) displaces a flat PLY grid: each vertex's height is the
  closed form of the bilinear lookup at its uv (pbrt reads images at (s, 1 - t), so the bottom row
  is at t = 0), and away from the clamped rows the recomputed normals are the tilted plane's.
* Without vertex uvs pbrt refuses a displacement, and so do we, in one line.
pbrt's own render of a displaced mesh: scenes/pbrt-features/displacement-plymesh.pbrt, docs/BENCHMARKS.md."""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from pyopencl_rt.scene.displacement import face_normal_sum, refine
from pyopencl_rt.scene.loaders import SceneError, load_scene


def grid(nx, ny, sx=2.0, sy=3.0):
    """A flat grid in z = 0 over [0, sx] x [0, sy], its uv (x / sx, y / sy), normals +z."""
    x, y = np.meshgrid(np.linspace(0, sx, nx + 1), np.linspace(0, sy, ny + 1))
    v = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], 1)
    k = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    a, b, c, d = k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, 1:].ravel(), k[1:, :-1].ravel()
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return v, f, v[:, :2] / [sx, sy], np.tile([0.0, 0.0, 1.0], (len(v), 1))


def edges(f):
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    keys, counts = np.unique(e, axis=0, return_counts=True)
    return keys, counts


def area(v, f):
    return 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum()


def test_refinement_keeps_the_surface_and_bounds_world_edges():
    v, f, uv, n = grid(2, 3)
    linear = np.diag([1.0, 2.5, 1.0])  # world edges along y are 2.5 times longer
    rv, rf, ruv, rn = refine(v, f, uv, n, linear, 0.3)
    w = rv @ linear.T
    keys, counts = edges(rf)
    lengths = np.linalg.norm(w[keys[:, 0]] - w[keys[:, 1]], axis=1)
    assert lengths.max() < 0.3 and len(rf) > 50 * len(f)
    assert np.isclose(area(rv, rf), area(v, f), rtol=1e-12)
    assert set(counts) == {1, 2}  # boundary edges once, inner edges twice: no T-junction
    boundary = lengths[counts == 1].sum()
    assert np.isclose(boundary, 2 * (2.0 + 2.5 * 3.0), rtol=1e-12)
    assert np.allclose(face_normal_sum(rv, rf), [0.0, 0.0, 1.0])  # none turned over
    assert np.allclose(ruv, rv[:, :2] / [2.0, 3.0]) and np.allclose(rn, [0.0, 0.0, 1.0])


def test_recomputed_normals_weigh_every_face_alike():
    """pbrt's ComputeNormals: a vertex's normal is the normalised sum of its faces' unit normals, not
    weighted by area or angle: a fold of a large face (normal +z) and a thin one tilted to +x."""
    v = np.array([[0, 0, 0], [0, 1, 0], [-5, 0, 0], [0.1, 0.5, -0.1]], np.float64)
    f = np.array([[0, 1, 2], [0, 3, 1]])  # (0, 1) the shared edge
    n1 = np.cross(v[1] - v[0], v[2] - v[1])
    n2 = np.cross(v[3] - v[0], v[1] - v[3])
    want = n1 / np.linalg.norm(n1) + n2 / np.linalg.norm(n2)
    got = face_normal_sum(v, f)
    assert np.allclose(got[0], want / np.linalg.norm(want)) and np.allclose(got[2], n1 / np.linalg.norm(n1))
    assert np.linalg.norm(n1) > 10 * np.linalg.norm(n2)  # an area-weighted sum would differ


def reference_refine(v, f, linear, max_edge):
    """The refinement in rounds over every triangle still too long (numpy, float64): each split at the
    midpoint of its longest edge (pbrt's comparisons), a midpoint shared through a dict.  The triangles
    as corner positions (T, 3, 3); pbrt's order of splits does not change which triangles come out."""
    v, f = [tuple(p) for p in np.asarray(v, np.float64)], [tuple(t) for t in f]
    mids, done = {}, []
    while f:
        p = np.asarray(v) @ np.asarray(linear).T
        nxt = []
        for a, b, c in f:
            d01, d12, d20 = (np.linalg.norm(p[j] - p[i]) for i, j in ((a, b), (b, c), (c, a)))
            if d01 < max_edge and d12 < max_edge and d20 < max_edge:
                done.append((a, b, c))
                continue
            if d01 > d12:
                x, y, z = (a, b, c) if d01 > d20 else (c, a, b)
            else:
                x, y, z = (b, c, a) if d12 > d20 else (c, a, b)
            key = (min(x, y), max(x, y))
            if key not in mids:
                mids[key] = len(v)
                v.append(tuple((np.asarray(v[x]) + np.asarray(v[y])) / 2))
            m = mids[key]
            nxt += [(x, m, z), (m, y, z)]
        f = nxt
    return np.asarray(v)[np.asarray(done)]


def test_refinement_is_the_reference_in_pbrts_order_of_splits():
    """An uneven mesh (a grid with moved vertices) under a rotation and a non-uniform scale: the same
    triangles, each with its corners in the same order, as the reference (to 1e-6: float32 midpoints)."""
    rng = np.random.default_rng(7)
    v, f, uv, n = grid(3, 2, 1.0, 1.0)
    v[:, :2] += rng.uniform(-0.1, 0.1, (len(v), 2))
    c, s = np.cos(0.4), np.sin(0.4)
    linear = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ np.diag([1.0, 1.7, 1.0])
    rv, rf, _, _ = refine(v, f, uv, n, linear, 0.1)
    want = reference_refine(v, f, linear, 0.1)
    got = np.asarray(rv, np.float64)[rf]
    def by_centroid(tris):  # each triangle keeps its corners' order; the list ordered by where it lies
        c = np.round(tris.mean(axis=1), 4)
        return tris[np.lexsort((c[:, 2], c[:, 1], c[:, 0]))]

    assert len(got) == len(want) > 40 * len(f)
    assert np.allclose(by_centroid(got), by_centroid(want), atol=1e-6)  # float32 midpoints


def _ply(path, v, f, uv):
    lines = ["ply", "format ascii 1.0", f"element vertex {len(v)}", "property float x", "property float y",
             "property float z", "property float u", "property float v", f"element face {len(f)}",
             "property list uchar int vertex_indices", "end_header"]
    lines += [f"{a:.9g} {b:.9g} {c:.9g} {s:.9g} {t:.9g}" for (a, b, c), (s, t) in zip(v, uv)]
    lines += [f"3 {a} {b} {c}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")


SCENE = """LookAt 1 1.5 -4  1 1.5 0  0 1 0
Camera "perspective"
WorldBegin
Texture "h" "float" "imagemap" "string filename" "ramp.png" "string encoding" "linear" "string wrap" "clamp"
    "float scale" {scale}
AttributeBegin
Scale 1 {sy} 1
Shape "plymesh" "string filename" "plane.ply" {disp}
AttributeEnd
"""


def test_a_ramp_image_lifts_the_grid_by_its_bilinear_lookup(tmp_path):
    H = 256
    ramp = np.repeat(np.arange(H, dtype=np.uint8)[:, None], 4, axis=1)  # row y (top first) holds y / 255
    Image.fromarray(ramp).save(tmp_path / "ramp.png")
    v, f, uv, _ = grid(2, 3)
    _ply(tmp_path / "plane.ply", v, f, uv)
    scale, sy = 0.5, 0.8
    (tmp_path / "s.pbrt").write_text(SCENE.format(scale=scale, sy=sy, disp='"texture displacement" "h" '
                                                                          '"float edgelength" 0.1'))
    mesh = load_scene(tmp_path / "s.pbrt")
    pos, faces = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces)
    corner_uv = np.asarray(mesh.uvs, np.float64).reshape(-1, 2)  # ours: v flipped (1 - t)
    corner_p = pos[faces].reshape(-1, 3)
    slope = -scale * H / (3 * sy * (H - 1))  # dz/dy where the ramp is linear (below)
    keys, _ = edges(faces)
    lifted = np.linalg.norm(pos[keys[:, 0]] - pos[keys[:, 1]], axis=1)
    assert lifted.max() < 0.1 * np.hypot(1, slope) + 1e-6 and len(faces) > 1000  # refined flat, then tilted
    # pbrt's (s, t) = (x / 2, y / 3) before the scale; the image's row coordinate is 1 - t; bilinear
    # between row centres (y + 0.5) / H, clamped at the first and last rows
    t = corner_p[:, 1] / sy / 3.0
    height = scale * np.clip(((1 - t) * H - 0.5) / (H - 1), 0, 1)
    assert np.abs(corner_p[:, 2] - height).max() < 2e-6, np.abs(corner_p[:, 2] - height).max()
    assert np.allclose(corner_uv[:, 1], 1 - t, atol=1e-6)
    # where the ramp is linear (t away from the clamped rows), the normals are the tilted plane's:
    # z = scale (H (1 - y / (3 sy)) - 0.5) / (H - 1), dz/dy = -scale H / (3 sy (H - 1))
    want = np.array([0.0, -slope, 1.0]) / np.hypot(slope, 1.0)
    normals = np.asarray(mesh.normals, np.float64).reshape(-1, 3)
    tri = pos[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    face_n = np.repeat(face_n / np.linalg.norm(face_n, axis=1, keepdims=True), 3, axis=0)
    flat = ~normals.any(axis=1)  # the builder stores 0 for corners whose normal is their face's
    normals[flat] = face_n[flat]
    inner = (t > 0.05) & (t < 0.95)  # a face away from the clamped rows (edges under 0.05 in t)
    assert inner.sum() > 1000
    assert np.abs(normals[inner] - want).max() < 1e-4


def test_a_displacement_without_uvs_is_one_line(tmp_path):
    Image.fromarray(np.zeros((4, 4), np.uint8)).save(tmp_path / "ramp.png")
    v, f, _, _ = grid(1, 1)
    lines = ["ply", "format ascii 1.0", f"element vertex {len(v)}", "property float x", "property float y",
             "property float z", f"element face {len(f)}", "property list uchar int vertex_indices", "end_header"]
    lines += [" ".join(map(str, p)) for p in v] + [f"3 {a} {b} {c}" for a, b, c in f]
    (tmp_path / "plane.ply").write_text("\n".join(lines) + "\n")
    (tmp_path / "s.pbrt").write_text(SCENE.format(scale=1, sy=1, disp='"texture displacement" "h"'))
    with pytest.raises(SceneError, match="needs the mesh's vertex uvs") as caught:
        load_scene(tmp_path / "s.pbrt")
    assert "\n" not in str(caught.value)
