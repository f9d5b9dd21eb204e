"""How next-event estimation picks a light (RenderSettings.light_sampler, render/lights.py):
Mitsuba's rule ("uniform": each emitter by its sampling_weight, then its triangles by area) from
the Mitsuba importer against the closed form, the settings of the TOML and pbrt-v4 readers, and
"uniform" and "power" giving the same image (the pick pmf is what the kernels divide by and weigh
MIS with)."""
from __future__ import annotations

import numpy as np

from pyopencl_rt.accel.bvh import build_bvh
from pyopencl_rt.device import abi
from pyopencl_rt.render.api import render_full
from pyopencl_rt.render.lights import build_lights
from pyopencl_rt.scene.model import Camera, Material, PointLight, RenderSettings, Scene

from harness import load_warned, tile_z

# a rectangle 2 x 6 (two triangles of area 6), radiance 50; a box of half-extents (1, 2, 3)
# (12 triangles: 2 bc on the +-x faces, 2 ca on +-y, 2 ab on +-z), radiance 1; a sphere of
# radius 0.5, radiance 3; a point light of sampling_weight 2
MITSUBA_LIGHTS = """<scene version="3.0.0">
    <shape type="rectangle">
        <transform name="to_world"><scale x="1" y="3"/><translate z="-5"/></transform>
        <emitter type="area"><rgb name="radiance" value="50"/></emitter>
    </shape>
    <shape type="cube">
        <transform name="to_world"><scale x="1" y="2" z="3"/><translate x="6"/></transform>
        <emitter type="area"><rgb name="radiance" value="1"/></emitter>
    </shape>
    <shape type="sphere">
        <point name="center" x="-6" y="0" z="0"/><float name="radius" value="0.5"/>
        <emitter type="area"><rgb name="radiance" value="3"/></emitter>
    </shape>
    <emitter type="point">
        <point name="position" x="0" y="5" z="0"/><rgb name="intensity" value="1000"/>
        <float name="sampling_weight" value="2"/>
    </emitter>
</scene>
"""


def light_table(scene):
    bvh = build_bvh(scene.vertices, scene.faces)
    lights, _, _, _ = build_lights(scene, bvh)
    return lights, bvh


def test_mitsuba_picks_emitters_by_sampling_weight_then_area(tmp_path):
    """Each emitter sampling_weight / sum (1, 1, 1, 2 of 5) whatever its size and power; within the
    box, each triangle its area's share (closed form from the half-extents)."""
    path = tmp_path / "lights.xml"
    path.write_text(MITSUBA_LIGHTS)
    scene, _ = load_warned(path)
    assert scene.settings.light_sampler == "uniform"
    lights, bvh = light_table(scene)
    pmf = lights["pmf"].astype(np.float64)
    kind = lights["kind"]
    assert np.isclose(pmf.sum(), 1.0, rtol=1e-6)
    assert np.allclose(pmf[kind == abi.LIGHT_POINT], [2 / 5], rtol=1e-6)
    assert np.allclose(pmf[kind == abi.LIGHT_SHAPE], [1 / 5], rtol=1e-6)
    tri = np.nonzero(kind == abi.LIGHT_TRIANGLE)[0]
    emitter = scene.face_emitters[bvh.prim_ids[lights["prim"][tri]]]
    a, b, c = 1.0, 2.0, 3.0
    total = 8 * (a * b + b * c + c * a)
    normal_axis = []
    for i in tri:  # the axis the triangle faces, from its corners
        v = np.stack([bvh.triangles[k][lights["prim"][i], :3] for k in ("v0", "v1", "v2")]).astype(np.float64)
        normal_axis.append(int(np.argmax(np.abs(np.cross(v[1] - v[0], v[2] - v[0])))))
    normal_axis = np.array(normal_axis)
    rect, box = np.unique(emitter)
    assert np.allclose(pmf[tri][emitter == rect], [1 / 10, 1 / 10], rtol=1e-6)
    face_area = {0: 2 * b * c, 1: 2 * c * a, 2: 2 * a * b}  # one triangle of a face of the box
    expect = np.array([face_area[k] / total / 5 for k in normal_axis[emitter == box]])
    assert len(expect) == 12 and np.isclose(expect.sum(), 1 / 5)
    assert np.allclose(pmf[tri][emitter == box], expect, rtol=1e-6)


def test_power_is_the_default_and_settings_are_read(tmp_path):
    """Our scenes pick by power unless told otherwise: TOML [render] light_sampler, pbrt-v4's
    Integrator "string lightsampler" (uniform, power, bvh; exhaustive as power; our default where
    the file names none)."""
    toml = tmp_path / "s.toml"
    body = ('[materials.lamp]\nemission = 1\n[[shape]]\ntype = "triangle"\nmaterial = "lamp"\n'
            'points = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\n')
    toml.write_text(body)
    assert load_warned(toml)[0].settings.light_sampler == "power"
    toml.write_text('[render]\nlight_sampler = "uniform"\n' + body)
    assert load_warned(toml)[0].settings.light_sampler == "uniform"
    for name, expect in (("uniform", "uniform"), ("power", "power"), ("bvh", "bvh"), ("exhaustive", "power"),
                         (None, "power")):
        pbrt = tmp_path / f"{name}.pbrt"
        param = "" if name is None else f' "string lightsampler" "{name}"'
        pbrt.write_text(f'Integrator "path"{param}\nWorldBegin\n'
                        'AttributeBegin\nAreaLightSource "diffuse"\n'
                        'Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0]\nAttributeEnd\n')
        scene, warned = load_warned(pbrt)
        assert scene.settings.light_sampler == expect
        assert bool([w for w in warned if "lightsampler" in w]) == (name == "exhaustive")


def two_lamps_scene(light_sampler: str) -> Scene:
    """A diffuse floor lit by a small bright quad, a large dim one and a point light (the
    independent sampler: per-pixel variances that are the error's, not an over-estimate of it)."""
    v = np.array([[-4, 0, -4], [-4, 0, 4], [4, 0, 4], [4, 0, -4],  # floor, facing +y
                  [-3, 2, -0.2], [-2.6, 2, -0.2], [-2.6, 2, 0.2], [-3, 2, 0.2],  # small lamp facing -y
                  [0, 3, -2], [3, 3, -2], [3, 3, 2], [0, 3, 2]], np.float32)  # large lamp facing -y
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [8, 9, 10], [8, 10, 11]], np.int32)
    mats = [Material("floor", albedo=(0.6, 0.6, 0.6)), Material("bright", albedo=(0, 0, 0), emission=(80, 80, 80)),
            Material("dim", albedo=(0, 0, 0), emission=(0.5, 0.5, 0.5))]
    return Scene(vertices=v, faces=f, face_materials=np.array([0, 0, 1, 1, 2, 2], np.int32), materials=mats,
                 camera=Camera(eye=(0, 6, 6), look_at=(0, 0, 0), up=(0, 1, 0), fov=60),
                 settings=RenderSettings(width=16, height=16, max_depth=3, integrator="path",
                                         sampler="independent", light_sampler=light_sampler),
                 lights=[PointLight(position=(2, 1, 2), intensity=(2, 2, 2))])


def test_uniform_and_power_picking_render_the_same_image(device):
    """The same mean image with either picking rule: every 4 x 4 tile, and the whole image's mean,
    within 4.5 standard errors (from both renders' per-pixel variances); the pmf of the light
    table differs (the bright lamp's triangles: most of the power picks, 2 of 5 uniform ones)."""
    renders = {}
    for seed, mode in enumerate(("power", "uniform"), 5):  # independent samples: the variances hold
        scene = two_lamps_scene(mode)
        lights, _ = light_table(scene)
        renders[mode] = (lights, render_full(scene, spp=1024, device=device, seed=seed))
    (lp, rp), (lu, ru) = renders["power"], renders["uniform"]
    assert not np.allclose(lp["pmf"], lu["pmf"], atol=1e-3)
    assert np.allclose(lu["pmf"], 1 / 5, atol=1e-6)  # 4 triangles and a point light, each by itself
    for r in (rp, ru):
        assert r.info["nonfinite_samples"] == 0
    a, b = rp.image.astype(np.float64), ru.image.astype(np.float64)
    z = tile_z(a, rp.film.variance_of_mean(), b, ru.film.variance_of_mean(), tile=4)
    assert z.max() < 4.5, z.max()
    va, vb = rp.film.variance_of_mean()[..., 0], ru.film.variance_of_mean()[..., 0]  # grey: one channel
    z_mean = abs(a[..., 0].mean() - b[..., 0].mean()) / np.sqrt((va.mean() + vb.mean()) / va.size)
    assert z_mean < 4.5, (a.mean(), b.mean(), z_mean)


def test_bad_light_picking_fields_are_refused():
    """check_scene names a light_sampler we do not have, an emitter index beyond the weights and a
    negative sampling_weight."""
    import dataclasses

    import pytest

    from pyopencl_rt.scene.validate import SceneValueError, check_scene

    check_scene(two_lamps_scene("uniform"))
    for change, message in (
            (lambda s: setattr(s, "settings", dataclasses.replace(s.settings, light_sampler="tree")), "light_sampler"),
            (lambda s: setattr(s, "face_emitters", np.array([-1, -1, 0, 0, 1, 1], np.int32)), "face_emitters"),
            (lambda s: setattr(s, "lights", [PointLight(sampling_weight=-1.0)]), "sampling_weight")):
        scene = two_lamps_scene("uniform")
        scene.emitter_weights = [1.0]
        change(scene)
        with pytest.raises(SceneValueError, match=message):
            check_scene(scene)
