"""Participating media in the scene model and the file formats (pyopencl_rt/scene/media.py, the
loaders' media): Mitsuba's .vol grids; Mitsuba 3 XML media, phase functions, volumes, shape
interiors and exteriors, null BSDFs, the sensor's medium and volpath settings, compared with
Mitsuba 3's own parse (scalar_rgb: its media's coefficients and majorant at points, its phase
functions); pbrt-v4 MakeNamedMedium / MediumInterface / "interface" shapes and the camera medium;
TOML [media] tables; the kernel records; the checks of scene/validate.py; the renderer takes such
scenes as they are (the volumetric integrator: tests/render/test_volpath.py)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.scene.loaders import SceneError, load_scene
from pyopencl_rt.scene.loaders.mitsuba_vol import read_vol, write_vol
from pyopencl_rt.scene.media import Grid, Medium, MediumInterface, PhaseFunction, pack_media
from pyopencl_rt.scene.validate import SceneValueError, check_scene
from harness import load_warned as load, mitsuba

SPHERE_LIGHT = '<shape type="sphere"><point name="center" x="0" y="5" z="0"/><emitter type="area"/></shape>'


# ----------------------------------------------------------------------------- .vol files
def test_vol_round_trip_and_mitsuba(tmp_path, rng):
    """write_vol and read_vol invert each other (1 and 3 channels, the box kept); Mitsuba's VolumeGrid
    reads our file and writes one we read, value for value."""
    mi = mitsuba()
    for channels in (1, 3):
        data = rng.random((3, 4, 5, channels)).astype(np.float32)
        write_vol(tmp_path / "a.vol", data, box=((-1, 0, 2), (1, 3, 4)))
        back, box = read_vol(tmp_path / "a.vol")
        assert np.array_equal(back, data) and box.tolist() == [[-1, 0, 2], [1, 3, 4]]
        theirs = mi.VolumeGrid(str(tmp_path / "a.vol"))
        assert list(theirs.size()) == [5, 4, 3] and theirs.channel_count() == channels
        assert np.array_equal(np.array(theirs, np.float32).reshape(data.shape), data)
        mi.VolumeGrid(data).write(str(tmp_path / "b.vol"))
        back, _ = read_vol(tmp_path / "b.vol")
        assert np.array_equal(back, data)


@pytest.mark.parametrize("patch,message", [
    (lambda b: b"XOL" + b[3:], "does not start with 'VOL'"),
    (lambda b: b[:3] + b"\x02" + b[4:], "version 2; only version 3"),
    (lambda b: b[:4] + (2).to_bytes(4, "little") + b[8:], "encoding 2; only 1"),
    (lambda b: b[:20] + (2).to_bytes(4, "little") + b[24:], "impossible grid"),
    (lambda b: b[:-4], "truncated"),
    (lambda b: b[:30], "shorter than its header"),
    # an OpenVDB file (its int32 magic 0x56444220) and a NanoVDB one: named as such, not "not a .vol"
    (lambda b: (0x56444220).to_bytes(4, "little") + b[4:], "OpenVDB / NanoVDB grid, which we do not read"),
    (lambda b: b"NanoVDB2" + b[8:], "OpenVDB / NanoVDB grid, which we do not read"),
])
def test_vol_errors(tmp_path, patch, message):
    write_vol(tmp_path / "a.vol", np.ones((2, 2, 2)))
    (tmp_path / "b.vol").write_bytes(patch((tmp_path / "a.vol").read_bytes()))
    with pytest.raises(SceneError, match=message):
        read_vol(tmp_path / "b.vol", "where")


# ----------------------------------------------------------------------------- Mitsuba 3 XML
def write_xml(tmp_path, body, name="s.xml"):
    path = tmp_path / name
    path.write_text(f'<scene version="3.0.0">\n{body}\n{SPHERE_LIGHT}\n</scene>\n')
    return path


def medium_xml(tmp_path, rng):
    write_vol(tmp_path / "density.vol", rng.uniform(0, 2, (3, 4, 5)), box=((-1, -1, -1), (2, 1, 3)))
    write_vol(tmp_path / "albedo.vol", rng.uniform(0, 1, (2, 2, 2, 3)))
    return write_xml(tmp_path, """
    <integrator type="volpathmis"><integer name="max_depth" value="12"/><integer name="rr_depth" value="3"/></integrator>
    <medium type="homogeneous" id="fog">
        <rgb name="albedo" value="0.9, 0.5, 0.3"/>
        <spectrum name="sigma_t" value="400:0.2, 700:0.6"/>
        <float name="scale" value="2"/>
        <phase type="hg"><float name="g" value="-0.3"/></phase>
    </medium>
    <medium type="heterogeneous" id="smoke">
        <volume type="gridvolume" name="sigma_t">
            <string name="filename" value="density.vol"/>
            <boolean name="use_grid_bbox" value="true"/>
            <transform name="to_world"><rotate y="1" angle="30"/><translate x="0.5"/></transform>
        </volume>
        <volume type="gridvolume" name="albedo">
            <string name="filename" value="albedo.vol"/>
            <string name="filter_type" value="nearest"/>
            <transform name="to_world"><scale value="3"/><translate x="-1" y="-1" z="-1"/></transform>
        </volume>
        <float name="scale" value="0.7"/>
        <boolean name="sample_emitters" value="false"/>
    </medium>
    <medium type="heterogeneous" id="box">
        <float name="sigma_t" value="0.4"/>
        <volume type="constvolume" name="albedo"><rgb name="value" value="0.2, 0.4, 0.6"/></volume>
    </medium>
    <sensor type="perspective"><ref id="fog"/>
        <transform name="to_world"><lookat origin="0, 0, 10" target="0, 0, 0" up="0, 1, 0"/></transform>
    </sensor>
    <shape type="cube"><bsdf type="null"/><ref name="interior" id="fog"/></shape>
    <shape type="sphere"><bsdf type="dielectric"/><ref name="interior" id="smoke"/><ref name="exterior" id="fog"/>
        <boolean name="flip_normals" value="true"/></shape>
    <shape type="rectangle"><bsdf type="null"/></shape>
    <shape type="rectangle"><ref name="exterior" id="box"/></shape>""")


def test_mitsuba_media_model(tmp_path, rng):
    """Media, interfaces, the camera's medium and the integrator of an XML scene, without a warning:
    homogeneous (spectrum sigma_t as a clamped reflectance, scale, hg g), heterogeneous (a gridvolume
    as the density with its to_world and use_grid_bbox, an RGB albedo grid, sample_emitters; a
    float sigma_t as a 1x1x1 grid on the unit cube, a constvolume albedo as a constant); a null cube
    (an index-matched transition into fog), a dielectric sphere with flip_normals (interior and
    exterior swapped), a null rectangle without media (index-matched, no transition), an exterior
    alone (a transition with a vacuum interior); volpathmis: spectral MIS, max_depth and rr_depth."""
    scene, warned = load(medium_xml(tmp_path, rng))
    assert warned == []
    names = [m.name for m in scene.media]
    assert names == ["fog", "smoke", "box"]
    fog, smoke, box = scene.media
    assert fog.type == "homogeneous" and fog.scale == 2 and fog.phase == PhaseFunction("hg", -0.3)
    assert fog.albedo == (0.9, 0.5, 0.3) and fog.sample_emitters
    assert smoke.type == "grid" and smoke.density.data.shape == (3, 4, 5, 1) and not smoke.sample_emitters
    assert smoke.albedo_grid.filter == "nearest" and smoke.albedo_grid.channels == 3
    assert box.density.data.shape == (1, 1, 1, 3) and np.allclose(box.density.to_world, np.eye(4))
    assert box.albedo == (0.2, 0.4, 0.6) and box.phase == PhaseFunction("isotropic")
    assert scene.camera_medium == 0
    fog_i, smoke_i, box_i = 0, 1, 2
    assert scene.interfaces == [MediumInterface(fog_i, -1, True, True), MediumInterface(fog_i, smoke_i, True, False),
                                MediumInterface(-1, -1, False, True), MediumInterface(-1, box_i, True, False)]
    assert scene.shape_interfaces.tolist() == [1, -1]  # flip_normals: smoke is outside the outward normal
    assert sorted(set(scene.face_interfaces.tolist())) == [0, 2, 3]
    st = scene.settings
    assert (st.spectral_mis, st.max_depth, st.rr_depth) == (True, 12, 3)


def test_mitsuba_media_against_mitsuba(tmp_path, rng):
    """Mitsuba 3 loads the same file: at random points its media's get_scattering_coefficients give
    our sigma_t (extinction x density grid) and sigma_s (x albedo or the albedo grid) to 1e-5, its
    get_majorant our majorant, its phase functions our value; the shapes' interior and exterior
    media are the ones we name."""
    mi = mitsuba()
    path = medium_xml(tmp_path, rng)
    ours, _ = load(path)
    theirs = mi.load_file(str(path))
    by_id = {}
    for shape in theirs.shapes():
        for m in (shape.interior_medium(), shape.exterior_medium()):
            if m is not None:
                by_id[m.id()] = m
    assert set(by_id) == {"fog", "smoke", "box"}
    for med in ours.media:
        m = by_id[med.name]
        inside = med.density.to_world if med.density is not None else np.diag([4.0, 4.0, 4.0, 1.0])
        q = rng.uniform(0.02, 0.98, (60, 3)) if med.density is not None else rng.uniform(-0.5, 0.5, (60, 3))
        pts = q @ inside[:3, :3].T + inside[:3, 3]
        e = med.extinction()
        sigma_t = np.broadcast_to(e * (med.density.eval(pts) if med.density is not None else 1.0), pts.shape)
        albedo = med.albedo_grid.eval(pts) if med.albedo_grid is not None else np.asarray(med.albedo)
        for p, st, a in zip(pts, sigma_t, np.broadcast_to(albedo, sigma_t.shape)):
            mei = mi.MediumInteraction3f()
            mei.p = mi.Point3f(*p)
            mei.wi = mi.Vector3f(0, 0, 1)
            mei.sh_frame = mi.Frame3f(mei.wi)
            ss, _, tt = m.get_scattering_coefficients(mei, True)
            assert np.allclose(np.array(tt), st, rtol=1e-5, atol=1e-6), med.name
            assert np.allclose(np.array(ss), st * a, rtol=1e-5, atol=1e-6), med.name
        assert np.allclose(np.array(m.get_majorant(mei, True)), med.majorant_rgb(), rtol=1e-6), med.name
        phase = m.phase_function()
        wo = mi.Vector3f(0.6, 0.0, -0.8)
        v, _ = phase.eval_pdf(mi.PhaseFunctionContext(None), mei, wo)
        g = med.phase.g
        ref = (1 - g * g) / (4 * np.pi * (1 + g * g + 2 * g * -0.8) ** 1.5)
        assert np.isclose(float(np.ravel(v)[0]), ref, rtol=1e-5)


def test_mitsuba_media_warnings_and_errors(tmp_path):
    """Approximated parts warn, one line each, and the rest loads: wrap_mode repeat, a grid sigma_t in a homogeneous medium, a medium ref without the
    interior/exterior name; malformed ones are errors: hg g outside (-1, 1), a gridvolume without a
    file, a 6-channel grid, interior not a medium, another medium type, phase function or volume
    (refused, never replaced); volpath sets the single-channel estimate."""
    write_vol(tmp_path / "g.vol", np.ones((2, 2, 2)) * 0.5)
    path = write_xml(tmp_path, """
    <integrator type="volpath"/>
    <medium type="homogeneous" id="a"/>
    <medium type="homogeneous" id="b"><phase type="isotropic"/>
        <volume type="gridvolume" name="sigma_t"><string name="filename" value="g.vol"/>
            <string name="wrap_mode" value="repeat"/></volume></medium>
    <medium type="heterogeneous" id="c"/>
    <shape type="cube"><ref name="interior" id="a"/><ref id="b"/></shape>""")
    scene, warned = load(path)
    said = [w.split(": ", 1)[1] for w in warned]
    assert said == [
        '<volume type="gridvolume">: wrap_mode "repeat" is read as "clamp" (they differ only in the outer half texel)',
        '<medium type="homogeneous" id="b">: a homogeneous medium needs a constant sigma_t; using the grid\'s mean '
        '(0.5, 0.5, 0.5)',
        '<medium type="homogeneous" id="b"> in <shape type="cube">: a shape\'s medium needs name="interior" or '
        'name="exterior"; ignored'], said
    assert scene.settings.spectral_mis is False
    assert scene.interfaces == [MediumInterface(0, -1)]
    for body, message in [
            ('<medium type="homogeneous" id="m"><phase type="hg"><float name="g" value="1"/></phase></medium>',
             r"g must lie in \(-1, 1\), got 1"),
            ('<medium type="heterogeneous" id="m"><volume type="gridvolume" name="sigma_t"/></medium>'
             '<shape type="cube"><ref name="interior" id="m"/></shape>', r'needs <string name="filename">'),
            ('<shape type="cube"><bsdf type="diffuse" name="interior"/><float name="exterior" value="1"/></shape>',
             r'"exterior" must be a <medium>'),
            ('<medium type="homogeneous" id="c"/><shape type="cube"><ref name="inside" id="c"/></shape>',
             r'<medium type="homogeneous" id="c"> in <shape type="cube">: a shape\'s medium is named "interior" or '
             r'"exterior"$'),
            ('<medium type="foggy" id="a"/><shape type="cube"><ref name="interior" id="a"/></shape>',
             r'bad\.xml:2: <medium type="foggy" id="a">: medium type "foggy" is not supported \(we render: '),
            ('<medium type="homogeneous" id="a"><phase type="sggx"/></medium>',
             r'<phase type="sggx">: phase type "sggx" is not supported'),
            ('<medium type="heterogeneous" id="a"><volume type="voxels" name="sigma_t"/></medium>',
             r'<volume type="voxels">: volume type "voxels" is not supported')]:
        with pytest.raises(SceneError, match=message):
            load(write_xml(tmp_path, body, "bad.xml"))
    write_vol(tmp_path / "six.vol", np.ones((1, 1, 1, 6)))
    with pytest.raises(SceneError, match="6 channels"):
        load(write_xml(tmp_path, '<medium type="heterogeneous" id="m"><volume type="gridvolume" name="sigma_t">'
                                 '<string name="filename" value="six.vol"/></volume></medium>'
                                 '<shape type="cube"><ref name="interior" id="m"/></shape>', "bad.xml"))


# ----------------------------------------------------------------------------- pbrt-v4
def pbrt(tmp_path, body, name="s.pbrt"):
    path = tmp_path / name
    path.write_text('LookAt 0 0 10  0 0 0  0 1 0\nCamera "perspective"\nWorldBegin\n'
                    'AttributeBegin AreaLightSource "diffuse" Shape "sphere" "float radius" 0.1 AttributeEnd\n'
                    + body)
    return path


TRI = 'Shape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2]'


def test_pbrt_media(tmp_path):
    """MakeNamedMedium homogeneous (sigma_a + sigma_s, scale, g; a preset) and uniformgrid (density
    nx ny nz on [p0, p1] in the medium's space, 0 beyond its texels); MediumInterface with two names,
    one (inside = outside: no transition), reset by AttributeEnd; the camera's medium is the outside
    one at Camera; "interface" shapes are index-matched boundaries; a ReverseOrientation sphere swaps
    inside and outside; simplevolpath: the single-channel estimate."""
    path = tmp_path / "s.pbrt"
    path.write_text(f"""Integrator "simplevolpath" "integer maxdepth" 4
MakeNamedMedium "cam" "string type" "homogeneous" "rgb sigma_a" [0.01 0.02 0.03] "rgb sigma_s" [0.1 0.1 0.1]
MediumInterface "" "cam"
Scale -1 1 1
LookAt 0 0 10  0 0 0  0 1 0
Camera "perspective"
WorldBegin
MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [0.5 0.5 0.5] "rgb sigma_s" [1 2 3]
  "float scale" 2 "float g" 0.5
MakeNamedMedium "milk" "string type" "homogeneous" "string preset" "Wholemilk"
AttributeBegin
  Translate 1 2 3
  Scale 2 2 2
  MakeNamedMedium "smoke" "string type" "uniformgrid" "integer nx" 2 "integer ny" 1 "integer nz" 3
    "float density" [0 1 2 3 4 5] "point3 p0" [-1 0 0] "point3 p1" [1 1 2] "float g" -2
AttributeEnd
AttributeBegin
  MediumInterface "fog" "cam"
  Material "interface"
  {TRI}
  MediumInterface "milk"
  Material "diffuse"
  {TRI}
  MediumInterface "smoke" ""
  ReverseOrientation
  Shape "sphere" "float radius" 1
AttributeEnd
{TRI}
AttributeBegin AreaLightSource "diffuse" Shape "sphere" "float radius" 0.1 AttributeEnd
""")
    scene, warned = load(path)
    assert warned == []
    names = [m.name for m in scene.media]
    assert names == ["fog", "cam", "smoke"]  # in order of first use; milk is never a transition
    fog, cam, smoke = scene.media
    assert scene.camera_medium == 1
    assert np.allclose(cam.extinction(), [0.11, 0.12, 0.13]) and np.allclose(cam.albedo, 0.1 / np.array([0.11, 0.12, 0.13]))
    assert np.allclose(fog.extinction(), [3, 5, 7]) and np.allclose(fog.albedo, [1 / 1.5, 2 / 2.5, 3 / 3.5])
    assert fog.phase == PhaseFunction("hg", 0.5)
    assert smoke.phase == PhaseFunction("hg", -0.99)  # pbrt clamps g
    assert smoke.density.data[:, 0, :, 0].tolist() == [[0, 1], [2, 3], [4, 5]] and smoke.density.outside == "zero"
    assert np.allclose(smoke.density.to_world @ [0, 0, 0, 1], [1 - 2, 2 + 0, 3 + 0, 1])
    assert np.allclose(smoke.density.to_world @ [1, 1, 1, 1], [1 + 2, 2 + 2, 3 + 4, 1])
    # the interface triangle: fog inside, cam outside; milk inside and out: no transition; the reversed
    # sphere: smoke outside its outward normal; after AttributeEnd: "" inside, cam outside, as before it
    assert scene.interfaces == [MediumInterface(0, 1, True, True), MediumInterface(-1, 2, True, False),
                                MediumInterface(-1, 1, True, False)]
    assert scene.face_interfaces.tolist() == [0, -1, 2]
    assert scene.shape_interfaces.tolist() == [1, 2]
    assert scene.settings.spectral_mis is False
    milk = pbrt(tmp_path, 'MakeNamedMedium "m" "string type" "homogeneous" "string preset" "Wholemilk" '
                          f'MediumInterface "m" "" {TRI}', "milk.pbrt")
    scene, _ = load(milk)
    assert np.allclose(scene.media[0].extinction(), np.add((2.55, 3.21, 3.77), (0.0011, 0.0024, 0.014)))


def test_pbrt_media_errors(tmp_path):
    for body, message in [
            (f'MediumInterface "nothing" "" {TRI}', r'medium "nothing" is not defined'),
            ('MakeNamedMedium "m" "string type" "homogeneous" MakeNamedMedium "m" "string type" "homogeneous"',
             r'medium "m" redefined'),
            ('MakeNamedMedium "m" "float scale" 1', r'needs "string type"'),
            ('MakeNamedMedium "m" "string type" "uniformgrid" "integer nx" 2 "float density" [1]',
             r"1 density values; expected nx\*ny\*nz = 2\*1\*1"),
            ('MakeNamedMedium "m" "string type" "uniformgrid"', r'no "density" values')]:
        with pytest.raises(SceneError, match=message):
            load(pbrt(tmp_path, body))
    scene, warned = load(pbrt(tmp_path, 'MakeNamedMedium "m" "string type" "homogeneous" "rgb Le" [1 1 1]\n'
                                        f'MediumInterface "m" ""\n{TRI}'))
    assert [w.split(": ", 1)[1] for w in warned] == [
        'MakeNamedMedium "m": "Le": emitting media are not supported; ignored']


# ----------------------------------------------------------------------------- TOML
TOML = """
[camera]
eye = [0, 1, 5]
look_at = [0, 1, 0]
medium = "air"

[media.fog]
sigma_t = [0.5, 1.0, 2.0]
albedo = 0.9
phase = "hg"
g = 0.3

[media.air]
sigma_t = 0.01
scale = 2

[media.smoke]
type = "grid"
density = [[[0, 1], [1, 2]], [[2, 3], [3, 4]]]
bounds = [[-1, 0, -1], [1, 2, 1]]
filter = "nearest"
outside = "zero"

[materials.light]
emission = 10

[[shape]]
type = "box"
size = 2
center = [0, 1, 0]
interior = "fog"
exterior = "air"
index_matched = true

[[shape]]
type = "sphere"
center = [0, 1, 0]
radius = 0.5
interior = "smoke"

[[shape]]
type = "quad"
points = [[-1, 3, -1], [1, 3, -1], [1, 3, 1], [-1, 3, 1]]
material = "light"
"""


def test_toml_media(tmp_path):
    """[media.NAME] (homogeneous and grid: inline density [z][y][x], bounds, filter, outside), a shape's
    interior / exterior / index_matched, [camera] medium; the kernel records of pack_media."""
    (tmp_path / "s.toml").write_text(TOML)
    scene, warned = load(tmp_path / "s.toml")
    assert warned == []
    fog, air, smoke = scene.media
    assert fog.phase == PhaseFunction("hg", 0.3) and fog.albedo == (0.9, 0.9, 0.9)
    assert np.allclose(air.extinction(), 0.02) and scene.camera_medium == 1
    assert smoke.density.data[1, 0, :, 0].tolist() == [2, 3] and np.allclose(smoke.density.to_world[:3, 3], [-1, 0, -1])
    assert scene.interfaces == [MediumInterface(0, 1, True, True), MediumInterface(2, -1, True, False)]
    assert scene.face_interfaces.tolist() == [0] * 12 + [-1, -1] and scene.shape_interfaces.tolist() == [1]
    assert scene.materials[scene.face_materials[0]].albedo == (0.0, 0.0, 0.0)
    b = pack_media(scene)
    assert [p.name for p in abi.MEDIA_PARAMS if not p.per_slot] == list(b)  # the per-path state is the renderer's
    m = b["media"]
    assert m["type"].tolist() == [abi.MEDIUM_TYPE_HOMOGENEOUS] * 2 + [abi.MEDIUM_TYPE_GRID]
    assert m["phase"].tolist() == [abi.PHASE_HG, abi.PHASE_ISOTROPIC, abi.PHASE_ISOTROPIC]
    assert np.allclose(m["majorant"][2], 4.0) and m["density_grid"].tolist() == [-1, -1, 0]
    assert b["medium_grids"][0]["filter"] == abi.GRID_NEAREST and b["medium_grids"][0]["outside"] == abi.GRID_ZERO
    assert b["grid_data"].tolist() == [0, 1, 1, 2, 2, 3, 3, 4]
    assert b["medium_interfaces"]["flags"].tolist() == [abi.MEDIUM_IF_TRANSITION | abi.MEDIUM_IF_NULL,
                                                        abi.MEDIUM_IF_TRANSITION]
    assert b["camera_medium"] == 1


@pytest.mark.parametrize("edit,message", [
    (("medium = \"air\"", "medium = \"water\""), r"\[camera\]: 'medium' must name a medium"),
    (("interior = \"smoke\"", "interior = \"steam\""), r"'interior' must name a medium"),
    (("g = 0.3", "g = 1.0"), r"'g' must lie in \(-1, 1\)"),
    (("phase = \"hg\"\n", ""), r"'g' is the asymmetry of phase = \"hg\""),
    (("albedo = 0.9", "albedo = 1.5"), r"'albedo' must be in \[0, 1\]"),
    (("sigma_t = 0.01", "sigma_t = -1"), r"'sigma_t' must be >= 0"),
    (("type = \"grid\"\n", ""), r"is for type = \"grid\" media"),
    (("density = [[[0, 1], [1, 2]], [[2, 3], [3, 4]]]", "density = [[0, 1], [1, 2]]"), r"'density' must be nested"),
    (("density = [[[0, 1], [1, 2]], [[2, 3], [3, 4]]]", 'file = "nothing.vol"'), r"grid file 'nothing.vol' not found"),
    (("bounds = [[-1, 0, -1], [1, 2, 1]]", "bounds = [[1, 0, -1], [1, 2, 1]]"), r"'bounds' must have its second"),
    (("index_matched = true", "index_matched = true\nmaterial = \"light\""), r"an index_matched shape has no material"),
])
def test_toml_media_errors(tmp_path, edit, message):
    (tmp_path / "s.toml").write_text(TOML.replace(*edit, 1))
    with pytest.raises(SceneError, match=message):
        load(tmp_path / "s.toml")


def test_toml_grid_from_vol_file(tmp_path, rng):
    data = rng.uniform(0, 1, (2, 3, 4, 3)).astype(np.float32)
    write_vol(tmp_path / "d.vol", data)
    (tmp_path / "s.toml").write_text(TOML.replace("density = [[[0, 1], [1, 2]], [[2, 3], [3, 4]]]",
                                                  'file = "d.vol"\nalbedo_file = "d.vol"'))
    scene, _ = load(tmp_path / "s.toml")
    smoke = scene.media[2]
    assert np.array_equal(smoke.density.data, data) and smoke.albedo_grid.data.shape == data.shape


# ----------------------------------------------------------------------------- the model
def test_validation_refuses_bad_media(tmp_path):
    (tmp_path / "s.toml").write_text(TOML)
    scene, _ = load(tmp_path / "s.toml")
    check_scene(scene)
    for change, message in [
            (lambda s: setattr(s.media[0], "albedo", (1.2, 0, 0)), "albedo must be 3 numbers in"),
            (lambda s: setattr(s.media[0], "sigma_t", (np.nan, 1, 1)), "sigma_t \\* scale must be"),
            (lambda s: setattr(s.media[0].phase, "g", 1.0), "-1 < g < 1"),
            (lambda s: setattr(s, "camera_medium", 7), "camera_medium 7"),
            (lambda s: setattr(s, "interfaces", [MediumInterface(5, -1)] + s.interfaces[1:]), "interior 5"),
            (lambda s: setattr(s, "face_interfaces", s.face_interfaces[:3]), "face_interfaces has 3 entries"),
            (lambda s: setattr(s.media[2].density, "data", -s.media[2].density.data), "density must be finite")]:
        bad, _ = load(tmp_path / "s.toml")
        change(bad)
        with pytest.raises(SceneValueError, match=message):
            check_scene(bad)


def test_renderer_takes_media_without_a_word(tmp_path):
    """render_full's scene argument passes a scene with media through untouched (the volumetric
    integrator renders them, cl/render/volpath.h), as it does a scene without; camera_relative moves the
    grids with the scene."""
    from pyopencl_rt.render.api import scene_argument

    (tmp_path / "s.toml").write_text(TOML)
    scene, _ = load(tmp_path / "s.toml")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert scene_argument(scene) is scene
    plain = load_scene("scenes/cornell-box.toml")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert scene_argument(plain) is plain
    moved = scene.camera_relative()
    assert np.allclose(moved.media[2].density.to_world[:3, 3], np.array([-1, 0, -1]) - np.array([0, 1, 5]))
    assert scene.media[2].density.to_world[0, 3] == -1  # the original is untouched


def test_grid_model():
    """Grid: shapes, maxima per channel (max_value when given), the majorant of a grid medium
    (extinction x the maxima), the local map of its box, and the host lookup at texel centres."""
    data = np.arange(24, dtype=np.float32).reshape(2, 3, 4, 1)
    g = Grid(data, to_world=np.diag([2.0, 3.0, 4.0, 1.0]))
    assert g.resolution == (4, 3, 2) and g.channels == 1 and g.maxima().tolist() == [23, 23, 23]
    m = Medium(sigma_t=(1, 2, 3), scale=0.5, density=g)
    assert m.majorant_rgb().tolist() == [11.5, 23, 34.5] and m.type == "grid"
    centres = np.array([[(x + 0.5) / 4 * 2, (y + 0.5) / 3 * 3, (z + 0.5) / 2 * 4] for z in range(2) for y in range(3)
                        for x in range(4)])
    assert np.allclose(g.eval(centres)[:, 0], np.arange(24))
    assert Grid(data, max_value=50).maxima().tolist() == [50, 50, 50]
    rgb = Grid(np.stack([data, 2 * data, 3 * data], -1)[..., 0, :])
    assert rgb.maxima().tolist() == [23, 46, 69]
    with pytest.raises(ValueError, match="a grid is"):
        Grid(np.zeros((2, 2)))
