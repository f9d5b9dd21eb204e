"""pbrt-v4 scenes (pyopencl_rt/scene/loaders/pbrt*.py): the tokenizer, every directive of the
supported subset against hand-computed values, the Cornell box against our TOML one (pbrt-v4 is
not pip-installable, so our TOML box, the same published data, stands in for the peer), warnings
and errors."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.scene.loaders import SceneError, load_scene
from pyopencl_rt.scene.pixel_filter import PixelFilter
from pyopencl_rt.scene.loaders.pbrt import tokenize
from pyopencl_rt.scene.loaders.pbrt_materials import equal_area_sphere_to_square, equal_area_square_to_sphere

from harness import load_warned as load
from scene_compare import render_pair_z, triangle_records, triangles_equal, write_exr_image, write_png_image
from pyopencl_rt.scene.shapes.sphere import of as sphere_of

SCENES = Path(__file__).resolve().parents[2] / "scenes"
CORNELL_PBRT = SCENES / "cornell-box.pbrt"
CORNELL_TOML = SCENES / "cornell-box.toml"
TRIANGLE = 'Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0]'


def write(tmp_path, text, name="s.pbrt") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def world(tmp_path, body, options=""):
    return load(write(tmp_path, f"{options}\nWorldBegin\n{body}\n"))


def line_of(path, text) -> int:
    return next(i for i, line in enumerate(Path(path).read_text().splitlines(), 1) if text in line)


def front_normals(scene):
    v = scene.vertices.astype(np.float64)[scene.faces]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def area(scene):
    v = scene.vertices.astype(np.float64)[scene.faces]
    return 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum()


# -- the tokenizer -----------------------------------------------------------------------------------

def test_tokenizer():
    text = 'Shape "trianglemesh" # a comment "with a string"\n  "point3 P" [0 -1.5e2\n .5]  "string s" "a \\"b\\""'
    toks = tokenize(text, "f.pbrt")
    assert [(t.kind, t.text, t.line) for t in toks] == [
        ("word", "Shape", 1), ("str", "trianglemesh", 1), ("str", "point3 P", 2), ("[", "[", 2),
        ("word", "0", 2), ("word", "-1.5e2", 2), ("word", ".5", 3), ("]", "]", 3), ("str", "string s", 3),
        ("str", 'a "b"', 3)]


# -- the Cornell box ---------------------------------------------------------------------------------

def test_cornell_box_pbrt_is_the_toml_cornell_box():
    scene, warned = load(CORNELL_PBRT)
    toml = load_scene(CORNELL_TOML)
    assert warned == [] and scene.format == "pbrt-v4"
    assert triangles_equal(triangle_records(scene), triangle_records(toml))
    assert [m.two_sided for m in scene.materials if m.is_emissive] == [False]
    assert scene.camera.eye == toml.camera.eye and np.isclose(scene.camera.vertical_fov(512, 512), toml.camera.fov)
    assert np.allclose(np.subtract(scene.camera.look_at, scene.camera.eye), [0, 0, 1])
    st = scene.settings
    assert (st.width, st.height, st.spp, st.max_depth) == (512, 512, 64, 8)


def test_cornell_box_pbrt_renders_as_the_toml_box():
    z = render_pair_z(load(CORNELL_PBRT)[0], load_scene(CORNELL_TOML))
    assert np.abs(z).max() < 4.5, z


def test_left_handed_lookat_is_mirrored(tmp_path):
    """Without the Scale -1 1 1, pbrt's left-handed camera sees the box mirrored (the red wall on
    the right): ours must render the mirror image of the TOML box."""
    path = write(tmp_path, CORNELL_PBRT.read_text().replace("Scale -1 1 1\n", ""))
    scene, warned = load(path)
    assert warned == []
    cam = scene.camera
    right = np.cross(np.subtract(cam.look_at, cam.eye), cam.up)  # our image's right
    red = [i for i, m in enumerate(scene.materials) if m.albedo[0] > 0.5 and m.albedo[1] < 0.1][0]
    red_x = scene.vertices[scene.faces[scene.face_materials == red]].reshape(-1, 3).mean(0) - cam.eye
    assert np.dot(red_x, right) > 0  # the red wall is on the right
    z = render_pair_z(scene, load_scene(CORNELL_TOML), flip_b=True)
    assert np.abs(z).max() < 4.5, z


# -- transforms and the graphics state --------------------------------------------------------------

def test_transforms_hand_computed(tmp_path):
    scene, warned = world(tmp_path, f"""
        AttributeBegin
          Translate 1 2 3
          Scale 2 2 2
          Rotate 90 0 0 1
          {TRIANGLE}
        AttributeEnd
        AttributeBegin
          Transform [0 1 0 0  -1 0 0 0  0 0 1 0  5 6 7 1]
          ConcatTransform [2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 1]
          {TRIANGLE}
          CoordinateSystem "mine"
        AttributeEnd
        {TRIANGLE}
        CoordSysTransform "mine"
        Identity
        Translate 0 0 9
        {TRIANGLE}""")
    assert warned == []
    v = scene.vertices.astype(np.float64).reshape(-1, 3, 3)
    # p' = T (S (R p)): (1, 0, 0) -> (0, 1, 0) -> (0, 2, 0) -> (1, 4, 3); (0, 1, 0) -> (-1, 0, 0) -> (-1, 2, 3)
    assert np.allclose(v[0], [[1, 2, 3], [1, 4, 3], [-1, 2, 3]])
    # Transform lists columns: x -> (0, 1, 0), y -> (-1, 0, 0), translation (5, 6, 7); then scale 2
    assert np.allclose(v[1], [[5, 6, 7], [5, 8, 7], [3, 6, 7]])
    assert np.allclose(v[2], [[0, 0, 0], [1, 0, 0], [0, 1, 0]])  # AttributeEnd restored the identity
    assert np.allclose(v[3], [[0, 0, 9], [1, 0, 9], [0, 1, 9]])


def test_reverse_orientation_and_mirrors_keep_the_front(tmp_path):
    scene, _ = world(tmp_path, f"""
        {TRIANGLE}
        AttributeBegin ReverseOrientation {TRIANGLE} AttributeEnd
        AttributeBegin Scale 1 1 -1 {TRIANGLE} AttributeEnd
        AttributeBegin Scale 1 1 -1 ReverseOrientation {TRIANGLE} AttributeEnd""")
    assert np.allclose(front_normals(scene)[:, 2], [1, -1, -1, 1])


def test_camera_film_sampler_integrator(tmp_path):
    def options(opts):
        return world(tmp_path, TRIANGLE, opts)

    s, w = options('LookAt 0 0 -5  0 0 0  0 1 0 Camera "perspective" "float fov" 50 '
                   'Film "rgb" "integer xresolution" 200 "integer yresolution" 100 "string filename" "x.exr" '
                   'Sampler "halton" "integer pixelsamples" 12 Integrator "path" "integer maxdepth" 3')
    assert w == []
    assert np.isclose(s.camera.vertical_fov(200, 100), 50)  # the shorter side is the height
    assert (s.settings.width, s.settings.height, s.settings.spp, s.settings.max_depth) == (200, 100, 12, 4)
    s, _ = options('Camera "perspective" "float fov" 50 "float lensradius" 0.1 "float focaldistance" 3 '
                   'Film "rgb" "integer xresolution" 100 "integer yresolution" 200')
    assert np.isclose(math.tan(math.radians(s.camera.vertical_fov(100, 200)) / 2), math.tan(math.radians(25)) * 2)
    # rendered landscape (pbrt's film edited, or --width / --height), the fov spans the height again
    assert np.isclose(s.camera.vertical_fov(200, 100), 50)
    assert (s.camera.aperture_radius, s.camera.focus_distance) == (0.1, 3)
    s, _ = options("")
    assert (s.settings.width, s.settings.height, s.settings.spp, s.settings.max_depth) == (1280, 720, 16, 6)
    s, w = options('PixelFilter "gaussian" Integrator "bdpt" Film "spectral"')
    assert [x.split(": ", 1)[1] for x in w] == ['Film "spectral": read as an "rgb" film',
                                                 'Integrator "bdpt": rendered with our path tracer (MIS)']
    s, w = options('Film "gbuffer" "integer xresolution" 20')  # its image is the rgb film's: silently
    assert w == [] and s.settings.width == 20
    assert s.settings.filter == PixelFilter("gaussian", (1.5, 1.5), sigma=0.5)


def test_pixel_filters(tmp_path):
    """pbrt-v4's PixelFilter types with their parameters and defaults (filters.cpp), the gaussian
    without a PixelFilter; a parameter of another type warns, a bad one is an error."""
    cases = {"": PixelFilter("gaussian", (1.5, 1.5), sigma=0.5),
             'PixelFilter "box"': PixelFilter("box", (0.5, 0.5)),
             'PixelFilter "box" "float xradius" 1 "float yradius" 2': PixelFilter("box", (1.0, 2.0)),
             'PixelFilter "gaussian" "float sigma" 0.3 "float xradius" 1': PixelFilter("gaussian", (1.0, 1.5),
                                                                                       sigma=0.3),
             'PixelFilter "mitchell" "float B" 0 "float C" 0.5': PixelFilter("mitchell", (2.0, 2.0), b=0.0, c=0.5),
             'PixelFilter "sinc"': PixelFilter("lanczos", (4.0, 4.0), tau=3.0),
             'PixelFilter "sinc" "float tau" 2 "float xradius" 2': PixelFilter("lanczos", (2.0, 4.0), tau=2.0),
             'PixelFilter "triangle"': PixelFilter("tent", (2.0, 2.0))}
    for text, expected in cases.items():
        s, w = world(tmp_path, TRIANGLE, text)
        assert w == [] and s.settings.filter == expected, text
    s, w = world(tmp_path, TRIANGLE, 'PixelFilter "box" "float sigma" 2')
    assert s.settings.filter == PixelFilter("box") and len(w) == 1 and '"float sigma" of PixelFilter' in w[0]
    s, w = world(tmp_path, TRIANGLE, 'PixelFilter "bspline"')
    assert s.settings.filter.type == "gaussian" and len(w) == 1 and 'PixelFilter "bspline": not supported' in w[0]
    with pytest.raises(SceneError, match=r's\.pbrt:\d+: PixelFilter "box": pixel filter radius x must be in'):
        world(tmp_path, TRIANGLE, 'PixelFilter "box" "float xradius" -1')


def test_orthographic_camera(tmp_path):
    """pbrt-v4's orthographic camera: its screen window (default [-a, a] x [-1, 1] for a frame
    a = width / height > 1) in camera space, scaled by the camera transform, centred on the eye;
    lens radius and focal distance as for the perspective camera; non-square pixels warn."""
    film = 'Film "rgb" "integer xresolution" 200 "integer yresolution" 100 '
    s, w = world(tmp_path, TRIANGLE, 'Scale -1 1 1 LookAt 0 0 -5  0 0 0  0 1 0 Camera "orthographic" ' + film)
    c = s.camera
    assert w == [] and c.projection == "orthographic" and np.isclose(c.extent, 2.0)
    assert np.allclose(c.eye, [0, 0, -5]) and np.allclose(np.subtract(c.look_at, c.eye), [0, 0, 1])
    # a window off centre: 4 wide along camera +x (the image's right: world -x here), 2 high
    s, w = world(tmp_path, TRIANGLE, 'Scale -1 1 1 LookAt 0 0 -5  0 0 0  0 1 0 Camera "orthographic" '
                                     '"float screenwindow" [-1 3 0 2] "float lensradius" 0.5 ' + film)
    c = s.camera
    assert w == [] and np.isclose(c.extent, 2.0) and np.allclose(c.eye, [-1, 1, -5])
    assert (c.aperture_radius, c.focus_distance) == (0.5, 1e6)
    # a scale before the camera scales camera space (camera-from-world): the window, [-1, 1] x [-2, 2]
    # for a frame taller than wide, is a third as large in the world
    s, w = world(tmp_path, TRIANGLE, 'Scale -3 3 1 LookAt 0 0 -5  0 0 0  0 1 0 Camera "orthographic" '
                                     'Film "rgb" "integer xresolution" 100 "integer yresolution" 200')
    assert w == [] and np.isclose(s.camera.extent, 4 / 3)
    s, w = world(tmp_path, TRIANGLE, 'Camera "orthographic" "float screenwindow" [-1 1 -1 1] ' + film)
    assert len(w) == 1 and "not square" in w[0] and np.isclose(s.camera.extent, 2.0)


# -- shapes ------------------------------------------------------------------------------------------

def test_shapes(tmp_path):
    from pyopencl_rt.bench.mitsuba_export import write_ply

    write_ply(tmp_path / "tri.ply", np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0]]), np.array([[0, 1, 2]]))
    s, w = world(tmp_path, 'Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 1 1 0 0 1 0] "integer indices" [0 1 2 0 2 3] '
                           '"point2 uv" [0 0 1 0 1 1 0 1]')
    assert np.isclose(area(s), 1) and np.allclose(s.uvs[0], [[0, 1], [1, 1], [1, 0]])  # (u, 1 - v)
    s, w = world(tmp_path, 'Shape "bilinearmesh" "point3 P" [0 0 0  2 0 0  0 3 0  2 3 0]')
    assert len(s.faces) == 2 and np.isclose(area(s), 6) and np.allclose(front_normals(s), [0, 0, 1])
    s, w = world(tmp_path, 'Shape "bilinearmesh" "point3 P" [0 0 0  1 0 0  0 1 0  1 1 1]')  # not flat
    assert len(s.faces) == 128 and np.allclose(s.vertices.max(0), [1, 1, 1]) and (front_normals(s)[:, 2] > 0).all()
    s, w = world(tmp_path, 'Shape "plymesh" "string filename" "tri.ply"')
    assert np.isclose(area(s), 2)
    s, w = world(tmp_path, 'Translate 1 2 3 Scale 2 2 2 Shape "sphere" "float radius" 1.5')
    assert np.allclose(sphere_of(s.shapes), [[1, 2, 3, 3]]) and len(s.faces) == 0
    s, w = world(tmp_path, 'Scale 1 1 2 Shape "sphere"')  # an ellipsoid: triangles
    assert len(sphere_of(s.shapes)) == 0 and np.allclose(s.vertices.max(0), [1, 1, 2], atol=1e-3)
    s, w = world(tmp_path, 'Shape "sphere" "float radius" 2 "float zmin" 0')  # a hemisphere
    assert np.isclose(area(s), 2 * math.pi * 4, rtol=0.01) and s.vertices[:, 2].min() >= -1e-6
    s, w = world(tmp_path, 'Shape "disk" "float radius" 2 "float height" 1')  # analytic (scene/shapes/disk.py)
    p = s.shapes["params"][0].astype(np.float64)
    assert len(s.faces) == 0 and np.isclose(p[27], 4 * math.pi) and np.allclose(p[24:27], [0, 0, 1])
    assert np.allclose(p[:12].reshape(3, 4)[:, 3], [0, 0, 1])
    textured = ('Texture "c" "spectrum" "checkerboard" "float uscale" 2 '
                'Material "diffuse" "texture reflectance" "c" ')
    for prefix in ("", "ReverseOrientation ", "Scale 1 1 -1 ", "ReverseOrientation Scale 1 -1 1 Rotate 30 1 0 0 "):
        disk = 'Shape "disk" "float radius" 2 "float height" 1'
        analytic = world(tmp_path, prefix + disk)[0].shapes["params"][0].astype(np.float64)
        mesh = world(tmp_path, textured + prefix + disk)[0]  # a textured disk: pbrt's triangles with its uv
        assert len(mesh.faces) >= 64 and np.isclose(area(mesh), analytic[27], rtol=1e-6), prefix
        assert np.allclose(front_normals(mesh), analytic[24:27], atol=1e-6), prefix  # the same front
        box_centre = (mesh.vertices.min(0) + mesh.vertices.max(0)) / 2
        assert np.allclose(box_centre, analytic[:12].reshape(3, 4)[:, 3], atol=1e-5), prefix
    s, w = world(tmp_path, 'Shape "disk" "float radius" 2 "float innerradius" 1')  # an annulus: triangles
    assert len(s.shapes) == 0 and np.isclose(area(s), 3 * math.pi)
    s, w = world(tmp_path, 'Shape "cylinder" "float radius" 0.5 "float zmin" 0 "float zmax" 2')  # analytic
    p = s.shapes["params"][0].astype(np.float64)
    assert len(s.faces) == 0 and np.isclose(p[25], 2 * math.pi * 0.5 * 2) and p[24] == 1  # outside its front
    for prefix in ("", "ReverseOrientation ", "Scale 1 1 -1 ", "ReverseOrientation Scale 1 -1 1 Rotate 30 1 0 0 "):
        tube = 'Shape "cylinder" "float radius" 0.5 "float zmin" -1 "float zmax" 2'
        analytic = world(tmp_path, prefix + tube)[0].shapes["params"][0].astype(np.float64)
        mesh = world(tmp_path, textured + prefix + tube)[0]  # a textured tube: pbrt's triangles
        m = analytic[:12].reshape(3, 4)
        v = mesh.vertices.astype(np.float64)[mesh.faces].mean(1)
        axis_point = m[:, 3] + np.outer(((v - m[:, 3]) @ m[:, 2]) / (m[:, 2] @ m[:, 2]), m[:, 2])
        outward = np.einsum("ij,ij->i", front_normals(mesh), v - axis_point) > 0
        assert outward.all() if analytic[24] > 0 else not outward.any(), prefix  # the same front
        assert np.isclose(area(mesh), analytic[25], rtol=1e-3), prefix
    s, w = world(tmp_path, 'Scale 1 2 1 Shape "cylinder"')  # an elliptic tube: triangles
    assert len(s.shapes) == 0 and len(s.faces) > 64
    s, w = world(tmp_path, 'Shape "loopsubdiv" "integer levels" 2 "point3 P" [0 0 0 1 0 0 0 1 0] '
                           '"integer indices" [0 1 2]\n' + TRIANGLE)
    assert w == [] and len(s.faces) == 16 + 1  # 4^2 triangles of the subdivided one
    with pytest.raises(SceneError, match=r':3: Shape "curve": shape type "curve" is not supported$'):
        world(tmp_path, 'Shape "curve" "point3 P" [0 0 0 1 0 0 2 0 0 3 0 0]\n' + TRIANGLE)


def test_object_instances(tmp_path):
    s, w = world(tmp_path, f"""
        ObjectBegin "tri" Translate 0 0 1 {TRIANGLE} ObjectEnd
        AttributeBegin Translate 10 0 0 ObjectInstance "tri" AttributeEnd
        AttributeBegin Translate 20 0 0 Scale 2 2 2 ObjectInstance "tri" AttributeEnd""")
    assert w == [] and len(s.faces) == 2
    assert np.allclose(s.vertices.astype(np.float64).reshape(-1, 3, 3)[:, 0], [[10, 0, 1], [20, 0, 2]])


# -- materials and textures ----------------------------------------------------------------------------

def test_materials(tmp_path):
    from pyopencl_rt.scene.loaders.mitsuba_metals import CONDUCTORS

    write_png_image(tmp_path / "t.png", np.full((2, 2, 3), 255, np.uint8))
    lines = [
        'Material "diffuse" "rgb reflectance" [0.1 0.2 0.3]',
        'Material "diffuse" "texture reflectance" "tex"',
        'Material "conductor"',
        'Material "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0.04',
        'Material "conductor" "rgb eta" [0.2 0.3 0.4] "rgb k" [3 3 3] "float uroughness" 0.25 "float vroughness" 0.25 '
        '"bool remaproughness" false',
        'Material "conductor" "rgb reflectance" [0.9 0.8 0.7]',
        'Material "dielectric" "float eta" 1.33 "float roughness" 0.01',
        'Material "dielectric" "spectrum eta" "glass-BK7"',
        'Material "conductor" "float uroughness" 0.04 "float vroughness" 0.25',
        'Material "coateddiffuse" "rgb reflectance" [0.6 0.5 0.4] "float roughness" 0.09 "float thickness" 0.1',
        'MakeNamedMaterial "thin" "string type" "thindielectric" NamedMaterial "thin"',
        'Material "interface"',
        'Material ""',  # pbrt-v4: "" and "none" are "interface"
        'Material "none"',
    ]
    body = 'Texture "tex" "spectrum" "imagemap" "string filename" "t.png"\n' + "\n".join(
        f"{line} Translate 2 0 0 {TRIANGLE}" for line in lines)
    s, w = world(tmp_path, body)
    mats = [s.materials[i] for i in s.face_materials]
    assert len(mats) == len(lines)  # the interface's triangle bounds media only (index-matched)
    assert [mi.null for mi in s.interfaces] == [True] and s.face_interfaces.tolist() == [-1] * (len(lines) - 3) + [0] * 3
    expect = [
        dict(type="diffuse", albedo=(0.1, 0.2, 0.3)),
        dict(type="diffuse", albedo=(1, 1, 1)),
        dict(type="conductor", eta=CONDUCTORS["Cu"][0], k=CONDUCTORS["Cu"][1], alpha=0.0),  # pbrt's default
        dict(type="conductor", eta=CONDUCTORS["Au"][0], alpha=pytest.approx(0.2)),  # sqrt(0.04)
        dict(type="conductor", eta=(0.2, 0.3, 0.4), k=(3, 3, 3), alpha=0.25),
        dict(type="conductor", eta=None, f0=(0.9, 0.8, 0.7)),
        dict(type="dielectric", ior=1.33, alpha=pytest.approx(0.1)),
        dict(type="dielectric", ior=1.5168),
        dict(type="conductor", alpha=pytest.approx(0.2), alpha_v=pytest.approx(0.5), is_anisotropic=True),
        dict(type="roughplastic", albedo=(0.6, 0.5, 0.4), ior=1.5, alpha=pytest.approx(0.3), distribution="ggx",
             nonlinear=True, specular_reflectance=(1, 1, 1)),
        dict(type="dielectric", ior=1.5, name="thin"),
        dict(type="diffuse", albedo=(0.0, 0.0, 0.0), emission=(0.0, 0.0, 0.0)),  # never scatters
    ] + [dict(name="pbrt-interface")] * 2
    for i, (mat, want) in enumerate(zip(mats, expect)):
        for key, value in want.items():
            assert getattr(mat, key) == value, (i, key, getattr(mat, key))
    assert mats[1].base_texture is not None and mats[1].base_texture.srgb
    assert [x.split(": ", 1)[1] for x in w] == [
        'Material "dielectric": glass-BK7 rendered without dispersion, at its d-line index 1.5168',
        'material "thin": approximated by a dielectric interface (a thin sheet refracts instead of passing light '
        'straight through)']
    for kind in ("hair", "measured", "subsurface"):  # refused, never replaced
        with pytest.raises(SceneError, match=f':3: Material "{kind}": material type "{kind}" is not supported$'):
            world(tmp_path, f'Material "{kind}" {TRIANGLE}')
    with pytest.raises(SceneError, match=r'material "skin": material type "subsurface" is not supported$'):
        world(tmp_path, f'MakeNamedMaterial "skin" "string type" "subsurface" NamedMaterial "skin" {TRIANGLE}')


def test_textures(tmp_path):
    write_png_image(tmp_path / "t.png", np.array([[[255, 0, 0]], [[0, 0, 255]]], np.uint8))  # red above blue
    s, w = world(tmp_path, """
        Texture "img" "spectrum" "imagemap" "string filename" "t.png" "string encoding" "linear" "float scale" 0.5
        Texture "check" "spectrum" "checkerboard" "float uscale" 2 "float vscale" 3 "float udelta" 0.3
            "float vdelta" -0.2 "rgb tex1" [1 1 1] "rgb tex2" [0 0 0]
        Texture "c" "spectrum" "constant" "rgb value" [0.2 0.3 0.4]
        Texture "moved" "spectrum" "imagemap" "string filename" "t.png" "float uscale" 4 "float vscale" 2
            "float udelta" 0.25 "float vdelta" 0.5 "string wrap" "clamp" "string filter" "point"
        Material "diffuse" "texture reflectance" "img" """ + TRIANGLE + """
        Material "diffuse" "texture reflectance" "check" """ + TRIANGLE + """
        Material "diffuse" "texture reflectance" "c" """ + TRIANGLE + """
        Material "diffuse" "texture reflectance" "moved" """ + TRIANGLE)
    assert w == []
    img, check, const, moved = (s.materials[i] for i in s.face_materials)
    assert not img.base_texture.srgb and np.allclose(img.base_texture.texels[:, 0, :3], [[0.5, 0, 0], [0, 0, 0.5]])
    from pyopencl_rt.scene.textures import lookup

    # pbrt-v4: (s, t) = (uscale u + udelta, vscale v + vdelta) of its uv, whose v is 1 - ours
    uv = np.random.default_rng(2).uniform(0, 1, (3000, 2))
    st = np.stack([2 * uv[:, 0] + 0.3, 3 * (1 - uv[:, 1]) - 0.2], -1)
    even = (np.floor(st[:, 0]) + np.floor(st[:, 1])) % 2 == 0  # tex1 where floor(s) + floor(t) is even
    t = check.base_texture
    got = lookup(t.texels, uv, t.wrap, t.filter, t.to_uv)[:, 0]
    assert np.mean(got != np.where(even, 1.0, 0.0)) < 1e-3
    # an image map is looked up at (s, 1 - t): our v' = 1 - t
    t = moved.base_texture
    assert (t.wrap, t.filter) == ("clamp", "nearest")
    st = np.stack([4 * uv[:, 0] + 0.25, 2 * (1 - uv[:, 1]) + 0.5], -1)
    want = lookup(t.texels, np.stack([st[:, 0], 1 - st[:, 1]], -1), "clamp", "nearest")
    assert np.allclose(lookup(t.texels, uv, t.wrap, t.filter, t.to_uv), want)
    assert const.albedo == (0.2, 0.3, 0.4) and const.base_texture is None


# -- lights ------------------------------------------------------------------------------------------

def test_lights(tmp_path):
    s, w = world(tmp_path, f"""
        AttributeBegin
          Translate 1 2 3
          LightSource "point" "rgb I" [1 2 3] "float scale" 2 "point3 from" [0 0 1]
          LightSource "distant" "point3 from" [0 0 0] "point3 to" [0 -1 0] "blackbody L" 6500
        AttributeEnd
        LightSource "infinite" "rgb L" [0.1 0.2 0.3]
        LightSource "spot"
        LightSource "goniometric"
        AttributeBegin
          AreaLightSource "diffuse" "rgb L" [4 5 6] "bool twosided" true "float scale" 0.5
          {TRIANGLE}
        AttributeEnd
        {TRIANGLE}""")
    point, distant, spot, goniometric = s.lights
    # pbrt-v4's goniometric light without a "filename" (warned) emits nothing
    assert type(goniometric).__name__ == "GoniometricLight" and goniometric.intensity == (0.0, 0.0, 0.0)
    assert point.position == (1, 2, 4) and point.intensity == (2, 4, 6)
    # pbrt-v4's defaults: from the origin along +z, coneangle 30, conedeltaangle 5, smoothstep
    assert (spot.position, spot.cutoff_angle, spot.beam(), spot.falloff) == ((0, 0, 0), 30, 25, "smoothstep")
    assert np.allclose(spot.frame()[:, 2], [0, 0, 1])
    assert np.allclose(distant.direction, [0, -1, 0])
    r, g, b = distant.irradiance  # 6500 K: nearly white, luminance 1
    assert np.isclose(0.2126 * r + 0.7152 * g + 0.0722 * b, 1, rtol=1e-3) and 0.9 < b / r < 1.3
    assert s.environment.radiance == (0.1, 0.2, 0.3) and s.environment.image is None
    lit, plain = (s.materials[i] for i in s.face_materials)
    assert lit.emission == (2, 2.5, 3) and lit.two_sided and lit.albedo == (0.5, 0.5, 0.5)
    assert not plain.is_emissive  # the area light ended with its attribute block
    assert [x.split(": ", 1)[1] for x in w] == ['LightSource "goniometric": no "filename": the light emits nothing, as in pbrt-v4']


def test_equal_area_octahedral_map():
    """pbrt-v4's equal-area square <-> sphere map: hand-computed points, the round trip, and
    equal areas (a uniform grid of the square gives directions uniform on the sphere)."""
    points = {(0.5, 0.5): (0, 0, 1), (0.0, 0.0): (0, 0, -1), (1.0, 0.5): (1, 0, 0), (0.5, 1.0): (0, 1, 0),
              (0.0, 0.5): (-1, 0, 0), (0.75, 0.5): (0.5 * math.sqrt(1.75), 0, 0.75)}
    for (u, v), d in points.items():
        assert np.allclose(equal_area_square_to_sphere(u, v), d, atol=1e-12), (u, v)
    n = 200
    u, v = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n)
    d = equal_area_square_to_sphere(u.ravel(), v.ravel())
    assert np.allclose(np.linalg.norm(d, axis=1), 1)
    assert np.allclose(np.stack(equal_area_sphere_to_square(d), 1), np.stack([u.ravel(), v.ravel()], 1), atol=1e-9)
    assert np.allclose(d.mean(0), 0, atol=1e-3) and np.allclose((d ** 2).mean(0), 1 / 3, atol=2e-3)


def test_infinite_light_map(tmp_path):
    """An octahedral map whose texels hold (their direction + 1) / 2, rotated 90 degrees about x:
    our resampled equirectangular texel looking along d holds (R^-1 d + 1) / 2."""
    n = 64
    u, v = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n)
    d = equal_area_square_to_sphere(u, v)
    write_exr_image(tmp_path / "sky.exr", (d + 1) / 2)
    s, w = world(tmp_path, f'AttributeBegin Rotate 90 1 0 0 LightSource "infinite" "string filename" "sky.exr" '
                           f'"float scale" 3 AttributeEnd {TRIANGLE}')
    env = s.environment
    assert w == [] and env.radiance == (3, 3, 3) and env.image.shape == (n, 2 * n, 3)
    h, wd = env.image.shape[:2]
    vv, uu = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(wd) + 0.5) / wd, indexing="ij")
    theta, phi = np.pi * vv, 2 * np.pi * uu
    ours = np.stack([-np.sin(theta) * np.sin(phi), np.cos(theta), np.sin(theta) * np.cos(phi)], -1)
    local = ours @ np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]).T  # R^-1 of Rotate 90 about x
    err = np.abs(env.image - (local + 1) / 2)
    assert np.median(err) < 0.01 and err.max() < 0.1


# -- files, warnings and errors --------------------------------------------------------------------------

def test_include_and_import(tmp_path):
    (tmp_path / "geo").mkdir()
    write(tmp_path, 'MakeNamedMaterial "m" "string type" "diffuse" "rgb reflectance" [0.2 0.2 0.2]\n',
          name="geo/materials.pbrt")
    write(tmp_path, f"NamedMaterial \"m\"\n{TRIANGLE}\n", name="geo/shapes.pbrt")
    s, w = world(tmp_path, 'Import "geo/materials.pbrt"\nInclude "geo/shapes.pbrt"')
    assert w == [] and s.materials[s.face_materials[0]].albedo == (0.2, 0.2, 0.2)


def test_unsupported_directives_and_parameters_warn(tmp_path):
    path = write(tmp_path, """Option "bool disablepixeljitter" true
ColorSpace "aces2065-1"
Camera "realistic"
WorldBegin
Attribute "shape" "float radius" 2
Material "diffuse" "float sigma" 20
Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0]
LightSource "goniometric"
TransformTimes 0 1
""")
    s, w = load(path)
    assert len(s.faces) == 1
    expect = [("Option", 'Option "bool disablepixeljitter": not supported; ignored'),
              ("ColorSpace", "ColorSpace 'aces2065-1': colours are read as linear sRGB"),
              ("Attribute", 'Attribute "shape": default parameters are not supported; ignored'),
              ("sigma", '"float sigma" of Material "diffuse": not supported; ignored'),
              ("goniometric", 'LightSource "goniometric": no "filename": the light emits nothing, as in pbrt-v4'),
              ("realistic", 'Camera "realistic": not supported; using a camera that frames the scene')]
    assert len(w) == len(expect), w
    for message, (needle, what) in zip(w, expect):
        assert message == f"{path}:{line_of(path, needle)}: {what}"
    assert s.warnings == w


MALFORMED = [
    ('Shape "trianglemesh" "point3 P" [0 0 0', r":1: \"point3 P\": a '\[' without its '\]'"),
    ('Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 x]', r":1: \"point3 P\": expected numbers, got 'x'"),
    ('Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1]', r":1: \"point3 P\": 8 numbers are not whole points"),
    ('Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0 1 1 0]',
     r":1: Shape \"trianglemesh\" needs \"integer indices\" \(it has 4 points\)"),
    ('Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 3]',
     r":1: \"integer indices\": an index outside \[0, 3\)"),
    ('Shape "trianglemesh" "point P" [0 0 0 1 0 0 0 1 0] "float P" 1', r':1: parameter "P" given twice'),
    ('Shape "trianglemesh" "point3" [0 0 0]', r':1: bad parameter declaration "point3" \(expected "type name"\)'),
    ('Shape "trianglemesh" "float3 P" [0 0 0]', r':1: unknown parameter type "float3"'),
    ('Shape "sphere" "float radius" "big"', r':1: "float radius" needs numbers'),
    ('Shape "sphere" "float radius" -1', r':1: Shape "sphere": radius must be > 0, got -1'),
    ('Shape "sphere" "string radius" "1"', r':1: "string radius": expected a float or integer parameter'),
    ('Shape "plymesh" "string filename" "none.ply"', r":1: Shape \"plymesh\": file 'none.ply' not found"),
    ("Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0\n]\nShepe", r":3: unknown directive 'Shepe'"),
    ('Translate 1 2', r":1: Translate needs 3 numbers, got 2"),
    ('Rotate 90 0 0 0', r":1: Rotate needs a non-zero axis"),
    ('Transform [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0]', r":1: Transform needs 16 numbers, got 15"),
    ('LookAt 0 0 0 0 0 0 0 1 0', r":1: LookAt: the eye and the point looked at are the same"),
    ('AttributeEnd', r":1: AttributeEnd without a matching AttributeBegin"),
    ('NamedMaterial "nothing"\n' + TRIANGLE, r":1: NamedMaterial: no material named 'nothing'"),
    ('Material "diffuse" "texture reflectance" "none"', r':1: "texture reflectance": no texture named "none"'),
    ('Include "missing.pbrt"', r":1: file 'missing.pbrt' not found"),
    ('Include "s.pbrt"', r":1: Include 's.pbrt': the file includes itself"),
    ('ObjectInstance "ghost"', r":1: ObjectInstance: no object named 'ghost'"),
    ('Shape "trianglemesh" "string s" "unterminated', r":1: unterminated string"),
    ('"point3 P" [0 0 0]', r":1: expected a directive \(such as Shape or AttributeBegin\), got \"point3 P\""),
    ('MakeNamedMaterial "m" "rgb reflectance" [1 1 1]', r':1: MakeNamedMaterial "m" needs "string type"'),
    ('Film "rgb" "integer xresolution" 0', r":1: Film: impossible resolution 0x720"),
    ('Integrator "path" "integer maxdepth" -1', r":1: Integrator: maxdepth must be >= 0, got -1"),
    ('Camera "perspective" "float fov" 180', r":1: Camera: fov must be between 0 and 180 degrees, got 180"),
]


@pytest.mark.parametrize("text,message", MALFORMED, ids=[f"case{i}" for i in range(len(MALFORMED))])
def test_malformed_input_is_one_clear_error(tmp_path, text, message):
    path = write(tmp_path, text + "\n" + TRIANGLE)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"{path}:"), msg
    assert re.search(message, msg), msg


def test_no_shapes_is_an_error(tmp_path):
    with pytest.raises(SceneError, match=r"s\.pbrt: the scene has no shapes that we can render"):
        load_scene(write(tmp_path, 'WorldBegin LightSource "infinite"'))


def test_shape_alpha_is_an_intersection_cutout(tmp_path):
    """pbrt-v4's shape "alpha": a float (1: opaque, the material unchanged) or a float texture
    (its first channel) makes the shape's material an alpha cut-out tested in the intersection
    (Material.cutout, stochastic: alpha_cutoff 0); shapes sharing a material and an alpha share
    the cut-out material."""
    write_png_image(tmp_path / "a.png", np.array([[[0, 10, 20], [255, 0, 0]]], np.uint8))
    s, w = world(tmp_path, f"""
        Texture "mask" "float" "imagemap" "string filename" "a.png" "string encoding" "linear" "string filter" "point"
        Material "diffuse"
        Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0] "float alpha" 1
        Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0] "float alpha" 0.25
        Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0] "float alpha" 0.25
        Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0] "texture alpha" "mask"
        """)
    assert w == []
    opaque, quarter, quarter2, textured = (s.materials[i] for i in s.face_materials)
    assert not opaque.cutout and quarter is quarter2
    assert quarter.cutout and quarter.opacity == 0.25 and quarter.alpha_cutoff == 0.0
    t = textured.scalar_textures["opacity"]
    assert textured.cutout and textured.opacity == 1.0 and t.filter == "nearest"
    assert np.allclose(t.texels[0, :, :3], [[0, 0, 0], [1, 1, 1]])  # channel 0, as pbrt's float textures
    assert s.material_defines().get("HAS_CUTOUTS")
