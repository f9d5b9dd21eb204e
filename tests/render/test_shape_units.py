"""Analytic shapes as units (issue 36): the registry, the kernel units and the generated dispatch
agree; the shapes' BVH finds what a float64 brute force over every shape finds; the analytic disk
(scene/shapes/disk.py, cl/shapes/disk.h) as an emitter against the closed form of a parallel
disk's irradiance, and read from TOML and Mitsuba XML.  Mitsuba's own renders of disks:
tests/render/test_shapes_mitsuba.py."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.device.cl_header import shape_units
from pyopencl_rt.device.kernels import cl_dir
from pyopencl_rt.errors import UserError
from pyopencl_rt.render.api import render_full
from pyopencl_rt.scene.loaders import load_scene
from pyopencl_rt.scene.model import Material
from pyopencl_rt.scene.shapes import REGISTRY, records
from pyopencl_rt.scene.shapes import cylinder as cylinder_unit
from pyopencl_rt.scene.shapes import disk as disk_unit

import harness
from test_lights import assert_pixels, pixel_points, plane_scene

UNIT_FUNCTIONS = ("intersect", "point", "normal", "sample")


def test_registry_units_and_dispatch_agree():
    """Every entry of abi.SHAPE_TYPES has its host module (registered under its name and code) and
    its kernel unit cl/shapes/<name>.h: the four functions, and its case inside the #ifdef that
    compiles it in; the generated header lists the cases in the enum's order, with an empty case
    for a type that is not compiled in."""
    assert list(REGISTRY) == list(abi.SHAPE_TYPES)
    for name, code in abi.SHAPE_TYPES.items():
        t = REGISTRY[name]
        assert t.code == code and t.documentation.startswith(f"``{name}``"), name
        src = (Path(cl_dir()) / "shapes" / f"{name}.h").read_text()
        for fn in UNIT_FUNCTIONS:
            assert re.search(rf"RT_INLINE \w+ shape_{fn}_{name}\(SHAPE_{fn.upper()}_PARAMS\)", src), (name, fn)
        guarded = src.split(f"#ifdef HAS_SHAPE_{name.upper()}", 1)
        assert len(guarded) == 2 and f"#define SHAPE_CASE_{name.upper()}(X) X({name}, {name.upper()})" in guarded[1]
    header = shape_units(abi.SHAPE_TYPES)
    cases = re.search(r"#define SHAPE_CASES\(X\) (.*)", header).group(1).split()
    assert cases == [f"SHAPE_CASE_{n.upper()}(X)" for n in abi.SHAPE_TYPES]
    for n in abi.SHAPE_TYPES:
        assert f'#include "shapes/{n}.h"\n#ifndef SHAPE_CASE_{n.upper()}\n#define SHAPE_CASE_{n.upper()}(X)\n' in header


# ------------------------------------------------------------------------------ the shapes' BVH

HITS = r"""
#include "scene/scene.h"
__kernel void hits(__global const BVHNode *nodes, __global const float4 *tris,
                   __global const BVHNode *shape_nodes, __global const Shape *shapes,
                   __global const float *ro, __global const float *rd, __global const float *rmax,
                   __global float *t_out, __global int *prim_out, __global int *occ_out)
{
    const int first = get_global_id(0) * PACKET_WIDTH; /* the rays of this work-item's lanes */
    pvec3 o, d;
    pfloat tmax, t, u, v;
    pint prim;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        pv3_set_lane(&o, k, vload3(first + k, ro));
        pv3_set_lane(&d, k, vload3(first + k, rd));
        PLANE(tmax, k) = rmax[first + k];
    }
    scene_closest_hit(nodes, tris, shape_nodes, shapes, o, d, PTRUE, &t, &prim, &u, &v);
    const pint occ = scene_occluded(nodes, tris, shape_nodes, shapes, o, d, PTRUE, tmax);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        t_out[first + k] = PLANE(t, k);
        prim_out[first + k] = PLANE_I(prim, k);
        occ_out[first + k] = PLANE_I(occ, k) != 0;
    }
}
"""


def random_shapes(rng, n_spheres=40, n_disks=40, n_cylinders=40) -> np.ndarray:
    """Spheres, disks (turned, scaled unevenly, some flipped) and open tubes (turned, some flipped)
    scattered in a box of side 20."""
    spheres = [REGISTRY["sphere"].params(rng.uniform(-10, 10, 3), rng.uniform(0.2, 1.5)) for _ in range(n_spheres)]
    disks = []
    for _ in range(n_disks):
        q, _r = np.linalg.qr(rng.normal(size=(3, 3)))
        m = np.eye(4)
        m[:3, :3] = q @ np.diag(rng.uniform(0.3, 2.0, 3))
        m[:3, 3] = rng.uniform(-10, 10, 3)
        disks.append(disk_unit.params(m, bool(rng.random() < 0.5)))
    tubes = [cylinder_unit.params(cylinder_unit.axis_to_world(c, c + rng.normal(size=3) * 2, rng.uniform(0.2, 1.0)),
                                  bool(rng.random() < 0.5))
             for c in rng.uniform(-10, 10, (n_cylinders, 3))]
    return np.concatenate([records("sphere", np.concatenate(spheres)), records("disk", np.concatenate(disks)),
                           records("cylinder", np.concatenate(tubes))])


def brute_force(shapes, o, d):
    """(S, N) float64 distances of each ray to each shape (inf: missed) and a margin per pair (how
    far the ray ahead passes from a rim or a tangent, relative; inf where the shape is behind it),
    from the records' float32 parameters."""
    p = shapes["params"].astype(np.float64)
    t = np.full((len(shapes), len(o)), np.inf)
    margin = np.full_like(t, np.inf)
    for i, (row, code) in enumerate(zip(p, shapes["type"])):
        if code == abi.SHAPE_TYPES["sphere"]:
            f = o - row[:3]
            b, c = (f * d).sum(1), (f * f).sum(1) - row[3] ** 2
            disc = b * b - c
            root = np.sqrt(np.maximum(disc, 0))
            t0, t1 = -b - root, -b + root
            ti = np.where(t0 > 0, t0, np.where(t1 > 0, t1, np.inf))
            t[i] = np.where(disc >= 0, ti, np.inf)
            margin[i] = np.where(t1 > 0, np.abs(disc) / row[3] ** 2, np.inf)
        elif code == abi.SHAPE_TYPES["disk"]:
            inv = row[12:24].reshape(3, 4)
            ol, dl = o @ inv[:, :3].T + inv[:, 3], d @ inv[:, :3].T
            with np.errstate(divide="ignore", invalid="ignore"):
                ti = -ol[:, 2] / dl[:, 2]
                x, y = ol[:, 0] + ti * dl[:, 0], ol[:, 1] + ti * dl[:, 1]
            r2 = x * x + y * y
            t[i] = np.where((ti > 0) & (r2 <= 1), ti, np.inf)
            margin[i] = np.where(ti > 0, np.abs(r2 - 1), np.inf)
        else:  # the unit tube in object space: the nearer root ahead whose z is in [0, 1]
            inv = row[12:24].reshape(3, 4)
            ol, dl = o @ inv[:, :3].T + inv[:, 3], d @ inv[:, :3].T
            a = dl[:, 0] ** 2 + dl[:, 1] ** 2
            b = ol[:, 0] * dl[:, 0] + ol[:, 1] * dl[:, 1]
            c = ol[:, 0] ** 2 + ol[:, 1] ** 2 - 1
            disc = b * b - a * c
            root = np.sqrt(np.maximum(disc, 0))
            best, rim = np.full(len(o), np.inf), np.full(len(o), np.inf)
            with np.errstate(divide="ignore", invalid="ignore"):
                for ti in ((-b + root) / a, (-b - root) / a):  # the farther first: the nearer overrides
                    z = ol[:, 2] + ti * dl[:, 2]
                    ok = (disc >= 0) & (ti > 0) & (z >= 0) & (z <= 1)
                    best = np.where(ok, ti, best)
                    rim = np.where(ti > 0, np.minimum(rim, np.minimum(np.abs(z), np.abs(z - 1))), rim)
            t[i] = best
            margin[i] = np.minimum(np.abs(disc) / np.maximum(a * a, 1e-30), rim)  # grazing, or at a rim
    return t, margin


def test_shape_bvh_finds_the_closest_shape(device, runtime, rng):
    """120 spheres, disks and tubes, 4096 rays from inside their box in random directions: the closest hit
    (shape and t within 1e-5, relative or absolute) and the occlusion of a segment to a random length are those
    of a float64 brute force over every shape, at one path per work-item and in lanes (whose bits
    equal the one path's); rays that graze a rim or a tangent (within 1e-3), or whose two nearest
    shapes lie within 1e-4 of each other, or whose segment ends within 1e-4 of the hit, are left out."""
    from pyopencl_rt.accel.shape_bvh import build_shape_bvh
    from pyopencl_rt.scene.shapes import bounds

    shapes = random_shapes(rng)
    nodes = build_shape_bvh(*bounds(shapes))
    n = 4096
    o = rng.uniform(-12, 12, (n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tmax = rng.uniform(0, 30, n)
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    t_ref, margin = brute_force(shapes, o32.astype(np.float64), d32.astype(np.float64))
    order = np.sort(t_ref, axis=0)
    nearest = np.argmin(t_ref, axis=0)
    t_near = order[0]
    hit = np.isfinite(t_near)
    clear = (margin > 1e-3).all(axis=0)
    with np.errstate(invalid="ignore"):
        clear &= ~hit | ((order[1] - t_near) > 1e-4 * np.maximum(t_near, 1))
        clear &= ~hit | (np.abs(tmax - t_near) > 1e-4 * np.maximum(t_near, 1))
    widths = ["0"] + ([harness.forced_lanes(device)] if harness.lane_kernels_build_on(device) else [])
    results = {}
    for w in widths:
        width = int(w) or 1
        k = harness.Kernels(HITS, defines={"HAS_SHAPES": True, "HAS_SHAPE_SPHERE": True, "HAS_SHAPE_DISK": True,
                                           "HAS_SHAPE_CYLINDER": True, "PACKET_WIDTH": width}, local_size=1)
        t, prim, occ = k(runtime, "hits", n // width, nodes=np.zeros(1, abi.BVH_NODE),
                         tris=np.zeros((3, 4), np.float32), shape_nodes=nodes, shapes=shapes, ro=o32, rd=d32, rmax=tmax.astype(np.float32),
                         t_out=n, prim_out=n, occ_out=n)
        results[w] = (t, prim, occ)
        assert clear.mean() > 0.9 and (clear & hit).sum() > 500
        c = clear & hit
        assert np.array_equal(abi.PRIM_SHAPE_FIRST - prim[c], nearest[c]), w
        bad = ~np.isclose(t[c], t_near[c], rtol=1e-5, atol=1e-5)  # atol: float32 rounding of origins up to 12
        assert not bad.any(), (w, t[c][bad][:5], t_near[c][bad][:5], shapes["type"][nearest[c][bad][:5]])
        assert (prim[clear & ~hit] == abi.PRIM_MISS).all(), w
        assert np.array_equal(occ[clear].astype(bool), (t_near < tmax)[clear]), w
    for w in widths[1:]:
        assert all(np.array_equal(a.view(np.uint32), b.view(np.uint32))
                   for a, b in zip(results["0"], results[w])), f"{w} lanes against one path"


def test_empty_shape_bvh_is_walked_and_left():
    """Without shapes (a kernel compiled with every feature still walks the shapes' BVH): a root
    with both children absent, so no ray enters it; one shape: its box on the left, nothing right."""
    from pyopencl_rt.accel.shape_bvh import build_shape_bvh

    empty = build_shape_bvh(np.zeros((0, 3)), np.zeros((0, 3)))
    assert len(empty) == 1 and empty["count_left"][0] == empty["count_right"][0] == -1
    one = build_shape_bvh(np.array([[0.0, 0, 0]]), np.array([[1.0, 1, 1]]))
    assert (one["count_left"][0], one["child_left"][0], one["count_right"][0]) == (1, 0, -1)
    assert (one["bmin_left"][0] < 0).all() and (one["bmax_left"][0] > 1).all()  # rounded outwards


# ---------------------------------------------------------------------------------- disk emitters

def parallel_disk_irradiance(rho_xz, h, radius, radiance):
    """The irradiance at a point of a plane under a Lambertian disk parallel to it (radius R, height
    h, its centre at horizontal distance rho): pi L / 2 (1 - (h^2 + rho^2 - R^2) /
    sqrt((h^2 + rho^2 + R^2)^2 - 4 R^2 rho^2)) (the differential element's view factor of a
    parallel disk); on the axis pi L R^2 / (h^2 + R^2)."""
    a = h * h + rho_xz**2
    return np.pi * radiance / 2 * (1 - (a - radius**2) / np.sqrt((a + radius**2) ** 2 - 4 * radius**2 * rho_xz**2))


def test_disk_light_over_plane(device):
    """A diffuse plane (albedo 0.5) under an analytic disk light of radius 1.5 at height 2, facing
    down, off the camera's axis: radiance rho / pi E at every pixel (pixel averages by 8 x 8
    quadrature of the closed form above), each within 5 standard errors, with MIS, light sampling
    alone (the disk sampled uniformly in area, cl/shapes/disk.h) and BSDF sampling alone (the disk
    hit by the shapes' BVH, its emission one-sided).  A disk facing up (its back to the plane)
    lights nothing."""
    rho, radiance, h, radius, size = 0.5, 3.0, 2.0, 1.5, 24
    centre = np.array([0.6, h, -0.3])
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = [radius, 0, 0], [0, 0, radius], [0, -1, 0], centre  # normal -y
    sc = plane_scene([], rho, size=size)
    sc.camera.eye, sc.camera.fov = (0.0, 1.0, 0.0), 70
    sc.materials.append(Material("lamp", albedo=(0.0,) * 3, emission=(radiance,) * 3))
    sc.shapes, sc.shape_materials = records("disk", disk_unit.params(m)), np.array([1], np.int32)
    rec = sc.camera.record(size, size)
    dirs = pixel_points(rec, size, size)
    eye = np.asarray(rec["origin"], np.float64)
    p = eye + dirs * (-eye[1] / dirs[..., 1:2])
    dist = np.hypot(p[..., 0] - centre[0], p[..., 2] - centre[2])
    e = parallel_disk_irradiance(dist, h, radius, radiance)
    expect = np.repeat((rho / np.pi * e).mean(-1)[..., None], 3, -1)
    for integ in ("path", "nee", "bsdf"):
        r = render_full(sc, spp=32, device=device, seed=4, integrator=integ)
        assert r.info["nonfinite_samples"] == 0
        assert_pixels(r, expect, f"disk light, {integ}")
    sc.shapes = records("disk", disk_unit.params(m, flip=True))
    assert render_full(sc, spp=4, device=device, seed=4).image.max() == 0


def test_tilted_ellipse_light_strategies_agree(device):
    """An elliptic disk light (scaled 1.6 x 0.5, tilted 40 degrees, two-sided) over the plane: light
    sampling alone (its area pi a b, its pdf dist^2 / (area cos)) and BSDF sampling alone (hits) are
    two unbiased estimates of one image, every 4 x 4 tile within 4.5 standard errors of each other."""
    size = 24
    a = np.radians(40)
    m = np.eye(4)
    m[:3, :3] = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]]) @ np.array(
        [[0, 0, 1], [1, 0, 0], [0, 1, 0]], float) @ np.diag([1.6, 0.5, 1.0])
    m[:3, 3] = (-0.4, 1.6, 0.2)
    sc = plane_scene([], 0.5, size=size)
    sc.camera.eye, sc.camera.fov = (0.0, 1.0, 0.0), 70
    sc.materials.append(Material("lamp", albedo=(0.0,) * 3, emission=(2.0, 1.5, 1.0), two_sided=True))
    sc.shapes, sc.shape_materials = records("disk", disk_unit.params(m)), np.array([1], np.int32)
    assert np.isclose(sc.shapes["params"][0, 27], np.pi * 1.6 * 0.5, rtol=1e-6)
    renders = [render_full(sc, spp=64, device=device, seed=s, integrator=i) for s, i in ((1, "nee"), (2, "bsdf"))]
    (a_img, a_var), (b_img, b_var) = ((r.image.astype(np.float64), r.film.variance_of_mean()) for r in renders)
    assert a_img.mean() > 0.02
    assert harness.tile_z(a_img, a_var, b_img, b_var, tile=4).max() < 4.5


def test_tube_light_strategies_agree(device):
    """An emissive open tube (radius 0.3, length 1.6, tilted, one-sided: its outside) over the plane:
    light sampling alone (uniform in area over phi and z, cl/shapes/cylinder.h) and BSDF sampling
    alone (hits) agree, every 4 x 4 tile within 4.5 standard errors; its record's area is 2 pi r l."""
    size = 24
    sc = plane_scene([], 0.5, size=size)
    sc.camera.eye, sc.camera.fov = (0.0, 1.0, 0.0), 70
    sc.materials.append(Material("lamp", albedo=(0.0,) * 3, emission=(1.5, 2.0, 3.0)))
    m = cylinder_unit.axis_to_world((-0.8, 1.4, -0.3), (0.6, 1.7, 0.5), 0.3)
    sc.shapes, sc.shape_materials = records("cylinder", cylinder_unit.params(m)), np.array([1], np.int32)
    assert np.isclose(sc.shapes["params"][0, 25], 2 * np.pi * 0.3 * np.linalg.norm([1.4, 0.3, 0.8]), rtol=1e-6)
    renders = [render_full(sc, spp=64, device=device, seed=s, integrator=i) for s, i in ((1, "nee"), (2, "bsdf"))]
    (a_img, a_var), (b_img, b_var) = ((r.image.astype(np.float64), r.film.variance_of_mean()) for r in renders)
    assert a_img.mean() > 0.02 and all(r.info["nonfinite_samples"] == 0 for r in renders)
    assert harness.tile_z(a_img, a_var, b_img, b_var, tile=4).max() < 4.5


# ----------------------------------------------------------------------------------- scene files

def test_toml_disk(tmp_path):
    """``[[shape]] type = "disk"``: its record from center, normal and radius (Mitsuba's frame of the
    normal); flip_normals turns its front; a radius of 0 and a zero normal are one line each."""
    table = '[[shape]]\ntype = "disk"\ncenter = [1, 2, 3]\nnormal = [0, 0, -2]\nradius = 0.5\n'
    path = tmp_path / "d.toml"
    path.write_text(table + "flip_normals = true\n")
    p = load_scene(str(path)).shapes["params"][0].astype(np.float64)
    assert np.allclose(p[24:27], [0, 0, 1]) and np.isclose(p[27], np.pi * 0.25)
    assert np.allclose(p[:12].reshape(3, 4)[:, 3], [1, 2, 3])
    for bad, needle in (("radius = 0.5", "radius = 0"), ("normal = [0, 0, -2]", "normal = [0, 0, 0]")):
        path.write_text(table.replace(bad, needle))
        with pytest.raises(UserError) as caught:
            load_scene(str(path))
        assert "\n" not in str(caught.value) and ("radius" in str(caught.value) or "normal" in str(caught.value))


def test_toml_and_mitsuba_cylinders(tmp_path):
    """``[[shape]] type = "cylinder"`` (p0, p1, radius, flip_normals) and Mitsuba's cylinder are one
    analytic record each; Mitsuba's under an uneven scale (an elliptic tube) is triangles with its
    exact normals, as a textured one is."""
    path = tmp_path / "c.toml"
    path.write_text('[[shape]]\ntype = "cylinder"\np0 = [0, 0, 0]\np1 = [0, 2, 0]\nradius = 0.5\nflip_normals = true\n')
    p = load_scene(str(path)).shapes["params"][0].astype(np.float64)
    assert p[24] == -1 and np.isclose(p[25], 2 * np.pi * 0.5 * 2)
    tube = '<shape type="cylinder"><float name="radius" value="0.5"/>{}</shape><emitter type="constant"/>'
    for extra, analytic in (("", True), ('<transform name="to_world"><scale x="2" y="1" z="1"/></transform>', False),
                            ('<bsdf type="diffuse"><texture name="reflectance" type="checkerboard"/></bsdf>', False)):
        scene = load_scene(harness.write_mitsuba_scene(tmp_path / "c.xml", tube.format(extra)))
        assert (len(scene.shapes), len(scene.faces) > 100) == ((1, False) if analytic else (0, True)), extra


def test_mitsuba_disk_is_analytic_unless_its_material_reads_uv(tmp_path):
    """A plain Mitsuba disk is one analytic record (an ellipse under its uneven to_world, its area pi
    a b); a textured one is Mitsuba's triangles with its uv; an instanced one stays a disk, moved."""
    plain = '<shape type="disk"><transform name="to_world"><scale x="2" y="0.5"/><translate z="1"/></transform></shape>'
    textured = ('<shape type="disk"><bsdf type="diffuse"><texture name="reflectance" type="checkerboard"/></bsdf>'
                '</shape>')
    group = ('<shape type="shapegroup" id="g"><shape type="disk"/></shape>'
             '<shape type="instance"><ref id="g"/><transform name="to_world"><translate x="3"/></transform></shape>')
    for body, n_faces, n_shapes in ((plain, 0, 1), (textured, None, 0), (group, 0, 1)):
        path = harness.write_mitsuba_scene(tmp_path / "disk.xml", body + '<emitter type="constant"/>')
        scene = load_scene(path)
        assert len(scene.shapes) == n_shapes and (n_faces is None and len(scene.faces) > 100 or
                                                  n_faces == len(scene.faces)), body
    assert np.isclose(load_scene(harness.write_mitsuba_scene(tmp_path / "p.xml", plain)).shapes["params"][0, 27],
                      np.pi)
    moved = load_scene(harness.write_mitsuba_scene(tmp_path / "g.xml", group)).shapes["params"][0]
    assert np.allclose(moved[:12].reshape(3, 4)[:, 3], [3, 0, 0])
