"""Mitsuba 3's directionalarea emitter (cl/render/lights.h, "directional area"): a flat emitter whose
light leaves along its normal alone, sampled by projecting the shading point onto it.  Mitsuba's
path tracer does not sample it (its image is black); its particle tracer does, and is the reference."""
from __future__ import annotations

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.errors import UserError
from pyopencl_rt.scene.loaders import load_scene

import harness

W, H = 64, 48
TILE = 8
RADIANCE = (2.0, 2.0, 1.5)
ALBEDO = 0.5


def _scene(tmp_path, integrator="path", max_depth=3, tilt=70, box=True, emitter_extra="", name="da") -> str:
    """A floor (albedo 0.5) under a 2.4 x 1.6 directionalarea rectangle at height 3, its normal turned
    ``tilt`` degrees from +z about x (90: straight down), and a small red cube in its beam."""
    cube = ('<shape type="cube"><transform name="to_world"><scale value="0.4"/><translate x="0.3" y="0.4"/>'
            '</transform><bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.3, 0.2"/></bsdf></shape>')
    rgb = ", ".join(map(str, RADIANCE))
    body = f"""<scene version="3.0.0">
<integrator type="{integrator}"><integer name="max_depth" value="{max_depth}"/></integrator>
<sensor type="perspective"><float name="fov" value="45"/>
  <transform name="to_world"><lookat origin="0, 6, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
  <sampler type="independent"><integer name="sample_count" value="256"/></sampler>
  <film type="hdrfilm"><integer name="width" value="{W}"/><integer name="height" value="{H}"/><rfilter type="box"/></film>
</sensor>
<shape type="rectangle">
  <transform name="to_world"><scale value="4"/><rotate x="1" angle="-90"/></transform>
  <bsdf type="diffuse"><rgb name="reflectance" value="{ALBEDO}"/></bsdf>
</shape>
{cube if box else ""}
<shape type="rectangle">
  <transform name="to_world"><scale x="1.2" y="0.8"/><rotate x="1" angle="{tilt}"/><translate y="3"/></transform>
  <emitter type="directionalarea"><rgb name="radiance" value="{rgb}"/>{emitter_extra}</emitter>
</shape>
</scene>
"""
    path = tmp_path / f"{name}_{integrator}_{max_depth}_{tilt}.xml"
    path.write_text(body)
    return str(path)


def test_matches_mitsubas_particle_tracer(tmp_path):
    """64 x 48: the beam tilted 20 degrees off vertical onto the floor, the cube's shadow in it and
    two bounces of indirect light, by Mitsuba's ptracer (4 batches of 256 spp: their spread its
    variance) and by us (the path tracer, 256 spp): every 8 x 8 tile within 4.5 sigma and the image
    means within 1% (measured: the largest tile 0.7 sigma, the means 0.02% apart).  With the beam's
    radiance 10% higher, Mitsuba's image is more than 4.5 sigma away in some tile (measured: 12):
    the comparison sees the emitter's strength."""
    mi = harness.mitsuba()
    theirs, their_var = harness.mitsuba_batches(mi, _scene(tmp_path, "ptracer"), batches=4)
    assert theirs.mean() > 0.01  # the particle tracer sees the beam (Mitsuba's path tracer: black)
    r = rt.render_full(load_scene(_scene(tmp_path)), spp=256, device="cpu", seed=1)
    ours, var = r.image.astype(np.float64), r.film.variance_of_mean()
    z = harness.tile_z(ours, var, theirs, their_var, TILE)
    assert z.max() < 4.5, np.round(z.max(-1), 1)
    assert abs(ours.mean() / theirs.mean() - 1) < 0.01, (ours.mean(), theirs.mean())
    z_brighter = harness.tile_z(ours * 1.1, var * 1.21, theirs, their_var, TILE)
    assert z_brighter.max() > 4.5


TOML = f"""camera = {{eye = [0, 6, 5], look_at = [0, 0, 0], fov = 45}}
film = {{width = {W}, height = {H}}}
render = {{max_depth = 2}}
[materials.floor]
albedo = [{ALBEDO}, {ALBEDO}, {ALBEDO}]
[materials.beam]
albedo = [0, 0, 0]
emission = {list(RADIANCE)}
emission_directional = true
[[shape]]
type = "quad"
material = "floor"
points = [[-4, 0, -4], [-4, 0, 4], [4, 0, 4], [4, 0, -4]]
[[shape]]  # its front, (p1 - p0) x (p2 - p0), faces down
type = "quad"
material = "beam"
points = [[-1.2, 3, -0.8], [1.2, 3, -0.8], [1.2, 3, 0.8], [-1.2, 3, 0.8]]
"""


@pytest.mark.parametrize("fmt", ["mitsuba", "toml"])
def test_direct_light_is_the_radiance_times_the_albedo_over_pi(tmp_path, fmt):
    """The beam straight down, direct light only (max_depth 2), no cube, from Mitsuba XML and from
    our TOML (`emission_directional`): a floor point whose vertical meets the emitter gets
    irradiance R (a parallel beam: no falloff with the distance), so its pixel is albedo R / pi
    (within 4.5 standard errors over the lit pixels; the two triangles are picked by power, so half
    the samples miss); a point beyond the emitter's outline, by a margin of a pixel's footprint, is
    exactly 0."""
    if fmt == "toml":
        path = tmp_path / "beam.toml"
        path.write_text(TOML)
    else:
        path = _scene(tmp_path, max_depth=2, tilt=90, box=False)
    r = rt.render_full(load_scene(str(path)), spp=64, device="cpu", seed=2, aovs="position")
    p = np.asarray(r.layers["position"], np.float64)
    image, var = r.image.astype(np.float64), r.film.variance_of_mean()
    on_floor = np.abs(p[..., 1]) < 1e-4
    x, z = np.abs(p[..., 0]), np.abs(p[..., 2])
    margin = 0.08  # wider than a pixel's footprint on the floor here
    lit = on_floor & (x < 1.2 - margin) & (z < 0.8 - margin)
    dark = on_floor & ((x > 1.2 + margin) | (z > 0.8 + margin))
    assert lit.sum() > 100 and dark.sum() > 300, (lit.sum(), dark.sum())
    expected = ALBEDO * np.asarray(RADIANCE) / np.pi
    mean = image[lit].mean(0)
    se = np.sqrt(var[lit].sum(0)) / lit.sum()
    assert (np.abs(mean - expected) < 4.5 * se).all(), (mean, expected, se)
    assert (image[dark] == 0).all()


def test_every_lane_width_renders_the_same_bits(device, monkeypatch, tmp_path):
    """The Mitsuba scene: one path per work-item and the device's lane width give the same film bit
    for bit, with the same rays."""
    widths = ("0", harness.forced_lanes(device))
    scene = load_scene(_scene(tmp_path))
    harness.assert_same_lanes(harness.lane_renders(scene, device, monkeypatch, widths, spp=4, seed=2, width=32,
                                                   height=24))


def test_a_directional_emitter_on_a_sphere_or_two_sided_is_refused(tmp_path):
    """From TOML (or the API), a directional emission on a sphere, or two-sided: one line (scene/validate.py)."""
    sphere = TOML + '[[shape]]\ntype = "sphere"\nmaterial = "beam"\ncenter = [0, 1, 0]\nradius = 0.3\n'
    two_sided = TOML.replace("emission_directional = true", "emission_directional = true\ntwo_sided = true")
    for name, text, needle in (("s.toml", sphere, "on a sphere"), ("t.toml", two_sided, "one-sided")):
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(UserError) as caught:
            rt.render_full(load_scene(str(path)), spp=1, device="cpu", width=8, height=8)
        assert "\n" not in str(caught.value) and needle in str(caught.value), str(caught.value)


@pytest.mark.parametrize("what,needle", [
    ("sphere", "curved shape"),
    ("to_world", "to_world"),
    ("texture", "texture"),
    ("curved mesh", "curved mesh"),
])
def test_what_it_cannot_render_is_one_line(tmp_path, what, needle):
    """A directionalarea on a sphere (no plane to project onto), with a to_world of its own (Mitsuba
    refuses it too), with a textured radiance, or on a curved mesh with vertex normals (Mitsuba emits
    along the interpolated normal): one line naming it."""
    emitter = '<emitter type="directionalarea"><rgb name="radiance" value="1"/></emitter>'
    if what == "sphere":
        shape = f'<shape type="sphere">{emitter}</shape>'
    elif what == "to_world":
        shape = ('<shape type="rectangle"><emitter type="directionalarea"><transform name="to_world">'
                 '<translate x="1"/></transform></emitter></shape>')
    elif what == "texture":
        shape = ('<shape type="rectangle"><emitter type="directionalarea"><texture name="radiance" '
                 'type="checkerboard"/></emitter></shape>')
    else:
        obj = tmp_path / "bent.obj"
        obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 1\nf 1 2 3\nf 2 4 3\n")
        shape = f'<shape type="obj"><string name="filename" value="{obj}"/>{emitter}</shape>'
    path = tmp_path / f"refused_{what.replace(' ', '_')}.xml"
    path.write_text(f'<scene version="3.0.0">{shape}</scene>')
    with pytest.raises(UserError) as caught:
        load_scene(str(path))
    message = str(caught.value)
    assert "\n" not in message and needle in message, message
