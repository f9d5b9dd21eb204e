"""Mitsuba 3 XML scenes (pyopencl_rt/scene/loaders/mitsuba_*.py): structure, values, transforms,
sensor, integrator, shapes, BSDFs, emitters, warnings and errors, checked against hand-computed
values and, where Mitsuba 3 imports (its scalar_rgb variant needs no LLVM), against Mitsuba itself."""
from __future__ import annotations

import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.device import abi
from pyopencl_rt.scene.loaders import SceneError, load_scene
from pyopencl_rt.scene.loaders.mitsuba_serialized import write_serialized
from pyopencl_rt.scene.pixel_filter import PixelFilter

from scene_compare import render_pair_z, triangle_records, triangles_equal, write_exr_image, write_png_image
from harness import load_warned as load, mitsuba
from pyopencl_rt.render.lights import environment_radiance
from pyopencl_rt.scene.shapes.sphere import of as sphere_of

SCENES = Path(__file__).resolve().parents[2] / "scenes"
CORNELL_XML = SCENES / "cornell-box.xml"
CORNELL_TOML = SCENES / "cornell-box.toml"


def write(tmp_path, body, name="s.xml", version="3.0.0") -> Path:
    path = tmp_path / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f'<scene version="{version}">\n{body}\n</scene>\n')
    return path


def line_of(path, text) -> int:
    """The line of the first occurrence of ``text`` in the file."""
    return next(i for i, line in enumerate(Path(path).read_text().splitlines(), 1) if text in line)


SPHERE = '<shape type="sphere"><float name="radius" value="0.5"/></shape>'


# -- the Cornell box -------------------------------------------------------------------------------

def test_cornell_box_xml_is_the_toml_cornell_box():
    xml, warned = load(CORNELL_XML)
    toml = load_scene(CORNELL_TOML)
    assert warned == [] and xml.warnings == [] and xml.format == "mitsuba-xml"
    light = [m.is_emissive for m in xml.materials]
    ours = triangle_records(xml, skip_emissive=True)
    assert triangles_equal(ours, triangle_records(toml, skip_emissive=True))
    # the light: a rectangle with the TOML quad's corners, area and downward front side
    lf = xml.faces[np.asarray(light)[xml.face_materials]]
    v = xml.vertices[lf].astype(np.float64)
    normals = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    assert np.allclose(normals / np.linalg.norm(normals, axis=1, keepdims=True), [0, -1, 0], atol=1e-6)
    assert np.isclose(0.5 * np.linalg.norm(normals, axis=1).sum(), 130 * 105, rtol=1e-6)
    assert np.allclose(v.reshape(-1, 3).min(0), [213, 548.7, 227], atol=1e-3)
    assert np.allclose(v.reshape(-1, 3).max(0), [343, 548.7, 332], atol=1e-3)
    lm = xml.materials[light.index(True)]
    assert lm.emission == (17, 12, 4) and lm.albedo == (0, 0, 0) and not lm.two_sided
    cam, tc = xml.camera, toml.camera
    assert cam.eye == tc.eye and np.isclose(cam.fov, tc.fov) and cam.up == tc.up
    assert np.allclose(np.subtract(cam.look_at, cam.eye), [0, 0, 1])
    st = xml.settings
    assert (st.width, st.height, st.spp, st.max_depth) == (512, 512, 64, 8)


def test_cornell_box_xml_renders_as_the_toml_box():
    xml, _ = load(CORNELL_XML)
    z = render_pair_z(xml, load_scene(CORNELL_TOML))
    assert np.abs(z).max() < 4.5, z


def _mitsuba_image(mi, path, width, height, batches, spp, **defines):
    scene = mi.load_file(str(path), resx=width, resy=height, spp=spp, **defines)
    images = np.stack([np.asarray(mi.render(scene, seed=i, spp=spp), np.float64) for i in range(batches)])
    return images.mean(0), images.var(0, ddof=1) / batches


def _z_against_mitsuba(ours_scene, mi_image, mi_var, width, height, spp, tile=8):
    r = rt.render_full(ours_scene, spp=spp, width=width, height=height, device="cpu", seed=5)
    ours, var = r.image.astype(np.float64), r.film.variance_of_mean()

    def tiles(a):
        return a.reshape(height // tile, tile, width // tile, tile, 3).sum(axis=(1, 3)) / tile ** 2

    z = (tiles(ours) - tiles(mi_image)) / np.sqrt((tiles(var) + tiles(mi_var)) / tile ** 2)
    whole = (ours.mean((0, 1)) - mi_image.mean((0, 1))) / np.sqrt((var + mi_var).sum((0, 1))) * width * height
    return z, whole, ours


@pytest.mark.parametrize("mirror", [False, True], ids=["as-published", "camera-mirrored"])
def test_cornell_box_matches_mitsuba(tmp_path, mirror):
    """The XML Cornell box rendered by Mitsuba 3 (scalar_rgb, 8 batches of 64 spp: their spread
    gives Mitsuba's variance) and by us (512 spp), 32 x 32, compared in 8 x 8 tiles: every tile and
    the image mean within the noise.  Mirrored: a <scale x="-1"/> before the lookat flips Mitsuba's
    image; we must flip ours the same way (the builder mirrors the scene)."""
    mi = mitsuba()
    path = CORNELL_XML
    if mirror:
        path = tmp_path / "cornell-box.xml"
        text = CORNELL_XML.read_text().replace('<lookat origin', '<scale x="-1"/>\n<lookat origin')
        path.write_text(text.replace('value="cornell-box/', f'value="{SCENES}/cornell-box/'))
    w = h = 32
    theirs, their_var = _mitsuba_image(mi, path, w, h, 8, 64)
    scene, warned = load(path, {"resx": w, "resy": h})
    assert warned == []
    z, whole, ours = _z_against_mitsuba(scene, theirs, their_var, w, h, 512)
    assert np.abs(z).max() < 4.5, f"tile z-scores {np.round(z, 2)}"
    assert np.abs(whole).max() < 4.0, f"image-mean z {whole}"
    red_left = ours[:, :8, 0].mean() > ours[:, -8:, 0].mean()
    assert red_left != mirror and (theirs[:, :8, 0].mean() > theirs[:, -8:, 0].mean()) != mirror


# -- structure ---------------------------------------------------------------------------------------

def test_defaults_substitution_and_defines(tmp_path):
    path = write(tmp_path, """
        <default name="spp" value="16"/>
        <default name="r" value="0.25"/>
        <sensor type="perspective">
            <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
            <film type="hdrfilm"><integer name="width" value="$w"/><integer name="height" value="24"/></film>
        </sensor>
        <shape type="sphere"><float name="radius" value="$r"/></shape>""")
    n = line_of(path, "$w")
    with pytest.raises(SceneError, match=rf"s\.xml:{n}: <integer name=\"width\">: undefined parameter \$w "):
        load_scene(path)
    scene, _ = load(path, {"w": 40})
    assert (scene.settings.spp, scene.settings.width, sphere_of(scene.shapes)[0, 3]) == (16, 40, 0.25)
    scene, _ = load(path, {"w": "8", "spp": "3", "r": "2"})  # a define beats the <default>
    assert (scene.settings.spp, scene.settings.width, sphere_of(scene.shapes)[0, 3]) == (3, 8, 2.0)


def test_include_ref_alias_and_nested_ids(tmp_path):
    (tmp_path / "parts").mkdir()
    write(tmp_path, '<bsdf type="diffuse" id="grey"><rgb name="reflectance" value="0.3 0.3 0.3"/></bsdf>',
          name="parts/materials.xml")
    path = write(tmp_path, """
        <include filename="parts/materials.xml"/>
        <alias id="grey" as="also-grey"/>
        <shape type="sphere">
            <bsdf type="twosided" id="red"><bsdf type="diffuse"><rgb name="reflectance" value="0.5,0.1,0.1"/></bsdf></bsdf>
        </shape>
        <shape type="sphere"><point name="center" x="3"/><ref id="red"/></shape>
        <shape type="sphere"><point name="center" x="6"/><ref id="also-grey"/></shape>
        <shape type="sphere"><point name="center" x="9"/><ref name="bsdf" id="grey"/></shape>""")
    scene, warned = load(path)
    assert warned == []
    albedo = [scene.materials[i].albedo for i in scene.shape_materials]
    assert albedo == [(0.5, 0.1, 0.1), (0.5, 0.1, 0.1), (0.3, 0.3, 0.3), (0.3, 0.3, 0.3)]
    assert scene.shape_materials[0] == scene.shape_materials[1]  # one material, referenced twice
    assert scene.materials[scene.shape_materials[0]].name == "red"


# -- files: Mitsuba's FileResolver -------------------------------------------------------------------

def _obj(path: Path, triangles: int) -> Path:
    """An OBJ file of ``triangles`` triangles (which file was read shows in the count)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [f"v {i} 0 0\nv {i} 1 0\nv {i} 0 1\nf {3 * i + 1} {3 * i + 2} {3 * i + 3}" for i in range(triangles)]
    path.write_text("\n".join(lines) + "\n")
    return path


def _mesh_shape(fname: str) -> str:
    return f'<shape type="obj"><string name="filename" value="{fname}"/></shape>'


def _triangles_read(path, mi=None) -> list:
    """The triangle count of each obj shape, as we load the file and (given ``mi``) as Mitsuba does."""
    if mi is None:
        return [len(load(path)[0].faces)]
    scene = mi.load_file(str(path))
    return [sum(s.face_count() for s in scene.shapes() if s.is_mesh())]


def test_included_files_name_files_through_the_main_files_search_path(tmp_path, monkeypatch):
    """Mitsuba resolves a file that a plugin names after the whole document is read, through the
    main file's search path, whichever file the plugin is written in: B/inc.xml's "meshes/x.obj"
    is A/meshes/x.obj, not A/B/meshes/x.obj.  An <include> inside B/inc.xml looks beside B/inc.xml
    first."""
    a = tmp_path / "A"
    _obj(a / "meshes" / "x.obj", 1)
    write(a, _mesh_shape("meshes/x.obj") + '<include filename="inner.xml"/>', name="B/inc.xml")
    write(a, SPHERE, name="B/inner.xml")  # beside the including file only
    main = write(a, '<include filename="B/inc.xml"/>', name="main.xml")
    monkeypatch.chdir(tmp_path)  # nothing to find in the current directory
    scene, warned = load(main)
    assert (len(scene.faces), len(sphere_of(scene.shapes)), warned) == (1, 1, [])
    _obj(a / "B" / "meshes" / "x.obj", 2)  # beside the included file: not looked at
    assert _triangles_read(main) == [1]
    try:
        import mitsuba as mi
    except ImportError:
        return
    mi.set_variant("scalar_rgb")
    assert _triangles_read(main, mi) == [1]


def test_path_folders_come_first_latest_first(tmp_path, monkeypatch):
    """<path value> puts its folder in front of the search path (before the main file's folder),
    the latest first; a relative value is looked for beside the file, then through the search
    path; an included file's <path> serves only that file's includes and spectrum files."""
    a = tmp_path / "A"
    for folder, n in (("", 1), ("p1", 2), ("p2", 3), ("p1/sub", 4), ("inc/only", 5)):
        _obj(a / folder / "m.obj", n)
    monkeypatch.chdir(tmp_path)
    cases = {"<path value='p1'/>": 2, "<path value='p1'/><path value='p2'/>": 3,
             "<path value='p2'/><path value='p1'/>": 2, "": 1,
             "<path value='p1'/><path value='sub'/>": 4,  # A/sub is not there: p1/sub, through the search path
             f"<path value='{a / 'p2'}'/>": 3}
    try:
        import mitsuba as mi
        mi.set_variant("scalar_rgb")
    except ImportError:
        mi = None
    for i, (paths, n) in enumerate(cases.items()):
        main = write(a, paths + _mesh_shape("m.obj"), name=f"main{i}.xml")
        assert _triangles_read(main) == [n], paths
        if mi is not None:
            assert _triangles_read(main, mi) == [n], paths
    # a <path> at the end of the main file serves every plugin (they are made after parsing)
    assert _triangles_read(write(a, _mesh_shape("m.obj") + "<path value='p2'/>", name="late.xml")) == [3]
    # an included file's <path>: its nested includes see it, the plugins do not
    write(a, "<path value='only'/><include filename='deep.xml'/>", name="inc/inc.xml")
    write(a / "inc" / "only", SPHERE, name="deep.xml")
    main = write(a, "<include filename='inc/inc.xml'/>", name="incmain.xml")
    scene, _ = load(main)
    assert len(sphere_of(scene.shapes)) == 1
    write(a, "<path value='only'/>" + _mesh_shape("m.obj"), name="inc/inc2.xml")
    main2 = write(a, "<include filename='inc/inc2.xml'/>", name="incmain2.xml")
    assert _triangles_read(main2) == [1]
    # ... and so do its spectrum files (read while parsing)
    (a / "inc" / "only" / "grey.spd").write_text("360 0.3\n830 0.3\n")
    write(a, "<path value='only'/><shape type='sphere'><bsdf type='diffuse'>"
             "<spectrum name='reflectance' filename='grey.spd'/></bsdf></shape>", name="inc/inc3.xml")
    main3 = write(a, "<include filename='inc/inc3.xml'/>", name="incmain3.xml")
    assert load(main3)[0].materials[0].albedo == pytest.approx((0.3,) * 3, rel=2e-3)
    if mi is not None:
        assert len([s for s in mi.load_file(str(main)).shapes() if not s.is_mesh()]) == 1
        assert _triangles_read(main2, mi) == [1]
        params = mi.traverse(mi.load_file(str(main3)))
        theirs = [np.ravel(params[k]) for k in params.keys() if k.endswith("bsdf.reflectance.value")]
        assert np.allclose(theirs, [load(main3)[0].materials[0].albedo], rtol=1e-4)


def test_missing_and_absolute_file_names(tmp_path, monkeypatch):
    a = tmp_path / "A"
    absolute = _obj(tmp_path / "elsewhere" / "abs.obj", 2)
    monkeypatch.chdir(tmp_path)
    assert _triangles_read(write(a, _mesh_shape(str(absolute)))) == [2]
    for body, message in [
        (_mesh_shape("meshes/none.obj"),
         rf"s\.xml:2: <shape type=\"obj\">: file 'meshes/none\.obj' not found \(searched {a}/, {tmp_path}/\)$"),
        ("<path value='p'/>" + _mesh_shape("none.obj"),
         rf"<path value=\"p\">: folder not found \(looked for {a}/p\)$"),
        (_mesh_shape(str(tmp_path / "none.obj")), rf"file '{tmp_path}/none\.obj' not found$"),
        ("<include filename='none.xml'/>", rf"<include>: file 'none\.xml' not found \(searched {a}/, {a}/, "),
    ]:
        with pytest.raises(SceneError) as info:
            load_scene(write(a, body))
        text = str(info.value)
        assert "\n" not in text and re.search(message, text), text


def test_values(tmp_path):
    path = write(tmp_path, """
        <sensor type="perspective">
            <float name="fov" value="30"/>
            <sampler type="independent"><integer name="sample_count" value="7"/></sampler>
            <film type="hdrfilm"><integer name="width" value="20"/><integer name="height" value="10"/></film>
        </sensor>
        <shape type="sphere"><point name="center" value="1, 2, 3"/><float name="radius" value="2"/>
            <boolean name="flip_normals" value="false"/>
            <bsdf type="diffuse"><spectrum name="reflectance" value="0.25"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="-1" z="4"/>
            <bsdf type="diffuse"><rgb name="reflectance" value="0.1 0.2 0.3"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="5"/>
            <bsdf type="diffuse"><spectrum name="reflectance" value="400:0.2, 500:0.4, 600:0.6"/></bsdf></shape>
        <emitter type="directional"><vector name="direction" value="0 -2 0"/><rgb name="irradiance" value="2"/></emitter>
        <emitter type="point"><point name="position" value="0,5,0"/></emitter>""")
    scene, warned = load(path)
    assert np.allclose(sphere_of(scene.shapes), [[1, 2, 3, 2], [-1, 0, 4, 1], [5, 0, 0, 1]])
    # the sampled spectrum: Mitsuba 3.9.1 scalar_rgb's reflectance (no light above 600 nm: no red)
    assert [scene.materials[i].albedo for i in scene.shape_materials] == [
        (0.25, 0.25, 0.25), (0.1, 0.2, 0.3), pytest.approx((0.134932, 0.511488, 0.288456), rel=1e-5)]
    assert scene.settings.spp == 7 and (scene.settings.width, scene.settings.height) == (20, 10)
    d, p = scene.lights
    assert d.direction == (0, -1, 0) and d.irradiance == (2, 2, 2) and p.position == (0, 5, 0)
    assert not warned
    # a parameter the plugin does not take is refused, as Mitsuba refuses an unreferenced property
    path = write(tmp_path, """
        <emitter type="point"><string name="id_unused" value="x"/><point name="position" value="0,5,0"/></emitter>""")
    with pytest.raises(SceneError, match=rf's\.xml:{line_of(path, "id_unused")}: <string name="id_unused"> of '
                                         r'<emitter type="point">: parameter not supported$'):
        load(path)


def test_transforms_compose_in_document_order(tmp_path):
    """A unit rectangle's corner (1, 1, 0) through scale x 2, rotate 90 about z, translate (0, 0, 5):
    (2, 1, 0) -> (-1, 2, 0) -> (-1, 2, 5); and a matrix (rows) after them."""
    path = write(tmp_path, """
        <shape type="rectangle"><transform name="to_world">
            <scale x="2"/><rotate z="1" angle="90"/><translate value="0 0 5"/>
        </transform></shape>
        <shape type="rectangle"><transform name="to_world">
            <scale value="3"/>
            <matrix value="0 -1 0 10  1 0 0 20  0 0 1 30  0 0 0 1"/>
            <matrix value="1 0 0  0 1 0  0 0 -1"/>
        </transform></shape>""")
    scene, _ = load(path)
    v = scene.vertices.astype(np.float64)
    first, second = v[:4], v[4:]
    assert np.allclose(sorted(map(tuple, np.round(first, 6))), sorted([(1, -2, 5), (1, 2, 5), (-1, 2, 5), (-1, -2, 5)]))
    # corner (1, 1, 0): scale 3 -> (3, 3, 0); matrix -> (-3 + 10, 3 + 20, 30); 3x3 flips z -> (7, 23, -30)
    assert any(np.allclose(p, [7, 23, -30]) for p in second)
    # the mirror (det < 0) keeps the rectangle's front on the transformed +z side: -z
    f = scene.faces[2]
    n = np.cross(v[f[1]] - v[f[0]], v[f[2]] - v[f[0]])
    assert n[2] < 0 and abs(n[0]) + abs(n[1]) < 1e-6


def test_lookat_and_fov_axes(tmp_path):
    def camera(attrs, film="100 50"):
        w, h = film.split()
        return load(write(tmp_path, f"""
            <sensor type="perspective">{attrs}
                <transform name="to_world"><lookat origin="1, 2, 3" target="1, 2, 13" up="0, 1, 0"/></transform>
                <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/></film>
            </sensor>{SPHERE}"""))[0].camera

    def vfov(cam, film="100 50"):  # the vertical field of view at the film's size
        return cam.vertical_fov(*map(int, film.split()))

    cam = camera('<float name="fov" value="90"/>')  # fov_axis x (Mitsuba's default)
    assert cam.eye == (1, 2, 3) and np.allclose(np.subtract(cam.look_at, cam.eye), [0, 0, 1])
    assert np.isclose(vfov(cam), 2 * math.degrees(math.atan(0.5)))  # tan(v/2) = tan(45) * 50 / 100
    # rendered at another size, the horizontal field of view stays the file's 90 degrees
    assert np.isclose(vfov(cam, "50 100"), 2 * math.degrees(math.atan(2.0)))
    assert np.isclose(vfov(camera('<float name="fov" value="40"/><string name="fov_axis" value="y"/>')), 40)
    assert np.isclose(vfov(camera('<float name="fov" value="40"/><string name="fov_axis" value="smaller"/>')), 40)
    assert np.isclose(vfov(camera('<float name="fov" value="40"/><string name="fov_axis" value="larger"/>',
                                  "50 100"), "50 100"), 40)
    diag = vfov(camera('<float name="fov" value="60"/><string name="fov_axis" value="diagonal"/>'))
    assert np.isclose(math.tan(math.radians(diag) / 2), math.tan(math.radians(30)) * 50 / math.hypot(100, 50))
    lens = vfov(camera('<string name="focal_length" value="35mm"/>'))  # 35 mm film diagonal
    assert np.isclose(math.tan(math.radians(lens) / 2), math.hypot(36, 24) / 70 * 50 / math.hypot(100, 50))
    thin = load(write(tmp_path, """<sensor type="thinlens"><float name="aperture_radius" value="0.2"/>
        <float name="focus_distance" value="7"/></sensor>""" + SPHERE))[0].camera
    assert (thin.aperture_radius, thin.focus_distance) == (0.2, 7.0)


def test_fov_conversion_agrees_with_mitsuba():
    from pyopencl_rt.scene.model import vertical_fov

    mi = mitsuba()
    for axis in ("x", "y", "diagonal", "smaller", "larger"):
        for w, h in ((200, 100), (90, 160)):
            s = mi.load_dict({"type": "perspective", "fov": 40.0, "fov_axis": axis,
                              "film": {"type": "hdrfilm", "width": w, "height": h}})
            x_fov = math.radians(float(np.ravel(mi.traverse(s)["x_fov"])[0]))
            ours = math.radians(vertical_fov(40.0, axis, w, h))
            assert np.isclose(math.tan(ours / 2) * w / h, math.tan(x_fov / 2), rtol=1e-5), (axis, w, h)


def test_integrators_film_filter_sampler(tmp_path):
    def settings(body):
        return load(write(tmp_path, body + SPHERE))

    (s, w) = settings('<integrator type="path"><integer name="max_depth" value="5"/>'
                      '<integer name="rr_depth" value="2"/></integrator>')
    assert (s.settings.max_depth, s.settings.rr_depth, w) == (5, 2, [])
    s, w = settings('<integrator type="direct"/>')
    assert s.settings.max_depth == 2 and w == []
    s, w = settings("")
    assert (s.settings.max_depth, s.settings.rr_depth, s.settings.width, s.settings.spp) == (-1, 5, 768, 4)
    s, w = settings('<integrator type="volpath"><integer name="max_depth" value="4"/></integrator>')
    assert s.settings.max_depth == 4 and w == [] and not s.settings.spectral_mis  # media: tests/scene/test_media_scene.py
    s, w = settings('<integrator type="prb"><integer name="max_depth" value="4"/></integrator>')
    assert s.settings.max_depth == 4 and w == []  # path replay's primal image is the path tracer's
    s, w = settings('<sensor type="perspective"><film type="hdrfilm"><rfilter type="gaussian"/></film></sensor>')
    assert w == [] and s.settings.filter == PixelFilter("gaussian", (2.0, 2.0), sigma=0.5)
    s, w = settings('<sensor type="perspective"><film type="hdrfilm"><rfilter type="box"/></film></sensor>')
    assert w == [] and s.settings.filter == PixelFilter("box")


def test_rfilters(tmp_path):
    """Mitsuba 3's reconstruction filters with their parameters and fixed radii (src/rfilters/),
    and its default (a gaussian of stddev 0.5, cut at 4 stddev) without an rfilter or a film."""
    def rfilter(inner):
        scene, w = load(write(tmp_path, f'<sensor type="perspective"><film type="hdrfilm">{inner}</film></sensor>'
                                        + SPHERE))
        return scene.settings.filter, w

    cases = {"": PixelFilter("gaussian", (2.0, 2.0), sigma=0.5),
             '<rfilter type="gaussian"><float name="stddev" value="0.25"/></rfilter>':
                 PixelFilter("gaussian", (1.0, 1.0), sigma=0.25),
             '<rfilter type="tent"/>': PixelFilter("tent", (1.0, 1.0)),
             '<rfilter type="tent"><float name="radius" value="1.5"/></rfilter>': PixelFilter("tent", (1.5, 1.5)),
             '<rfilter type="mitchell"/>': PixelFilter("mitchell", (2.0, 2.0)),
             '<rfilter type="mitchell"><float name="B" value="0.5"/><float name="C" value="0.25"/></rfilter>':
                 PixelFilter("mitchell", (2.0, 2.0), b=0.5, c=0.25),
             '<rfilter type="catmullrom"/>': PixelFilter("mitchell", (2.0, 2.0), b=0.0, c=0.5),
             '<rfilter type="lanczos"/>': PixelFilter("lanczos", (3.0, 3.0), tau=3.0),
             '<rfilter type="lanczos"><integer name="lobes" value="2"/></rfilter>':
                 PixelFilter("lanczos", (2.0, 2.0), tau=2.0)}
    for inner, expected in cases.items():
        assert rfilter(inner) == (expected, []), inner
    assert load(write(tmp_path, SPHERE))[0].settings.filter == PixelFilter("gaussian", (2.0, 2.0), sigma=0.5)


def _film(inner: str) -> str:
    return f'<sensor type="perspective"><film type="hdrfilm">{inner}</film></sensor>'


# integrator, film and rfilter settings Mitsuba renders otherwise than we could: one line each
REFUSED_SETTINGS = [
    ('<integrator type="bdpt"><integer name="max_depth" value="4"/></integrator>',
     r'<integrator type="bdpt">: integrator type "bdpt" is not supported'),
    ('<integrator type="path"><boolean name="hide_emitters" value="true"/></integrator>',
     r'<integrator type="path">: hide_emitters true is not supported'),
    ('<sensor type="perspective"><film type="specfilm"/></sensor>',
     r'<film type="specfilm">: film type "specfilm" is not supported'),
    (_film('<integer name="crop_width" value="2"/>'),
     r'<integer name="crop_width"> of <film type="hdrfilm">: parameter not'),
    (_film('<rfilter type="box"><float name="stddev" value="1"/></rfilter>'),
     r'<float name="stddev"> of <rfilter type="box">: parameter not supported'),
    (_film('<rfilter type="bspline"/>'), r'<rfilter type="bspline">: rfilter type "bspline" is not supported'),
    (_film('<rfilter type="tent"><float name="radius" value="40"/></rfilter>'),
     r'<rfilter type="tent">: pixel filter radius x must be in'),
]


@pytest.mark.parametrize("body, message", REFUSED_SETTINGS)
def test_settings_we_cannot_render_are_refused(tmp_path, body, message):
    with pytest.raises(SceneError, match=message):
        load(write(tmp_path, body + SPHERE))


def test_emitter_without_bsdf_is_black_and_checkerboard_to_uv(tmp_path):
    """Mitsuba gives a shape with an area emitter and no BSDF a diffuse of reflectance 0 (one
    without an emitter 0.5); a checkerboard is a 2 x 2 image looked up nearest and repeated
    through its to_uv (the lookup's affine map, rows 0, 1 and columns 0, 1, 3 of the 4 x 4): color0
    where the fractional parts of the transformed (u, v) lie on the same side of 1/2."""
    from pyopencl_rt.scene.textures import lookup

    scene, w = load(write(tmp_path, '<shape type="sphere"><emitter type="area"/></shape>'
                                    '<shape type="sphere"><point name="center" x="3"/></shape>'))
    assert w == [] and [scene.materials[i].albedo for i in scene.shape_materials] == [(0, 0, 0), (0.5, 0.5, 0.5)]

    def checker(to_uv):
        scene, w = load(write(tmp_path, '<shape type="rectangle"><bsdf type="diffuse"><texture name="reflectance" '
                                        f'type="checkerboard"><transform name="to_uv">{to_uv}</transform></texture>'
                                        '</bsdf></shape>'))
        return scene.materials[0].base_texture, w

    rng = np.random.default_rng(3)
    uv = rng.uniform(0, 1, (4000, 2))
    for to_uv, m in (('<scale x="5" y="3"/>', np.array([[5, 0, 0], [0, 3, 0]])),
                     ('<scale x="2.5" y="2"/><translate x="0.1" y="-0.3"/>', np.array([[2.5, 0, 0.1], [0, 2, -0.3]])),
                     ('<rotate z="1" angle="30"/><scale x="4" y="4"/>',
                      4 * np.array([[math.cos(math.pi / 6), -math.sin(math.pi / 6), 0],
                                    [math.sin(math.pi / 6), math.cos(math.pi / 6), 0]]))):
        tex, w = checker(to_uv)
        assert w == [] and (tex.width, tex.height, tex.filter, tex.wrap) == (2, 2, "nearest", "repeat")
        assert np.allclose(tex.to_uv, m.reshape(-1), atol=1e-6)
        t = uv @ m[:, :2].T + m[:, 2]
        odd = ((t[:, 0] % 1) > 0.5) ^ ((t[:, 1] % 1) > 0.5)
        # color0 0.4, color1 0.2 (Mitsuba's defaults), linear
        got = lookup(tex.texels, uv, tex.wrap, tex.filter, tex.to_uv)[:, 0]
        assert np.mean(np.abs(got - np.where(odd, 0.2, 0.4)) > 1e-6) < 1e-3


def test_orthographic_sensor(tmp_path):
    """Mitsuba's orthographic sensor: a film 2 wide and 2 / aspect high (local x, y), scaled by
    to_world, at near_clip along the viewing direction; image right on local -x as for the
    perspective sensor (a <scale x="-1"/> mirrors the scene); uneven scales warn."""
    def sensor(transform, film='<integer name="width" value="200"/><integer name="height" value="120"/>',
               extra=""):
        body = (f'<sensor type="orthographic">{extra}<transform name="to_world">{transform}</transform>'
                f'<film type="hdrfilm">{film}</film></sensor>')
        return load(write(tmp_path, body + SPHERE))

    s, w = sensor('<scale x="1.5" y="1.5"/><lookat origin="-5, 0, 3" target="0, 0, 1" up="0, 0, 1"/>',
                  extra='<float name="near_clip" value="1"/>')
    c = s.camera
    d = np.array([5.0, 0.0, -2.0]) / math.sqrt(29)
    assert w == [] and c.projection == "orthographic"
    assert np.isclose(c.extent, 2 * 1.5 * 120 / 200) and np.allclose(c.eye, np.array([-5, 0, 3]) + d)
    assert np.allclose(np.subtract(c.look_at, c.eye), d)
    s, w = sensor('<lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/>')
    assert w == [] and np.isclose(s.camera.extent, 2 * 120 / 200) and np.allclose(s.camera.eye, [0, 0, 0.01])
    s, w = sensor('<scale x="2" y="1"/><lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/>')
    assert len(w) == 1 and "unevenly" in w[0] and np.isclose(s.camera.extent, 2 * 120 / 200)
    with pytest.raises(SceneError, match=r'<float name="fov"> of <sensor type="orthographic">: parameter not'):
        sensor('<lookat origin="0, 0, 0" target="0, 0, 1" up="0, 1, 0"/>', extra='<float name="fov" value="40"/>')


def test_moment_and_aov_wrappers_render_their_nested_integrator_silently(tmp_path):
    def settings(body):
        return load(write(tmp_path, body + SPHERE))

    nested = ('<integrator type="path"><integer name="max_depth" value="6"/><integer name="rr_depth" value="3"/>'
              '</integrator>')
    s, w = settings(f'<integrator type="moment">{nested}</integrator>')
    assert (s.settings.max_depth, s.settings.rr_depth, w) == (6, 3, [])
    s, w = settings(f'<integrator type="aov"><string name="aovs" value="dd.y:depth,nn:sh_normal"/>{nested}</integrator>')
    assert (s.settings.max_depth, s.settings.rr_depth, w) == (6, 3, [])
    s, w = settings('<integrator type="moment"><integrator type="direct"/></integrator>')
    assert s.settings.max_depth == 2 and w == []
    # two nested integrators: Mitsuba renders both; we render the first
    s, w = settings(f'<integrator type="moment">{nested}<integrator type="direct"/></integrator>')
    assert s.settings.max_depth == 6 and len(w) == 1
    assert w[0].endswith('<integrator type="direct"> in <integrator type="moment">: only the first nested '
                         "integrator is rendered; ignored")


def test_shapes_closed_form(tmp_path):
    write_serialized(tmp_path / "tri.serialized", [
        (np.eye(3), [[0, 1, 2]]), (np.eye(3) * 2, [[0, 1, 2]], [[0, 0], [1, 0], [0, 1]])])
    from pyopencl_rt.bench.mitsuba_export import write_ply

    write_ply(tmp_path / "tri.ply", np.eye(3), np.array([[0, 1, 2]]))
    (tmp_path / "quad.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                                       "vn 0 0 1\nf 1/1/1 2/2/1 3/3/1 4/4/1\n")
    shapes = {
        "rectangle": ("", 4.0, [0, 0, 1]),
        "cube": ("", 24.0, None),
        "disk": ("", math.pi, [0, 0, 1]),
        "cylinder": ('<point name="p0" value="0 0 1"/><point name="p1" value="0 0 4"/><float name="radius" value="2"/>',
                     2 * math.pi * 2 * 3, None),
        "obj": ('<string name="filename" value="quad.obj"/><boolean name="face_normals" value="true"/>', 1.0, [0, 0, 1]),
        "ply": ('<string name="filename" value="tri.ply"/>', math.sqrt(3) / 2, np.ones(3) / math.sqrt(3)),
        "serialized": ('<string name="filename" value="tri.serialized"/><integer name="shape_index" value="1"/>',
                       math.sqrt(3) * 2, np.ones(3) / math.sqrt(3)),
    }
    for stype, (params, area, normal) in shapes.items():
        for flip in (False, True):
            fl = '<boolean name="flip_normals" value="true"/>' if flip else ""
            scene, w = load(write(tmp_path, f'<shape type="{stype}">{params}{fl}</shape>'))
            assert w == [], (stype, w)
            if stype == "disk":  # analytic (scene/shapes/disk.py): its record's area and front
                p = scene.shapes["params"][0].astype(np.float64)
                assert len(scene.faces) == 0 and np.isclose(p[27], area, rtol=1e-6)
                assert np.allclose(p[24:27], -np.asarray(normal) if flip else normal, atol=1e-6), flip
                continue
            if stype == "cylinder":  # analytic (scene/shapes/cylinder.py): its area, its front outside or in
                p = scene.shapes["params"][0].astype(np.float64)
                assert len(scene.faces) == 0 and np.isclose(p[25], area, rtol=1e-6) and p[24] == (-1 if flip else 1)
                continue
            v = scene.vertices.astype(np.float64)[scene.faces]
            n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
            assert np.isclose(0.5 * np.linalg.norm(n, axis=1).sum(), area, rtol=1e-6), stype
            if normal is not None:
                unit = n / np.linalg.norm(n, axis=1, keepdims=True)
                assert np.allclose(unit, -np.asarray(normal) if flip else normal, atol=1e-6), stype
            else:  # closed or tube: fronts face away from the axis / centre
                centre = v.reshape(-1, 3).mean(0)
                out = np.einsum("ij,ij->i", n, v.mean(1) - centre * ([1, 1, 0] if stype == "cylinder" else 1))
                assert (out < 0).all() if flip else (out > 0).all(), stype
    scene, _ = load(write(tmp_path, '<shape type="obj"><string name="filename" value="quad.obj"/></shape>'))
    assert np.allclose(scene.uvs[0], [[0, 1], [1, 1], [1, 0]])  # vt v flipped, as Mitsuba's flip_tex_coords
    scene, _ = load(write(tmp_path, """<shape type="sphere"><point name="center" value="1 0 0"/>
        <float name="radius" value="2"/><transform name="to_world"><scale value="3"/><translate x="1"/></transform>
        </shape>"""))
    assert np.allclose(sphere_of(scene.shapes), [[4, 0, 0, 6]])


def test_serialized_reads_what_mitsuba_reads(tmp_path):
    mi = mitsuba()
    rng = np.random.default_rng(1)
    v = rng.random((10, 3))
    f = rng.integers(0, 10, (7, 3))
    write_serialized(tmp_path / "m.serialized", [(v, f)])
    shape = mi.load_dict({"type": "serialized", "filename": str(tmp_path / "m.serialized")})
    p = mi.traverse(shape)
    theirs = np.asarray(p["vertex_positions"]).reshape(-1, 3)[np.asarray(p["faces"]).reshape(-1, 3)]
    scene, _ = load(write(tmp_path, '<shape type="serialized"><string name="filename" value="m.serialized"/></shape>'))
    assert np.allclose(scene.vertices[scene.faces], theirs, atol=1e-6)


# -- BSDFs and textures ------------------------------------------------------------------------------

def _materials(tmp_path, bsdfs: str):
    """The material of each rectangle (two triangles), one rectangle per BSDF, and the warnings."""
    body = "".join(f'<shape type="rectangle"><transform name="to_world"><translate x="{3 * i}"/></transform>{b}</shape>'
                   for i, b in enumerate(bsdfs.strip().split("\n")))
    scene, warned = load(write(tmp_path, body))
    return [scene.materials[i] for i in scene.face_materials[::2]], warned


def test_bsdfs(tmp_path):
    from pyopencl_rt.scene.loaders.mitsuba_metals import CONDUCTORS as METALS

    mats, warned = _materials(tmp_path, """
<bsdf type="diffuse"/>
<bsdf type="dielectric"><float name="int_ior" value="1.6"/><string name="ext_ior" value="water"/></bsdf>
<bsdf type="roughdielectric"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/><rgb name="specular_transmittance" value="0.9, 0.8, 0.7"/></bsdf>
<bsdf type="thindielectric"/>
<bsdf type="conductor"/>
<bsdf type="conductor"><string name="material" value="Au"/></bsdf>
<bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/><rgb name="eta" value="0.2 0.9 1.1"/><rgb name="k" value="3 2.5 2"/></bsdf>
<bsdf type="roughconductor"><string name="material" value="Cu"/></bsdf>
<bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.1 0.2 0.3"/></bsdf>
<bsdf type="roughplastic"><string name="distribution" value="ggx"/><float name="alpha" value="0.25"/><float name="int_ior" value="1.5"/><float name="ext_ior" value="1"/></bsdf>
<bsdf type="principled"><rgb name="base_color" value="0.8 0.5 0.2"/><float name="metallic" value="0.7"/><float name="roughness" value="0.4"/><float name="sheen" value="0"/></bsdf>
<bsdf type="twosided"><bsdf type="conductor"><rgb name="specular_reflectance" value="0.5"/></bsdf></bsdf>
<bsdf type="mask"><float name="opacity" value="0.5"/><bsdf type="diffuse"><rgb name="reflectance" value="0.2"/></bsdf></bsdf>
<bsdf type="bumpmap"><texture type="rawconstant" name="h"><float name="value" value="0.5"/></texture><float name="scale" value="2"/><bsdf type="roughconductor"/></bsdf>""")
    expect = [
        dict(type="diffuse", albedo=(0.5, 0.5, 0.5)),
        dict(type="dielectric", ior=pytest.approx(1.6 / 1.333), alpha=0.0),
        dict(type="dielectric", ior=pytest.approx(1.5046 / 1.000277), alpha=0.3, tint=(0.9, 0.8, 0.7),
             distribution="ggx", masking="separable", alpha_v=None),
        dict(type="dielectric", ior=pytest.approx(1.5046 / 1.000277), alpha=0.0, thin=True),
        dict(type="conductor", eta=None, f0=(1.0, 1.0, 1.0), alpha=0.0),  # Mitsuba's "none": a mirror
        dict(type="conductor", eta=METALS["Au"][0], k=METALS["Au"][1]),
        dict(type="conductor", eta=(0.2, 0.9, 1.1), k=(3, 2.5, 2), alpha=0.2),
        dict(type="conductor", eta=METALS["Cu"][0], alpha=0.1, distribution="beckmann"),
        dict(type="plastic", albedo=(0.1, 0.2, 0.3), ior=pytest.approx(1.49 / 1.000277), nonlinear=False,
             specular_reflectance=(1.0, 1.0, 1.0)),
        dict(type="roughplastic", albedo=(0.5, 0.5, 0.5), alpha=0.25, ior=1.5, distribution="ggx"),
        dict(type="principled", metallic=0.7, albedo=(0.8, 0.5, 0.2), params=
             {"roughness": 0.4, "anisotropic": 0.0, "spec_trans": 0.0, "spec_tint": 0.0, "sheen": 0.0,
              "sheen_tint": 0.0, "clearcoat": 0.0, "clearcoat_gloss": 0.0, "flatness": 0.0, "rates": (1, 1, 1, 0)},
             ior=pytest.approx(2 / (1 - math.sqrt(0.04)) - 1)),  # Mitsuba's eta from specular 0.5
        dict(type="conductor", eta=None, f0=(0.5, 0.5, 0.5)),
        dict(type="diffuse", albedo=(0.2, 0.2, 0.2), masked=True, opacity=0.5, one_sided=True),
        dict(type="conductor", alpha=0.1, bump_map=True, normal_scale=2.0, map_conventions=("side", "flip", "terminator")),
    ]
    for i, (mat, want) in enumerate(zip(mats, expect)):
        for key, value in want.items():
            assert getattr(mat, key) == value, (i, key, getattr(mat, key))
    expected_warnings = []
    assert len(warned) == len(expected_warnings)
    for w, needle in zip(warned, expected_warnings):
        assert re.match(r".*s\.xml:\d+: ", w) and needle in w, (w, needle)


def test_named_conductors_are_mitsubas_rgb():
    """Every named conductor of mitsuba_metals.py has the eta and k Mitsuba's scalar_rgb gives a
    roughconductor of that ``material`` (to float32 rounding), and Mitsuba has no other name."""
    import os

    from pyopencl_rt.scene.loaders.mitsuba_metals import CONDUCTORS

    mi = mitsuba()
    data = Path(mi.__file__).parent / "data" / "ior"
    if data.is_dir():
        assert set(CONDUCTORS) == {f[:-len(".k.spd")] for f in os.listdir(data) if f.endswith(".k.spd")}
    for name, (eta, k) in CONDUCTORS.items():
        params = mi.traverse(mi.load_dict({"type": "roughconductor", "material": name}))
        theirs = [float(x) for x in params["eta.value"]], [float(x) for x in params["k.value"]]
        assert np.allclose(eta, theirs[0], rtol=1e-6, atol=1e-9), (name, eta, theirs[0])
        assert np.allclose(k, theirs[1], rtol=1e-6, atol=1e-9), (name, k, theirs[1])


def test_rough_distributions(tmp_path):
    """roughconductor / roughdielectric keep Mitsuba's distribution (Beckmann by default), alpha_u and
    alpha_v (numbers or textures: the alpha and alpha_v texture slots) and its separable masking;
    alpha with alpha_u is an error, as in Mitsuba."""
    mats, warned = _materials(tmp_path, """
<bsdf type="roughconductor"><string name="material" value="a-C"/><float name="alpha_u" value="0.3"/><float name="alpha_v" value="0.05"/></bsdf>
<bsdf type="roughdielectric"><string name="distribution" value="ggx"/><texture type="checkerboard" name="alpha_u"/><float name="alpha_v" value="0.2"/></bsdf>
<bsdf type="roughconductor"><texture type="checkerboard" name="alpha_u"/><texture type="checkerboard" name="alpha_v"><float name="color0" value="0.1"/></texture></bsdf>""")
    assert warned == []
    a, b, c = mats
    assert (a.distribution, a.masking, a.alpha, a.alpha_v, a.is_anisotropic) == ("beckmann", "separable", 0.3, 0.05, True)
    assert (b.distribution, b.alpha, b.alpha_v, set(b.scalar_textures), b.is_anisotropic) == (
        "ggx", 1.0, 0.2, {"alpha"}, True)
    assert (c.alpha, c.alpha_v, set(c.scalar_textures)) == (1.0, 1.0, {"alpha", "alpha_v"}) and c.is_anisotropic
    rec = c.record({id(t): i for i, t in enumerate(c.textures())})
    assert rec["flags"] & abi.MATERIAL_FLAG_ANISOTROPIC and rec["tex_params"] == abi.TEXP_ALPHA | (abi.TEXP_ALPHA_V << 4)
    with pytest.raises(SceneError, match="alpha_u and alpha_v"):
        _materials(tmp_path, '<bsdf type="roughconductor"><float name="alpha" value="0.1"/>'
                             '<float name="alpha_u" value="0.2"/><float name="alpha_v" value="0.3"/></bsdf>')


def test_textures(tmp_path):
    write_png_image(tmp_path / "tex.png", np.full((4, 8, 3), 255, np.uint8) * np.array([1, 0, 0], np.uint8))
    mats, warned = _materials(tmp_path, """
<bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="tex.png"/><string name="filter_type" value="bilinear"/><string name="wrap_mode" value="repeat"/></texture></bsdf>
<bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" value="tex.png"/><boolean name="raw" value="true"/><string name="filter_type" value="nearest"/><string name="wrap_mode" value="clamp"/></texture></bsdf>
<bsdf type="diffuse"><texture type="checkerboard" name="reflectance"><rgb name="color0" value="0.1"/><rgb name="color1" value="0.9"/></texture></bsdf>
<bsdf type="roughconductor"><string name="distribution" value="ggx"/><texture type="checkerboard" name="alpha"/></bsdf>
<bsdf type="principled"><texture type="checkerboard" name="metallic"><transform name="to_uv"><scale x="4" y="2"/></transform><float name="color0" value="0.9"/><float name="color1" value="0.1"/></texture><texture type="bitmap" name="roughness"><string name="filename" value="tex.png"/></texture></bsdf>""")
    assert mats[0].albedo == (1, 1, 1) and mats[0].base_texture.srgb and mats[0].base_texture.texels.shape == (4, 8, 4)
    assert np.allclose(mats[0].base_texture.texels[..., :3], [1, 0, 0])
    assert not mats[1].base_texture.srgb
    assert (mats[0].base_texture.wrap, mats[0].base_texture.filter) == ("repeat", "bilinear")
    assert (mats[1].base_texture.wrap, mats[1].base_texture.filter) == ("clamp", "nearest")
    t = mats[2].base_texture.texels[..., 0]
    n = t.shape[0]  # Mitsuba's checkerboard: color0 where u and v are on the same side of 1/2
    assert np.allclose([t[0, 0], t[n - 1, n - 1], t[0, n - 1], t[n - 1, 0]], [0.1, 0.1, 0.9, 0.9])
    # a texture of a scalar parameter: factor 1 and the texture in its slot, as Mitsuba's eval_1 reads
    # it: a colour image's luminance, a checkerboard with color0 and color1 swapped (checkerboard.cpp)
    alpha = mats[3].scalar_textures["alpha"].texels
    assert mats[3].alpha == 1.0 and np.allclose([alpha[0, 0, 0], alpha[0, -1, 0]], [0.2, 0.4])
    metallic, roughness = (mats[4].scalar_textures[k].texels for k in ("metallic", "roughness"))
    assert mats[4].metallic == 1.0 and mats[4].params["roughness"] == 1.0
    from pyopencl_rt.scene.textures import lookup

    mt = mats[4].scalar_textures["metallic"]
    uv = np.random.default_rng(1).uniform(0, 1, (2000, 2))
    same = ((4 * uv[:, 0] % 1) > 0.5) == ((2 * uv[:, 1] % 1) > 0.5)  # to_uv: u * 4, v * 2
    got = lookup(mt.texels, uv, mt.wrap, mt.filter, mt.to_uv)
    assert np.allclose(got[:, 0], np.where(same, 0.1, 0.9)) and np.allclose(metallic[..., :3], metallic[..., :1])
    assert np.allclose(roughness[..., :3], 0.212671)  # luminance of the red image
    assert warned == []
    # only the alpha of rough conductors is textured: a textured eta is refused (not its mean)
    with pytest.raises(SceneError, match=r'<texture type="checkerboard"> as "eta" of <bsdf type="roughconductor">: '
                                         r'a texture is not supported here'):
        _materials(tmp_path, '<bsdf type="roughconductor"><texture type="checkerboard" name="eta"/></bsdf>')


# -- spectra ------------------------------------------------------------------------------------------

from pyopencl_rt.scene.loaders.mitsuba_spectrum import (CIE_D65, CIE_WAVELENGTHS, CIE_XYZ, Spectrum,  # noqa: E402
                                                        parse_pairs, spectrum_rgb)

EQUAL_ENERGY_RGB = (1.204794, 0.948291, 0.908916)  # XYZ (1, 1, 1) in linear sRGB: Mitsuba's xyz_to_srgb(1)
SPECTRA = ["360:0.5, 830:0.5", "400:0.2, 500:0.4, 600:0.6", "605:0, 610:1, 615:0", "380:0.9, 450:0.1, 700:0.05",
           "400:0.78, 500:0.78, 600:0.78, 700:0.78", "400:0, 500:8, 600:15.6, 700:18.4", "350:2, 560:0.1, 900:3"]


def _integrated_rgb(text, context):
    """The RGB of a sampled spectrum by a float64 integration of our own (0.05 nm trapezoids,
    everything linear between samples): ∫ s x̄ȳz̄ (× D65 for reflectances) / ∫ ȳ (× D65), to
    linear sRGB, clamped as Mitsuba clamps.  Mitsuba sums 1000 samples instead; its ȳ and D65
    normalisations are of that sum, and it samples a spectrum's ends on its grid, which puts it
    within 0.5 % of this (of the largest channel)."""
    pairs = np.array([[float(x) for x in p.split(":")] for p in text.split(",")])
    w = np.linspace(360.0, 830.0, 9401)
    s = np.interp(w, pairs[:, 0], pairs[:, 1]) * ((w >= pairs[0, 0]) & (w <= pairs[-1, 0]))
    cmf = np.stack([np.interp(w, CIE_WAVELENGTHS, CIE_XYZ[:, k]) for k in range(3)], 1)
    light = np.interp(w, CIE_WAVELENGTHS, CIE_D65) if context != "emission" else np.ones_like(w)
    xyz = np.trapezoid(cmf * (s * light)[:, None], w, axis=0) / np.trapezoid(cmf[:, 1] * light, w)
    m = np.array([[3.2404542, -1.5371385, -0.4985314], [-0.9692660, 1.8760108, 0.0415560],
                  [0.0556434, -0.2040259, 1.0572252]])  # XYZ -> linear sRGB (IEC 61966-2-1)
    rgb = m @ xyz
    return np.clip(rgb, 0, 1) if context == "reflectance" else np.maximum(rgb, 0)


@pytest.mark.parametrize("context", ["reflectance", "unbounded", "emission"])
def test_sampled_spectra_integrate_as_mitsuba_does(context):
    for text in SPECTRA:
        ours = np.array(spectrum_rgb(parse_pairs(text), context)[0])
        ref = _integrated_rgb(text, context)
        assert np.abs(ours - ref).max() <= 5e-3 * max(ref.max(), 1e-3), (text, ours, ref)


def test_constant_flat_and_narrow_spectra():
    for c in (0.0, 0.25, 1.0, 3.0):
        const = Spectrum(None, (c,))
        assert spectrum_rgb(const, "reflectance") == ((c, c, c), None)  # a uniform texture: exactly c
        assert spectrum_rgb(const, "unbounded") == ((c, c, c), None)
        assert spectrum_rgb(const, "emission")[0] == pytest.approx(tuple(c * x for x in EQUAL_ENERGY_RGB), rel=1e-6)
    # flat over Mitsuba's whole range: c, to Mitsuba's D65 normalisation (its 3.9.1 values)
    flat, raw = spectrum_rgb(parse_pairs("360:0.5, 830:0.5"), "reflectance")
    assert raw is None and flat == pytest.approx((0.499493, 0.499437, 0.499401), rel=1e-5)
    assert flat == pytest.approx((0.5,) * 3, rel=1.5e-3)
    # an equal-energy emitter given by samples is (almost) the constant one: Mitsuba's 3.9.1 value
    assert spectrum_rgb(parse_pairs("360:1, 830:1"), "emission")[0] == \
        pytest.approx((1.20488, 0.948228, 0.909267), rel=1e-5)
    # a spectrum given over 400-700 nm only is zero outside: a little darker than its value
    part = spectrum_rgb(parse_pairs("400:0.78, 500:0.78, 600:0.78, 700:0.78"), "reflectance")[0]
    assert part == pytest.approx((0.776367, 0.77981, 0.776029), rel=1e-5)
    # a narrow band at 610 nm is red: green and blue come out a little negative and are clamped
    for context in ("reflectance", "emission"):
        rgb, raw = spectrum_rgb(parse_pairs("605:0, 610:1, 615:0"), context)
        assert rgb[0] > 0.1 and rgb[1:] == (0.0, 0.0) and raw[1] < 0 and raw[2] < 0
    # a reflectance above 1 is clamped to 1; an emitter or an unbounded one keeps it
    assert spectrum_rgb(parse_pairs("400:3, 700:3"), "reflectance")[0] == (1.0, 1.0, 1.0)
    assert min(spectrum_rgb(parse_pairs("400:3, 700:3"), "unbounded")[0]) > 2.5


def test_spectra_in_scenes(tmp_path):
    """Each property where a <spectrum> appears is made RGB in its context: reflectance,
    unbounded (conductor eta/k) or emission; a .spd file is found through the search path."""
    (tmp_path / "spectra").mkdir()
    (tmp_path / "spectra" / "red.spd").write_text("# a reddish reflectance\n400 0.1\n550 0.2\n\n700 0.8 extra\n")
    path = write(tmp_path, """<path value="spectra"/>
        <shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" filename="red.spd"/></bsdf></shape>
        <shape type="sphere"><bsdf type="conductor"><spectrum name="eta" value="400:0.5, 500:2, 700:3"/>
            <spectrum name="k" value="6.15"/></bsdf></shape>
        <shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="605:0, 610:1, 615:0"/></bsdf></shape>
        <shape type="rectangle"><emitter type="area"><spectrum name="radiance" value="400:0, 500:8, 600:15.6, 700:18.4"/>
            </emitter></shape>
        <emitter type="point"><spectrum name="intensity" value="300"/></emitter>
        <emitter type="directional"><spectrum type="d65" name="irradiance"><rgb name="color" value="1 2 3"/>
            <float name="scale" value="2"/></spectrum></emitter>
        <emitter type="constant"><spectrum name="radiance" value="0.5"/></emitter>""")
    scene, warned = load(path)
    red, metal, band = (scene.materials[i] for i in scene.shape_materials)
    assert red.albedo == spectrum_rgb(parse_pairs("400:0.1, 550:0.2, 700:0.8"), "reflectance")[0]
    assert red.albedo[0] > red.albedo[1] > red.albedo[2]
    assert metal.eta == spectrum_rgb(parse_pairs("400:0.5, 500:2, 700:3"), "unbounded")[0]
    assert metal.eta == pytest.approx((2.6708, 2.25286, 1.1811), rel=1e-5)  # Mitsuba 3.9.1: above 1, kept
    assert metal.k == (6.15, 6.15, 6.15)
    assert band.albedo[1:] == (0.0, 0.0)
    light = next(m for m in scene.materials if m.is_emissive)
    assert light.emission == spectrum_rgb(parse_pairs("400:0, 500:8, 600:15.6, 700:18.4"), "emission")[0]
    point, directional = scene.lights
    # the suite's pointlight scene: an equal-energy 300 is Mitsuba's (361.4, 284.5, 272.7), not grey 300
    assert point.intensity == pytest.approx((361.438, 284.487, 272.675), rel=1e-5)
    assert directional.irradiance == (2, 4, 6)  # d65 in an RGB variant: color x scale
    assert scene.environment.radiance == pytest.approx(tuple(0.5 * x for x in EQUAL_ENERGY_RGB), rel=1e-6)
    n = line_of(path, "605:0")
    assert len(warned) == 1 and re.match(
        rf".*s\.xml:{n}: <spectrum name=\"reflectance\"> of <bsdf type=\"diffuse\">: the spectrum's colour "
        r"\(0\.1041, -0\.001, -0\.002\) is out of gamut; clamped to \(0\.1041, 0\.0, 0\.0\), as Mitsuba does", warned[0])


def test_spectra_agree_with_mitsuba(tmp_path):
    """Our import against Mitsuba's own (scalar_rgb) for the same XML: reflectance (diffuse),
    unbounded (conductor eta) and emission (point, area, constant) contexts, 1e-4 relative."""
    mi = mitsuba()

    def theirs(xml, key):
        return np.ravel(mi.traverse(mi.load_string(xml))[key]) * np.ones(3)

    (tmp_path / "s.spd").write_text("380 0.3\n480 0.9\n580 0.2\n680 0.6\n")
    values = SPECTRA + ["0.5", "2"]
    for text in values + ["FILE"]:
        attr = 'filename="{}"'.format(tmp_path / "s.spd") if text == "FILE" else f'value="{text}"'
        spec = f'<spectrum name="NAME" {attr}/>'
        ours_path = write(tmp_path, f"""
            <shape type="sphere"><bsdf type="diffuse">{spec.replace("NAME", "reflectance")}</bsdf></shape>
            <shape type="sphere"><bsdf type="conductor">{spec.replace("NAME", "eta")}</bsdf></shape>
            <shape type="rectangle"><emitter type="area">{spec.replace("NAME", "radiance")}</emitter></shape>
            <emitter type="point">{spec.replace("NAME", "intensity")}</emitter>
            <emitter type="constant">{spec.replace("NAME", "radiance")}</emitter>""")
        scene, _ = load(ours_path)
        diffuse, conductor = (scene.materials[i] for i in scene.shape_materials)
        area = next(m for m in scene.materials if m.is_emissive)
        v3 = 'version="3.0.0"'
        pairs = [
            (diffuse.albedo, theirs(f'<bsdf {v3} type="diffuse">{spec.replace("NAME", "reflectance")}</bsdf>',
                                    "reflectance.value")),
            (conductor.eta, theirs(f'<bsdf {v3} type="conductor">{spec.replace("NAME", "eta")}</bsdf>', "eta.value")),
            (area.emission, theirs(f'<shape {v3} type="rectangle"><emitter type="area">'
                                   f'{spec.replace("NAME", "radiance")}</emitter></shape>', "emitter.radiance.value")),
            (scene.lights[0].intensity, theirs(f'<emitter {v3} type="point">{spec.replace("NAME", "intensity")}'
                                               "</emitter>", "intensity.value")),
            (scene.environment.radiance, theirs(f'<emitter {v3} type="constant">{spec.replace("NAME", "radiance")}'
                                                "</emitter>", "radiance.value")),
        ]
        for ours, mitsubas in pairs:
            if text == "2" and ours is diffuse.albedo:
                continue  # Mitsuba keeps a uniform reflectance of 2; we clamp reflectances to 1 (with a warning)
            if ours is None:  # an eta with a zero channel: our conductor mapping's perfect mirror
                assert conductor.f0 is not None and min(mitsubas) == 0
                continue
            assert np.allclose(ours, mitsubas, rtol=1e-4, atol=1e-6), (text, ours, mitsubas)


# -- emitters ----------------------------------------------------------------------------------------

def test_emitters(tmp_path):
    image = np.zeros((2, 4, 3), np.float32)
    image[:, :, 0] = [1, 2, 3, 4]  # Mitsuba's column u in [k/4, (k+1)/4): value k + 1
    write_exr_image(tmp_path / "env.exr", image)
    path = write(tmp_path, SPHERE + """
        <shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1 2 3"/></emitter></shape>
        <emitter type="point"><rgb name="intensity" value="5"/><transform name="to_world"><translate value="1 2 3"/></transform></emitter>
        <emitter type="directional"><transform name="to_world"><rotate x="1" angle="90"/></transform></emitter>
        <emitter type="envmap"><string name="filename" value="env.exr"/><float name="scale" value="2"/></emitter>
        <emitter type="constant"/>
        <emitter type="spot"/>
        <emitter type="projector"><float name="fov" value="40"/><float name="scale" value="3"/></emitter>""")
    scene, warned = load(path)
    area = [m for m in scene.materials if m.is_emissive]
    # an emitter without a BSDF reflects nothing (Mitsuba's shape.cpp)
    assert len(area) == 1 and area[0].emission == (1, 2, 3) and area[0].albedo == (0, 0, 0)
    point, directional, spot, projector = scene.lights
    assert point.position == (1, 2, 3) and point.intensity == (5, 5, 5)
    # Mitsuba's defaults: cutoff 20, beam 3/4 of it; the projector's fov along x, 1 x 1 without an image
    assert (spot.cutoff_angle, spot.beam(), spot.position, spot.texture) == (20, 15, (0, 0, 0), None)
    assert (projector.fov, projector.scale, projector.aspect(), projector.irradiance) == (40, 3, 1, (1, 1, 1))
    assert np.allclose(directional.direction, [0, -1, 0])  # +z rotated 90 degrees about x
    env = scene.environment
    # read as it is, Mitsuba's layout (rows on the poles) in a frame turned half a turn about +y:
    # Mitsuba's +x at u = 1/4, +z at 1/2, -x at 3/4, -z at 0 (docs/SCENE_FORMAT.md)
    assert env.radiance == (2, 2, 2) and np.array_equal(env.image, image) and env.rows == "poles"
    assert np.allclose(env.rotation, np.diag([-1, 1, -1]))
    axes = np.array([[1, 0, 0], [0, 0, 1], [-1, 0, 0], [0, 0, -1]], np.float64)  # Mitsuba's u = 1/4 + k/4
    assert np.allclose(environment_radiance(env, axes)[:, 0], 2 * np.array([1.5, 2.5, 3.5, 2.5]))
    # rotated 90 degrees about y: the map's +x (Mitsuba's u = 1/4) looks along world -z
    rotated = write(tmp_path, SPHERE + """<emitter type="envmap"><string name="filename" value="env.exr"/>
        <transform name="to_world"><rotate y="1" angle="90"/></transform></emitter>""", name="r.xml")
    assert np.allclose(environment_radiance(load(rotated)[0].environment, axes[3:])[:, 0], 1.5)
    assert [w.split(": ", 1)[1] for w in warned] == ["a second environment light: we render one; ignored"]
    assert line_of(path, "constant") == int(warned[0].split(":")[1])


def test_envmap_agrees_with_mitsuba(tmp_path):
    """Our environment, looked up as our kernels do (environment_radiance: the float64 reference
    of cl/render/lights.h, tests/render/test_lights.py), against Mitsuba's envmap emitter, for
    random directions and the poles, with a to_world rotation; an axis that is not a unit vector
    (Mitsuba does not normalise it: not a rotation) has the map resampled."""
    mi = mitsuba()
    h, w = 32, 64
    v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    image = np.stack([1 + np.sin(2 * np.pi * u), 1 + v, 1 + np.cos(np.pi * v) * np.cos(2 * np.pi * u)], -1)
    write_exr_image(tmp_path / "env.exr", image)
    rng = np.random.default_rng(3)
    d = rng.normal(size=(400, 3))
    d[:2] = [[0, 1, 0], [0, -1, 0]]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    path = write(tmp_path, SPHERE + """<emitter type="envmap"><string name="filename" value="env.exr"/>
        <transform name="to_world"><rotate y="1" angle="40"/><rotate x="1" angle="-25"/></transform></emitter>""")
    env = load(path)[0].environment
    emitter = mi.load_file(str(path)).emitters()[0]
    si = mi.SurfaceInteraction3f()
    theirs = []
    for di in d:
        si.wi = mi.Vector3f(*(-di))
        theirs.append(np.ravel(emitter.eval(si)))
    assert env.rows == "poles"
    assert np.allclose(environment_radiance(env, d), theirs, rtol=1e-4, atol=1e-6)
    skewed = write(tmp_path, SPHERE + """<emitter type="envmap"><string name="filename" value="env.exr"/>
        <transform name="to_world"><rotate x="0.3" y="1" z="0.2" angle="30"/></transform></emitter>""", name="s.xml")
    env = load(skewed)[0].environment
    assert env.rows == "centred" and env.rotation is None


# -- warnings and errors -----------------------------------------------------------------------------

def test_unsupported_elements_warn_and_the_render_goes_on(tmp_path):
    """What is not a plugin at all warns and the render goes on; a plugin type we do not render is
    refused with one line that names it (never replaced by another: tests/scene/test_mitsuba_plugins.py)."""
    path = write(tmp_path, """
        <integrator type="aov"><string name="aovs" value="nn:sh_normal"/><integrator type="path"/></integrator>
        <shape type="sphere"/>
        <rgb name="stray" value="1"/>
        <unknown/>""")
    scene, warned = load(path)
    assert len(sphere_of(scene.shapes)) == 1 and scene.materials[0].albedo == (0.5, 0.5, 0.5)
    assert warned == [f"{path}:{line_of(path, 'stray')}: <rgb name=\"stray\">: a property of the scene itself; ignored",
                      f"{path}:{line_of(path, 'unknown')}: <unknown>: unknown element; ignored"]
    assert scene.warnings == warned
    refused = [('<sensor type="radiancemeter"/>', '<sensor type="radiancemeter">: sensor type "radiancemeter"'),
               ('<medium type="homogeneous" id="fog"><phase type="rayleigh"/></medium>'
                '<shape type="sphere"><ref name="interior" id="fog"/></shape>', '<phase type="rayleigh">: phase type'),
               ('<shape type="ellipsoids" id="g"/>', '<shape type="ellipsoids" id="g">: shape type "ellipsoids"'),
               ('<shape type="sphere"><bsdf type="hair"/></shape>', '<bsdf type="hair">: bsdf type "hair"'),
               ('<shape type="sphere"><emitter type="point"/></shape>',
                '<emitter type="point"> in <shape type="sphere">: only area and directionalarea emitters attach to shapes'),
               ('<emitter type="sunsky"/>', '<emitter type="sunsky">: emitter type "sunsky" is not supported')]
    for body, what in refused:
        bad = write(tmp_path, body, name="bad.xml")
        with pytest.raises(SceneError) as exc:
            load(bad)
        assert str(exc.value).startswith(f"{bad}:2: {what}"), str(exc.value)


MALFORMED = [
    ("<shape type='sphere'>", r"s\.xml:3:\d+: not well-formed XML \(mismatched tag\)"),
    ("<shape type='sphere'><float name='radius' value='big'/></shape>",
     r"s\.xml:2: <float name=\"radius\">: \"value\" must be numbers, got 'big'"),
    ("<shape type='sphere'><float name='radius'/></shape>", r"s\.xml:2: <float name=\"radius\"> needs a \"value\" attribute"),
    ("<shape type='sphere'><rgb name='x' value='1 2'/></shape>", r"\"value\" must be 1 or 3 finite numbers, got '1 2'"),
    ("<shape type='sphere'><integer name='x' value='1.5'/></shape>", r"\"value\" must be an integer, got '1.5'"),
    ("<shape type='sphere'><boolean name='flip_normals' value='yes'/></shape>", r"must be true or false, got 'yes'"),
    ("<shape type='sphere'><float name='radius' value='1'/><float name='radius' value='2'/></shape>",
     r"s\.xml:2: <shape type=\"sphere\">: property \"radius\" given twice \(first at line 2\)"),
    ("<shape type='sphere'><ref id='nothing'/></shape>", r"<ref id=\"nothing\">: no object with id=\"nothing\" defined"),
    ("<bsdf type='diffuse' id='a'/><bsdf type='diffuse' id='a'/>", r"id \"a\" is already used \(at .*s\.xml:2\)"),
    ("<shape><float name='radius' value='1'/></shape>", r"<shape> needs a \"type\" attribute"),
    ("<include filename='missing.xml'/>", r"<include>: file 'missing.xml' not found"),
    ("<include filename='s.xml'/>", r"<include>: 's\.xml' includes itself"),
    ("<shape type='obj'/>", r"<shape type=\"obj\"> needs <string name=\"filename\">"),
    ("<shape type='obj'><string name='filename' value='no.obj'/></shape>", r"file 'no\.obj' not found"),
    ("<shape type='rectangle'><transform name='to_world'><rotate angle='30'/></transform></shape>",
     r"<rotate> needs a non-zero axis"),
    ("<shape type='rectangle'><transform name='to_world'><rotate x='1'/></transform></shape>",
     r"<rotate> needs a \"angle\" attribute"),
    ("<shape type='rectangle'><transform name='to_world'><matrix value='1 2 3'/></transform></shape>",
     r"\"value\" must be 9 or 16 finite numbers"),
    ("<shape type='rectangle'><transform name='to_world'><scale x='0'/></transform></shape>", r"a zero scale"),
    ("<sensor type='perspective'><transform name='to_world'><lookat origin='0 0 0' target='0 0 0'/></transform>"
     "</sensor>", r"<lookat>: origin and target are the same point"),
    ("<sensor type='perspective'><float name='fov' value='200'/></sensor>", r"fov must be between 0 and 180"),
    ("<sensor type='perspective'><string name='fov_axis' value='z'/><float name='fov' value='20'/></sensor>",
     r"unknown fov_axis 'z'"),
    ("<sensor type='thinlens'/>", r"<sensor type=\"thinlens\"> needs <float name=\"aperture_radius\">"),
    ("<sensor type='perspective'><film type='hdrfilm'><integer name='width' value='0'/></film></sensor>",
     r"\"width\" must be >= 1, got 0"),
    ("<shape type='sphere'><bsdf type='dielectric'><string name='int_ior' value='unobtainium'/></bsdf></shape>",
     r"unknown int_ior 'unobtainium'"),
    ("<shape type='sphere'><float name='radius' value='-1'/></shape>", r"\"radius\" must be > 0, got -1"),
    ("<shape type='sphere'><string name='radius' value='1'/></shape>", r"\"radius\" must be a <float>, got <string>"),
    ("<integrator type='path'><integer name='max_depth' value='0'/></integrator>", r"max_depth 0 renders nothing"),
    ("<shape type='sphere'><bsdf type='diffuse'><spectrum name='reflectance' value='400:0.5'/></bsdf></shape>",
     r"<spectrum name=\"reflectance\">: \"value\" must be 'wavelength:value' pairs .*: a sampled spectrum needs at "
     r"least two wavelengths"),
    ("<shape type='sphere'><bsdf type='diffuse'><spectrum name='reflectance' value='500:1, 400:1'/></bsdf></shape>",
     r"the wavelengths must increase"),
    ("<shape type='sphere'><bsdf type='diffuse'><spectrum name='reflectance' value='400:1, 500:x'/></bsdf></shape>",
     r"'500:x' is not a wavelength:value pair"),
    ("<shape type='sphere'><bsdf type='diffuse'><spectrum name='reflectance' value='1' filename='a.spd'/></bsdf>"
     "</shape>", r"<spectrum name=\"reflectance\">: give \"value\" or \"filename\", not both"),
    ("<shape type='sphere'><bsdf type='diffuse'><spectrum name='reflectance' filename='no.spd'/></bsdf></shape>",
     r"s\.xml:2: <spectrum name=\"reflectance\">: spectrum file 'no\.spd' not found \(searched "),
    ("<shape type='sphere'><bsdf type='diffuse'><spectrum name='reflectance' filename='s.xml'/></bsdf></shape>",
     r"<spectrum name=\"reflectance\">: 's\.xml': line 1: expected 'wavelength value', got '<scene"),
]


@pytest.mark.parametrize("body,message", MALFORMED, ids=[f"case{i}" for i in range(len(MALFORMED))])
def test_malformed_input_is_one_clear_error(tmp_path, body, message):
    path = write(tmp_path, body + ("" if "sphere" in body or "include" in body or "<bsdf" in body else SPHERE))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    text = str(info.value)
    assert "\n" not in text and re.search(r"s\.xml(:\d+)+: ", text), text
    assert re.search(message, text), text


def test_root_and_version_errors(tmp_path):
    (tmp_path / "a.xml").write_text("<scenery/>")
    with pytest.raises(SceneError, match=r"a\.xml:1: the root element must be <scene>, not <scenery>"):
        load_scene(tmp_path / "a.xml")
    (tmp_path / "b.xml").write_text("<scene>" + SPHERE + "</scene>")
    with pytest.raises(SceneError, match=r'b\.xml:1: <scene> needs a version attribute'):
        load_scene(tmp_path / "b.xml")
    (tmp_path / "c.xml").write_text('<scene version="3.0.0"><bsdf type="diffuse"/></scene>')
    with pytest.raises(SceneError, match=r"c\.xml: the scene has no shapes that we can render"):
        load_scene(tmp_path / "c.xml")


def test_version_0_6_files_are_upgraded(tmp_path):
    """Mitsuba 0.6 names (camelCase, <lookAt>, <srgb>) read as Mitsuba 3 upgrades them."""
    path = write(tmp_path, """
        <integrator type="path"><integer name="maxDepth" value="3"/></integrator>
        <sensor type="perspective"><float name="fov" value="30"/><string name="fovAxis" value="y"/>
            <transform name="toWorld"><lookAt origin="0 0 -5" target="0 0 0" up="0 1 0"/></transform>
            <sampler type="independent"><integer name="sampleCount" value="9"/></sampler></sensor>
        <shape type="sphere"><bsdf type="dielectric"><float name="intIOR" value="1.7"/></bsdf></shape>
        <shape type="sphere"><point name="center" x="3"/><bsdf type="diffuse"><srgb name="reflectance" value="0.5"/></bsdf></shape>""",
                 version="0.6.0")
    scene, warned = load(path)
    assert warned == []
    assert (scene.settings.max_depth, scene.settings.spp, scene.camera.eye) == (3, 9, (0, 0, -5))
    assert scene.camera.fov == pytest.approx(30)
    assert scene.materials[0].ior == pytest.approx(1.7 / 1.000277)
    assert scene.materials[1].albedo == pytest.approx((0.21404,) * 3, abs=1e-5)  # sRGB 0.5 decoded


# -- the exporter's round trip, the sidecar and the CLI ---------------------------------------------------

class _LookAt:
    def __init__(self, origin, target, up):
        self.origin, self.target, self.up = origin, target, up


class _FakeMitsuba:
    """What mitsuba_export.dict_from_arrays needs of Mitsuba, recording the look_at arguments."""

    class ScalarTransform4f:
        look_at = staticmethod(lambda origin, target, up: _LookAt(origin, target, up))

        def __init__(self, matrix):
            self.matrix = np.asarray(matrix, np.float64)


def dict_to_xml(d: dict) -> str:
    """Mitsuba XML for a ``mi.load_dict`` dict (the subset mitsuba_export.py writes)."""
    tags = {"integrator": "integrator", "sensor": "sensor", "sampler": "sampler", "film": "film",
            "rfilter": "rfilter", "bsdf": "bsdf", "material": "bsdf", "emitter": "emitter"}

    scalars = ((bool, "boolean", lambda v: str(v).lower()), (int, "integer", str), (float, "float", repr),
               (str, "string", str))

    def num(v):
        return ", ".join(repr(float(x)) for x in np.ravel(v))

    def value(name, v):
        if isinstance(v, dict):
            if v["type"] == "rgb":
                return f'<rgb name="{name}" value="{num(v["value"])}"/>'
            return plugin(tags.get(name, "shape"), v)
        for kind, tag, text in scalars:  # bool before int: a bool is an int
            if isinstance(v, kind):
                return f'<{tag} name="{name}" value="{text(v)}"/>'
        if isinstance(v, _LookAt):
            return (f'<transform name="{name}"><lookat origin="{num(v.origin)}" target="{num(v.target)}" '
                    f'up="{num(v.up)}"/></transform>')
        if hasattr(v, "matrix"):
            return f'<transform name="{name}"><matrix value="{num(np.asarray(v.matrix))}"/></transform>'
        return f'<point name="{name}" value="{num(v)}"/>'

    def plugin(tag, spec):
        inner = "".join(value(k, v) for k, v in spec.items() if k != "type")
        return f'<{tag} type="{spec["type"]}">{inner}</{tag}>'

    body = "\n".join(value(k, v) for k, v in d.items() if k != "type")
    return f'<scene version="3.0.0">\n{body}\n</scene>\n'


@pytest.mark.parametrize("real_mitsuba", [False, True], ids=["lookat", "matrix"])
def test_exporter_output_reimported_equals_the_original(tmp_path, real_mitsuba):
    from pyopencl_rt.bench.mitsuba_export import dict_from_arrays, scene_arrays

    mi = mitsuba() if real_mitsuba else _FakeMitsuba
    original = load_scene(SCENES / "cornell-spheres.toml")
    d = dict_from_arrays(scene_arrays(original, spp=32), mi, tmpdir=str(tmp_path))
    (tmp_path / "exported.xml").write_text(dict_to_xml(d))
    back, warned = load(tmp_path / "exported.xml")
    assert warned == []
    assert triangles_equal(triangle_records(back), triangle_records(original))
    assert np.allclose(sphere_of(back.shapes), sphere_of(original.shapes))
    assert [back.materials[i].albedo for i in back.shape_materials] == \
        [original.materials[i].albedo for i in original.shape_materials]
    c, o = back.camera, original.camera
    assert np.allclose(c.eye, o.eye) and np.isclose(c.fov, o.fov) and np.allclose(c.up, o.up)
    fwd = np.subtract(o.look_at, o.eye)
    assert np.allclose(np.subtract(c.look_at, c.eye), fwd / np.linalg.norm(fwd))
    for key in ("width", "height", "max_depth", "rr_depth"):
        assert getattr(back.settings, key) == getattr(original.settings, key)
    assert back.settings.spp == 32


@pytest.mark.parametrize("real_mitsuba", [False, True], ids=["fake", "mitsuba"])
def test_exporter_orthographic_camera_and_filters(tmp_path, real_mitsuba):
    """The export of an orthographic camera and of each filter Mitsuba can express reads back as
    the original; a filter it cannot express is refused."""
    import dataclasses

    from pyopencl_rt.bench.mitsuba_export import dict_from_arrays, mitsuba_rfilter, scene_arrays

    mi = mitsuba() if real_mitsuba else _FakeMitsuba
    original = load_scene(SCENES / "cornell-spheres.toml")
    original.camera = dataclasses.replace(original.camera, projection="orthographic", extent=450.0)
    for flt in (PixelFilter("gaussian", (1.2, 1.2), sigma=0.3), PixelFilter("tent", (1.5, 1.5)),
                PixelFilter("mitchell", (2.0, 2.0), b=0.0, c=0.5), PixelFilter("lanczos", (2.0, 2.0), tau=2.0)):
        original.settings.filter = flt
        d = dict_from_arrays(scene_arrays(original, spp=4), mi, tmpdir=str(tmp_path))
        (tmp_path / "exported.xml").write_text(dict_to_xml(d))
        back, warned = load(tmp_path / "exported.xml")
        assert warned == [] and back.settings.filter == flt
        c, o = back.camera, original.camera
        assert c.projection == "orthographic" and np.isclose(c.extent, o.extent) and np.allclose(c.eye, o.eye)
        assert np.allclose(c.up, o.up)
    for bad in (PixelFilter("box", (1.0, 1.0)), PixelFilter("gaussian", (1.5, 1.5)), PixelFilter("tent", (1.0, 2.0)),
                PixelFilter("lanczos", (4.0, 4.0))):
        with pytest.raises(ValueError, match="Mitsuba"):
            mitsuba_rfilter(bad.as_dict())


def test_sidecar_records_format_and_warnings(tmp_path):
    path = write(tmp_path, SPHERE + '<emitter type="constant"/><emitter type="constant"/>')
    scene, warned = load(path)
    r = rt.render_full(scene, spp=1, width=4, height=4, device="cpu")
    assert r.info["scene_format"] == "mitsuba-xml"
    assert r.info["scene_warnings"] == warned and len(warned) == 1


def test_cli_render_with_defines(tmp_path, capsys, monkeypatch):
    from pyopencl_rt.cli import main

    monkeypatch.setattr(warnings, "formatwarning", warnings.formatwarning)  # main() sets its own

    path = write(tmp_path, '<default name="n" value="3"/><sensor type="perspective"><sampler type="independent">'
                           '<integer name="sample_count" value="$n"/></sampler></sensor>' + SPHERE +
                 '<emitter type="constant"/><emitter type="constant"/>')
    out = tmp_path / "o.exr"
    with pytest.warns(UserWarning, match="a second environment light"):
        main(["render", str(path), "-o", str(out), "--width", "4", "--height", "4", "-D", "n=2", "-q", "-d", "cpu"])
    info = json.loads(out.with_suffix(".json").read_text())
    assert info["spp"] == 2 and info["scene_format"] == "mitsuba-xml" and len(info["scene_warnings"]) == 1
    assert warnings.formatwarning("w", UserWarning, "f.py", 1) == "pyopencl-rt: warning: w\n"  # one line each
    for args, message in ((["-D", "n"], "--define n: expected NAME=VALUE"),
                          (["-D", "m=1"], None)):
        bad = write(tmp_path, "<shape type='sphere'><float name='radius' value='$m'/></shape>"
                              "<shape type='sphere'><float name='radius' value='x'/></shape>", name="bad.xml")
        with pytest.raises(SystemExit) as exc:
            main(["render", str(bad), "-o", str(out)] + args)
        assert exc.value.code == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and err.startswith("pyopencl-rt: error: ")
        if message:
            assert message in err
        else:
            assert re.search(r"bad\.xml:\d+: <float name=\"radius\">: \"value\" must be numbers, got 'x'", err)
