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
def test_angle_weighted_normals_of_a_mesh_file_as_read(mesh):
    """A mesh file's float32 vertices and int32 faces, passed as read (no float64 / int64 copy):
    the reference's normals of the same values widened."""
    v, f = MESHES[mesh]()
    v32 = v.astype(np.float32)
    _same(angle_weighted_normals(v32, f.astype(np.int32)), ref_angle_weighted_normals(v32.astype(np.float64), f))
    keys = (np.arange(f.size).reshape(-1, 3) // 2).astype(np.int32)
    _same(angle_weighted_normals(v32, f.astype(np.int32), keys),
          ref_angle_weighted_normals(v32.astype(np.float64), f, keys.astype(np.int64)))


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
    want = ref_face_normals(n, len(n), as_given)
    _same(scene.face_normals(), want)
    prim = np.random.default_rng(8).permutation(500)[:400].astype(np.int32)
    _same(scene.face_normals(prim), want[prim])  # the BVH's order, gathered in the same pass
    assert scene.has_shading_normals() == bool(np.any(want))
    only_bad = n.copy()
    only_bad[:, 0, 0] = np.nan  # every face has a bad corner: all flat
    scene.normals = only_bad
    assert not scene.has_shading_normals() and not np.any(ref_face_normals(only_bad, len(n), as_given))
    scene.normals = np.zeros_like(n)
    assert not scene.has_shading_normals()
    one = np.zeros_like(n)
    one[123] = n[1]
    scene.normals = one
    assert scene.has_shading_normals() == bool(np.any(ref_face_normals(one, len(n), as_given)))


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


@pytest.mark.parametrize("mesh", sorted(MESHES))
def test_used_vertex_reach_matches_reference(mesh):
    """The validation's one pass: all used vertices finite, and their largest |coordinate|, as
    np.unique(faces) gives them; a non-finite vertex no face uses does not count."""
    v, f = MESHES[mesh]()
    f = f[f.max(axis=1) < len(v) - 1]  # the last vertex unused
    for vertices in (v, v.astype(np.float32)):
        for faces in (f, f.astype(np.int32)):
            used = np.asarray(vertices, np.float64)[np.unique(faces)]
            assert meshops.used_vertex_reach(vertices, faces) == (True, float(np.abs(used).max()))
    v = v.copy()
    v[-1] = np.nan
    assert meshops.used_vertex_reach(v, f)[0]
    v[f[5, 1], 2] = np.inf
    assert not meshops.used_vertex_reach(v, f)[0] and not meshops.used_vertex_reach(v.astype(np.float32), f)[0]


def test_scene_bounds_of_used_vertices():
    v, f = _heightfield()
    v = v.astype(np.float32)
    v = np.concatenate([v, [[100.0, 100.0, 100.0]]]).astype(np.float32)  # unused: not in the bounds
    scene = Scene(vertices=v, faces=f.astype(np.int32), face_materials=np.zeros(len(f), np.int32), materials=[])
    lo, hi = scene_bounds(scene)
    used = v[np.unique(f)].astype(np.float64)
    assert np.array_equal(lo, used.min(axis=0)) and np.array_equal(hi, used.max(axis=0))


# --- the binary PLY fast path (scene/mesh.py: read_binary_ply) against trimesh ----------------

def _write_ply(path, vertex_fields, columns, faces, count="uchar", index="int", endian="<", counts=None):
    """A binary PLY of these vertex properties ([(ply type, name)], their columns) and faces."""
    import numpy as _np

    kinds = {"float": "f4", "double": "f8", "uchar": "u1", "char": "i1", "int": "i4", "uint": "u4",
             "ushort": "u2"}
    fmt = "binary_little_endian" if endian == "<" else "binary_big_endian"
    lines = ["ply", f"format {fmt} 1.0", f"element vertex {len(columns[0])}"]
    lines += [f"property {t} {n}" for t, n in vertex_fields]
    lines += [f"element face {len(faces)}", f"property list {count} {index} vertex_indices", "end_header"]
    vd = _np.empty(len(columns[0]), [(n, endian + kinds[t]) for t, n in vertex_fields])
    for (t, n), c in zip(vertex_fields, columns):
        vd[n] = c
    width = faces.shape[1]
    fd = _np.empty(len(faces), [("n", endian + kinds[count]), ("i", endian + kinds[index], (width,))])
    fd["n"] = width if counts is None else counts
    fd["i"] = faces
    path.write_bytes(("\n".join(lines) + "\n").encode() + vd.tobytes() + fd.tobytes())
    return path


def _ply_variants(tmp_path):
    v, f = heightfield(12)
    rng = np.random.default_rng(3)
    n = rng.standard_normal((len(v), 3))
    rgb = rng.integers(0, 256, (len(v), 3))
    xyz = [("float", "x"), ("float", "y"), ("float", "z")]
    out = {
        "plain": _write_ply(tmp_path / "plain.ply", xyz, list(v.T), f),
        "normals": _write_ply(tmp_path / "normals.ply", xyz + [("float", "nx"), ("float", "ny"), ("float", "nz")],
                              list(v.T) + list(n.T), f),
        "colours": _write_ply(tmp_path / "colours.ply", xyz + [("uchar", "red"), ("uchar", "green"), ("uchar", "blue")],
                              list(v.T) + list(rgb.T), f),
        "double_uint_big": _write_ply(tmp_path / "double.ply", [("double", "x"), ("double", "y"), ("double", "z")],
                                      list(v.astype(np.float64).T), f, count="uchar", index="uint", endian=">"),
        "char_count": _write_ply(tmp_path / "charcount.ply", xyz, list(v.T), f, count="char"),
    }
    # texture coordinates under each of the names trimesh reads
    for u, w in (("u", "v"), ("s", "t"), ("texture_u", "texture_v")):
        out[f"uv_{u}"] = _write_ply(tmp_path / f"uv_{u}.ply", xyz + [("float", u), ("float", w)],
                                    list(v.T) + [rng.random(len(v)), rng.random(len(v))], f)
    # trimesh's case, which the fast path leaves to it
    quads = np.stack([f[0::2, 0], f[0::2, 1], f[0::2, 2], f[1::2, 2]], 1)
    out["quads"] = _write_ply(tmp_path / "quads.ply", xyz, list(v.T), quads)
    return out


def test_binary_ply_fast_path_matches_trimesh(tmp_path):
    import trimesh

    from pyopencl_rt.scene.loaders.meshfile import ply_extras, trimesh_uvs
    from pyopencl_rt.scene.mesh import PlyMesh, flatten, load_trimesh

    for name, path in _ply_variants(tmp_path).items():
        fast = load_trimesh(path)
        assert isinstance(fast, PlyMesh) == (name != "quads"), name
        ref = trimesh.load(str(path), process=False)
        v, f = flatten(fast, name)
        rv, rf = flatten(ref, name)
        assert np.array_equal(v, rv) and v.dtype == rv.dtype and np.array_equal(f, rf) and f.dtype == rf.dtype, name
        got, want = ply_extras(fast, f), ply_extras(ref, rf)
        assert (got.normals is None) == (want.normals is None), name
        if want.normals is not None:
            _same(got.normals, want.normals)
        assert sorted(got.attributes) == sorted(want.attributes), name
        for key in want.attributes:
            _same(got.attributes[key], want.attributes[key])
        uv, ref_uv = trimesh_uvs(fast, v, f), trimesh_uvs(ref, rv, rf)
        assert (uv is None) == (ref_uv is None) == (not name.startswith("uv")), name
        if uv is not None:
            assert np.array_equal(uv, ref_uv) and uv.dtype == ref_uv.dtype, name


def test_binary_ply_fast_path_declines_what_it_does_not_read(tmp_path):
    from pyopencl_rt.scene.mesh import read_binary_ply

    v, f = heightfield(4)
    xyz = [("float", "x"), ("float", "y"), ("float", "z")]
    good = _write_ply(tmp_path / "good.ply", xyz, list(v.T), f)
    assert read_binary_ply(good) is not None
    short = tmp_path / "short.ply"
    short.write_bytes(good.read_bytes()[:-5])
    assert read_binary_ply(short) is None
    mixed = _write_ply(tmp_path / "mixed.ply", xyz, list(v.T), np.concatenate([f, f[:, :1]], 1), counts=3)
    assert read_binary_ply(mixed) is None  # the counts do not match the records
    ascii_ply = tmp_path / "ascii.ply"
    ascii_ply.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                         "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                         "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    assert read_binary_ply(ascii_ply) is None
    two = _write_ply(tmp_path / "two.ply", xyz + [("float", "u"), ("float", "v"), ("float", "s"), ("float", "t")],
                     list(v.T) + [v[:, 0]] * 4, f)
    assert read_binary_ply(two) is None  # which pair trimesh takes is its business
    lone = _write_ply(tmp_path / "lone.ply", xyz + [("float", "u")], list(v.T) + [v[:, 0]], f)
    assert read_binary_ply(lone) is None


def test_a_loaded_mesh_keeps_the_unit_normals_the_kernels_read(tmp_path):
    """A Mitsuba XML's PLY without normals, loaded: the scene's own normals are face_normals()'s
    values of the angle-weighted, flattened normals (the numpy reference), written once in place
    (normals_unit), so the kernels read them as they are; face_normals() and its BVH-order gather
    give those values, bit for bit, and making them unit again changes nothing."""
    from pyopencl_rt.bench.scale_scene import write_ply
    from pyopencl_rt.scene.loaders import load_scene

    v, f = heightfield(24)
    write_ply(tmp_path / "mesh.ply", v, f)
    (tmp_path / "scene.xml").write_text(
        '<scene version="3.0.0"><shape type="ply"><string name="filename" value="mesh.ply"/></shape>'
        '<emitter type="constant"/></scene>')
    scene = load_scene(tmp_path / "scene.xml")
    raw = flat_where_planar(v, f, ref_angle_weighted_normals(v, f))
    expected = meshops.unit_corner_normals(raw, len(f))
    assert scene.normals_unit and not scene.normals_as_given
    _same(np.asarray(scene.normals).reshape(-1, 3, 3), expected)
    _same(scene.face_normals(), expected)
    prim = np.random.default_rng(0).permutation(len(f))
    _same(scene.face_normals(prim), expected[prim])
    scene.make_normals_unit()  # already unit: left as it is
    _same(np.asarray(scene.normals).reshape(-1, 3, 3), expected)


def test_bounds_are_the_float64_reduction_of_the_points():
    """meshops.bounds (one column at a time, no float64 copy) against the float64 axis-0 reduction
    it replaced: the same corners bit for bit, NaN propagated, an empty set inverted."""
    rng = np.random.default_rng(11)
    for dtype in (np.float32, np.float64):
        p = (rng.standard_normal((10_001, 3)) * [1e-3, 1.0, 1e6]).astype(dtype)
        lo, hi = meshops.bounds(p)
        assert lo.dtype == hi.dtype == np.float64
        assert np.array_equal(lo, p.astype(np.float64).min(axis=0)) and np.array_equal(hi, p.astype(np.float64).max(axis=0))
    p[5, 1] = np.nan
    lo, hi = meshops.bounds(p)
    assert np.isnan(lo[1]) and np.isnan(hi[1]) and np.isfinite(lo[[0, 2]]).all()
    lo, hi = meshops.bounds(np.zeros((0, 3), np.float32))
    assert (lo == np.inf).all() and (hi == -np.inf).all()


def test_finite_rows_are_the_rows_all_finite():
    """meshops.finite_rows (column by column) against np.isfinite(points).all(axis=1), with NaN,
    +-inf in each column and float64 values beyond float32's range kept as they are (finite)."""
    rng = np.random.default_rng(12)
    p = rng.standard_normal((1000, 3))
    p[rng.integers(0, 1000, 60), rng.integers(0, 3, 60)] = rng.choice([np.nan, np.inf, -np.inf], 60)
    p[7] = (1e300, 0.0, 0.0)
    for a in (p, p.astype(np.float32)):
        with np.errstate(over="ignore"):
            assert np.array_equal(meshops.finite_rows(a), np.isfinite(a).all(axis=1))
