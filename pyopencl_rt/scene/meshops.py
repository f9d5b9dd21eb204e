"""The per-face passes over big meshes, compiled with numba (issue 35: scenes of millions of
triangles): one pass each, over the faces in parallel where the result does not depend on the
order, without the (F, 3, 3) float64 temporaries of the numpy expressions they replace.

Each function returns exactly (bit for bit) what the numpy code it replaced returned; the
arithmetic is the same IEEE double arithmetic in the same order (numba compiles without
fast-math, so no fused multiply-adds), and the one transcendental, the corner angles' arccos,
is still numpy's (its SIMD arccos may differ from libm's in the last bit).
tests/scene/test_meshops.py compares each with the numpy reference.

* :func:`angle_weighted_normals`: Mitsuba's vertex normals (assembly.angle_weighted_normals);
* :func:`flat_where_planar`: corner normals equal to the geometric normal zeroed (assembly's);
* :func:`unit_corner_normals`: Scene.face_normals' unit per-corner normals;
* :func:`used_vertices`: which vertices some face uses (the np.unique(faces) of the checks);
* :func:`finite_faces`: which faces have three vertices finite in float32.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


def _jit(**extra):
    """numba.njit (releasing the GIL), cached on disk where numba finds a writable place (as
    accel/bvh_binned.py)."""
    def decorate(fn):
        options = dict(nogil=True, error_model="numpy", **extra)
        try:
            return njit(cache=True, **options)(fn)
        except RuntimeError:
            return njit(**options)(fn)
    return decorate


@_jit(inline="always")
def _corner_cos(ax, ay, az, bx, by, bz, cx, cy, cz):
    """The cosine of the angle at a between b and c, clipped to [-1, 1] (NaN for a zero edge)."""
    d0x, d0y, d0z = bx - ax, by - ay, bz - az
    d1x, d1y, d1z = cx - ax, cy - ay, cz - az
    l0 = math.sqrt(d0x * d0x + d0y * d0y + d0z * d0z)
    l1 = math.sqrt(d1x * d1x + d1y * d1y + d1z * d1z)
    d0x, d0y, d0z = d0x / l0, d0y / l0, d0z / l0
    d1x, d1y, d1z = d1x / l1, d1y / l1, d1z / l1
    cs = d0x * d1x + d0y * d1y + d0z * d1z
    if cs < -1.0:
        return -1.0
    if cs > 1.0:
        return 1.0
    return cs


@_jit(parallel=True)
def _face_normals_and_cosines(v, f, n_out, cos_out):
    """Per face: the unit geometric normal in float64 (0 for a degenerate face) and the cosine of
    each corner's angle, clipped to [-1, 1] (NaN where an edge has no length)."""
    for i in prange(f.shape[0]):
        a, b, c = f[i, 0], f[i, 1], f[i, 2]
        # float32 vertices widen exactly: the same double arithmetic as with a float64 copy
        p0x, p0y, p0z = np.float64(v[a, 0]), np.float64(v[a, 1]), np.float64(v[a, 2])
        p1x, p1y, p1z = np.float64(v[b, 0]), np.float64(v[b, 1]), np.float64(v[b, 2])
        p2x, p2y, p2z = np.float64(v[c, 0]), np.float64(v[c, 1]), np.float64(v[c, 2])
        e1x, e1y, e1z = p1x - p0x, p1y - p0y, p1z - p0z
        e2x, e2y, e2z = p2x - p0x, p2y - p0y, p2z - p0z
        nx = e1y * e2z - e1z * e2y
        ny = e1z * e2x - e1x * e2z
        nz = e1x * e2y - e1y * e2x
        length = math.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0:
            n_out[i, 0], n_out[i, 1], n_out[i, 2] = nx / length, ny / length, nz / length
        else:
            n_out[i, 0], n_out[i, 1], n_out[i, 2] = 0.0, 0.0, 0.0
        cos_out[i, 0] = _corner_cos(p0x, p0y, p0z, p1x, p1y, p1z, p2x, p2y, p2z)
        cos_out[i, 1] = _corner_cos(p1x, p1y, p1z, p2x, p2y, p2z, p0x, p0y, p0z)
        cos_out[i, 2] = _corner_cos(p2x, p2y, p2z, p0x, p0y, p0z, p1x, p1y, p1z)


@_jit()
def _accumulate(n, angle, keys, sums):
    """sums[keys[i, k]] += n[i] * angle[i, k] (NaN angles as 0), corner k = 0 of every face, then
    k = 1, then k = 2: np.add.at's order, so the sums are the same to the bit."""
    for k in range(3):
        for i in range(keys.shape[0]):
            a = angle[i, k]
            if math.isnan(a):
                a = 0.0
            j = keys[i, k]
            sums[j, 0] += n[i, 0] * a
            sums[j, 1] += n[i, 1] * a
            sums[j, 2] += n[i, 2] * a


@_jit(parallel=True)
def _normalise_rows(sums):
    """Each row made unit length in place; (1, 0, 0) (Mitsuba's) where it has no length."""
    for j in prange(sums.shape[0]):
        x, y, z = sums[j, 0], sums[j, 1], sums[j, 2]
        length = math.sqrt(x * x + y * y + z * z)
        if length > 0:
            sums[j, 0], sums[j, 1], sums[j, 2] = x / length, y / length, z / length
        else:
            sums[j, 0], sums[j, 1], sums[j, 2] = 1.0, 0.0, 0.0


@_jit(parallel=True)
def _gather_corners(rows, keys, out):
    """out[i, k] = float32(rows[keys[i, k]])."""
    for i in prange(keys.shape[0]):
        for k in range(3):
            j = keys[i, k]
            for c in range(3):
                out[i, k, c] = np.float32(rows[j, c])


def _as_float(a) -> np.ndarray:
    """``a`` C-contiguous as float32 or float64 (as given; other types as float64)."""
    a = np.asarray(a)
    return np.ascontiguousarray(a if a.dtype in (np.float32, np.float64) else a.astype(np.float64))


def _as_index(a) -> np.ndarray:
    """``a`` C-contiguous as int32 or int64 (as given; other types as int64)."""
    a = np.asarray(a)
    return np.ascontiguousarray(a if a.dtype in (np.int32, np.int64) else a.astype(np.int64))


def angle_weighted_normals(vertices, faces, keys=None, out=None) -> np.ndarray:
    """Per-corner (F, 3, 3) float32 vertex normals as Mitsuba 3 computes them for a mesh without
    any: see :func:`pyopencl_rt.scene.loaders.assembly.angle_weighted_normals`; written into
    ``out`` (C-contiguous float32 (F, 3, 3): a part of the scene's stacked array) if given."""
    v = _as_float(vertices).reshape(-1, 3)  # float32 or float64 as given: no copy of a mesh file's
    f = _as_index(faces).reshape(-1, 3)
    keys = f if keys is None else _as_index(keys).reshape(-1, 3)
    if out is not None and (out.shape != (len(f), 3, 3) or out.dtype != np.float32 or not out.flags.c_contiguous):
        raise ValueError(f"out must be a C-contiguous float32 ({len(f)}, 3, 3) array")
    if len(f) == 0:
        return np.zeros((0, 3, 3), np.float32) if out is None else out
    n = np.empty((len(f), 3))
    cosines = np.empty((len(f), 3))
    with np.errstate(invalid="ignore", divide="ignore"):
        _face_normals_and_cosines(v, f, n, cosines)
        angle = np.arccos(cosines, out=cosines)  # numpy's arccos, as before
    sums = np.zeros((int(keys.max()) + 1, 3))
    _accumulate(n, angle, keys, sums)
    del n, angle, cosines
    _normalise_rows(sums)
    if out is None:
        out = np.empty((len(f), 3, 3), np.float32)
    _gather_corners(sums, keys, out)
    return out


@_jit(parallel=True)
def _flat_faces(v, f, n, tolerance, flat):
    """flat[i]: the three corner normals n[i] (float32) within ``tolerance`` of the face's unit
    geometric normal (float64) in every component."""
    for i in prange(f.shape[0]):
        a, b, c = f[i, 0], f[i, 1], f[i, 2]
        p0x, p0y, p0z = np.float64(v[a, 0]), np.float64(v[a, 1]), np.float64(v[a, 2])
        e1x, e1y, e1z = np.float64(v[b, 0]) - p0x, np.float64(v[b, 1]) - p0y, np.float64(v[b, 2]) - p0z
        e2x, e2y, e2z = np.float64(v[c, 0]) - p0x, np.float64(v[c, 1]) - p0y, np.float64(v[c, 2]) - p0z
        gx = e1y * e2z - e1z * e2y
        gy = e1z * e2x - e1x * e2z
        gz = e1x * e2y - e1y * e2x
        length = math.sqrt(gx * gx + gy * gy + gz * gz)
        gx, gy, gz = gx / length, gy / length, gz / length
        ok = True
        for k in range(3):
            if not (abs(np.float64(n[i, k, 0]) - gx) <= tolerance and abs(np.float64(n[i, k, 1]) - gy) <= tolerance
                    and abs(np.float64(n[i, k, 2]) - gz) <= tolerance):
                ok = False
        flat[i] = ok


@_jit(parallel=True)
def _zero_flat(n, flat, nonzero):
    """n[i] = 0 where flat[i]; nonzero[i]: some component of n[i] is left non-zero."""
    for i in prange(n.shape[0]):
        any_left = False
        for k in range(3):
            for c in range(3):
                if flat[i]:
                    n[i, k, c] = 0.0
                elif n[i, k, c] != 0:
                    any_left = True
        nonzero[i] = any_left


def flat_where_planar(vertices, faces, normals, tolerance: float = 1e-5, inplace: bool = False):
    """See :func:`pyopencl_rt.scene.loaders.assembly.flat_where_planar`; ``inplace``: ``normals``
    (float32 (F, 3, 3), C-contiguous) is written in place rather than copied."""
    if normals is None or len(faces) == 0:
        return None
    if inplace and isinstance(normals, np.ndarray) and normals.dtype == np.float32 and normals.flags.c_contiguous:
        n = normals.reshape(-1, 3, 3)
    else:
        n = np.array(normals, np.float32).reshape(-1, 3, 3)
    f = _as_index(faces).reshape(-1, 3)
    v = _as_float(vertices)
    flat = np.empty(len(f), np.bool_)
    with np.errstate(invalid="ignore", divide="ignore"):
        _flat_faces(v, f, n, float(tolerance), flat)
    nonzero = np.empty(len(f), np.bool_)
    _zero_flat(n, flat, nonzero)
    return n if nonzero.any() else None


@_jit(inline="always")
def _unit_corner(n, i, k, as_given):
    """Corner k of face i of n made unit length (as given with ``as_given``), and whether that
    corner is usable (its normalisation finite and its length non-zero)."""
    x, y, z = np.float64(n[i, k, 0]), np.float64(n[i, k, 1]), np.float64(n[i, k, 2])
    length = math.sqrt(x * x + y * y + z * z)
    ux, uy, uz = x / length, y / length, z / length
    good = math.isfinite(ux) and math.isfinite(uy) and math.isfinite(uz) and length > 0
    if as_given:
        ux, uy, uz = x, y, z
    return good, np.float32(ux), np.float32(uy), np.float32(uz)


@_jit(inline="always")
def _unit_face(n, i, as_given, out, j):
    """out[j] = Scene.face_normals of face i of n: each corner normal made unit length (kept as
    given with ``as_given``), all 0 if a corner normal is non-finite or of zero length.  Returns
    whether some component of out[j] is non-zero."""
    good = True
    for k in range(3):
        ok, out[j, k, 0], out[j, k, 1], out[j, k, 2] = _unit_corner(n, i, k, as_given)
        good = good and ok
    nonzero = False
    for k in range(3):
        for c in range(3):
            if not good:
                out[j, k, c] = 0.0
            elif out[j, k, c] != 0:
                nonzero = True
    return nonzero


@_jit(parallel=True)
def _unit_corner_normals(n, prim, as_given, out, nonzero):
    """out[j] = the unit corner normals of face prim[j] (of face j where prim is empty)."""
    gather = prim.shape[0] > 0
    for j in prange(out.shape[0]):
        i = np.int64(prim[j]) if gather else np.int64(j)
        nonzero[j] = _unit_face(n, i, as_given, out, j)


def _as_normals(normals, n_faces):
    return _as_float(np.asarray(normals).reshape(n_faces, 3, 3))


def unit_corner_normals(normals, n_faces: int, as_given: bool = False, prim=None, out=None) -> np.ndarray:
    """(F, 3, 3) float32: Scene.face_normals of per-corner ``normals`` (any real dtype); with
    ``prim`` (int indices), its rows prim only, gathered (face_normals()[prim] in one pass);
    written into ``out`` (C-contiguous float32 of that shape: a mapped device buffer) if given."""
    n = _as_normals(normals, n_faces)
    prim = np.zeros(0, np.int64) if prim is None else np.ascontiguousarray(prim)
    rows = len(prim) if len(prim) else n_faces
    if len(prim) and (prim.min() < 0 or prim.max() >= n_faces):
        raise IndexError("prim out of range")
    if out is None:
        out = np.empty((rows, 3, 3), np.float32)
    elif out.shape != (rows, 3, 3) or out.dtype != np.float32 or not out.flags.c_contiguous:
        raise ValueError(f"out must be a C-contiguous float32 ({rows}, 3, 3) array")
    nonzero = np.empty(rows, np.bool_)
    if rows:
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            _unit_corner_normals(n, prim, bool(as_given), out, nonzero)
    return out


@_jit(parallel=True)
def _any_shading(n, as_given, flags):
    """flags[i]: face i of n keeps a non-zero normal in Scene.face_normals (_unit_face's rule)."""
    for i in prange(n.shape[0]):
        good = True
        nonzero = False
        for k in range(3):
            ok, ux, uy, uz = _unit_corner(n, i, k, as_given)
            good = good and ok
            if ux != 0 or uy != 0 or uz != 0:
                nonzero = True
        flags[i] = good and nonzero


def any_shading_normal(normals, n_faces: int, as_given: bool = False) -> bool:
    """np.any(Scene.face_normals()) without the (F, 3, 3) array: some face keeps a non-zero normal."""
    if n_faces == 0:
        return False
    n = _as_normals(normals, n_faces)
    flags = np.empty(n_faces, np.bool_)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        _any_shading(n, bool(as_given), flags)
    return bool(flags.any())


@_jit(parallel=True)
def _used_reach(v, f):
    """Over every corner of every face: how many coordinates are not finite, and the largest
    absolute finite one (0.0 for none)."""
    bad = 0
    reach = 0.0
    for i in prange(f.shape[0]):
        for k in range(3):
            j = f[i, k]
            for c in range(3):
                x = abs(np.float64(v[j, c]))
                if math.isfinite(x):
                    reach = max(reach, x)
                else:
                    bad += 1
    return bad, reach


def used_vertex_reach(vertices, faces) -> tuple[bool, float]:
    """(all the vertices some face uses are finite, the largest absolute coordinate among them):
    the validation's question of the vertices of np.unique(faces), in one parallel pass over the
    faces without the mask (faces must hold indices in [0, len(vertices)))."""
    v = _as_float(vertices).reshape(-1, 3)
    f = _as_index(faces).reshape(-1, 3)
    if len(f) == 0:
        return True, 0.0
    with np.errstate(invalid="ignore", over="ignore"):
        bad, reach = _used_reach(v, f)
    return bad == 0, float(reach)


def used_vertices(faces, n_vertices: int) -> np.ndarray:
    """(V,) bool: the vertices some face uses (the set np.unique(faces) gives, as a mask; faces
    must hold indices in [0, n_vertices))."""
    used = np.zeros(int(n_vertices), np.bool_)
    used[np.asarray(faces).reshape(-1)] = True
    return used


@_jit(parallel=True)
def _finite_rows32(v, out):
    for j in prange(v.shape[0]):
        ok = True
        for c in range(3):
            x = np.float32(v[j, c])
            if not math.isfinite(x):
                ok = False
        out[j] = ok


def finite_rows(points) -> np.ndarray:
    """(N,) bool: every coordinate of the (N, 3) point is finite; column by column (10x faster than
    ``np.isfinite(points).all(axis=1)``, which reduces over the short axis)."""
    p = np.asarray(points)
    return np.isfinite(p[:, 0]) & np.isfinite(p[:, 1]) & np.isfinite(p[:, 2])


def finite_vertices32(vertices) -> np.ndarray:
    """(V,) bool: the vertex is finite in float32 (a double beyond float32's range is not)."""
    v = np.asarray(vertices)
    if v.dtype == np.float32:
        return finite_rows(v) if v.ndim == 2 else np.zeros(0, bool)
    v = np.ascontiguousarray(v, np.float64).reshape(-1, 3)
    out = np.empty(len(v), np.bool_)
    with np.errstate(over="ignore", invalid="ignore"):
        _finite_rows32(v, out)
    return out


def finite_faces(vertices, faces) -> np.ndarray:
    """(F,) bool: the faces whose three vertices are finite in float32."""
    finite = finite_vertices32(vertices)
    f = np.asarray(faces)
    if len(f) == 0:
        return np.zeros(0, bool)
    if finite.all():
        return np.ones(len(f), bool)
    return finite[f].all(axis=1)


def bounds(points) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi): the float64 corners of the box around (N, 3) ``points`` (N = 0: +inf, -inf).  One
    column at a time: numpy reduces an (N, 3) array along axis 0 some 20 times slower than its three
    strided columns (0.21 against 0.01 s for 4M float32 points), and min and max are exact in the
    points' own type, so no float64 copy is made.  NaN propagates, as np.min's."""
    p = np.asarray(points)
    if not len(p):
        return np.full(3, np.inf), np.full(3, -np.inf)
    return (np.array([p[:, k].min() for k in range(3)], np.float64),
            np.array([p[:, k].max() for k in range(3)], np.float64))
