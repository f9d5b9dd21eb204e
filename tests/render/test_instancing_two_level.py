"""Two-level instancing (cl/accel/instances.h, pyopencl_rt/accel/instances.py): the TLAS over
instances and one BLAS per shape group give the hits and the image of the flattened scene
(pyopencl_rt/scene/instances.py:flattened, the copies the loaders made before), at width 1 and in
lanes; device memory grows with the instances, not their triangles; Mitsuba and pbrt-v4 files take
this path.

Build cost (CI runs the suite on 2 cores): the flattened references are compiled as the two-level
scenes are, with HAS_INSTANCES and an empty TLAS (:func:`as_two_level`), and the renders with the
scenes' own features (one small program shared by every render here; the suite's every-feature
program with HAS_INSTANCES would be built for this file alone), so each width and layout is one
build.  That an empty TLAS changes no hit is asserted bit for bit against the plain program."""
from __future__ import annotations

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.accel.device_bvh import layout_defines, node_buffer
from pyopencl_rt.device import abi
from pyopencl_rt.scene.instances import flattened, scene_bvh, two_level
from pyopencl_rt.scene.loaders import load_scene
from pyopencl_rt.scene.loaders.instancing import INSTANCING_ENV
from pyopencl_rt.scene.lights import Environment, PointLight
from pyopencl_rt.scene.model import BlasGroup, Instance, Material, Scene

import harness

OCTAHEDRON = ("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
              "vn 1 0 0\nvn -1 0 0\nvn 0 1 0\nvn 0 -1 0\nvn 0 0 1\nvn 0 0 -1\n"
              + "".join(f"f {a}//{a} {b}//{b} {c}//{c}\n" for a, b, c in
                        [(1, 3, 5), (3, 2, 5), (2, 4, 5), (4, 1, 5), (3, 1, 6), (2, 3, 6), (4, 2, 6), (1, 4, 6)]))
# moved; scaled unevenly and turned; mirrored, turned about two axes and moved
TRANSFORMS = ['<translate x="-2.1"/>', '<scale x="1" y="1.6" z="0.6"/><rotate x="1" angle="-30"/>',
              '<scale x="-1" y="1" z="1"/><rotate y="1" angle="50"/><rotate z="1" angle="35"/><translate x="2.1" y="0.1"/>']


def mitsuba_file(tmp_path) -> str:
    """A group (a smooth octahedron scaled by its own to_world, a panel) in three instances
    (TRANSFORMS) before a wall, under a point light."""
    (tmp_path / "octa.obj").write_text(OCTAHEDRON)
    shapes = ('<shape type="obj"><string name="filename" value="octa.obj"/>'
              '<transform name="to_world"><scale value="0.5"/></transform>'
              '<bsdf type="diffuse"><rgb name="reflectance" value="0.8, 0.3, 0.2"/></bsdf></shape>'
              '<shape type="rectangle"><transform name="to_world"><scale x="0.6" y="0.3"/><translate y="-0.7" '
              'z="-0.4"/></transform><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.3, 0.9"/></bsdf>'
              '</shape>')
    content = f'<shape type="shapegroup" id="g">{shapes}</shape>' + "".join(
        f'<shape type="instance"><ref id="g"/><transform name="to_world">{t}</transform></shape>' for t in TRANSFORMS)
    wall = '<bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>'
    body = harness.mitsuba_stage(harness.mitsuba_sensor("0.2, 0.3, 4.5", 60, 24, 16, max_depth=3, spp=4), content,
                                 wall, light_z=4, intensity=15)
    return harness.write_mitsuba_scene(tmp_path / "instancing.xml", body)


@pytest.fixture
def two_level_scene(tmp_path, monkeypatch):
    monkeypatch.setenv(INSTANCING_ENV, "two-level")
    scene = load_scene(mitsuba_file(tmp_path))
    assert [i.blas for i in scene.instances] == [0, 0, 0] and len(scene.blas_groups) == 1
    return scene


def as_two_level(scene):
    """``scene`` (without two-level instances) with an empty shape group (no faces, no instance):
    drawn the same, by the two-level scenes' program (HAS_INSTANCES, a TLAS with no instance)."""
    assert not two_level(scene)
    s = flattened(scene)
    s.blas_groups = [BlasGroup("empty", len(s.faces), 0)]
    return s


SOURCE = r"""
#include "scene/scene.h"
__kernel void hits(__global const BVHNode *nodes, __global const float4 *tris,
                   __global const BVHNode *shape_nodes, __global const Shape *shapes,
                   __global const BVHNode *tlas, __global const Instance *instances,
                   __global const BVHNode *blas_nodes, __global const float *ro, __global const float *rd,
                   __global const float *rmax, __global float *t_out, __global int *prim_out,
                   __global int *inst_out, __global int *occ_out)
{
    const int i0 = get_global_id(0) * PACKET_WIDTH;
    pvec3 o, d;
    pfloat tmax;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        PLANE(o.x, k) = ro[3 * (i0 + k)]; PLANE(o.y, k) = ro[3 * (i0 + k) + 1]; PLANE(o.z, k) = ro[3 * (i0 + k) + 2];
        PLANE(d.x, k) = rd[3 * (i0 + k)]; PLANE(d.y, k) = rd[3 * (i0 + k) + 1]; PLANE(d.z, k) = rd[3 * (i0 + k) + 2];
        PLANE(tmax, k) = rmax[i0 + k];
    }
    pfloat t, u, v;
    pint prim, inst = PINT(-1);
    scene_closest_hit(nodes, tris, shape_nodes, shapes, o, d, PTRUE, &t, &prim, &u, &v INSTANCE_HIT_ARGS(&inst));
    const pint occ = scene_occluded(nodes, tris, shape_nodes, shapes, o, d, PTRUE, tmax INSTANCE_ARGS);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        t_out[i0 + k] = PLANE(t, k); prim_out[i0 + k] = PLANE_I(prim, k);
        inst_out[i0 + k] = PLANE_I(inst, k); occ_out[i0 + k] = PLANE_I(occ, k) != 0;
    }
}
"""


def trace(runtime, scene, width, layout, o, d, tmax):
    """Closest hits (t, the face in the flattened scene's numbering, -1: none) and any-hit answers
    of the rays, by a harness kernel compiled with HAS_INSTANCES where the scene has shape groups."""
    bvh = scene_bvh(scene)
    defines = {"HAS_TRIANGLES": True, "PACKET_WIDTH": width, **layout_defines(layout)}
    if scene.blas_groups:
        defines["HAS_INSTANCES"] = True
        extra = bvh.buffers(layout)
    else:
        extra = {"tlas": np.zeros(1, abi.BVH_NODE), "blas_nodes": np.zeros(1, abi.BVH_NODE),
                 "instances": np.zeros(1, abi.INSTANCE)}
    k = harness.Kernels(SOURCE, defines=defines, local_size=1)
    nodes = node_buffer(getattr(bvh, "world", bvh), layout)
    blas = extra["blas_nodes"]
    n = len(o)
    t, prim, inst, occ = k(runtime, "hits", n // width, nodes=np.frombuffer(nodes.tobytes(), abi.BVH_NODE),
                           tris=bvh.triangles.view(np.float32).reshape(-1, 4), shape_nodes=np.zeros(1, abi.BVH_NODE),
                           shapes=np.zeros(1, abi.SHAPE),
                           tlas=extra["tlas"], instances=extra["instances"],
                           blas_nodes=np.frombuffer(blas.tobytes() + bytes(-len(blas.tobytes()) % 64 or 64), abi.BVH_NODE),
                           ro=o, rd=d, rmax=tmax, t_out=n, prim_out=n, inst_out=n, occ_out=n)
    # the face each hit is of, in the flattened scene's numbering
    face = np.where(prim >= 0, bvh.prim_ids[np.maximum(prim, 0)], -1)
    if two_level(scene):
        g = scene.blas_groups[0]
        flat_first = {j: r.first_face for j, r in enumerate(flattened(scene).instances)}
        idx = np.asarray(bvh.order)[np.maximum(inst, 0)]
        moved = np.array([flat_first[j] for j in idx]) + face - g.first_face
        face = np.where(inst >= 0, moved, face)
    else:
        assert (inst == -1).all()
    return t, face, occ


def random_rays(scene, rng, n):
    """Rays from points around the scene toward points on its instances and everywhere."""
    flat = flattened(scene)
    v = np.asarray(flat.vertices, np.float64)
    lo, hi = v.min(0) - 0.5, v.max(0) + 0.5
    o = rng.uniform(lo, hi, (n, 3))
    target = np.where(rng.random((n, 1)) < 0.7, v[rng.integers(0, len(v), n)] + rng.normal(0, 0.2, (n, 3)),
                      rng.uniform(lo, hi, (n, 3)))
    d = target - o
    tmax = rng.uniform(0.2, 1.2, n)  # shadow segments ending before or past the target
    return o.astype(np.float32), d.astype(np.float32), tmax.astype(np.float32)


@pytest.mark.parametrize("width,layout", [(1, "binary"), (1, "wide8"), (8, "wide8")])
def test_two_level_hits_match_flattened(device, runtime, rng, two_level_scene, width, layout):
    """4096 random rays through a group under a translation, an uneven scale with a turn, and a
    mirror with two turns: closest-hit t within 2e-5 max(t, 1) of the flattened scene's (the ray's
    move into the group rounds relative to the coordinates), the same face where no two faces are within that of each other,
    and the same any-hit answer but for segments ending within 1e-4 of a surface; binary and 8-wide
    BLAS layouts, one ray per work-item and 8 lanes (each lane enters its instances alone).  The
    flattened scene is traced by the same program (an empty TLAS); at 8 lanes (the lane loop over
    the TLAS) also by the program without HAS_INSTANCES, bit for bit the same."""
    if width > 1:
        harness.require_lane_kernels(device, width)
    o, d, tmax = random_rays(two_level_scene, rng, 4096)
    t2, f2, occ2 = trace(runtime, two_level_scene, width, layout, o, d, tmax)
    flat = flattened(two_level_scene)
    t1, f1, occ1 = trace(runtime, as_two_level(flat), width, layout, o, d, tmax)
    if width > 1:
        for a, b in zip(trace(runtime, flat, width, layout, o, d, tmax), (t1, f1, occ1)):
            assert np.array_equal(a, b)
    hit = np.isfinite(t1)
    assert hit.mean() > 0.4 and (f1[hit] >= 0).all()
    assert np.array_equal(np.isfinite(t2), hit)
    # the move into the group rounds relative to the coordinates (about 1 here), not to t
    err = np.abs(t2[hit] - t1[hit]) / np.maximum(t1[hit], 1.0)
    assert err.max() < 2e-5, err.max()
    # the same face but at ties (edges where two faces meet within the rounding)
    assert (f2[hit] == f1[hit]).mean() > 0.995
    near = np.abs(t1 - tmax) <= 1e-4 * np.maximum(t1, 1)
    assert np.array_equal(occ2[~near], occ1[~near])
    assert occ1.any() and (~occ1).any()


def test_two_level_renders_the_flattened_image(device, own_features, two_level_scene):
    """24 x 16, 4 spp, the same seed, the CPU's default schedule (the megakernel in lanes where
    PoCL's x86 device builds them, each lane walking its instances alone; else one path per
    work-item): the two-level scene's image is the flattened scene's up to the transform's rounding
    (measured: max 5e-7 absolute on pixel values about 0.2, in the wavefront and the lanes alike;
    asserted 1e-5).  Both are one program (the flattened scene with an empty TLAS, its world hits
    checked bit for bit above).  The wavefront stages and 8 lanes against width 1 are covered hit
    by hit above."""
    a = rt.render_full(two_level_scene, spp=4, device=device, seed=5)
    b = rt.render_full(as_two_level(flattened(two_level_scene)), spp=4, device=device, seed=5)
    assert "HAS_INSTANCES" in a.info["features"] and a.info["features"] == b.info["features"]
    assert a.info["lanes"] == b.info["lanes"]
    assert a.image.mean() > 0.05
    assert np.abs(a.image - b.image).max() < 1e-5


def test_memory_grows_with_instances_not_triangles(device, own_features):
    """10^5 instances of a 128-triangle group (a subdivided octahedron, smooth) on a grid, each
    turned: the device buffers hold the group's triangles once (tris: 128 x 48 bytes), 112 bytes a
    record and at most 64 bytes of TLAS per instance, where flattening would take 1.28e7 triangles
    (610 MB of triangles alone); a 16 x 16 image renders with hits on the instances (under the
    image test's program: the same features)."""
    n = 100_000
    v, f = subdivided_octahedron(2)
    side = int(np.ceil(np.sqrt(n)))
    ij = np.stack(np.divmod(np.arange(n), side), axis=1).astype(np.float64)
    m = np.tile(np.eye(4), (n, 1, 1))
    angle = np.arange(n) * 0.7
    m[:, 0, 0], m[:, 0, 2], m[:, 2, 0], m[:, 2, 2] = np.cos(angle), np.sin(angle), -np.sin(angle), np.cos(angle)
    m[:, 0, 3], m[:, 2, 3] = 3 * (ij[:, 0] - side / 2), -3 * ij[:, 1]
    scene = Scene(vertices=v.astype(np.float32), faces=f.astype(np.int32), face_materials=np.zeros(len(f), np.int32),
                  materials=[Material(albedo=(0.7, 0.7, 0.7))])
    scene.blas_groups = [BlasGroup("o", 0, len(f))]
    scene.instances = [Instance("o", mk, blas=0) for mk in m]
    scene.normals = v[f].astype(np.float32)  # the unit sphere's
    scene.lights = [PointLight(position=(0.0, 20.0, 0.0), intensity=(400.0, 400.0, 400.0))]
    scene.environment = Environment(radiance=(0.0, 0.0, 0.0))  # none, as the image test's program has one
    scene.camera = rt.Camera(eye=(0.0, 6.0, 8.0), look_at=(0.0, 0.0, -20.0), fov=50.0)
    scene.settings.width = scene.settings.height = 16
    bvh = scene_bvh(scene)
    bufs = bvh.buffers("wide8")
    assert len(bvh.triangles) == len(f) == 128
    assert bufs["instances"].nbytes == abi.INSTANCE.itemsize * n == 112 * n
    assert bufs["tlas"].nbytes <= 64 * n
    assert bufs["blas_nodes"].nbytes < 64 * 1024  # the group's BVH once
    r = rt.render_full(scene, spp=1, device=device, seed=1)
    assert r.image.shape == (16, 16, 3) and np.isfinite(r.image).all()
    assert "HAS_INSTANCES" in r.info["features"]
    # lit only where the instances are: the light on them, nothing from the (black) sky
    assert (r.image.max(axis=2) > 0).mean() > 0.3


def subdivided_octahedron(levels):
    """An octahedron's faces split in four ``levels`` times, pushed onto the unit sphere."""
    v = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
    f = np.array([(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)])
    for _ in range(levels):
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        tri = np.concatenate([np.stack(t, 1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
        v, f = tri.reshape(-1, 3), np.arange(len(tri) * 3).reshape(-1, 3)
    return v / np.linalg.norm(v, axis=1, keepdims=True), f


def test_pbrt_object_instances_take_the_two_level_path(tmp_path, monkeypatch):
    """pbrt-v4's ObjectBegin / ObjectInstance: with $PYOPENCL_RT_INSTANCING=two-level the object's
    triangles are kept once (a BlasGroup) and each ObjectInstance is a record at its CTM; the
    flattened scene puts the second instance's corners where its CTM moves them; the default
    (auto) flattens so few triangles."""
    text = ('LookAt 0 0 5  0 0 0  0 1 0\nCamera "perspective"\nWorldBegin\n'
            'ObjectBegin "tri"\nShape "trianglemesh" "point3 P" [0 0 0 1 0 0 0 1 0] "integer indices" [0 1 2]\n'
            'ObjectEnd\nObjectInstance "tri"\nAttributeBegin\nTranslate 2 0 0\nScale 1 2 1\n'
            'ObjectInstance "tri"\nAttributeEnd\n')
    path = tmp_path / "inst.pbrt"
    path.write_text(text)
    monkeypatch.setenv(INSTANCING_ENV, "two-level")
    scene = load_scene(str(path))
    assert len(scene.blas_groups) == 1 and scene.blas_groups[0].n_faces == 1 and len(scene.faces) == 1
    assert [i.blas for i in scene.instances] == [0, 0]
    flat = flattened(scene)
    v = np.asarray(flat.vertices, np.float64)[flat.faces[flat.instances[1].first_face]]
    # (2, 0, 0), (3, 0, 0), (2, 2, 0); x negated: a plain LookAt mirrors pbrt's scene (docs/SCENE_FORMAT.md)
    assert np.allclose(np.array(sorted(map(tuple, np.abs(v)))), [(2, 0, 0), (2, 2, 0), (3, 0, 0)], atol=1e-6), v
    monkeypatch.setenv(INSTANCING_ENV, "auto")
    assert not load_scene(str(path)).blas_groups
