"""The light BVH (light_sampler "bvh": pyopencl_rt/render/light_tree.py, cl/render/light_tree.h):
the tree holds every light once along its bit trail, its importance is a conservative bound (no
light that can light a point gets probability 0 there), the device's picks follow the float64
pmf of the host's reference (chi-square, ALPHA as in test_sampling.py), the device's
light_tree_pmf (what the MIS weights use) equals it, every lane width gives the bits of width 1,
and a render picking by the tree has the mean of one picking by power, with less variance on
many spread-out lights."""
from __future__ import annotations

import numpy as np
import pytest

from pyopencl_rt.accel.bvh import build_bvh
from pyopencl_rt.device import abi
from pyopencl_rt.render.api import render_full
from pyopencl_rt.render.light_tree import tree_pmfs
from pyopencl_rt.render.lights import build_lights
from pyopencl_rt.scene.model import Camera, Environment, Material, PointLight, RenderSettings, Scene

import harness
from harness import assert_chi2, tile_z
from pyopencl_rt.scene.shapes.sphere import records as sphere_records

ALPHA = 1e-4

HARNESS = r"""
#include "render/light_tree.h"

/* per lane j: (p, n) = pn[6 j ..], u[j]; out: the light picked (-1: none) and its pmf, and
 * light_tree_pmf of trail[j] from the same point */
__kernel void h_tree(__global const LightNode *nodes, __global const float *pn, __global const float *u,
                     __global const int *trail, __global int *light, __global float *pmf, __global float *pmf_of)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    pvec3 p, n;
    pfloat uu;
    pint tr;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const int j = base + k;
        pv3_set_lane(&p, k, vload3(0, pn + 6 * j));
        pv3_set_lane(&n, k, vload3(0, pn + 6 * j + 3));
        PLANE(uu, k) = u[j];
        PLANE_I(tr, k) = trail[j];
    }
    pfloat prob;
    const pint got = light_tree_sample(nodes, PTRUE, p, n, uu, &prob);
    const pfloat of = light_tree_pmf(nodes, tr, p, n);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const int j = base + k;
        light[j] = PLANE(prob, k) > 0.0f ? PLANE_I(got, k) : -1;
        pmf[j] = PLANE(prob, k);
        pmf_of[j] = PLANE(of, k);
    }
}
"""


def tree_kernels(width):
    return harness.Kernels(HARNESS, defines={"PACKET_WIDTH": width})


def quad(c, size, normal):
    """Two triangles of a square of side `size` at c facing `normal` (a unit axis vector)."""
    n = np.asarray(normal, np.float64)
    t = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
    t /= np.linalg.norm(t)
    b = np.cross(n, t)
    h = 0.5 * size
    v = np.array([c - h * t - h * b, c + h * t - h * b, c + h * t + h * b, c - h * t + h * b])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def lamps_scene(light_sampler="bvh", n_lamps=120, seed=7, environment=False, size=16):
    """A diffuse floor (y = 0, 8 x 8) and a wall (x = -4) under n_lamps small quads at heights 0.3
    to 3 facing down, sideways or up (a third of them two-sided), two emissive spheres, a point
    light, optionally a constant sky; the camera looks down at the floor."""
    rng = np.random.default_rng(seed)
    verts, faces, mats = [], [], []

    def add(v, f, m):
        faces.append(f + sum(len(x) for x in verts))
        verts.append(v)
        mats.extend([m] * len(f))

    add(*quad(np.zeros(3), 8.0, (0, 1, 0)), 0)
    add(*quad(np.array([-4.0, 2.0, 0.0]), 8.0, (1, 0, 0)), 0)
    normals = [(0, -1, 0)] * 3 + [(1, 0, 0), (-1, 0, 0), (0, 0, 1), (0, 1, 0)]
    for i in range(n_lamps):
        c = np.array([rng.uniform(-3.8, 3.8), rng.uniform(0.3, 3.0), rng.uniform(-3.8, 3.8)])
        add(*quad(c, rng.uniform(0.05, 0.2), normals[rng.integers(len(normals))]), 1 + i % 3)
    materials = [Material("floor", albedo=(0.7, 0.7, 0.7)),
                 Material("warm", albedo=(0, 0, 0), emission=(30, 20, 8)),
                 Material("cold", albedo=(0, 0, 0), emission=(8, 14, 30)),
                 Material("both", albedo=(0, 0, 0), emission=(20, 20, 20), two_sided=True)]
    spheres = np.array([[2.5, 1.0, -2.0, 0.1], [-1.0, 2.5, 1.5, 0.05]], np.float32)
    scene = Scene(vertices=np.concatenate(verts).astype(np.float32), faces=np.concatenate(faces).astype(np.int32),
                  face_materials=np.array(mats, np.int32), materials=materials,
                  camera=Camera(eye=(0, 7, 6), look_at=(0, 0, 0), up=(0, 1, 0), fov=60),
                  settings=RenderSettings(width=size, height=size, max_depth=3, integrator="path",
                                          light_sampler=light_sampler),
                  shapes=sphere_records(spheres), shape_materials=np.array([1, 3], np.int32),
                  lights=[PointLight(position=(1.0, 1.5, 1.0), intensity=(3, 3, 3))],
                  environment=Environment(radiance=(0.2, 0.3, 0.5)) if environment else None)
    return scene


def tree_of(scene):
    bvh = build_bvh(scene.vertices, scene.faces)
    lights, _, _, nodes = build_lights(scene, bvh)
    return lights, nodes, bvh


def shading_points(rng, n):
    """Points over the floor, on the wall and in the air (normal 0: a medium's point)."""
    p = np.column_stack([rng.uniform(-3.9, 3.9, n), np.zeros(n), rng.uniform(-3.9, 3.9, n)])
    nrm = np.tile([0.0, 1.0, 0.0], (n, 1))
    wall = np.arange(n) % 3 == 1
    p[wall, 0], p[wall, 1] = -3.999, rng.uniform(0, 4, wall.sum())
    nrm[wall] = [1.0, 0.0, 0.0]
    air = np.arange(n) % 3 == 2
    p[air, 1] = rng.uniform(0.2, 3.5, air.sum())
    nrm[air] = 0.0
    return p, nrm


def test_tree_holds_every_light_once_and_bounds_what_can_light():
    """Every bounded light of positive power is one leaf, reached by its trail; the infinitely far
    ones are not in the tree and keep their share (pbrt-v4's 1 / (n + 1)); the pmfs over the tree
    sum to at most 1, and a light gets probability > 0 at every point in front of it (the
    importance is a bound, never 0 where the light can shine)."""
    scene = lamps_scene(environment=True)
    lights, nodes, bvh = tree_of(scene)
    kind, trail = lights["kind"], lights["trail"]
    bounded = kind != abi.LIGHT_ENVIRONMENT
    assert (trail[bounded] >= 0).all() and (trail[~bounded] == -1).all()
    leaves = nodes[nodes["child"] < 0]
    assert sorted(-1 - leaves["child"]) == sorted(np.flatnonzero(bounded))
    for i in np.flatnonzero(bounded):  # the trail's walk ends at the light's leaf
        node, t = 0, int(trail[i])
        while nodes[node]["child"] >= 0:
            node = int(nodes[node]["child"]) if t & 1 else node + 1
            t >>= 1
        assert -1 - nodes[node]["child"] == i
    assert np.allclose(lights["pmf"][~bounded], 0.5) and np.allclose(lights["pmf"][bounded], 0.5)
    rng = np.random.default_rng(3)
    p, n = shading_points(rng, 300)
    pmf = tree_pmfs(nodes, len(lights), p, n)
    assert (pmf.sum(1) <= 1 + 1e-9).all()
    tri = np.flatnonzero(kind == abi.LIGHT_TRIANGLE)
    v = [bvh.triangles[k][lights["prim"][tri], :3].astype(np.float64) for k in ("v0", "v1", "v2")]
    ng = np.cross(v[1] - v[0], v[2] - v[0])
    two = np.array([scene.materials[m].two_sided for m in lights["material"][tri]])
    side = np.einsum("pk,lk->pl", p, ng) - np.einsum("lk,lk->l", v[0], ng)[None, :]
    lit = (side > 1e-6 * np.linalg.norm(ng, axis=1)) | (two[None, :] & (np.abs(side) > 1e-6))
    assert lit.sum() > 1000
    assert (pmf[:, tri][lit] > 0).all()
    sph = np.flatnonzero((kind == abi.LIGHT_SHAPE) | (kind == abi.LIGHT_POINT))
    assert len(sph) == 3
    assert (pmf[:, sph] > 0).all()


@pytest.mark.parametrize("width", [1, 16])
def test_device_picks_follow_the_host_pmf(device, runtime, width):
    """At four shading points (floor, wall, air, under a lamp) 2^17 picks each: the lights' counts
    (and the picks of none) against the float64 pmf of the host's reference (chi-square), the pmf
    each pick reports and
    light_tree_pmf of every light equal to it (1e-4 relative and absolute); at width 16 the bits
    of width 1 (same inputs)."""
    if width > 1:
        harness.require_lane_kernels(device, width)
    scene = lamps_scene()
    lights, nodes, _ = tree_of(scene)
    points = np.array([[0.5, 0.0, 0.3], [-3.999, 1.5, 1.0], [1.0, 2.0, -1.0], [2.0, 0.0, 2.0]])
    normals = np.array([[0, 1, 0], [1, 0, 0], [0, 0, 0], [0, 1, 0]], np.float64)
    expect = tree_pmfs(nodes, len(lights), points, normals)
    rng = np.random.default_rng(11)
    N = 1 << 17
    bounded = np.flatnonzero(lights["trail"] >= 0)
    outputs = []
    for k in range(len(points)):
        pn = np.tile(np.concatenate([points[k], normals[k]]), (N, 1)).astype(np.float32)
        u = harness.uniforms(rng, N)
        trail = lights["trail"][bounded[np.arange(N) % len(bounded)]]
        light, pmf, pmf_of = tree_kernels(width)(runtime, "h_tree", N // width, nodes, pn, u, trail,
                                                 np.zeros(N, np.int32), np.zeros(N, np.float32), np.zeros(N, np.float32))
        outputs.append((light, pmf, pmf_of))
        # bin 0: no light (every light out of reach at a node: probability 1 - the pmfs' sum)
        counts = np.bincount(light + 1, minlength=len(lights) + 1)
        assert_chi2(counts, np.concatenate([[max(0.0, 1 - expect[k].sum())], expect[k]]) * N, ALPHA, f"point {k}")
        got = light >= 0
        assert np.allclose(pmf[got], expect[k][light[got]], rtol=1e-4, atol=1e-7)
        assert np.allclose(pmf_of, expect[k][bounded[np.arange(N) % len(bounded)]], rtol=1e-4, atol=1e-7)
    if width > 1:
        rng = np.random.default_rng(11)
        for k in range(len(points)):
            pn = np.tile(np.concatenate([points[k], normals[k]]), (N, 1)).astype(np.float32)
            u = harness.uniforms(rng, N)
            trail = lights["trail"][bounded[np.arange(N) % len(bounded)]]
            one = tree_kernels(1)(runtime, "h_tree", N, nodes, pn, u, trail, np.zeros(N, np.int32),
                                  np.zeros(N, np.float32), np.zeros(N, np.float32))
            for a, b in zip(one, outputs[k]):
                assert np.array_equal(a, b)


def test_bvh_and_power_render_the_same_mean_with_less_variance_by_bvh(device):
    """A floor and a wall under 120 small lamps, two spheres, a point light and a sky: the tree's
    picks and power's give the same image (every 4 x 4 tile and the mean within 4.5 standard
    errors, from the per-pixel sample variances, which bound the Sobol means' from above in practice),
    and the tree's variance is lower in most pixels (the median ratio; its picks follow the lamps
    near each point)."""
    renders = {}
    for seed, mode in enumerate(("power", "bvh"), 3):
        scene = lamps_scene(mode, environment=True)
        renders[mode] = render_full(scene, spp=256, device=device, seed=seed)
    rp, rb = renders["power"], renders["bvh"]
    for r in (rp, rb):
        assert r.info["nonfinite_samples"] == 0
    a, b = rp.image.astype(np.float64), rb.image.astype(np.float64)
    va, vb = rp.film.variance_of_mean(), rb.film.variance_of_mean()
    z = tile_z(a, va, b, vb, tile=4)
    assert z.max() < 4.5, z.max()
    z_mean = abs(a.mean() - b.mean()) / np.sqrt((va.mean() + vb.mean()) / va.size)
    assert z_mean < 4.5, (a.mean(), b.mean(), z_mean)
    seen = va.sum(-1) > 0
    ratio = np.median(vb.sum(-1)[seen] / va.sum(-1)[seen])
    assert ratio < 0.7, ratio


def test_many_lights_scene_is_its_script_and_builds_a_tree(tmp_path):
    """scenes/many-lights.toml: its lamps are what many-lights/make_lamps.py writes (byte for byte),
    3072 quads (6144 emissive triangles) facing down, every one a leaf of the tree (trails within
    31 bits)."""
    import importlib.util
    from pathlib import Path

    from pyopencl_rt.scene.loaders import load_scene

    folder = Path(__file__).resolve().parents[2] / "scenes"
    spec = importlib.util.spec_from_file_location("make_lamps", folder / "many-lights" / "make_lamps.py")
    make = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make)
    make.write(str(tmp_path))
    for g in range(make.GROUPS):
        assert (tmp_path / f"lamps-{g}.obj").read_bytes() == (folder / "many-lights" / f"lamps-{g}.obj").read_bytes()
    scene = load_scene(folder / "many-lights.toml")
    assert scene.settings.light_sampler == "bvh"
    lights, nodes, bvh = tree_of(scene)
    assert len(lights) == 6144 and (lights["kind"] == abi.LIGHT_TRIANGLE).all()
    assert (lights["trail"] >= 0).all() and len(nodes) == 2 * len(lights) - 1
    leaves = nodes[nodes["child"] < 0]
    assert (leaves["axis"][:, 1] < -0.999).all()  # every lamp faces down


def test_cli_light_sampler_option_reaches_the_kernels(tmp_path, monkeypatch, capsys):
    """``render --light-sampler bvh`` on a scene that picks by power builds the tree (the sidecar's
    light_tree; LIGHT_TREE compiled in where each scene gets its own kernel), and the scene's own
    choice stands without the option."""
    import json

    from pyopencl_rt.cli import main
    from pyopencl_rt.render.settings import every_feature

    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "lamps.toml"
    scene.write_text('[camera]\neye = [0, 3, 3]\nlook_at = [0, 0, 0]\n[materials.lamp]\nemission = 5\n'
                     '[[shape]]\ntype = "quad"\npoints = [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]]\n'
                     '[[shape]]\ntype = "quad"\nmaterial = "lamp"\n'
                     'points = [[0, 1, 0], [0.2, 1, 0], [0.2, 1, 0.2], [0, 1, 0.2]]\n')
    for option, expect in ((["--light-sampler", "bvh"], True), ([], False)):
        out = tmp_path / f"out{len(option)}.exr"
        try:
            main(["render", str(scene), "-o", str(out), "--width", "4", "--height", "4", "--spp", "1", "-q",
                  "--device", "cpu", *option])
        except SystemExit as exc:
            assert exc.code == 0, capsys.readouterr().err
        info = json.loads(out.with_suffix(".json").read_text())
        assert info["light_tree"] is expect, info
        if not every_feature():
            assert ("LIGHT_TREE" in info["features"]) == expect, info["features"]
