"""Mesh loading (``load_mesh``, ``flatten``, ``check_triangles``) and the geometry forms ``trace`` takes."""
import warnings

import numpy as np
import pytest
import trimesh

from pyopencl_rt import trace
from pyopencl_rt.errors import UserError
from pyopencl_rt.scene.mesh import MeshError, check_triangles, flatten, load_mesh


def dyadic_sphere():
    """An icosphere with coordinates rounded to multiples of 1/64: exact in float32 and in every
    text format trimesh writes, so loaded triangles can be compared exactly."""
    m = trimesh.creation.icosphere(subdivisions=2, radius=1.5)
    v = np.round(np.asarray(m.vertices) * 64) / 64
    return trimesh.Trimesh(v, m.faces, process=False)


def triangle_set(vertices, faces):
    """Triangles as a set of vertex triples, each rotated to start at its smallest vertex
    (insensitive to face order, vertex order and vertex sharing; sensitive to winding)."""
    out = set()
    for tri in np.asarray(vertices, np.float64)[np.asarray(faces)]:
        pts = [tuple(p) for p in tri]
        k = min(range(3), key=lambda i: pts[i])
        out.add(tuple(pts[k:] + pts[:k]))
    return out


def assert_one_line_naming(exc, path):
    msg = str(exc)
    assert "\n" not in msg
    assert str(path) in msg


def test_mesh_error_is_a_user_error():
    assert issubclass(MeshError, UserError)


@pytest.mark.parametrize("ext", ["obj", "ply", "stl", "glb"])
def test_formats_give_the_source_triangles(tmp_path, ext):
    mesh = dyadic_sphere()
    path = tmp_path / f"mesh.{ext}"
    mesh.export(path)
    v, f = load_mesh(path)
    assert v.dtype == np.float32 and v.shape[1] == 3 and v.flags.c_contiguous
    assert f.dtype == np.int32 and f.shape == (len(mesh.faces), 3) and f.flags.c_contiguous
    assert triangle_set(v, f) == triangle_set(mesh.vertices, mesh.faces)


def rot_z90(p):
    x, y, z = p
    return np.array([-y, x, z])


def rot_x(p, angle):
    x, y, z = p
    c, s = np.cos(angle), np.sin(angle)
    return np.array([x, c * y - s * z, s * y + c * z])


def test_gltf_scene_node_transforms_are_applied(tmp_path):
    """Node a: rotate 90 degrees about z, then translate; node b, a child of a: rotate 30 degrees
    about x, then translate; so b's world transform is a's applied after b's own."""
    tri_a = [[1.0, 0, 0], [0, 2, 0], [0, 0, 3]]
    tri_b = [[1.0, 1, 0], [2, 1, 0], [1, 2, 0.5]]
    t_a, t_b, angle = np.array([10.0, 0, 0]), np.array([0, 5.0, -1.0]), np.radians(30)
    a = np.eye(4)
    a[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    a[:3, 3] = t_a
    b = np.eye(4)
    b[:3, :3] = [[1, 0, 0], [0, np.cos(angle), -np.sin(angle)], [0, np.sin(angle), np.cos(angle)]]
    b[:3, 3] = t_b
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.Trimesh(tri_a, [[0, 1, 2]], process=False), node_name="a", geom_name="ga", transform=a)
    scene.add_geometry(trimesh.Trimesh(tri_b, [[0, 1, 2]], process=False), node_name="b", geom_name="gb",
                       parent_node_name="a", transform=b)
    path = tmp_path / "scene.glb"
    scene.export(path)

    v, f = load_mesh(path)
    assert f.shape == (2, 3)
    expected_a = [rot_z90(p) + t_a for p in tri_a]
    expected_b = [rot_z90(rot_x(p, angle) + t_b) + t_a for p in tri_b]
    got = sorted((v[tri].tolist() for tri in f), key=lambda t: t[0][1])  # a's first vertex has y = 1
    want = sorted(([list(p) for p in expected_a], [list(p) for p in expected_b]), key=lambda t: t[0][1])
    np.testing.assert_allclose(np.array(got), np.array(want), atol=1e-5)
    # flatten of the in-memory scene agrees with the file round trip
    v2, f2 = flatten(scene)
    np.testing.assert_allclose(v2[f2], v[f], atol=1e-5)


@pytest.mark.parametrize("bad_value", [np.nan, np.inf, -np.inf, 1e39], ids=["nan", "inf", "-inf", "overflow"])
def test_non_finite_vertices_drop_their_faces(bad_value):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [bad_value, 0, 0], [0, 0, 1]], np.float64)
    f = np.array([[0, 1, 2], [1, 2, 3], [0, 3, 4], [0, 1, 4]])
    with pytest.warns(UserWarning, match=r"mymesh: 1 vertices .*dropped the 2 faces"):
        v32, f32 = check_triangles(v, f, "mymesh")
    assert f32.tolist() == [[0, 1, 2], [0, 1, 4]]
    assert np.isfinite(v32).all()
    np.testing.assert_array_equal(v32[[0, 1, 2, 4]], v[[0, 1, 2, 4]])


def test_non_finite_vertices_in_a_file(tmp_path):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [np.nan, 0, 0]], np.float64)
    mesh = trimesh.Trimesh(v, [[0, 1, 2], [1, 2, 3], [0, 3, 1]], process=False)
    path = tmp_path / "nan.ply"
    mesh.export(path)
    with pytest.warns(UserWarning, match=r"dropped the 2 faces") as record:
        _, f = load_mesh(path)
    assert str(path) in str(record[0].message)
    assert f.tolist() == [[0, 1, 2]]


def test_finite_mesh_gives_no_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_triangles(np.eye(3), [[0, 1, 2]])


@pytest.mark.parametrize("vertices, faces, words", [
    (np.eye(3), [[0, 1, 3]], "out of range"),
    (np.eye(3), [[0, 1, -1]], "out of range"),
    (np.zeros((3, 2)), [[0, 1, 2]], "vertices"),
    (np.zeros((3, 3, 1)), [[0, 1, 2]], "vertices"),
    (np.array([["a", "b", "c"]]), [[0, 0, 0]], "vertices"),
    (np.eye(3), [[0, 1, 2, 0]], "faces"),
    (np.eye(3), [0, 1, 2], "faces"),
    (np.eye(3), [[0.0, 1.0, 2.0]], "faces"),
], ids=["index-too-big", "index-negative", "vertices-2d", "vertices-3axes", "vertices-strings",
        "quads", "faces-1d", "faces-float"])
def test_bad_arrays_raise_mesh_error(vertices, faces, words):
    with pytest.raises(MeshError, match=words) as info:
        check_triangles(vertices, faces, "the/file.obj")
    assert_one_line_naming(info.value, "the/file.obj")


def test_out_of_range_index_in_a_file(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    assert_one_line_naming(info.value, path)


def test_flatten_rejects_other_objects():
    with pytest.raises(MeshError, match="dict"):
        flatten({"vertices": np.eye(3)}, name="thing")


def test_missing_file(tmp_path):
    path = tmp_path / "nope.obj"
    with pytest.raises(MeshError, match="no such file") as info:
        load_mesh(path)
    assert_one_line_naming(info.value, path)


def test_folder(tmp_path):
    with pytest.raises(MeshError, match="folder") as info:
        load_mesh(tmp_path)
    assert_one_line_naming(info.value, tmp_path)


def _latin1_decode(text, initial="utf-8"):
    return text if isinstance(text, str) else text.decode("latin-1", errors="ignore")


@pytest.mark.parametrize("ext, decoder", [
    ("obj", "default"), ("ply", "default"), ("stl", "default"), ("glb", "default"),
    # binary PLY/GLB never go through trimesh's text decoding; OBJ and ASCII STL do
    ("obj", "charset-detector"),
    ("stl", "charset-detector"),
])
def test_garbage_file(tmp_path, monkeypatch, ext, decoder):
    """Random bytes are an error, not an empty mesh.  ``charset-detector`` emulates an environment
    with charset_normalizer installed, where trimesh decodes undecodable bytes as text anyway."""
    if decoder == "charset-detector":
        monkeypatch.setattr(trimesh.util, "decode_text", _latin1_decode)
    path = tmp_path / f"garbage.{ext}"
    path.write_bytes(np.random.default_rng(1).bytes(4000))
    with pytest.raises(MeshError) as info:
        load_mesh(path)
    assert_one_line_naming(info.value, path)


def test_empty_mesh(tmp_path):
    v, f = check_triangles(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    assert v.shape == (0, 3) and v.dtype == np.float32
    assert f.shape == (0, 3) and f.dtype == np.int32
    path = tmp_path / "empty.obj"
    path.write_text("# no geometry\n")
    v, f = load_mesh(path)
    assert v.shape == (0, 3) and f.shape == (0, 3)
    v, f = flatten(trimesh.Scene())
    assert v.shape == (0, 3) and f.shape == (0, 3)


def test_trace_accepts_pair_trimesh_and_scene(device):
    base = dyadic_sphere()
    shift = np.array([0.5, -0.25, 1.0])  # dyadic: the shifted coordinates are exact
    moved = trimesh.Trimesh(base.vertices + shift, base.faces, process=False)
    transform = np.eye(4)
    transform[:3, 3] = shift
    scene = trimesh.Scene()
    scene.add_geometry(base, transform=transform)
    pair = (np.asarray(moved.vertices, np.float32), np.asarray(moved.faces, np.int32))

    rng = np.random.default_rng(5)
    n = 2000
    origins = shift + rng.normal(size=(n, 3)) * 0.2 + np.array([0, 0, 6.0])
    targets = shift + rng.uniform(-2.2, 2.2, size=(n, 3))  # some rays miss the sphere (radius 1.5)
    directions = targets - origins
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)

    results = [trace(g, origins, directions, device=device) for g in (pair, moved, scene)]
    ref = results[0]
    hit = ref["prim_id"] >= 0
    assert 0.2 * n < hit.sum() < 0.95 * n
    for other in results[1:]:
        np.testing.assert_array_equal(other["prim_id"], ref["prim_id"])
        np.testing.assert_array_equal(other["t"], ref["t"])
        np.testing.assert_array_equal(other["normal"], ref["normal"])
    # and the hits are the right ones: Embree on the same triangles
    emb = trace(pair, origins, directions, backend="embree")
    assert np.mean(emb["prim_id"] == ref["prim_id"]) > 0.99
    np.testing.assert_allclose(ref["t"][hit], emb["t"][hit], rtol=1e-4)
