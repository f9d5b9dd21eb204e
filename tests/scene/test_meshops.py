"""The compiled per-face passes (pyopencl_rt/scene/meshops.py, issue 35) give the same arrays, bit
for bit, as the numpy code they replaced, kept here as the float64 reference: on the heightfield
of the scale benchmark, on random meshes with degenerate, repeated and shared-corner faces, and
on meshes with non-finite vertices."""
from __future__ import annotations

import numpy as np
import pytest

from pyopencl_rt.bench.scale_scene import heightfield
from pyopencl_rt.scene import meshops
from pyopencl_rt.scene.loaders.assembly import angle_weighted_normals, flat_where_planar, scene_bounds
from pyopencl_rt.scene.model import Scene


# --- the numpy implementations as they were before issue 35 -----------------------------------

def ref_angle_weighted_normals(vertices, faces, keys=None):
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    keys = f if keys is None else np.asarray(keys, np.int64).reshape(-1, 3)
    if len(f) == 0:
        return np.zeros((0, 3, 3), np.float32)
    p = v[f]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    ok = length[:, 0] > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        n = np.where(ok[:, None], n / np.where(length > 0, length, 1.0), 0.0)
    sums = np.zeros((int(keys.max()) + 1, 3))
    for k in range(3):
        d0 = p[:, (k + 1) % 3] - p[:, k]
        d1 = p[:, (k + 2) % 3] - p[:, k]
        with np.errstate(invalid="ignore", divide="ignore"):
            d0 /= np.linalg.norm(d0, axis=1, keepdims=True)
            d1 /= np.linalg.norm(d1, axis=1, keepdims=True)
        angle = np.nan_to_num(np.arccos(np.clip(np.sum(d0 * d1, axis=1), -1.0, 1.0)))
        np.add.at(sums, keys[:, k], n * angle[:, None])
    length = np.linalg.norm(sums, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where(length > 0, sums / np.where(length > 0, length, 1.0), [1.0, 0.0, 0.0])
    return unit[keys].astype(np.float32)


def ref_flat_where_planar(vertices, faces, normals, tolerance=1e-5):
    if normals is None or len(faces) == 0:
        return None
    n = np.asarray(normals, np.float32).reshape(-1, 3, 3).copy()
    p = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    g = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    with np.errstate(invalid="ignore", divide="ignore"):
        g /= np.linalg.norm(g, axis=1, keepdims=True)
    flat = (np.abs(n - g[:, None, :]) <= tolerance).all(axis=(1, 2))
    n[flat] = 0.0
    return n if n.any() else None


def ref_face_normals(normals, n_faces, as_given):
    n = np.asarray(normals, np.float64).reshape(n_faces, 3, 3)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        length = np.linalg.norm(n, axis=2, keepdims=True)
        unit = n / length
    good = np.isfinite(unit).all(axis=2, keepdims=True) & (length > 0)
    if as_given:
        unit = n
    unit = np.where(good, unit, 0.0)
    flat = ~good.all(axis=(1, 2))
    unit[flat] = 0.0
    with np.errstate(over="ignore"):
        return unit.astype(np.float32)


def ref_finite_faces(vertices, faces):
    with np.errstate(over="ignore", invalid="ignore"):
        finite = np.isfinite(np.asarray(vertices, np.float64).astype(np.float32)).all(axis=1)
    return finite[faces].all(axis=1) if len(faces) else np.zeros(0, bool)


# --- meshes -------------------------------------------------------------------------------------

def _random_mesh(seed, n_vertices=300, n_faces=2000):
    rng = np.random.default_rng(seed)
    v = rng.standard_normal((n_vertices, 3)) * np.exp(rng.uniform(-3, 3, (n_vertices, 1)))
    f = rng.integers(0, n_vertices, (n_faces, 3))
    f[::17, 1] = f[::17, 0]                     # degenerate: a repeated corner
    f[::23] = f[::23, [1, 2, 0]]                # rotated copies ...
    f[1::29] = f[0:-1:29]                       # ... and duplicates of other faces
    v[5] = v[6]                                 # two vertices at one place: zero-length edges
    f[::31, 2] = 6
    f[::31, 1] = 5
    return v, f


def _heightfield():
    v, f = heightfield(40)
    return v.astype(np.float64), f.astype(np.int64)


MESHES = {"heightfield": _heightfield, **{f"random{s}": (lambda s=s: _random_mesh(s)) for s in range(3)}}


def _same(a, b):
    assert a.dtype == b.dtype and a.shape == b.shape
    assert np.array_equal(a.view(np.uint32), b.view(np.uint32))  # bit for bit (NaN and -0 included)


@pytest.mark.parametrize("mesh", sorted(MESHES))
def test_angle_weighted_normals_match_reference(mesh):
    v, f = MESHES[mesh]()
    _same(angle_weighted_normals(v, f), ref_angle_weighted_normals(v, f))
    keys = np.arange(f.size).reshape(-1, 3) // 2  # other corner groups than the face indices
    _same(angle_weighted_normals(v, f, keys), ref_angle_weighted_normals(v, f, keys))
    _same(angle_weighted_normals(v, f[:0]), ref_angle_weighted_normals(v, f[:0]))


@pytest.mark.parametrize("mesh", sorted(MESHES))
def test_flat_where_planar_matches_reference(mesh):
    v, f = MESHES[mesh]()
    v32 = v.astype(np.float32)
    n = ref_angle_weighted_normals(v, f)
    want = ref_flat_where_planar(v32, f, n)
    got = flat_where_planar(v32, f, n)
    assert (want is None) == (got is None)
    if want is not None:
        _same(got, want)
    inplace = n.copy()
    got = flat_where_planar(v32, f, inplace, inplace=True)
    if want is not None:
        _same(inplace, want)
    # geometric normals as corner normals: every face flat, so none left
    g = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    with np.errstate(invalid="ignore", divide="ignore"):
        g = (g / np.linalg.norm(g, axis=1, keepdims=True)).astype(np.float32)
    corner = np.repeat(g[:, None], 3, axis=1)
    want = ref_flat_where_planar(v32, f, corner)
    got = flat_where_planar(v32, f, corner)
    assert (want is None) == (got is None)
    if want is not None:
        _same(got, want)


@pytest.mark.parametrize("as_given", [False, True])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_face_normals_match_reference(as_given, dtype):
    rng = np.random.default_rng(7)
    n = (rng.standard_normal((500, 3, 3)) * np.exp(rng.uniform(-20, 20, (500, 3, 1)))).astype(dtype)
    n[3, 1] = 0.0
    n[5, 2, 0] = np.nan
    n[7, 0, 1] = np.inf
    n[9] = 0.0
    if dtype == np.float64:
        n[11, 0] = 1e300  # overflows the squares
    _same(meshops.unit_corner_normals(n, len(n), as_given), ref_face_normals(n, len(n), as_given))
    scene = Scene(vertices=np.zeros((3, 3), np.float32), faces=np.zeros((500, 3), np.int32),
                  face_materials=np.zeros(500, np.int32), materials=[], normals=n, normals_as_given=as_given)
    first = scene.face_normals()
    _same(first, ref_face_normals(n, len(n), as_given))
    assert scene.face_normals() is first  # computed once
    scene.normals = -n  # a new array: computed again
    _same(scene.face_normals(), ref_face_normals(-n, len(n), as_given))
    assert scene.has_shading_normals()
    scene.normals = np.zeros_like(n)
    assert not scene.has_shading_normals()


@pytest.mark.parametrize("mesh", sorted(MESHES))
def test_finite_faces_and_used_vertices_match_reference(mesh):
    v, f = MESHES[mesh]()
    v = v.copy()
    v[::13] = np.nan
    v[1::19, 1] = 1e39  # finite in float64, not in float32
    v[2::37, 2] = -np.inf
    assert np.array_equal(meshops.finite_faces(v, f), ref_finite_faces(v, f))
    with np.errstate(over="ignore"):
        v32 = v.astype(np.float32)
    assert np.array_equal(meshops.finite_faces(v32, f), ref_finite_faces(v, f))
    used = meshops.used_vertices(f, len(v))
    assert np.array_equal(np.flatnonzero(used), np.unique(f))


def test_scene_bounds_of_used_vertices():
    v, f = _heightfield()
    v = v.astype(np.float32)
    v = np.concatenate([v, [[100.0, 100.0, 100.0]]]).astype(np.float32)  # unused: not in the bounds
    scene = Scene(vertices=v, faces=f.astype(np.int32), face_materials=np.zeros(len(f), np.int32), materials=[])
    lo, hi = scene_bounds(scene)
    used = v[np.unique(f)].astype(np.float64)
    assert np.array_equal(lo, used.min(axis=0)) and np.array_equal(hi, used.max(axis=0))
