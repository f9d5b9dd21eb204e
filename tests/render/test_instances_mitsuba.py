"""Mitsuba 3's shapegroup / instance (pyopencl_rt/scene/loaders/instancing.py) rendered as Mitsuba
renders them: one small XML scene, a group instanced three times (moved; scaled unevenly; rotated),
rendered by Mitsuba (scalar_rgb) at test time and by us, compared tile by tile."""
from __future__ import annotations

import warnings

import numpy as np

import pyopencl_rt as rt
from pyopencl_rt.scene.loaders import load_scene

import harness
from pyopencl_rt.scene.shapes.sphere import of as sphere_of

W, H, TILE = 48, 32, 8

# an octahedron shaded smoothly (its vertex normals are its corners' directions): its shading
# normals show whether they were moved by the inverse transpose
OCTAHEDRON = ("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
              "vn 1 0 0\nvn -1 0 0\nvn 0 1 0\nvn 0 -1 0\nvn 0 0 1\nvn 0 0 -1\n"
              + "".join(f"f {a}//{a} {b}//{b} {c}//{c}\n" for a, b, c in
                        [(1, 3, 5), (3, 2, 5), (2, 4, 5), (4, 1, 5), (3, 1, 6), (2, 3, 6), (4, 2, 6), (1, 4, 6)]))


def _scene(tmp_path, variant=False) -> str:
    """The group: the octahedron (scaled 0.5 by its own to_world), a sphere above it (moved by its
    own to_world) and a small panel below and behind; three instances: moved left; scaled (1, 1.6,
    0.6) and turned about x (the sphere an ellipsoid); turned about y and z and moved right.  Over a
    grey wall, under a point light and a constant sky.  ``variant``: the middle instance without its
    uneven scale, to show that the comparison sees it."""
    (tmp_path / "octa.obj").write_text(OCTAHEDRON)
    shapes = ('<shape type="obj"><string name="filename" value="octa.obj"/>'
              '<transform name="to_world"><scale value="0.5"/></transform>'
              '<bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.3, 0.2"/></bsdf></shape>'
              '<shape type="sphere"><float name="radius" value="0.3"/>'
              '<transform name="to_world"><translate x="0.1" y="0.75"/></transform>'
              '<bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.7, 0.3"/></bsdf></shape>'
              '<shape type="rectangle"><transform name="to_world"><scale x="0.6" y="0.3"/><translate y="-0.7" '
              'z="-0.4"/></transform><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.3, 0.9"/></bsdf>'
              '</shape>')
    instances = ['<translate x="-2.1"/>',
                 ("" if variant else '<scale x="1" y="1.6" z="0.6"/>') + '<rotate x="1" angle="-30"/>',
                 '<rotate y="1" angle="50"/><rotate z="1" angle="35"/><translate x="2.1" y="0.1"/>']
    content = f'<shape type="shapegroup" id="g">{shapes}</shape>\n' + "".join(
        f'<shape type="instance"><ref id="g"/><transform name="to_world">{t}</transform></shape>' for t in instances)
    wall = '<bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>'
    body = harness.mitsuba_stage(harness.mitsuba_sensor("0.2, 0.3, 4.5", 60, W, H, max_depth=3, spp=16), content, wall,
                                 light_z=4, intensity=15)
    return harness.write_mitsuba_scene(tmp_path / f"instancing{'_variant' if variant else ''}.xml", body)




def test_instances_match_mitsuba(tmp_path):
    """48 x 32, a shapegroup (a smooth octahedron, a sphere, a panel, each with its own to_world)
    instanced three times (moved; scaled unevenly and turned: the sphere an ellipsoid, the normals
    by the inverse transpose; turned about two axes), by Mitsuba (4 batches of 32 spp: their spread
    its variance) and by us (256 spp): every 8 x 8 tile within 4.5 sigma (measured: 3.6; with each
    corner normal made unit length after the uneven scale, as for a mesh that is not instanced,
    the octahedron's tiles were 10 sigma off).  Mitsuba's render of the variant (the middle instance
    not scaled) is more than 10 sigma from ours in some tile (measured: 111): the comparison sees
    the instance's transform."""
    mi = harness.mitsuba()

    path = _scene(tmp_path)
    theirs, their_var = harness.mitsuba_batches(mi, path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # every element is read without a word
        scene = load_scene(path)
    assert len(scene.instances) == 3 and len(sphere_of(scene.shapes)) == 2
    r = rt.render_full(scene, spp=256, device="cpu", seed=3)
    ours, var = r.image.astype(np.float64), r.film.variance_of_mean()
    z = harness.tile_z(ours, var, theirs, their_var, TILE)
    assert z.max() < 4.5, np.round(z.max(-1), 1)
    other, other_var = harness.mitsuba_batches(mi, _scene(tmp_path, variant=True))
    z_other = harness.tile_z(ours, var, other, other_var, TILE).max(-1)
    assert z_other.max() > 10, np.round(z_other, 1)
