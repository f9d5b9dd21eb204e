"""Scene files: TOML, OBJ+MTL and plain meshes into Scene (host only, no OpenCL needed)."""
import math
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.errors import UserError
from pyopencl_rt.scene.loaders import load_scene
from pyopencl_rt.scene.pixel_filter import PixelFilter

import harness
from pyopencl_rt.scene.shapes.sphere import of as sphere_of

SCENES = Path(__file__).resolve().parents[2] / "scenes"
BOX_CENTRE = np.array([278.0, 274.4, 279.6])


def face_normals(scene):
    v = scene.vertices.astype(np.float64)[scene.faces]
    return np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])


def centroids(scene):
    return scene.vertices.astype(np.float64)[scene.faces].mean(axis=1)


def mat_name(scene, face):
    return scene.materials[scene.face_materials[face]].name


@pytest.fixture(scope="module")
def cbox():
    return load_scene(SCENES / "cornell-box.toml")


# ---------------------------------------------------------------------------------------------
# cornell-box.toml


def test_cornell_box_counts(cbox):
    # 5 room quads + light + 2 blocks x 5 quads = 16 quads = 32 triangles
    assert cbox.faces.shape == (32, 3)
    assert cbox.vertices.dtype == np.float32 and cbox.faces.dtype == np.int32
    assert cbox.face_materials.dtype == np.int32 and cbox.face_materials.shape == (32,)
    assert len(sphere_of(cbox.shapes)) == 0


def test_cornell_box_bounds(cbox):
    lo = cbox.vertices.min(axis=0)
    hi = cbox.vertices.max(axis=0)
    np.testing.assert_allclose(lo, [0, 0, 0], atol=1e-3)
    np.testing.assert_allclose(hi, [556.0, 548.8, 559.2], atol=1e-3)


def test_cornell_box_walls_face_inwards(cbox):
    n = face_normals(cbox)
    c = centroids(cbox)
    room = [i for i in range(len(n)) if mat_name(cbox, i) in ("red", "green", "light")
            or (mat_name(cbox, i) == "white" and (c[i, 1] < 1 or c[i, 1] > 548 or c[i, 2] > 559))]
    # floor (2) + ceiling (2) + back (2) + red (2) + green (2) + light (2)
    assert len(room) == 12
    for i in room:
        assert np.dot(n[i], BOX_CENTRE - c[i]) > 0, f"face {i} ({mat_name(cbox, i)}) faces outwards"
        # and it faces the centre squarely, not at a grazing angle
        cos = np.dot(n[i], BOX_CENTRE - c[i]) / np.linalg.norm(n[i]) / np.linalg.norm(BOX_CENTRE - c[i])
        assert cos > 0.3


def test_cornell_box_blocks_face_outwards_from_their_block(cbox):
    n = face_normals(cbox)
    c = centroids(cbox)
    short = [(130, 65), (82, 225), (240, 272), (290, 114)]
    tall = [(423, 247), (265, 296), (314, 456), (472, 406)]
    for corners, height in ((short, 165.0), (tall, 330.0)):
        xz = np.mean(corners, axis=0)
        block_centre = np.array([xz[0], height / 2, xz[1]])
        lo = np.min(corners, axis=0)
        hi = np.max(corners, axis=0)
        inside = [i for i in range(len(c)) if lo[0] - 1e-3 <= c[i, 0] <= hi[0] + 1e-3
                  and lo[1] - 1e-3 <= c[i, 2] <= hi[1] + 1e-3 and 1e-3 < c[i, 1] <= height + 1e-3]
        assert len(inside) == 10  # 5 quads
        for i in inside:
            assert np.dot(n[i], c[i] - block_centre) > 0


def test_cornell_box_light(cbox):
    light = [i for i in range(len(cbox.faces)) if mat_name(cbox, i) == "light"]
    assert len(light) == 2
    mat = cbox.materials[cbox.face_materials[light[0]]]
    assert mat.emission == (17.0, 12.0, 4.0) and mat.albedo == (0.0, 0.0, 0.0)
    assert not mat.two_sided
    n = face_normals(cbox)[light]
    area = 0.5 * np.linalg.norm(n, axis=1).sum()
    assert area == pytest.approx(130 * 105, rel=0.01)
    unit = n / np.linalg.norm(n, axis=1, keepdims=True)
    np.testing.assert_allclose(unit, [[0, -1, 0]] * 2, atol=1e-6)
    y = cbox.vertices[np.unique(cbox.faces[light])][:, 1]
    assert np.all(y < 548.8) and np.all(y > 548.0)  # just below the ceiling, not in its plane
    # only the light emits
    emitters = [i for i in range(len(cbox.faces)) if cbox.materials[cbox.face_materials[i]].is_emissive]
    assert emitters == light


def test_cornell_box_materials(cbox):
    c = centroids(cbox)
    assert mat_name(cbox, int(np.argmin(c[:, 0]))) == "green"  # x = 0: right wall
    assert mat_name(cbox, int(np.argmax(c[:, 0]))) == "red"  # x ~ 556: left wall
    assert mat_name(cbox, int(np.argmin(c[:, 1]))) == "white"  # floor
    assert mat_name(cbox, int(np.argmax(c[:, 2]))) == "white"  # back wall
    by_name = {m.name: m for m in cbox.materials}
    assert by_name["white"].albedo == (0.725, 0.71, 0.68)
    assert by_name["red"].albedo == (0.63, 0.065, 0.05)
    assert by_name["green"].albedo == (0.14, 0.45, 0.091)
    for name in ("white", "red", "green"):
        assert not by_name[name].is_emissive


def test_cornell_box_camera_and_settings(cbox):
    cam = cbox.camera
    assert cam.eye == (278.0, 273.0, -800.0)
    assert cam.look_at == (278.0, 273.0, 0.0)
    assert cam.up == (0.0, 1.0, 0.0)
    assert cam.fov == pytest.approx(math.degrees(2 * math.atan(12.5 / 35)), abs=1e-3)
    assert cam.fov == pytest.approx(39.3077, abs=1e-3)
    s = cbox.settings
    assert (s.width, s.height, s.spp, s.max_depth) == (512, 512, 64, 8)
    assert s.integrator in ("path", "bsdf", "nee")


def test_fov_axis_spans_its_side_at_any_size(tmp_path):
    """fov_axis "x": the horizontal field of view is fov whatever the film's shape (the camera
    record's right vector is tan(fov / 2) long, its up vector that times height / width)."""
    path = tmp_path / "c.toml"
    path.write_text('[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 90\nfov_axis = "x"\n'
                    '[[shape]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1\n')
    cam = load_scene(path).camera
    for w, h in ((200, 100), (100, 200), (64, 64)):
        rec = cam.record(w, h)
        assert np.linalg.norm(rec["right"]) == pytest.approx(1.0, rel=1e-6), (w, h)
        assert np.linalg.norm(rec["up"]) == pytest.approx(h / w, rel=1e-6), (w, h)
        assert cam.vertical_fov(w, h) == pytest.approx(math.degrees(2 * math.atan(h / w)))


def test_cornell_spheres():
    scene = load_scene(SCENES / "cornell-spheres.toml")
    assert scene.faces.shape == (12, 3)  # room + light, no blocks
    np.testing.assert_allclose(sphere_of(scene.shapes), [[185, 100, 169, 100], [370, 100, 351, 100]])
    assert sphere_of(scene.shapes).dtype == np.float32 and scene.shape_materials.dtype == np.int32
    assert [scene.materials[i].name for i in scene.shape_materials] == ["white", "white"]
    # the spheres rest on the floor and lie inside the room
    assert np.all(sphere_of(scene.shapes)[:, 1] - sphere_of(scene.shapes)[:, 3] >= 0)
    n = face_normals(scene)
    c = centroids(scene)
    assert np.all(np.einsum("ij,ij->i", n, BOX_CENTRE - c) > 0)


# ---------------------------------------------------------------------------------------------
# OBJ + MTL


TWO_MTL_OBJ = """\
mtllib two.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 2 0 0
usemtl red
f 1 2 3
usemtl lamp
f 1 3 4
usemtl red
f 1/1/1 4/1/1 5/1/1
f -5 -4 -2 -1
"""

TWO_MTL = """\
# comment
newmtl red
Ka 0 0 0
Kd 0.63 0.065 0.05
newmtl lamp
Kd 0 0 0
Ke 17 12 4
"""


def test_obj_per_face_materials(tmp_path):
    (tmp_path / "two.obj").write_text(TWO_MTL_OBJ)
    (tmp_path / "two.mtl").write_text(TWO_MTL)
    scene = load_scene(tmp_path / "two.obj")
    # 3 triangles + a quad fanned into 2
    assert scene.faces.shape == (5, 3)
    names = [mat_name(scene, i) for i in range(5)]
    assert names == ["red", "lamp", "red", "red", "red"]
    np.testing.assert_array_equal(scene.faces[:3], [[0, 1, 2], [0, 2, 3], [0, 3, 4]])
    np.testing.assert_array_equal(scene.faces[3:], [[1, 2, 4], [1, 4, 5]])
    by_name = {m.name: m for m in scene.materials}
    assert by_name["red"].albedo == pytest.approx((0.63, 0.065, 0.05))
    assert not by_name["red"].is_emissive
    assert by_name["lamp"].emission == pytest.approx((17, 12, 4))
    assert by_name["lamp"].albedo == pytest.approx((0, 0, 0))
    assert scene.settings.spp == 64  # defaults
    assert_camera_frames(scene)


def test_toml_mesh_with_file_materials_and_override(tmp_path):
    (tmp_path / "two.obj").write_text(TWO_MTL_OBJ)
    (tmp_path / "two.mtl").write_text(TWO_MTL)
    (tmp_path / "s.toml").write_text("""
[materials.lamp]
emission = [1, 2, 3]
two_sided = true
[[shape]]
type = "mesh"
file = "two.obj"
use_file_materials = true
translate = [10, 0, 0]
""")
    scene = load_scene(tmp_path / "s.toml")
    names = [mat_name(scene, i) for i in range(len(scene.faces))]
    assert names == ["red", "lamp", "red", "red", "red"]
    lamp = scene.materials[scene.face_materials[1]]
    assert lamp.emission == (1.0, 2.0, 3.0) and lamp.two_sided
    assert scene.materials[scene.face_materials[0]].albedo == pytest.approx((0.63, 0.065, 0.05))
    assert scene.vertices[:, 0].min() == pytest.approx(10.0)


# ---------------------------------------------------------------------------------------------
# other mesh formats: default material and a framing camera


def assert_camera_frames(scene):
    cam = scene.camera
    eye = np.asarray(cam.eye, np.float64)
    forward = np.asarray(cam.look_at, np.float64) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, cam.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    lo = scene.vertices.min(axis=0).astype(np.float64)
    hi = scene.vertices.max(axis=0).astype(np.float64)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    d = corners - eye
    depth = d @ forward
    assert np.all(depth > 0)
    tan_v = math.tan(math.radians(cam.fov) / 2)
    tan_h = tan_v * scene.settings.width / scene.settings.height
    assert np.all(np.abs(d @ up) / depth <= tan_v)
    assert np.all(np.abs(d @ right) / depth <= tan_h)
    # looks along -z at the centre
    np.testing.assert_allclose(forward, [0, 0, -1], atol=1e-9)
    np.testing.assert_allclose(cam.look_at, (lo + hi) / 2, rtol=1e-5, atol=1e-5)
    # and not absurdly far away: the box fills a fair part of the view
    fill = max(np.max(np.abs(d @ up) / depth) / tan_v, np.max(np.abs(d @ right) / depth) / tan_h)
    assert fill > 0.3


@pytest.mark.parametrize("ext", ["glb", "ply", "stl"])
def test_mesh_formats_default_material_and_camera(tmp_path, ext):
    import trimesh

    mesh = trimesh.creation.box(extents=[4.0, 1.0, 2.0])
    mesh.apply_translation([10.0, -3.0, 5.0])
    path = tmp_path / f"box.{ext}"
    mesh.export(path)
    scene = load_scene(path)
    assert len(scene.faces) == 12
    assert len(scene.materials) == 1
    if ext == "glb":  # glTF: the file's material (glTF's default white one here; tests/scene/test_textures.py)
        assert scene.materials[0].type == "gltf" and scene.materials[0].albedo == (1.0, 1.0, 1.0)
    else:
        assert scene.materials[0].albedo == (0.8, 0.8, 0.8)
    assert not scene.materials[0].is_emissive
    np.testing.assert_array_equal(scene.face_materials, 0)
    np.testing.assert_allclose(scene.vertices.min(axis=0), [8, -3.5, 4], atol=1e-5)
    assert scene.camera.fov == 40.0
    assert_camera_frames(scene)


# ---------------------------------------------------------------------------------------------
# TOML transforms and shapes


TRI_OBJ = "v 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\n"


def _toml_mesh(tmp_path, extra):
    (tmp_path / "tri.obj").write_text(TRI_OBJ)
    (tmp_path / "s.toml").write_text(f'[[shape]]\ntype = "mesh"\nfile = "tri.obj"\n{extra}\n')
    return load_scene(tmp_path / "s.toml")


def test_transform_scale_rotate_translate(tmp_path):
    scene = _toml_mesh(tmp_path, 'scale = [2, 3, 4]\nrotate = {axis = [0, 0, 1], angle = 90}\ntranslate = [10, 20, 30]')
    # scale: (2,0,0) (0,3,0) (0,0,4); rotate 90 deg about +z: (x,y,z) -> (-y,x,z); translate
    np.testing.assert_allclose(scene.vertices, [[10, 22, 30], [7, 20, 30], [10, 20, 34]], atol=1e-5)
    # proper rotation/positive scale: winding unchanged
    np.testing.assert_array_equal(scene.faces, [[0, 1, 2]])


def test_transform_rotation_list_in_order(tmp_path):
    scene = _toml_mesh(tmp_path, 'rotate = [{axis = [0, 0, 1], angle = 90}, {axis = [1, 0, 0], angle = 90}]')
    # z 90: (x,y,z)->(-y,x,z); then x 90: (x,y,z)->(x,-z,y)
    # (1,0,0)->(0,1,0)->(0,0,1); (0,1,0)->(-1,0,0)->(-1,0,0); (0,0,1)->(0,0,1)->(0,-1,0)
    np.testing.assert_allclose(scene.vertices, [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], atol=1e-6)


def test_transform_matrix(tmp_path):
    scene = _toml_mesh(tmp_path, 'matrix = [[0, -1, 0, 5], [1, 0, 0, 6], [0, 0, 2, 7], [0, 0, 0, 1]]')
    np.testing.assert_allclose(scene.vertices, [[5, 7, 7], [4, 6, 7], [5, 6, 9]], atol=1e-6)


def test_mirror_keeps_normal_on_transformed_side(tmp_path):
    plain = _toml_mesh(tmp_path, "")
    mirrored = _toml_mesh(tmp_path, "scale = [-1, 1, 1]")
    n0 = face_normals(plain)[0]
    n1 = face_normals(mirrored)[0]
    # the mirror image of the original normal (1,1,1) is (-1,1,1)
    assert np.dot(n0, [1, 1, 1]) > 0
    assert np.dot(n1, [-1, 1, 1]) > 0
    flipped = _toml_mesh(tmp_path, "flip_normals = true")
    assert np.dot(face_normals(flipped)[0], [1, 1, 1]) < 0


def test_quad_triangle_box_sphere(tmp_path):
    (tmp_path / "s.toml").write_text("""
[materials.glow]
emission = 5
[[shape]]
type = "quad"
points = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
[[shape]]
type = "triangle"
material = "glow"
points = [[0, 0, 1], [0, 1, 1], [1, 0, 1]]
[[shape]]
type = "box"
size = [2, 4, 6]
center = [10, 0, 0]
[[shape]]
type = "sphere"
material = "glow"
center = [0, 0, -5]
radius = 0.5
""")
    scene = load_scene(tmp_path / "s.toml")
    assert scene.faces.shape == (2 + 1 + 12, 3)
    n = face_normals(scene)
    # quad: (p0,p1,p2) and (p0,p2,p3), normal +z (right-hand rule of the listed order)
    np.testing.assert_array_equal(scene.vertices[scene.faces[:2]], [[[0, 0, 0], [1, 0, 0], [1, 1, 0]],
                                                                    [[0, 0, 0], [1, 1, 0], [0, 1, 0]]])
    assert n[0][2] > 0 and n[1][2] > 0
    assert n[2][2] < 0  # triangle listed clockwise seen from +z
    box = slice(3, 15)
    np.testing.assert_allclose(scene.vertices[np.unique(scene.faces[box])].min(axis=0), [9, -2, -3])
    np.testing.assert_allclose(scene.vertices[np.unique(scene.faces[box])].max(axis=0), [11, 2, 3])
    c = centroids(scene)[box]
    assert np.all(np.einsum("ij,ij->i", n[box], c - [10, 0, 0]) > 0)  # box faces point outwards
    assert mat_name(scene, 0) == "default" and mat_name(scene, 2) == "glow"
    np.testing.assert_allclose(sphere_of(scene.shapes), [[0, 0, -5, 0.5]])
    assert scene.materials[scene.shape_materials[0]].emission == (5.0, 5.0, 5.0)
    assert_camera_frames_spheres(scene)


def assert_camera_frames_spheres(scene):
    # no [camera]: the framing camera looks at the centre of everything, spheres included
    lo = np.minimum(scene.vertices.min(axis=0), (sphere_of(scene.shapes)[:, :3] - sphere_of(scene.shapes)[:, 3:]).min(axis=0))
    hi = np.maximum(scene.vertices.max(axis=0), (sphere_of(scene.shapes)[:, :3] + sphere_of(scene.shapes)[:, 3:]).max(axis=0))
    np.testing.assert_allclose(scene.camera.look_at, (lo + hi) / 2, atol=1e-5)


def test_orthographic_camera_and_pixel_filters(tmp_path):
    """[camera] type = "orthographic" with its extent (default 2), and [film] filter by name or
    table with each type's defaults (box 0.5, tent 1, gaussian sigma 0.5 cut at 4 sigma, mitchell
    1/3, 1/3 over radius 2, lanczos tau 3 over radius tau); the box without one."""
    sphere = '[[shape]]\ntype = "sphere"\ncenter = [0,0,0]\nradius = 1\n'

    def scene(text):
        (tmp_path / "s.toml").write_text(text + sphere)
        return load_scene(tmp_path / "s.toml")

    s = scene('[camera]\neye = [0,0,5]\nlook_at = [0,0,0]\ntype = "orthographic"\nextent = 3.5\n')
    assert (s.camera.projection, s.camera.extent) == ("orthographic", 3.5) and s.settings.filter == PixelFilter()
    rec = s.camera.record(40, 20)
    assert rec["projection"] == abi.PROJECTION_ORTHOGRAPHIC
    assert np.allclose(rec["up"], [0, 1.75, 0]) and np.allclose(rec["right"], [3.5, 0, 0])
    assert scene('[camera]\neye = [0,0,5]\nlook_at = [0,0,0]\ntype = "orthographic"\n').camera.extent == 2.0
    assert scene('[camera]\neye = [0,0,5]\nlook_at = [0,0,0]\n').camera.projection == "perspective"
    cases = {'"gaussian"': PixelFilter("gaussian", (2.0, 2.0), sigma=0.5),
             '{type = "gaussian", sigma = 0.3}': PixelFilter("gaussian", (1.2, 1.2), sigma=0.3),
             '{type = "gaussian", sigma = 0.5, radius = 1.5}': PixelFilter("gaussian", (1.5, 1.5), sigma=0.5),
             '{type = "tent"}': PixelFilter("tent", (1.0, 1.0)),
             '{type = "box", radius = [1, 0.5]}': PixelFilter("box", (1.0, 0.5)),
             '"mitchell"': PixelFilter("mitchell", (2.0, 2.0)),
             '{type = "mitchell", b = 0, c = 0.5}': PixelFilter("mitchell", (2.0, 2.0), b=0.0, c=0.5),
             '{type = "lanczos", tau = 2}': PixelFilter("lanczos", (2.0, 2.0), tau=2.0)}
    for text, expected in cases.items():
        assert scene(f"[film]\nfilter = {text}\n").settings.filter == expected, text


# ---------------------------------------------------------------------------------------------
# errors: one line, naming the file


def _error(tmp_path, text, name="bad.toml"):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(UserError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg
    assert name in msg
    return msg


def test_error_unknown_shape_type(tmp_path):
    msg = _error(tmp_path, '[[shape]]\ntype = "quad"\npoints = [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]\n'
                           '[[shape]]\ntype = "quad"\npoints = [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]\n'
                           '[[shape]]\ntype = "cube"\n')
    assert "[[shape]] #3" in msg and "unknown type 'cube'" in msg


def test_error_unknown_key(tmp_path):
    msg = _error(tmp_path, '[[shape]]\ntype = "sphere"\ncenter = [0,0,0]\nradius = 1\ncolour = "red"\n')
    assert "unknown key 'colour'" in msg and "#1" in msg
    msg = _error(tmp_path, '[camera]\neye = [0,0,1]\nlook_at = [0,0,0]\nfocal = 35\n[[shape]]\ntype = "sphere"\ncenter = [0,0,0]\nradius = 1\n')
    assert "unknown key 'focal'" in msg and "[camera]" in msg
    msg = _error(tmp_path, '[lights]\n')
    assert "unknown key 'lights'" in msg
    msg = _error(tmp_path, '[materials.m]\nalbedo = 0.5\nroughness = 0.1\n[[shape]]\ntype = "sphere"\ncenter = [0,0,0]\nradius = 1\n')
    assert "[materials.m]" in msg and "'roughness'" in msg


def test_error_missing_mesh_file(tmp_path):
    msg = _error(tmp_path, '[[shape]]\ntype = "mesh"\nfile = "meshes/bunny.ply"\n')
    assert "bunny.ply" in msg and "bad.toml" in msg


def test_error_bad_vector_length(tmp_path):
    msg = _error(tmp_path, '[[shape]]\ntype = "sphere"\ncenter = [0, 0]\nradius = 1\n')
    assert "'center'" in msg and "3 numbers" in msg
    msg = _error(tmp_path, '[[shape]]\ntype = "quad"\npoints = [[0,0,0],[1,0,0],[1,1,0]]\n')
    assert "'points'" in msg
    msg = _error(tmp_path, '[[shape]]\ntype = "quad"\npoints = [[0,0,0],[1,0,0],[1,1,0],[0,1]]\n')
    assert "points[3]" in msg
    msg = _error(tmp_path, '[materials.m]\nalbedo = [1, 0.5]\n[[shape]]\ntype = "sphere"\ncenter = [0,0,0]\nradius = 1\n')
    assert "'albedo'" in msg


@pytest.mark.parametrize("text, needle", [
    ('[render]\nspp = "many"\n', "'spp'"),
    ('[render]\nspp = 1.5\n', "'spp'"),
    ('[render]\nintegrator = "bdpt"\n', "integrator 'bdpt'"),
    ('[render]\nadaptive = 1\n', "'adaptive'"),
    ('[render]\ntarget_error = 0\n', "'target_error'"),
    ('[render]\ntarget_error = "low"\n', "'target_error'"),
    ('[film]\nwidth = 0\n', "'width'"),
    ('[film]\nwidth = true\n', "'width'"),
    ('[camera]\neye = [0,0,0]\nlook_at = [0,0,0]\n', "same point"),
    ('[camera]\neye = [0,0,1]\nlook_at = [0,0,0]\nfov = 200\n', "'fov'"),
    ('[camera]\nlook_at = [0,0,0]\n', "'eye'"),
    ('[materials.m]\nalbedo = [2, 0, 0]\n', "'albedo'"),
    ('[materials.m]\nemission = [-1, 0, 0]\n', "'emission'"),
    ('[materials.m]\ntype = "glass"\n', "unknown type 'glass'"),
    ('[materials.m]\ntwo_sided = 1\n', "'two_sided'"),
    ('[camera]\neye = [0,0,1]\nlook_at = [0,0,0]\ntype = "fisheye"\n', "unknown type 'fisheye'"),
    ('[camera]\neye = [0,0,1]\nlook_at = [0,0,0]\ntype = "orthographic"\nfov = 30\n',
     "'fov' is not a key of an orthographic camera"),
    ('[camera]\neye = [0,0,1]\nlook_at = [0,0,0]\nextent = 3\n', "'extent' is not a key of a perspective camera"),
    ('[camera]\neye = [0,0,1]\nlook_at = [0,0,0]\nfov_axis = "z"\n', "unknown fov_axis 'z'"),
    ('[camera]\neye = [0,0,1]\nlook_at = [0,0,0]\ntype = "orthographic"\nfov_axis = "x"\n',
     "'fov_axis' is not a key of an orthographic camera"),
    ('[camera]\neye = [0,0,1]\nlook_at = [0,0,0]\ntype = "orthographic"\nextent = 0\n', "'extent' must be > 0"),
    ('[film]\nfilter = "cubic"\n', "unknown type 'cubic'"),
    ('[film]\nfilter = 3\n', "[film] filter: must be a filter's name or a table"),
    ('[film]\nfilter = {type = "box", sigma = 1}\n', "unknown key 'sigma'"),
    ('[film]\nfilter = {type = "tent", radius = [1, 2, 3]}\n', "'radius' must be a list of 2 numbers or one number"),
    ('[film]\nfilter = {type = "gaussian", sigma = 0}\n', "'sigma' must be > 0"),
    ('[film]\nfilter = {type = "lanczos", radius = 17}\n', "radius x must be in (0, 16] pixels"),
])
def test_error_bad_values(tmp_path, text, needle):
    sphere = '[[shape]]\ntype = "sphere"\ncenter = [0,0,0]\nradius = 1\n'
    assert needle in _error(tmp_path, text + sphere)


@pytest.mark.parametrize("shape, needle", [
    ('type = "sphere"\ncenter = [0,0,0]\nradius = -1\n', "'radius'"),
    ('type = "sphere"\ncenter = [0,0,0]\n', "missing 'radius'"),
    ('type = "sphere"\ncenter = [0,0,0]\nradius = 1\nmaterial = "nope"\n', "unknown material 'nope'"),
    ('type = "sphere"\ncenter = [0,0,0]\nradius = 1\ntranslate = [1,0,0]\n', "unknown key 'translate'"),
    ('points = [[0,0,0],[1,0,0],[1,1,0]]\n', "missing 'type'"),
    ('type = "triangle"\npoints = [[0,0,0],[1,0,0],[2,0,0]]\n', "degenerate"),
    ('type = "triangle"\npoints = [[0,0,0],[1,0,0],[0,1,0]]\nrotate = {axis = [0,0,1]}\n', "'angle'"),
    ('type = "triangle"\npoints = [[0,0,0],[1,0,0],[0,1,0]]\nscale = [1, 2]\n', "'scale'"),
    ('type = "triangle"\npoints = [[0,0,0],[1,0,0],[0,1,0]]\nmatrix = [[1,0,0,0],[0,1,0,0],[0,0,1,0]]\n', "'matrix'"),
    ('type = "triangle"\npoints = [[0,0,0],[1,0,0],[0,1,0]]\nmatrix = [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\ntranslate = [1,0,0]\n', "not both"),
    ('type = "box"\nsize = [1, 0, 1]\n', "'size'"),
])
def test_error_bad_shapes(tmp_path, shape, needle):
    msg = _error(tmp_path, "[[shape]]\n" + shape)
    assert needle in msg and "[[shape]] #1" in msg


def test_error_toml_syntax_and_missing_scene(tmp_path):
    msg = _error(tmp_path, "[camera\neye = 1\n")
    assert "TOML" in msg
    with pytest.raises(UserError) as info:
        load_scene(tmp_path / "nothere.toml")
    assert "nothere.toml" in str(info.value) and "\n" not in str(info.value)
    msg = _error(tmp_path, "[film]\nwidth = 64\n")
    assert "no shapes" in msg


def test_error_broken_mesh_file(tmp_path):
    (tmp_path / "broken.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 99\n")
    msg = _error(tmp_path, '[[shape]]\ntype = "mesh"\nfile = "broken.ply"\n')
    assert "broken.ply" in msg


def test_error_broken_obj(tmp_path):
    msg = _error(tmp_path, "v 0 0 0\nv 1 0 0\nf 1 2 7\n", name="bad.obj")
    assert "bad.obj:3" in msg


# ---------------------------------------------------------------------------------------------
# material types


def _materials(tmp_path, **tables):
    """The materials, by name, of a scene of a sphere and the tables ``[materials.NAME]`` of ``tables``."""
    text = harness.toml_tables(**{f"materials.{name}": table for name, table in tables.items()})
    (tmp_path / "m.toml").write_text(text + '[[shape]]\ntype = "sphere"\ncenter = [0,0,0]\nradius = 1\n')
    return {m.name: m for m in load_scene(tmp_path / "m.toml").materials}


def test_material_types_parse(tmp_path):
    from pyopencl_rt.scene.materials.conductor import METALS as CONDUCTORS

    m = _materials(tmp_path, mirror=dict(type="conductor"),
                   gold=dict(type="conductor", metal="gold", roughness=0.5, emission=2),
                   custom=dict(type="conductor", eta=[0.2, 0.9, 1.1], k=3, alpha=0.1),
                   schlick=dict(type="conductor", f0=[0.9, 0.6, 0.3]),
                   glass=dict(type="dielectric", ior=1.33, roughness=0.2),
                   plastic=dict(type="gltf", base_color=[0.8, 0.1, 0.1], metallic=0, roughness=0.4),
                   defaults=dict(type="gltf"))
    assert m["mirror"].type == "conductor" and m["mirror"].eta is None and m["mirror"].f0 == (1, 1, 1)
    assert m["mirror"].alpha == 0.0
    assert m["gold"].eta == CONDUCTORS["gold"][0] and m["gold"].k == CONDUCTORS["gold"][1]
    assert m["gold"].alpha == pytest.approx(0.25) and m["gold"].emission == (2.0, 2.0, 2.0)
    assert m["custom"].eta == (0.2, 0.9, 1.1) and m["custom"].k == (3.0, 3.0, 3.0) and m["custom"].alpha == 0.1
    assert m["schlick"].f0 == (0.9, 0.6, 0.3)
    assert m["glass"].type == "dielectric" and m["glass"].ior == 1.33 and m["glass"].alpha == pytest.approx(0.04)
    assert m["plastic"].albedo == (0.8, 0.1, 0.1) and m["plastic"].metallic == 0 and m["plastic"].alpha == pytest.approx(0.16)
    assert (m["defaults"].albedo, m["defaults"].metallic, m["defaults"].alpha, m["defaults"].ior) == ((1, 1, 1), 1, 1, 1.5)
    from pyopencl_rt.device import abi
    rec = m["schlick"].record()
    assert rec["type"] == abi.MATERIAL_CONDUCTOR and rec["flags"] & abi.MATERIAL_FLAG_CONDUCTOR_F0
    assert m["gold"].record()["flags"] & abi.MATERIAL_FLAG_CONDUCTOR_F0 == 0


@pytest.mark.parametrize("text, needle", [
    ('type = "conductor"\nmetal = "brass"\n', "unknown metal 'brass'"),
    ('type = "conductor"\nmetal = "gold"\nf0 = 1\n', "only one of"),
    ('type = "conductor"\neta = 1.5\n', "go together"),
    ('type = "conductor"\neta = 0\nk = 1\n', "'eta'"),
    ('type = "conductor"\neta = 1\nk = -1\n', "'k'"),
    ('type = "conductor"\nroughness = 1.5\n', "'roughness'"),
    ('type = "conductor"\nroughness = 0.1\nalpha = 0.1\n', "not both"),
    ('type = "conductor"\nalbedo = 0.5\n', "unknown key 'albedo'"),
    ('type = "dielectric"\nior = 0\n', "'ior'"),
    ('type = "dielectric"\nmetal = "gold"\n', "unknown key 'metal'"),
    ('type = "gltf"\nmetallic = 2\n', "'metallic'"),
    ('type = "gltf"\nbase_color = [1, 2, 0]\n', "'base_color'"),
    ('type = "diffuse"\nior = 1.5\n', "unknown key 'ior'"),
])
def test_material_errors(tmp_path, text, needle):
    msg = _error(tmp_path, "[materials.m]\n" + text + '[[shape]]\ntype = "sphere"\ncenter = [0,0,0]\nradius = 1\n')
    assert needle in msg and "[materials.m]" in msg and "\n" not in msg


def test_mtl_material_types(tmp_path):
    from pyopencl_rt.scene.loaders import parse_mtl

    (tmp_path / "x.mtl").write_text("""
newmtl glass
Kd 0 0 0
Ni 1.45
illum 7
newmtl fade
d 0.5
newmtl mirror
Kd 0 0 0
Ks 0.9 0.9 0.9
illum 3
newmtl plastic
Kd 0.5 0.1 0.1
Ks 0.5 0.5 0.5
Ns 98
illum 2
newmtl pbr
Kd 0.7 0.7 0.2
Pm 1
Pr 0.5
newmtl matte
Kd 0.3 0.3 0.3
Ks 0 0 0
illum 2
""")
    m = parse_mtl(tmp_path / "x.mtl")
    assert m["glass"].type == "dielectric" and m["glass"].ior == 1.45 and m["glass"].alpha == 0.0
    assert m["fade"].type == "dielectric" and m["fade"].ior == 1.5
    assert m["mirror"].type == "conductor" and m["mirror"].f0 == (0.9, 0.9, 0.9) and m["mirror"].eta is None
    assert m["plastic"].type == "gltf" and m["plastic"].metallic == 0.0
    assert m["plastic"].alpha == pytest.approx(math.sqrt(2 / 100))
    assert m["pbr"].type == "gltf" and m["pbr"].metallic == 1.0 and m["pbr"].alpha == pytest.approx(0.25)
    assert m["matte"].type == "diffuse"


@pytest.mark.parametrize("name", ["cornell-jensen.toml", "veach-mis.toml"])
def test_material_scenes_load(name):
    scene = load_scene(SCENES / name)
    types = {m.type for m in scene.materials}
    assert types >= ({"conductor", "dielectric"} if "jensen" in name else {"conductor"})
    scene.material_records()
