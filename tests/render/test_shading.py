"""Shading normals, normal and bump maps and vertex colours (cl/scene/shading.h): closed forms
(a coarse sphere mesh with vertex normals shades as the exact sphere, far better than flat; an
identity normal map and a constant bump map change nothing), the loaders' normals, attributes and
Mitsuba's conventions (face_normals, computed normals, transforms), and whole scenes against
Mitsuba 3 itself.  The lanes' bit-identity: tests/render/test_path_lanes.py."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.scene.loaders import load_scene
from pyopencl_rt.scene.loaders.assembly import angle_weighted_normals
from pyopencl_rt.scene.loaders.builder import SceneBuilder, quad_mesh, sphere_mesh
from pyopencl_rt.scene.model import MITSUBA_MAP, Camera, DirectionalLight, Material, PointLight, RenderSettings
from pyopencl_rt.scene.textures import texture_from_array

import harness

LIGHT = np.array([0.3, -0.4, -1.0])


@pytest.fixture
def shading_device(device, second_implementation, monkeypatch):
    """``device``; on a second CPU implementation (Intel's runtime beside PoCL) with the scenes'
    own kernels: the suite's every-feature 16-lane megakernel was built on Intel's compiler for
    these two tests alone (45.7 CPU s cold for both; their own two programs 27.1 s)."""
    from pyopencl_rt.render.settings import FEATURES_ENV

    if second_implementation:
        monkeypatch.setenv(FEATURES_ENV, "scene")
    return device


def translated(x, y=0.0, z=0.0):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


# ----------------------------------------------------------------------------- closed forms
def test_coarse_smooth_sphere_shades_as_the_exact_sphere(shading_device):
    """A sphere of 64 x 8 facets under a directional light, direct lighting only, next to our
    analytic sphere (one scene, one kernel; the camera visits each): where the camera ray meets
    the exact sphere more than 0.1 inside its outline (the facets' silhouette lies inside it), the
    exact radiance is albedo / pi E max(0, n . l).  The analytic sphere matches it to the pixel
    jitter (0.04% measured), the facets with vertex normals within 1.5% (0.84% measured: the
    interpolated normal is not the exact normal at the facet's point), the flat facets not (5.7%
    measured), and smooth beats flat fivefold."""
    b = SceneBuilder("spheres", "test")
    mat = Material("white", albedo=(0.8, 0.8, 0.8))
    v, f, uv = sphere_mesh(1.0, n_theta=8)
    b.add_mesh(v, f, mat, uvs=uv, matrix=translated(-10))
    b.add_mesh(v, f, mat, uvs=uv, normals=v[f], matrix=translated(10))
    b.add_sphere((0, 0, 0), 1.0, mat)
    b.add_light(DirectionalLight(direction=tuple(LIGHT), irradiance=(3.0, 3.0, 3.0)))
    b.camera = Camera(eye=(0, 0, 4), look_at=(0, 0, 0), fov=40)
    b.settings = RenderSettings(width=64, height=64, spp=8, max_depth=2)
    scene = b.build()
    assert scene.has_shading_normals() and not scene.face_normals()[: len(f)].any()  # the flat mesh has none
    W = 64
    yy, xx = (np.mgrid[0:W, 0:W] + 0.5) / W
    tan = math.tan(math.radians(20))
    d = np.stack([(2 * xx - 1) * tan, (1 - 2 * yy) * tan, -np.ones_like(xx)], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    o = np.array([0.0, 0.0, 4.0])
    b_ = d @ o
    disc = b_ ** 2 - (o @ o - 1)
    p = o + (-b_ - np.sqrt(np.maximum(disc, 0)))[..., None] * d
    core = (disc > 0) & (np.linalg.norm(np.cross(p, d), axis=-1) < 0.9)
    exact = 0.8 / math.pi * 3.0 * np.maximum(p @ (-LIGHT / np.linalg.norm(LIGHT)), 0)
    err = {}
    for name, x in (("analytic", 0.0), ("flat", -10.0), ("smooth", 10.0)):
        scene.camera = Camera(eye=(x, 0, 4), look_at=(x, 0, 0), fov=40)
        image = rt.render_full(scene, device=shading_device, seed=1).image[..., 1].astype(np.float64)
        err[name] = np.abs(image - exact)[core].mean() / exact[core].mean()
    assert err["analytic"] < 0.002, err
    assert err["smooth"] < 0.015, err
    assert err["flat"] > 0.04 and err["smooth"] < err["flat"] / 5, err


IDENTITY = texture_from_array(np.full((2, 2, 3), [0.5, 0.5, 1.0], np.float32), name="identity normal map")
CONSTANT = texture_from_array(np.full((4, 4), 0.3, np.float32), name="constant height")


def _map_scene(kind):
    """Diffuse, rough gold and rough glass balls (smooth normals) on a floor, each material with
    the map ``kind`` ("none", "normal": identity, "bump": constant) under Mitsuba's rules."""
    extra = {"none": {}, "normal": dict(normal_texture=IDENTITY, map_conventions=MITSUBA_MAP),
             "bump": dict(normal_texture=CONSTANT, bump_map=True, normal_scale=3.0, map_conventions=MITSUBA_MAP)}[kind]
    b = SceneBuilder("maps", "test")
    mats = [Material("white", albedo=(0.8, 0.7, 0.6), **extra),
            Material("gold", type="conductor", eta=(0.18, 0.42, 1.37), k=(3.42, 2.35, 1.77), alpha=0.1, **extra),
            Material("glass", type="dielectric", ior=1.5, alpha=0.05, **extra)]
    v, f, uv = sphere_mesh(0.5, n_theta=12)
    for i, m in enumerate(mats):
        b.add_mesh(v, f, m, uvs=uv, normals=(v / 0.5)[f], matrix=translated(1.1 * i - 1.1))
    qv, qf, quv = quad_mesh([(-3, -0.5, -3), (-3, -0.5, 3), (3, -0.5, 3), (3, -0.5, -3)])
    b.add_mesh(qv, qf, Material("floor", albedo=(0.5, 0.5, 0.5), **extra), uvs=quv)
    b.add_light(DirectionalLight(direction=(0.3, -0.6, -1.0), irradiance=(2.0, 2.0, 2.0)))
    b.add_light(PointLight(position=(0, 2, 2), intensity=(2, 2, 2)))
    b.camera = Camera(eye=(0, 0.8, 3.5), look_at=(0, 0, 0), fov=45)
    b.settings = RenderSettings(width=48, height=32, spp=16, max_depth=5)
    return b.build()


def test_identity_normal_map_and_constant_bump_map_change_nothing(shading_device):
    """Mitsuba's test_normalmap_identity idea: a normal map of (0.5, 0.5, 1) everywhere, and a
    bump map of a constant height, render what no map renders, to float rounding (the tilted
    normal is the shading normal renormalised; the shadowing term is 1 to rounding): measured, 80%
    of the pixels bit for bit and the others within 3e-5."""
    none = rt.render_full(_map_scene("none"), device=shading_device, seed=4).image.astype(np.float64)
    for kind in ("normal", "bump"):
        scene = _map_scene(kind)
        assert "HAS_NORMAL_MAPS" in scene.material_defines()
        image = rt.render_full(scene, device=shading_device, seed=4).image.astype(np.float64)
        diff = np.abs(image - none)
        assert diff.max() < 1e-3 * none.max(), (kind, diff.max())
        assert (diff.max(-1) == 0).mean() > 0.5, kind


# ----------------------------------------------------------------------------- against Mitsuba
def _write_obj(path, v, f, uv, normals):
    """An OBJ with a vt per corner (v up, as OBJ has it) and a vn per vertex."""
    lines = [f"v {x:.7f} {y:.7f} {z:.7f}" for x, y, z in v]
    lines += [f"vn {x:.7f} {y:.7f} {z:.7f}" for x, y, z in normals]
    lines += [f"vt {u:.7f} {1 - t:.7f}" for u, t in uv.reshape(-1, 2)]
    lines += ["f " + " ".join(f"{f[i, k] + 1}/{3 * i + k + 1}/{f[i, k] + 1}" for k in range(3)) for i in range(len(f))]
    path.write_text("\n".join(lines) + "\n")


def _write_ply_colors(path, v, f, rgb):
    """A binary PLY with float r, g, b per vertex and no normals (Mitsuba computes them, so do we)."""
    vert = np.zeros(len(v), [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("r", "<f4"), ("g", "<f4"), ("b", "<f4")])
    vert["x"], vert["y"], vert["z"] = v.T
    vert["r"], vert["g"], vert["b"] = rgb.T
    face = np.zeros(len(f), [("n", "u1"), ("i", "<i4", (3,))])
    face["n"], face["i"] = 3, f
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\n"
              + "".join(f"property float {c}\n" for c in "xyzrgb")
              + f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    path.write_bytes(header.encode() + vert.tobytes() + face.tobytes())


def _shape(filename, x, bsdf, kind="obj"):
    return (f'<shape type="{kind}"><string name="filename" value="{filename}"/>'
            f'<transform name="to_world"><rotate x="1" angle="-70"/><translate x="{x}"/></transform>{bsdf}</shape>')


def _mitsuba_scene(tmp_path, maps=True) -> str:
    """Three balls on a floor under a directional light and a constant sky: a smooth OBJ sphere
    with a normal map over a diffuse, one with a bump map, and a PLY sphere without normals whose
    diffuse reflectance is its vertex colours (mesh_attribute)."""
    from PIL import Image

    v, f, uv = sphere_mesh(0.5, n_theta=12)
    _write_obj(tmp_path / "ball.obj", v, f, uv, v / 0.5)
    rgb = 0.15 + 0.8 * (v / 0.5 * 0.5 + 0.5)
    _write_ply_colors(tmp_path / "colored.ply", v, f, rgb)
    y, x = (np.mgrid[0:64, 0:64] + 0.5) / 64
    n = np.stack([0.6 * np.sin(2 * np.pi * 2 * x), 0.6 * np.cos(2 * np.pi * 3 * y), np.ones_like(x)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    Image.fromarray(np.round((n * 0.5 + 0.5) * 255).astype(np.uint8), "RGB").save(tmp_path / "normal.png")
    h = 0.5 + 0.5 * np.sin(2 * np.pi * 3 * x) * np.sin(2 * np.pi * 2 * y)
    Image.fromarray(np.round(h * 255).astype(np.uint8), "L").save(tmp_path / "height.png")
    diffuse = '<bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.6, 0.5"/></bsdf>'
    normal = ('<bsdf type="normalmap"><texture name="normalmap" type="bitmap"><boolean name="raw" value="true"/>'
              f'<string name="filename" value="normal.png"/></texture>{diffuse}</bsdf>') if maps else diffuse
    bump = ('<bsdf type="bumpmap"><texture name="height" type="bitmap"><boolean name="raw" value="true"/>'
            '<string name="filename" value="height.png"/></texture><float name="scale" value="0.15"/>'
            f'{diffuse}</bsdf>') if maps else diffuse
    colors = ('<bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance">'
              '<string name="name" value="vertex_color"/></texture></bsdf>')
    body = f"""{harness.mitsuba_sensor("0, 0.9, 3.2", 50, 48, 32, max_depth=3, spp=64)}
<emitter type="directional"><vector name="direction" value="0.3, -0.6, -1"/><rgb name="irradiance" value="2.5"/></emitter>
<emitter type="constant"><rgb name="radiance" value="0.25"/></emitter>
{_shape("ball.obj", -1.1, normal)}
{_shape("ball.obj", 0.0, bump)}
{_shape("colored.ply", 1.1, colors, "ply")}
<shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/><scale value="4"/>
  <translate y="-0.5"/></transform><bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>
"""
    return harness.write_mitsuba_scene(tmp_path / ("maps.xml" if maps else "plain.xml"), body)




def test_smooth_normals_maps_and_vertex_colors_match_mitsuba(tmp_path):
    """A Mitsuba 3 XML scene of a smooth OBJ sphere under a normal map, one under a bump map and
    a PLY sphere whose reflectance is its vertex colours (its normals computed, by Mitsuba and by
    us), 48 x 32: rendered by Mitsuba (scalar_rgb, 8 batches of 64 spp: their spread is its
    variance) and by us (1024 spp); every 8 x 8 tile within 4.5 sigma and the image mean within 4
    (measured: 1.8 and 0.2).  The same scene without the maps, by Mitsuba, is many sigma away from
    the one with them in the mapped balls' tiles: the comparison sees each map."""
    mi = harness.mitsuba()
    path = _mitsuba_scene(tmp_path)
    theirs, their_var = harness.mitsuba_batches(mi, path)
    plain, plain_var = harness.mitsuba_batches(mi, _mitsuba_scene(tmp_path, maps=False))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # every element above is read without a word
        scene = load_scene(path)
    defines = scene.material_defines()
    assert {"HAS_SHADING_NORMALS", "HAS_NORMAL_MAPS", "HAS_VERTEX_COLORS"} <= set(defines)
    r = rt.render_full(scene, spp=1024, device="cpu", seed=5)
    ours, var = r.image.astype(np.float64), r.film.variance_of_mean()
    z = harness.tile_z(ours, var, theirs, their_var)  # the sky: 0 / 0
    mean_z = (ours.mean((0, 1)) - theirs.mean((0, 1))) / np.sqrt((var + their_var).sum((0, 1))) * ours[..., 0].size
    assert np.abs(z).max() < 4.5, np.round(z, 1)
    assert np.abs(mean_z).max() < 4.0, mean_z
    z_plain = harness.tile_z(plain, plain_var, theirs, their_var)
    # the normal-mapped ball fills tile columns 0-1, the bump-mapped one 2-3 (measured: 18 and 10)
    assert np.abs(z_plain[:, :2]).max() > 10 and np.abs(z_plain[:, 2:4]).max() > 6, np.round(z_plain, 1)


# ----------------------------------------------------------------------------- the loaders
def test_obj_vertex_normals_per_corner(tmp_path):
    """vn by index (also relative), made unit length; a triangle of a polygon that names no vn at
    one corner is shaded flat (0); an OBJ without vn has no normals (flat, not computed), nor has
    one whose vn are its faces' geometric normals (they would shade the same: nothing is compiled
    in for them)."""
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
                                    "vn 0 0 2\nvn 0 0.6 0.8\n"
                                    "f 1//1 2//2 3//-1\nf 1//1 3//1 4\nf 2 5 3\n")
    scene, warned = harness.load_warned(tmp_path / "m.obj")
    assert warned == []
    n = scene.face_normals()
    assert np.allclose(n[0], [[0, 0, 1], [0, 0.6, 0.8], [0, 0.6, 0.8]]) and not n[1:].any()
    assert scene.has_shading_normals()
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n")
    assert not harness.load_warned(tmp_path / "flat.obj")[0].has_shading_normals()
    (tmp_path / "planar.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n")
    planar = harness.load_warned(tmp_path / "planar.obj")[0]
    assert planar.normals is None and "HAS_SHADING_NORMALS" not in planar.material_defines()


def test_angle_weighted_normals_are_mitsubas():
    """The corner of a cube: three faces meeting at right angles weigh alike, (1, 1, 1) / sqrt 3;
    a vertex whose faces are all degenerate gets Mitsuba's (1, 0, 0)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [5, 5, 5]], np.float64)
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [4, 4, 4]])
    n = angle_weighted_normals(v, f)
    assert np.allclose(n[0, 0], -np.ones(3) / math.sqrt(3)) and np.allclose(n[3], [1, 0, 0])


def _mi_ply(tmp_path, v, f, extra_props=(), extra=None, normals=None):
    props = list("xyz") + (["nx", "ny", "nz"] if normals is not None else []) + list(extra_props)
    vert = np.zeros(len(v), [(c, "<f4") for c in props])
    for c, col in zip("xyz", v.T):
        vert[c] = col
    if normals is not None:
        for c, col in zip(("nx", "ny", "nz"), normals.T):
            vert[c] = col
    for c, col in (extra or {}).items():
        vert[c] = col
    face = np.zeros(len(f), [("n", "u1"), ("i", "<i4", (3,))])
    face["n"], face["i"] = 3, f
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\n"
              + "".join(f"property float {c}\n" for c in props)
              + f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
    (tmp_path / "m.ply").write_bytes(header.encode() + vert.tobytes() + face.tobytes())


def _xml(tmp_path, shape_body, name="s.xml"):
    path = tmp_path / name
    path.write_text(f'<scene version="3.0.0"><shape type="ply"><string name="filename" value="m.ply"/>{shape_body}'
                    "</shape></scene>")
    return path


def test_mitsuba_mesh_normals_as_mitsuba_has_them(tmp_path):
    """A PLY without normals under an uneven scale: Mitsuba computes its vertex normals in world
    space, and so do we (the same to 1e-5, read back from Mitsuba where it imports); with
    face_normals none; a PLY's own normals move with the inverse transpose, and flip_normals
    turns them around."""
    v, f, _ = sphere_mesh(1.0, n_theta=6)
    v = np.asarray(v, np.float32)
    _mi_ply(tmp_path, v, f)
    to_world = '<transform name="to_world"><scale x="2" y="1" z="0.5"/><rotate x="1" angle="30"/></transform>'
    scene, warned = harness.load_warned(_xml(tmp_path, to_world))
    assert warned == [] and scene.has_shading_normals()
    ours = scene.face_normals()
    assert np.allclose(ours, angle_weighted_normals(scene.vertices, scene.faces), atol=1e-6)
    flat, warned = harness.load_warned(_xml(tmp_path, to_world + '<boolean name="face_normals" value="true"/>', "flat.xml"))
    assert warned == [] and flat.normals is None and not flat.has_shading_normals()
    try:
        import mitsuba as mi
    except ImportError:
        mi = None
    if mi is not None:
        mi.set_variant("scalar_rgb")
        mesh = mi.load_file(str(tmp_path / "s.xml")).shapes()[0]
        faces = np.asarray(mesh.faces_buffer()).reshape(-1, 3)
        theirs = np.asarray(mesh.vertex_normals_buffer()).reshape(-1, 3)[faces]
        assert np.array_equal(faces, np.asarray(f)) and np.abs(ours - theirs).max() < 1e-5
    n = (v / np.linalg.norm(v, axis=1, keepdims=True))
    _mi_ply(tmp_path, v, f, normals=n)
    scaled, _ = harness.load_warned(_xml(tmp_path, '<transform name="to_world"><scale x="2" y="1" z="1"/></transform>', "n.xml"))
    want = n[f] * [0.5, 1, 1]
    assert np.allclose(scaled.face_normals(), want / np.linalg.norm(want, axis=-1, keepdims=True), atol=1e-6)
    flipped, _ = harness.load_warned(_xml(tmp_path, '<boolean name="flip_normals" value="true"/>', "flip.xml"))
    assert np.allclose(flipped.face_normals(), -n[f][:, ::-1], atol=1e-6)  # the corners reversed with the faces


def test_mesh_attribute_colors(tmp_path):
    """A PLY's vertex r, g, b as Mitsuba's "vertex_color" and a face's as "face_color", named by a
    diffuse reflectance's mesh_attribute (its scale multiplies); an attribute the shape lacks
    warns and renders 1."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    f = np.array([[0, 1, 2]])
    rgb = np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]], np.float32)
    _mi_ply(tmp_path, v, f, extra_props=("r", "g", "b"), extra=dict(zip("rgb", rgb.T)))

    def bsdf(attr, scale=1.0):
        return (f'<bsdf type="diffuse"><texture type="mesh_attribute" name="reflectance"><string name="name" '
                f'value="{attr}"/><float name="scale" value="{scale}"/></texture></bsdf>')

    scene, warned = harness.load_warned(_xml(tmp_path, bsdf("vertex_color", 0.5)))
    assert warned == [] and scene.materials[0].vertex_colors and scene.materials[0].albedo == (0.5, 0.5, 0.5)
    assert np.allclose(scene.face_colors(), rgb[None]) and "HAS_VERTEX_COLORS" in scene.material_defines()
    scene, warned = harness.load_warned(_xml(tmp_path, bsdf("face_color"), "missing.xml"))
    assert len(warned) == 1 and 'mesh attribute "face_color"' in warned[0]
    assert np.allclose(scene.face_colors(), 1.0)


def test_serialized_normals(tmp_path):
    """Mitsuba's serialized files: their vertex normals, as written."""
    from pyopencl_rt.scene.loaders.mitsuba_serialized import write_serialized

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    n = np.array([[0, 0, 1], [0, 0.6, 0.8], [0.6, 0, 0.8]], np.float32)
    write_serialized(tmp_path / "m.serialized", [(v, np.array([[0, 1, 2]]), None, n)])
    (tmp_path / "s.xml").write_text('<scene version="3.0.0"><shape type="serialized">'
                                    '<string name="filename" value="m.serialized"/></shape></scene>')
    scene, warned = harness.load_warned(tmp_path / "s.xml")
    assert warned == [] and np.allclose(scene.face_normals()[0], n)


def test_pbrt_normals(tmp_path):
    """pbrt-v4's "normal N" per vertex, moved with the inverse transpose and turned around by
    ReverseOrientation; a partial sphere's facets carry the exact sphere normal."""
    (tmp_path / "s.pbrt").write_text(
        'Scale -1 1 1\nLookAt 0 0 5  0 0 0  0 1 0\nCamera "perspective"\nWorldBegin\n'  # no mirroring
        'AttributeBegin\nScale 2 1 1\nShape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2]'
        ' "normal N" [1 0 1  1 0 1  1 0 1]\nAttributeEnd\n'
        'AttributeBegin\nReverseOrientation\nShape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] '
        '"integer indices" [0 1 2] "normal N" [0 0.6 0.8  0 0.6 0.8  0 0 1]\nAttributeEnd\n'
        'Shape "sphere" "float radius" 2 "float zmax" 1\n')
    scene, warned = harness.load_warned(tmp_path / "s.pbrt")
    assert warned == []
    n = scene.face_normals()
    assert np.allclose(n[0], np.array([0.5, 0, 1]) / math.hypot(0.5, 1), atol=1e-6)
    assert np.allclose(n[1], [[0, 0, -1], [0, -0.6, -0.8], [0, -0.6, -0.8]])  # corners reversed with the face
    centres = scene.vertices[scene.faces[2:]].astype(np.float64)
    assert np.allclose(n[2:], centres / np.linalg.norm(centres, axis=-1, keepdims=True), atol=1e-6)


def test_gltf_normals_colors_and_normal_texture(tmp_path):
    """glTF's NORMAL (through the node's inverse transpose), COLOR_0 (linear, multiplying the
    base colour: every material then reads the colours, white where a primitive has none) and
    normalTexture with its scale (linear)."""
    import base64
    import json
    from io import BytesIO

    from PIL import Image

    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    nrm = np.array([[0, 0, 1], [0, 1, 1], [1, 0, 1]], np.float32) / np.array([1, math.sqrt(2), math.sqrt(2)],
                                                                              np.float32)[:, None]
    col = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
    blob = pos.tobytes() + nrm.tobytes() + col.tobytes()
    png = BytesIO()
    Image.new("RGB", (2, 2), (128, 128, 255)).save(png, "PNG")
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "scale": [1, 2, 1]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "COLOR_0": 2}, "material": 0}]}],
        "materials": [{"normalTexture": {"index": 0, "scale": 0.5}}],
        "textures": [{"source": 0}],
        "images": [{"uri": "data:image/png;base64," + base64.b64encode(png.getvalue()).decode()}],
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(blob).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 36 * k, "byteLength": 36} for k in range(3)],
        "accessors": [{"bufferView": k, "componentType": 5126, "count": 3, "type": "VEC3"} for k in range(3)],
    }
    (tmp_path / "t.gltf").write_text(json.dumps(doc))
    scene, warned = harness.load_warned(tmp_path / "t.gltf")
    assert warned == []
    want = nrm * [1, 0.5, 1]
    assert np.allclose(scene.face_normals()[0], want / np.linalg.norm(want, axis=1, keepdims=True), atol=1e-6)
    assert np.allclose(scene.face_colors()[0], col)
    m = scene.materials[0]
    assert m.vertex_colors and m.normal_scale == 0.5 and not m.bump_map and m.map_conventions == ()
    assert np.allclose(m.normal_texture.texels[0, 0, :3], [128 / 255, 128 / 255, 1.0])  # linear, not sRGB-decoded


def test_bad_normals_and_colors_are_one_line_errors():
    """A Scene made in code: per-corner normals or colours of the wrong size, or colours that are
    negative or not finite, are refused by the scene check with one line (non-finite or zero
    normals are not an error: those faces are shaded flat)."""
    from pyopencl_rt.scene.validate import SceneValueError, check_scene

    v, f, _ = sphere_mesh(1.0, n_theta=4)
    scene = SceneBuilder("s", "test")
    scene.add_mesh(v, f, Material())
    scene.camera = Camera()
    scene = scene.build()
    for field, value, what in (("normals", np.zeros((len(scene.faces), 3)), "normals must be"),
                               ("colors", np.full((len(scene.faces), 3, 3), -1.0), "colors must be finite"),
                               ("colors", np.full((len(scene.faces), 3, 3), np.nan), "colors must be finite")):
        bad = scene.__class__(**{**scene.__dict__, field: value})
        with pytest.raises(SceneValueError, match=what):
            check_scene(bad)
    nan = scene.__class__(**{**scene.__dict__, "normals": np.full((len(scene.faces), 3, 3), np.nan)})
    check_scene(nan)
    assert not nan.has_shading_normals()
