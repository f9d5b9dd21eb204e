"""Point, directional and environment lights, and the thin-lens camera, on every available device.

Closed forms where they exist (a point or directional light over a diffuse plane, a white
furnace under a constant environment, the blur of an edge seen through a thin lens), the
environment map's importance sampling against the luminance distribution (chi-square, as in
tests/render/test_sampling.py: tests/harness.py's chi2_test), and light sampling against BSDF sampling under an environment map
(tile-wise z-tests).  Robustness: no NaN or Inf for extreme parameters.  The lights' functions
(cl/render/lights.h) and the hit geometry (cl/scene/scene.h: hit_point, hit_normal) in harness
kernels: each kind of light sample against its closed form at width 1, and 8 and 16 lanes giving
width 1's bits lane by lane."""
import warnings

import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.render.lights import LUMINANCE, environment_radiance, environment_tables, other_lights
from pyopencl_rt.render.api import render_full
from pyopencl_rt.scene.model import (Camera, DirectionalLight, Environment, Material, PointLight, ProjectorLight,
                                     RenderSettings, Scene, SpotLight, look_at_frame)

import harness
from pyopencl_rt.scene.shapes.sphere import records as sphere_records

ALPHA = 1e-4

HARNESS = harness.Kernels(r"""
#include "render/lights.h"

/* out per item: wi (3), pdf of the sample, env_pdf(wi), Le.x, Le.y, Le.z */
__kernel void h_env_sample(__global const Light *lt, __global const float *env_map, __global const float *env_cdf,
                           __global const float *u, __global float *out)
{
    const int i = get_global_id(0);
    pvec3 wi;
    pfloat pdf;
    const float3 Le = pv3_lane(env_sample(lt, env_map, env_cdf, PFLOAT(u[2 * i]), PFLOAT(u[2 * i + 1]), &wi, &pdf), 0);
    const float3 w = pv3_lane(wi, 0);
    __global float *o = out + 8 * i;
    o[0] = w.x; o[1] = w.y; o[2] = w.z; o[3] = PLANE(pdf, 0);
    const pfloat pdf_w = env_pdf(lt, env_map, env_cdf, pv3_from(w));
    o[4] = PLANE(pdf_w, 0);
    o[5] = Le.x; o[6] = Le.y; o[7] = Le.z;
}

/* out per direction: env_pdf, radiance.x */
__kernel void h_env_eval(__global const Light *lt, __global const float *env_map, __global const float *env_cdf,
                         __global const float *w, __global float *out)
{
    const int i = get_global_id(0);
    const pvec3 d = pv3_from(load3(w, i));
    const pfloat pdf = env_pdf(lt, env_map, env_cdf, d);
    out[2 * i] = PLANE(pdf, 0);
    out[2 * i + 1] = pv3_lane(env_radiance(lt, env_map, d), 0).x;
}
""", defines={"HAS_ENVIRONMENT": True})

# The lights' and hits' functions over PACKET_WIDTH lanes per work-item (lane k of item i: entry
# i * PACKET_WIDTH + k of each array), built at every width: each lane must give the bits of width 1.
LANE_SOURCE = r"""
#include "render/lights.h"

#define L_IN 14  /* per lane: ref (3), u (2), p (3), ng (3), w (3) */
#define L_OUT 24 /* per lane: got, ls.p (3), ls.err (3), ls.n (3), ls.Le (3), ls.pdf, ls.far, ls.delta,
                  * light_pdf(p, ng), env_pdf(w), env_radiance(w) (3), ls.tex, ls.tu, ls.tv */
/* index: (light, active) per lane; env_light: the environment light's index */
__kernel void h_lights(__global const float *vertices, __global const int *faces, __global const int *prim_ids,
                       __global const Shape *spheres,
                       __global const Material *materials, __global const float *env_map,
                       __global const float *env_cdf, __global const Light *lights, int env_light,
                       __global const int *index, __global const float *in, __global float *out)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    pint li, act;
    pvec3 ref, p, ng, w;
    pfloat ux, uy;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const int j = base + k;
        __global const float *a = in + L_IN * j;
        PLANE_I(li, k) = index[2 * j];
        PLANE_I(act, k) = index[2 * j + 1];
        pv3_set_lane(&ref, k, vload3(0, a));
        PLANE(ux, k) = a[3];
        PLANE(uy, k) = a[4];
        pv3_set_lane(&p, k, vload3(0, a + 5));
        pv3_set_lane(&ng, k, vload3(0, a + 8));
        pv3_set_lane(&w, k, vload3(0, a + 11));
    }
    act = act != 0; /* a mask */
    LightSample ls;
    const pint got = light_sample_all(MESH_ARGS, spheres, materials, env_map, env_cdf, lights, li, act, ref, ux, uy, &ls);
    const pfloat lpdf = light_pdf(spheres, lights, li, ref, p, ng);
    const pfloat epdf = env_pdf(lights + env_light, env_map, env_cdf, w);
    const pvec3 eL = env_radiance(lights + env_light, env_map, w);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        __global float *o = out + L_OUT * (base + k);
        o[0] = PLANE_I(got, k) != 0 ? 1.0f : 0.0f;
        vstore3(pv3_lane(ls.p, k), 0, o + 1);
        vstore3(pv3_lane(ls.err, k), 0, o + 4);
        vstore3(pv3_lane(ls.n, k), 0, o + 7);
        vstore3(pv3_lane(ls.Le, k), 0, o + 10);
        o[13] = PLANE(ls.pdf, k);
        o[14] = PLANE(ls.far, k);
        o[15] = PLANE_I(ls.delta, k) != 0 ? 1.0f : 0.0f;
        o[16] = PLANE(lpdf, k);
        o[17] = PLANE(epdf, k);
        o[18] = pv3_lane(eL, k).x; o[19] = pv3_lane(eL, k).y; o[20] = pv3_lane(eL, k).z;
        o[21] = (float)PLANE_I(ls.tex, k); o[22] = PLANE(ls.tu, k); o[23] = PLANE(ls.tv, k);
    }
}

#define H_IN 9  /* per lane: o (3), d (3), t, u, v */
#define H_OUT 9 /* per lane: hit_point (3), its error bound (3), hit_normal (3) */
__kernel void h_hits(__global const float *vertices, __global const int *faces, __global const int *prim_ids,
                     __global const Shape *spheres,
                     __global const int *prims,
                     __global const float *in, __global float *out)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    pint prim;
    pvec3 o, d;
    pfloat t, u, v;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const int j = base + k;
        __global const float *a = in + H_IN * j;
        PLANE_I(prim, k) = prims[j];
        pv3_set_lane(&o, k, vload3(0, a));
        pv3_set_lane(&d, k, vload3(0, a + 3));
        PLANE(t, k) = a[6];
        PLANE(u, k) = a[7];
        PLANE(v, k) = a[8];
    }
    pvec3 err;
    const pvec3 p = hit_point(MESH_ARGS, spheres, prim, o, d, t, u, v, &err);
    const pvec3 n = hit_normal(MESH_ARGS, spheres, prim, p, prim != PRIM_MISS);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        __global float *r = out + H_OUT * (base + k);
        vstore3(pv3_lane(p, k), 0, r);
        vstore3(pv3_lane(err, k), 0, r + 3);
        vstore3(pv3_lane(n, k), 0, r + 6);
    }
}
"""
LANE_DEFINES = {"HAS_ENVIRONMENT": True, "HAS_DELTA_LIGHTS": True, "HAS_SHAPES": True, "HAS_SHAPE_SPHERE": True,
                "HAS_TRIANGLES": True}


def lane_kernels(width):
    """The lane harness at `width` lanes (wider than 1: with the 8-wide BVH the packet traversal
    needs, as the renderer builds it)."""
    return harness.Kernels(LANE_SOURCE, defines={**LANE_DEFINES, "PACKET_WIDTH": width, "BVH_WIDE8": width > 1})


def empty_mesh():
    return dict(vertices=np.zeros((0, 3), np.float32), faces=np.zeros((0, 3), np.int32),
                face_materials=np.zeros(0, np.int32))


def env_map_image():
    """An 8 x 16 map: random texels, a zero row, zero texels and a bright spot."""
    r = np.random.default_rng(7)
    img = r.uniform(0.1, 2.0, (8, 16, 3)).astype(np.float32)
    img[2] = 0.0
    img[5, 3:6] = 0.0
    img[1, 10] = (40.0, 30.0, 20.0)
    return img


def _env_light(img, scale=(1.0, 1.0, 1.0)):
    sc = Scene(**empty_mesh(), materials=[Material()], shapes=sphere_records(np.array([[0, 0, 0, 1]], np.float32)),
               shape_materials=np.array([0], np.int32), environment=Environment(radiance=scale, image=img))
    recs, _ = other_lights(sc)
    return sc, recs


def uv_of(w):
    u = np.mod(np.arctan2(-w[:, 0], w[:, 2]) / (2 * np.pi), 1.0)
    v = np.arccos(np.clip(w[:, 1], -1, 1)) / np.pi
    return u, v


@pytest.mark.parametrize("compensated", [False, True], ids=["complete", "compensated"])
def test_env_map_sampling_chi2(runtime, compensated):
    """1M samples of the environment map on the device: their cells (each split 2 x 2, to see
    uniformity inside cells too) follow the density the tables give (chi-square, p > 1e-4); the
    sample's pdf equals env_pdf() of its direction; Le is the bilinearly interpolated map there (the
    float64 reference of environment_radiance); env_pdf integrates to 1 over the sphere.  Complete
    tables: the estimate of the map's integral over the sphere from Le / pdf agrees with quadrature
    (no direction of positive radiance has density 0: else the estimate falls short).  The tables
    of MIS compensation: no sample falls where the map is at or below its mean over the sphere, the
    brightest texel is sampled more often than with complete tables, and env_pdf is 0 in every
    direction whose cell is below the mean (BSDF sampling alone covers them)."""
    img = env_map_image()
    tm, cdf, mean, cells = environment_tables(img, compensated=compensated)
    sc, light = _env_light(img)
    assert cells == 4 and light[0]["cells"] == cells  # a small map: 4 x 4 cells per texel
    h, w = cells * img.shape[0], cells * img.shape[1]  # the sampling cells
    n = 1_000_000
    rng = np.random.default_rng(3)
    u = rng.random((n, 2), dtype=np.float32)
    u = np.minimum(u, np.float32(1 - 2**-24))
    out = HARNESS(runtime, "h_env_sample", n, light, tm, cdf, u, (n, 8))
    wi, pdf, pdf_eval, le = out[:, :3], out[:, 3].astype(np.float64), out[:, 4].astype(np.float64), out[:, 5:]
    assert np.all(np.isfinite(out))
    ok = pdf > 0
    assert ok.mean() > 0.9999
    wi, pdf, pdf_eval, le = wi[ok], pdf[ok], pdf_eval[ok], le[ok]
    assert np.allclose(np.linalg.norm(wi, axis=1), 1, atol=1e-5)
    uu, vv = uv_of(wi.astype(np.float64))
    # away from cell borders (float rounding may land a sample in the neighbour), pdfs agree
    inner = (np.abs(uu * w - np.round(uu * w)) > 1e-3) & (np.abs(vv * h - np.round(vv * h)) > 1e-3)
    assert np.allclose(pdf[inner], pdf_eval[inner], rtol=2e-3)
    reference = environment_radiance(sc.environment, wi.astype(np.float64))
    assert np.allclose(le, reference, rtol=1e-4, atol=1e-5)
    # chi-square on 2 x 2 sub-cells against the tables' cell probabilities, even within a cell
    marg, cond = cdf[: h + 1].astype(np.float64), cdf[h + 1:].reshape(h, w + 1).astype(np.float64)
    p_cell = np.diff(marg)[:, None] * np.diff(cond, axis=1)
    sub_c = np.minimum((uu * 2 * w).astype(int), 2 * w - 1)
    sub_r = np.minimum((vv * 2 * h).astype(int), 2 * h - 1)
    observed = np.bincount(sub_r * 2 * w + sub_c, minlength=4 * h * w)
    expected = np.repeat(np.repeat(p_cell / 4, 2, 0), 2, 1).reshape(-1) * ok.sum()
    assert observed[expected == 0].sum() <= 1e-5 * n  # only by float rounding at cell borders
    nz = expected > 0
    harness.assert_chi2(observed[nz], expected[nz], ALPHA, "environment map")
    # unbiased: E[Le / pdf] = the integral of the map over the sphere (Gauss-Legendre in theta, a
    # fine midpoint rule in phi, the map being piecewise bilinear in (u, v))
    if compensated:
        # the samples' radiance exceeds the mean (cells straddling it aside: their average does),
        # and the bright spot's texel (row 1, column 10) takes more of them than complete tables give
        lum = le.astype(np.float64) @ LUMINANCE
        assert np.mean(lum > mean) > 0.97
        complete = np.diff(environment_tables(img)[1][: h + 1].astype(np.float64))
        rows = slice(cells * 1, cells * 2)
        assert np.diff(marg)[rows].sum() > 1.2 * complete[rows].sum()
        d = rng.normal(size=(n // 10, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        ev = HARNESS(runtime, "h_env_eval", len(d), light, tm, cdf, d.astype(np.float32), (len(d), 2))
        du, dv = uv_of(d)
        cell_p = p_cell[np.minimum((dv * h).astype(int), h - 1), np.minimum((du * w).astype(int), w - 1)]
        inner = (np.abs(du * w - np.round(du * w)) > 1e-3) & (np.abs(dv * h - np.round(dv * h)) > 1e-3)
        assert np.all(ev[inner & (cell_p == 0), 0] == 0) and (inner & (cell_p == 0)).mean() > 0.3
        vals = ev[:, 0].astype(np.float64) * 4 * np.pi
        assert abs(vals.mean() - 1) < 5 * vals.std() / np.sqrt(len(vals)) + 1e-4
        return
    est = (le.astype(np.float64) @ LUMINANCE) / pdf * ok.mean()
    x, wq = np.polynomial.legendre.leggauss(8)
    t, tw = harness.gauss_legendre_cells(np.linspace(0, np.pi, 2 * h + 1), x, wq)
    phi = (np.arange(8 * w) + 0.5) / (8 * w) * 2 * np.pi
    tt, pp = np.meshgrid(t, phi, indexing="ij")
    d = np.stack([-np.sin(tt) * np.sin(pp), np.cos(tt), np.sin(tt) * np.cos(pp)], -1).reshape(-1, 3)
    lum = (environment_radiance(sc.environment, d) @ LUMINANCE).reshape(tt.shape)
    integral = ((lum * np.sin(tt)).mean(1) * tw).sum() * 2 * np.pi
    assert abs(est.mean() - integral) < 5 * est.std() / np.sqrt(len(est)) + 1e-4 * integral, (est.mean(), integral)
    # normalisation: E[pdf(w) 4 pi] over uniform directions = 1
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ev = HARNESS(runtime, "h_env_eval", n, light, tm, cdf, d.astype(np.float32), (n, 2))
    vals = ev[:, 0].astype(np.float64) * 4 * np.pi
    assert abs(vals.mean() - 1) < 5 * vals.std() / np.sqrt(n) + 1e-4
    assert np.all(ev[ev[:, 1] > 0, 0] > 0), "a direction of positive radiance has density 0"


@pytest.mark.parametrize("rotate", [False, True])
def test_env_map_is_mitsubas(runtime, tmp_path, rotate):
    """Mitsuba's envmap read from its XML (rows on the poles, phi centred, a rotated to_world): the
    kernel's radiance in random directions equals Mitsuba 3's own emitter.eval() there, and its
    density integrates to 1."""
    mi = harness.mitsuba()
    from pyopencl_rt.imageio import write_exr
    from pyopencl_rt.scene.loaders import load_scene

    img = env_map_image()
    write_exr(tmp_path / "sky.exr", img)
    transform = '<transform name="to_world"><rotate y="1" angle="70"/><rotate x="0.6" z="0.8" angle="25"/></transform>' if rotate else ""
    xml = f"""<scene version="3.0.0"><emitter type="envmap"><string name="filename" value="sky.exr"/>
        <float name="scale" value="1.5"/>{transform}</emitter>
        <shape type="sphere"><float name="radius" value="0.1"/></shape></scene>"""
    (tmp_path / "env.xml").write_text(xml)
    scene = load_scene(tmp_path / "env.xml")
    assert scene.environment.rows == "poles"
    tm, cdf, _, _ = environment_tables(scene.environment.image, scene.environment.rows, scene.environment.rotation)
    light = other_lights(scene)[0][-1:]
    n = 4096
    d = np.random.default_rng(5).normal(size=(n, 3))
    d[:4] = [[0, 1, 0], [0, -1, 0], [0, 0, -1], [1, 0, 0]]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ev = HARNESS(runtime, "h_env_eval", n, light, tm, cdf, d.astype(np.float32), (n, 2))
    emitter = mi.load_string(xml.replace("sky.exr", str(tmp_path / "sky.exr"))).emitters()[0]
    theirs = np.empty(n)
    for i in range(n):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-d[i]))
        theirs[i] = emitter.eval(si)[0]
    assert np.allclose(ev[:, 1], theirs, rtol=1e-4, atol=1e-6), np.abs(ev[:, 1] - theirs).max()
    assert np.allclose(environment_radiance(scene.environment, d)[:, 0], theirs, rtol=1e-4, atol=1e-6)


def test_env_map_of_zeros_and_constant(runtime):
    """A map of zeros samples uniformly in (u, v) with finite pdfs and zero radiance; a constant
    environment (no map) samples the sphere uniformly, pdf 1 / (4 pi)."""
    img = np.zeros((4, 8, 3), np.float32)
    tm, cdf, mean, _ = environment_tables(img)
    assert mean == 0 and np.all(np.isfinite(cdf))
    _, light = _env_light(img)
    u = np.random.default_rng(1).random((4096, 2), dtype=np.float32)
    out = HARNESS(runtime, "h_env_sample", 4096, light, tm, cdf, u, (4096, 8))
    assert np.all(np.isfinite(out)) and np.all(out[:, 5:] == 0)
    const = light.copy()
    const["prim"] = 0
    const["material"] = 0
    out = HARNESS(runtime, "h_env_sample", 4096, const, tm, cdf, u, (4096, 8))
    assert np.allclose(out[:, 3], 1 / (4 * np.pi)) and np.allclose(out[:, 4], 1 / (4 * np.pi))


# ----------------------------------------------------------------------------------- lanes
# wide cones from near the origin, so that many of lane_inputs' reference points are lit
SPOTS = [SpotLight(position=(0.2, 0.5, 0.1), intensity=(2.0, 1.0, 3.0), cutoff_angle=70, beam_width=40,
                   to_world=look_at_frame((0.2, 0.5, 0.1), (1, -1, 0.5), (0, 1, 0))),
         SpotLight(position=(-0.3, 0.2, 0.4), intensity=(1.0, 2.0, 0.5), cutoff_angle=80, beam_width=50,
                   falloff="smoothstep", to_world=np.diag([1.0, 2.0, 0.5])),
         ProjectorLight(position=(0.1, -0.2, 0.3), irradiance=(1.0, 0.5, 2.0), scale=1.5, fov=120,
                        to_world=look_at_frame((0.1, -0.2, 0.3), (-1, 0.5, 1), (0, 1, 0)))]


def cone_closed_form(rec, ref):
    """(Le, u, v) of spot and projector records at reference points ref (float64, numpy): the
    closed forms of cl/render/lights.h, Mitsuba's falloff computed as spot.cpp does."""
    p = rec["p"].astype(np.float64)
    to_ref = ref - p
    d2 = (to_ref ** 2).sum(1)
    l = np.einsum("nij,nj->ni", rec["frame"].astype(np.float64).reshape(-1, 3, 3), to_ref)
    cos = l[:, 2] / np.linalg.norm(l, axis=1)
    cc, cb, cut, inv = (rec["cone"][:, i].astype(np.float64) for i in range(4))
    with np.errstate(divide="ignore", invalid="ignore"):
        u = 0.5 + rec["uv_scale"][:, 0] * l[:, 0] / l[:, 2]
        v = 0.5 + rec["uv_scale"][:, 1] * l[:, 1] / l[:, 2]
        mitsuba = np.where(cos > cc, np.where(cos >= cb, 1.0, (cut - np.arccos(np.clip(cos, -1, 1))) * inv), 0.0)
        t = np.clip((cos - cc) / (cb - cc), 0, 1)
        smooth = t * t * (3 - 2 * t)
        spot = np.where(rec["flags"] & abi.LIGHT_SPOT_SMOOTHSTEP, smooth, mitsuba) / d2
        inside = (l[:, 2] > 0) & (u >= 0) & (u <= 1) & (v >= 0) & (v <= 1)
        cos_n = (rec["dir"].astype(np.float64) * to_ref).sum(1) / np.sqrt(d2)
        proj = np.where(inside, 1 / (l[:, 2] ** 2 * cos_n), 0.0)
    f = np.where(rec["kind"] == abi.LIGHT_SPOT, spot, proj)
    return rec["rgb"].astype(np.float64) * f[:, None], u, v


def lights_setup(rng, env_image):
    """Emissive triangles (one- and two-sided materials), emissive spheres, a point, a directional
    and an environment light (env_image None: constant), as the kernels read them."""
    n_tri = 6
    tri = (rng.normal(size=(n_tri, 1, 3)) * 3 + rng.normal(size=(n_tri, 3, 3))).astype(np.float32)
    tris = np.zeros((3 * n_tri, 4), np.float32)
    tris[:, :3] = tri.reshape(-1, 3)
    # what the kernels read (MESH_PARAMS): the corners as vertices in a shuffled order, the faces
    # that index them in another, and each (reordered) triangle's face
    order = rng.permutation(3 * n_tri)
    vertices = np.ascontiguousarray(tri.reshape(-1, 3)[order]).reshape(-1)
    prim_ids = rng.permutation(n_tri).astype(np.int32)
    faces = np.zeros((n_tri, 3), np.int32)
    faces[prim_ids] = np.argsort(order).reshape(n_tri, 3)
    centres = rng.normal(size=(3, 3)) * 3
    spheres = sphere_records(np.column_stack([centres, [0.5, 1.0, 2.0]]).astype(np.float32))
    materials = np.stack([Material("one-sided", emission=(1.0, 2.0, 3.0)).record(),
                          Material("two-sided", emission=(4.0, 0.5, 1.0), two_sided=True).record()])
    if env_image is None:
        env = Environment(radiance=(0.5, 1.0, 2.0))
        tm, cdf = np.zeros(abi.ENV_MAP_HEADER, np.float32), np.zeros(1, np.float32)
    else:
        env = Environment(radiance=(0.5, 1.0, 2.0), image=env_image)
        tm, cdf, _, _ = environment_tables(env_image)
    sc = Scene(**empty_mesh(), materials=[Material()], shapes=sphere_records(np.array([[0, 0, 0, 4]], np.float32)),
               shape_materials=np.array([0], np.int32),
               lights=[PointLight(position=(0.5, 1.0, -0.3), intensity=(2.0, 3.0, 4.0)),
                       DirectionalLight(direction=(0.3, -1.0, 0.2), irradiance=(1.0, 2.0, 0.5)),
                       *SPOTS],
               environment=env)
    others, _ = other_lights(sc)
    area = np.zeros(n_tri + 3, abi.LIGHT)
    area["kind"][:n_tri] = abi.LIGHT_TRIANGLE
    area["prim"][:n_tri] = np.arange(n_tri)
    area["material"][:n_tri] = np.arange(n_tri) % 2
    p = tri.astype(np.float64)
    area["area"][:n_tri] = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    area["kind"][n_tri:] = abi.LIGHT_SHAPE
    area["prim"][n_tri:] = np.arange(3)
    area["material"][n_tri:] = np.arange(3) % 2
    area["area"][n_tri:] = 4 * np.pi * spheres["params"][:, 3].astype(np.float64) ** 2
    lights = np.concatenate([area, others])
    return dict(tris=tris, mesh=(vertices, faces.reshape(-1), prim_ids), spheres=spheres, materials=materials, env_map=tm, env_cdf=cdf, lights=lights,
                env_light=len(lights) - 1)


def lane_inputs(rng, setup, n):
    """Per lane: a light of every kind (half the lanes in runs of one kind, to have packets of one
    kind, half at random), 90% active; a reference point (for a sphere, inside it in 30% of the
    lanes), uniforms, a point on the light with its normal (light_pdf), a unit direction (a few
    along +-y, the poles of the map)."""
    lights, tris, spheres = setup["lights"], setup["tris"], setup["spheres"]
    pick = rng.integers(0, len(lights), n)
    pick[: n // 2] = np.sort(pick[: n // 2])
    active = (rng.random(n) < 0.9).astype(np.int32)
    kind, prim = lights["kind"][pick], lights["prim"][pick]
    ref = rng.normal(size=(n, 3)) * 4
    u = harness.uniforms(rng, (n, 2))
    p, ng = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    t = kind == abi.LIGHT_TRIANGLE
    v = tris[:, :3].astype(np.float64).reshape(-1, 3, 3)[prim[t]]
    b = rng.dirichlet((1, 1, 1), t.sum())
    p[t] = np.einsum("nk,nkc->nc", b, v)
    ng[t] = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    # 5% of the triangles' reference points in the light's plane (to rounding): its side in doubt
    plane = rng.random(t.sum()) < 0.05
    ab = rng.uniform(-3, 3, (t.sum(), 2))
    inplane = v[:, 0] + ab[:, :1] * (v[:, 1] - v[:, 0]) + ab[:, 1:] * (v[:, 2] - v[:, 0])
    ref[np.flatnonzero(t)[plane]] = inplane[plane]
    s = kind == abi.LIGHT_SHAPE
    c, r = spheres["params"][prim[s], :3].astype(np.float64), spheres["params"][prim[s], 3].astype(np.float64)
    dirs = rng.normal(size=(s.sum(), 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    p[s] = c + r[:, None] * dirs
    ng[s] = dirs
    inside = rng.random(s.sum()) < 0.3
    ref[np.flatnonzero(s)[inside]] = (c + 0.8 * r[:, None] * rng.uniform(-1, 1, (s.sum(), 3)) / np.sqrt(3))[inside]
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    w[:8] = [[0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1e-8, 1], [1e-20, -1, 0]]
    ins = np.concatenate([ref, u, p, ng, w], axis=1).astype(np.float32)
    return np.stack([pick, active], 1).astype(np.int32), ins


def run_lights(runtime, width, setup, index, ins):
    n = len(index)
    return lane_kernels(width)(runtime, "h_lights", n // width, *setup["mesh"], setup["spheres"], setup["materials"],
                               setup["env_map"], setup["env_cdf"], setup["lights"], setup["env_light"], index, ins,
                               (n, 24))


def test_light_sample_all_one_lane(runtime, rng):
    """Width 1: light_sample_all's sample of each kind against its closed form (point: Le = I /
    d^2 along the unit direction to ref; directional: far = 1.01 (|ref - centre| + radius), p =
    ref + far n; both delta with pdf 1), light_pdf() of the sampled point equals the sample's pdf
    for area lights (the cone's pdf for a sphere seen from outside exactly), env_pdf() of an
    environment sample's direction its pdf, inactive lanes get no sample."""
    for image in (env_map_image(), None):
        setup = lights_setup(rng, image)
        lights = setup["lights"]
        n = 4096
        index, ins = lane_inputs(rng, setup, n)
        out = run_lights(runtime, 1, setup, index, ins).astype(np.float64)
        got, lp, n_, le, pdf, far, delta = (out[:, 0] == 1, out[:, 1:4], out[:, 7:10], out[:, 10:13], out[:, 13],
                                            out[:, 14], out[:, 15] == 1)
        kind = lights["kind"][index[:, 0]]
        act = index[:, 1] == 1
        assert not got[~act].any()
        rec = lights[index[:, 0]]
        ref = ins[:, :3].astype(np.float64)
        pt = act & (kind == abi.LIGHT_POINT)
        assert got[pt].all() and delta[pt].all() and np.all(pdf[pt] == 1) and np.all(far[pt] == 0)
        d = ref[pt] - rec["p"][pt]
        d2 = (d * d).sum(1)
        assert np.allclose(le[pt], rec["rgb"][pt] / d2[:, None], rtol=1e-5)
        assert np.allclose(n_[pt], d / np.sqrt(d2)[:, None], atol=1e-5)
        dl = act & (kind == abi.LIGHT_DIRECTIONAL)
        assert got[dl].all() and delta[dl].all() and np.all(pdf[dl] == 1)
        assert np.allclose(n_[dl], -rec["dir"][dl], atol=1e-7) and np.allclose(le[dl], rec["rgb"][dl])
        fd = 1.01 * (np.linalg.norm(ref[dl] - rec["p"][dl], axis=1) + rec["radius"][dl])
        assert np.allclose(far[dl], fd, rtol=1e-5)
        assert np.allclose(lp[dl], ref[dl] + far[dl, None] * n_[dl], rtol=1e-5, atol=1e-5)
        # spot and projector: delta lights at p, Le and (u, v) as the closed forms have them
        cone = act & ((kind == abi.LIGHT_SPOT) | (kind == abi.LIGHT_PROJECTOR))
        assert got[cone].all() and delta[cone].all() and np.all(pdf[cone] == 1) and np.all(far[cone] == 0)
        assert np.all(out[cone, 21] == -1)
        le_cf, u_cf, v_cf = cone_closed_form(rec[cone], ref[cone])
        lit = le_cf.max(1) > 0
        assert lit.mean() > 0.2 and (~lit).any()
        assert np.allclose(le[cone], le_cf, rtol=2e-4, atol=1e-7)
        assert np.allclose(lp[cone], rec["p"][cone])
        assert np.allclose(out[cone, 22][lit], u_cf[lit], atol=1e-4) and np.allclose(out[cone, 23][lit], v_cf[lit], atol=1e-4)
        ev = act & (kind == abi.LIGHT_ENVIRONMENT)
        assert got[ev].mean() > 0.99 and not delta[ev].any() and np.all(far[ev] > 0)
        e = ev & got
        assert np.allclose(np.linalg.norm(n_[e], axis=1), 1, atol=1e-5)
        ep = HARNESS(runtime, "h_env_eval", int(e.sum()), lights[setup["env_light"]:], setup["env_map"],
                     setup["env_cdf"], n_[e].astype(np.float32), (int(e.sum()), 2))
        assert np.mean(np.isclose(ep[:, 0], pdf[e], rtol=2e-3)) > 0.99  # texel borders aside
        area = act & ((kind == abi.LIGHT_TRIANGLE) | (kind == abi.LIGHT_SHAPE))
        assert not delta[area].any() and np.all(far[area] == 0)
        a = area & got
        assert a.sum() > 0.9 * area.sum() and np.all(pdf[a] > 0)
        # light_pdf at the sampled point, from the same reference point
        ins2 = ins.copy()
        ins2[:, 5:8], ins2[:, 8:11] = out[:, 1:4], out[:, 7:10]
        out2 = run_lights(runtime, 1, setup, index, ins2).astype(np.float64)
        to_ref = ref - lp
        cos = np.abs((to_ref * n_).sum(1)) / np.linalg.norm(to_ref, axis=1)
        clear = a & (cos > 1e-3)  # not (nearly) in the light's plane: cos_l's rounding, relative, is small
        assert clear.sum() > 0.9 * a.sum() and np.allclose(out2[clear, 16], pdf[clear], rtol=1e-3)
        cone = a & (kind == abi.LIGHT_SHAPE)
        si = np.where(kind == abi.LIGHT_SHAPE, rec["prim"], 0)
        c = setup["spheres"]["params"][si, :3].astype(np.float64)
        cone &= ((ref - c) ** 2).sum(1) > setup["spheres"]["params"][si, 3].astype(np.float64) ** 2
        assert cone.sum() > 0 and np.array_equal(out2[cone, 16], pdf[cone])
        # n faces ref; emission: the material's where it faces ref (or two-sided), else 0
        mat = setup["materials"][np.where(area, rec["material"], 0)]
        assert np.all(((to_ref * n_).sum(1) >= -1e-5 * np.linalg.norm(to_ref, axis=1))[a])
        two = (mat["flags"] & abi.MATERIAL_FLAG_TWO_SIDED) != 0
        tri_a = a & (kind == abi.LIGHT_TRIANGLE)
        p = setup["tris"][:, :3].astype(np.float64).reshape(-1, 3, 3)[np.where(tri_a, rec["prim"], 0)]
        ng = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        front = (ng * n_).sum(1) > 0
        lit = two | front
        assert np.all(le[tri_a & lit] == mat["emission"][tri_a & lit]) and np.all(le[tri_a & ~lit] == 0)
        # a sphere's outside emits toward a reference point outside; seen from inside, only two-sided
        sph_in = a & (kind == abi.LIGHT_SHAPE) & ~cone
        assert sph_in.sum() > 0 and np.all(le[sph_in & ~two] == 0)
        assert np.all(le[sph_in & two] == mat["emission"][sph_in & two])
        assert np.mean(np.all(le[cone] == mat["emission"][cone], axis=1)) > 0.99


@pytest.mark.parametrize("width", [8, 16])
def test_lights_lanes_equal_one_lane(device, runtime, rng, width):
    """light_sample_all, light_pdf, env_radiance, env_pdf (an environment map and a constant one)
    and hit_point / hit_normal (triangles, spheres, misses) give, in every lane of width 8 and 16,
    the bits width 1 gives: lights of every kind mixed in the packets, references inside and
    outside spheres."""
    harness.require_lane_kernels(device, width)
    n = 16 * 384
    for image in (env_map_image(), None):
        setup = lights_setup(rng, image)
        index, ins = lane_inputs(rng, setup, n)
        one = run_lights(runtime, 1, setup, index, ins)
        lanes = run_lights(runtime, width, setup, index, ins)
        kind = setup["lights"]["kind"][index[:, 0]]
        got = one[:, 0] == 1
        assert np.array_equal(one[:, 0], lanes[:, 0]) and got.mean() > 0.5
        bits1, bitsw = one.view(np.uint32), lanes.view(np.uint32)
        assert np.array_equal(bits1[got, :16], bitsw[got, :16]), "light_sample_all"
        assert np.array_equal(bits1[got, 21:], bitsw[got, 21:]), "light_sample_all: a texture's (u, v)"
        assert {abi.LIGHT_SPOT, abi.LIGHT_PROJECTOR} <= set(kind[got].tolist())
        area = (kind == abi.LIGHT_TRIANGLE) | (kind == abi.LIGHT_SHAPE)
        assert np.array_equal(bits1[area, 16], bitsw[area, 16]), "light_pdf"
        assert np.array_equal(bits1[:, 17:21], bitsw[:, 17:21]), "env_pdf, env_radiance"
    # hits: triangles (barycentrics inside and a little outside), spheres from outside and inside, misses
    tris, spheres = setup["tris"], setup["spheres"]
    prims = rng.integers(0, len(tris) // 3, n).astype(np.int32)
    sph = rng.random(n) < 0.4
    prims[sph] = abi.PRIM_SHAPE_FIRST - rng.integers(0, len(spheres), sph.sum())
    prims[rng.random(n) < 0.05] = abi.PRIM_MISS
    o = rng.normal(size=(n, 3)) * 5
    d = rng.normal(size=(n, 3))
    t = rng.uniform(0, 3, n)
    uv = rng.uniform(-0.1, 0.7, (n, 2))
    hin = np.concatenate([o, d, t[:, None], uv], axis=1).astype(np.float32)
    mesh = setup["mesh"]
    one = lane_kernels(1)(runtime, "h_hits", n, *mesh, spheres, prims, hin, (n, 9))
    lanes = lane_kernels(width)(runtime, "h_hits", n // width, *mesh, spheres, prims, hin, (n, 9))
    hit = prims != abi.PRIM_MISS
    assert np.array_equal(one[hit].view(np.uint32), lanes[hit].view(np.uint32)), "hit_point, hit_normal"


def test_hit_point_and_normal(runtime, rng):
    """Width 1: a triangle's hit point interpolates its vertices with the barycentrics (error bound
    >= the actual error), its normal is the unit (v1 - v0) x (v2 - v0); a sphere's point is o + t d
    projected onto the surface, its normal the outward unit normal."""
    setup = lights_setup(rng, None)
    tris, spheres = setup["tris"], setup["spheres"]
    n = 2048
    prims = rng.integers(0, len(tris) // 3, n).astype(np.int32)
    sph = np.arange(n) % 2 == 1
    prims[sph] = abi.PRIM_SHAPE_FIRST - rng.integers(0, len(spheres), sph.sum())
    o = rng.normal(size=(n, 3)) * 5
    d = rng.normal(size=(n, 3))
    t = rng.uniform(0.1, 3, n)
    uv = rng.dirichlet((1, 1, 1), n)[:, 1:]
    hin = np.concatenate([o, d, t[:, None], uv], axis=1).astype(np.float32)
    mesh = setup["mesh"]
    out = lane_kernels(1)(runtime, "h_hits", n, *mesh, spheres, prims, hin, (n, 9)).astype(np.float64)
    p, err, nrm = out[:, :3], out[:, 3:6], out[:, 6:]
    v = tris[:, :3].astype(np.float64).reshape(-1, 3, 3)
    tr = ~sph
    vt = v[prims[tr]]
    b = hin[tr, 7:9].astype(np.float64)
    exact = (1 - b.sum(1))[:, None] * vt[:, 0] + b[:, :1] * vt[:, 1] + b[:, 1:] * vt[:, 2]
    assert np.all(np.abs(p[tr] - exact) <= err[tr] + 1e-12)
    ng = np.cross(vt[:, 1] - vt[:, 0], vt[:, 2] - vt[:, 0])
    assert np.allclose(nrm[tr], ng / np.linalg.norm(ng, axis=1, keepdims=True), atol=1e-5)
    s = abi.PRIM_SHAPE_FIRST - prims[sph]
    c, r = spheres["params"][s, :3].astype(np.float64), spheres["params"][s, 3].astype(np.float64)
    q = hin[sph, :3].astype(np.float64) + hin[sph, 6:7] * hin[sph, 3:6].astype(np.float64) - c
    expect = c + r[:, None] * q / np.linalg.norm(q, axis=1, keepdims=True)
    assert np.all(np.abs(np.linalg.norm(p[sph] - c, axis=1) - r) <= np.linalg.norm(err[sph], axis=1))
    assert np.allclose((p[sph] - c) / r[:, None], (expect - c) / r[:, None], atol=1e-4)
    assert np.allclose(nrm[sph], (p[sph] - c) / r[:, None], atol=1e-5)


# ----------------------------------------------------------------------------------- renders
def plane_scene(lights, rho=0.5, integrator="path", size=32, env=None):
    """A diffuse square of side 20 at y = 0 (facing +y), seen from above."""
    v = np.array([[-10, 0, -10], [-10, 0, 10], [10, 0, 10], [10, 0, -10]], np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    return Scene(vertices=v, faces=f, face_materials=np.zeros(2, np.int32),
                 materials=[Material("plane", albedo=(rho,) * 3)],
                 camera=Camera(eye=(0, 4, 0), look_at=(0, 0, 0), up=(0, 0, -1), fov=60),
                 settings=RenderSettings(width=size, height=size, max_depth=2, integrator=integrator),
                 lights=lights, environment=env)


def pixel_points(cam_rec, width, height, k=8):
    """Supersampled (k x k per pixel) camera directions: H x W x k*k x 3."""
    j = (np.arange(k) + 0.5) / k
    xs = (np.arange(width)[:, None] + j[None, :]).reshape(-1) / width * 2 - 1
    ys = 1 - (np.arange(height)[:, None] + j[None, :]).reshape(-1) / height * 2
    f, r, u = (np.asarray(cam_rec[n], np.float64) for n in ("forward", "right", "up"))
    d = f + xs[None, :, None] * r + ys[:, None, None] * u  # (H k) x (W k) x 3
    return d.reshape(height, k, width, k, 3).transpose(0, 2, 1, 3, 4).reshape(height, width, k * k, 3)


def assert_pixels(r, expect, label, k=5.0):
    img = r.image.astype(np.float64)
    se = np.sqrt(r.film.variance_of_mean())
    bad = np.abs(img - expect) > k * se + 2e-4 * np.abs(expect) + 1e-6
    assert not bad.any(), f"{label}: {bad.sum()} pixels off, worst {np.abs(img - expect).max():.3g}"


def test_point_light_over_plane(device):
    """Radiance rho / pi * I cos(theta) / r^2 at every pixel (pixel averages by 8 x 8 quadrature),
    with MIS (path) and with light sampling alone (nee)."""
    lp, intensity, rho = np.array([0.7, 2.0, -0.4]), 5.0, 0.5
    sc = plane_scene([PointLight(position=tuple(lp), intensity=(intensity,) * 3)], rho)
    rec = sc.camera.record(32, 32)
    d = pixel_points(rec, 32, 32)
    eye = np.asarray(rec["origin"], np.float64)
    p = eye + d * (-eye[1] / d[..., 1:2])
    to_l = lp - p
    r2 = (to_l**2).sum(-1)
    e = intensity * to_l[..., 1] / np.sqrt(r2) / r2
    expect = np.repeat((rho / np.pi * e).mean(-1)[..., None], 3, -1)
    for integ in ("path", "nee"):
        r = render_full(sc, spp=16, device=device, seed=2, integrator=integ)
        assert r.info["nonfinite_samples"] == 0
        assert_pixels(r, expect, f"point light, {integ}")


def test_spot_and_projector_over_plane(device):
    """Radiance rho / pi * E on the plane (pixel averages by 8 x 8 quadrature) under a textured
    spot with Mitsuba's linear falloff, a spot with pbrt-v4's smoothstep and a textured projector
    with Mitsuba's normalisation (E = pi scale irradiance texture / (z^2 cos) cos_surface, z the
    depth along its axis: a plane facing it is lit by exactly pi scale irradiance texture / z^2
    there), each tilted, light sampling alone (the lights are delta lights: no other strategy sees
    them); the pixels on a light's edge (the cone's, the projected image's) left out."""
    from pyopencl_rt.scene.textures import bilinear, texture_from_array

    rho, size = 0.5, 16
    tex = texture_from_array(np.array([[[1.0, 0.2, 0.2], [0.2, 1.0, 0.2], [0.3, 0.3, 0.3]],
                                       [[0.2, 0.2, 1.0], [1.0, 1.0, 1.0], [0.0, 0.5, 1.0]]], np.float32))
    sp, pp = np.array([0.4, 2.0, -0.3]), np.array([-0.5, 2.5, 0.4])
    lights = [SpotLight(position=tuple(sp), intensity=(3.0, 2.0, 4.0), cutoff_angle=40, beam_width=25, texture=tex,
                        to_world=look_at_frame(sp, (0.2, 0, 0.1), (0, 0, 1))),
              SpotLight(position=tuple(sp), intensity=(3.0, 2.0, 4.0), cutoff_angle=35, beam_width=20,
                        falloff="smoothstep", to_world=look_at_frame(sp, (-0.3, 0, 0), (1, 0, 0))),
              ProjectorLight(position=tuple(pp), irradiance=(1.0, 2.0, 0.5), texture=tex, scale=0.7, fov=50,
                             to_world=look_at_frame(pp, (-0.2, 0, 0.1), (0, 0, 1)))]
    for light in lights:
        sc = plane_scene([light], rho, size=size)
        rec = sc.camera.record(size, size)
        d = pixel_points(rec, size, size)
        eye = np.asarray(rec["origin"], np.float64)
        p = (eye + d * (-eye[1] / d[..., 1:2])).reshape(-1, 3)
        r_ = other_lights(sc)[0][0]
        le, u, v = cone_closed_form(np.repeat(r_[None], len(p), 0), p)
        if light.texture is not None:
            with np.errstate(invalid="ignore"):
                le *= bilinear(light.texture.texels[..., :3], np.stack([u, v], 1))
        to_l = np.asarray(light.position) - p
        e = np.nan_to_num(le) * (to_l[:, 1] / np.linalg.norm(to_l, axis=1))[:, None]
        expect = (rho / np.pi * e).reshape(size, size, -1, 3).mean(2)
        r = render_full(sc, spp=8, device=device, seed=2, integrator="nee")
        assert r.info["nonfinite_samples"] == 0
        # pixels across the light's edge (the cone's, the image's) left out: 8 samples may all miss a sliver
        lit = (np.nan_to_num(le).max(1) > 0).reshape(size, size, -1)
        keep = lit.all(2) | ~lit.any(2)
        assert keep.mean() > 0.6 and lit.all(2).mean() > 0.1
        expect, r.image[~keep] = np.where(keep[..., None], expect, 0), 0
        assert_pixels(r, expect, type(light).__name__)


def test_goniometric_light_over_plane(device):
    """pbrt-v4's goniometric light: radiance rho / pi * I Y(w) cos(theta) / r^2 on the plane, Y the
    profile's nearest texel at the equal-area square point (pbrt_materials.equal_area_sphere_to_square,
    the map pbrt's infinite lights are read with) of w, the direction from the light in its frame
    with y and z swapped (the profile's pole along local +y), at the pixels whose 8 x 8 quadrature
    points all see one texel (pixel averages by quadrature).  A random profile of 8 x 8 texels, a
    tilted frame, light sampling alone (a delta light)."""
    from pyopencl_rt.scene.lights.goniometric import GoniometricLight, profile_texture
    from pyopencl_rt.scene.loaders.pbrt_materials import equal_area_sphere_to_square
    from pyopencl_rt.scene.textures import texture_from_array

    rho, size, n = 0.5, 16, 8
    profile = profile_texture(texture_from_array(np.random.default_rng(5).uniform(0.1, 2.0, (n, n, 3)).astype(np.float32)))
    lp, intensity = np.array([0.3, 1.5, -0.2]), np.array([2.0, 3.0, 4.0])
    frame = look_at_frame(lp, (1.0, 0.0, 0.5), (0.0, 1.0, 0.3))
    sc = plane_scene([GoniometricLight(position=tuple(lp), intensity=tuple(intensity), texture=profile,
                                       to_world=frame)], rho, size=size)
    rec = sc.camera.record(size, size)
    d = pixel_points(rec, size, size)
    eye = np.asarray(rec["origin"], np.float64)
    p = (eye + d * (-eye[1] / d[..., 1:2])).reshape(-1, 3)
    w = (p - lp) @ np.linalg.inv(frame).T  # in the light's frame
    w = w[:, [0, 2, 1]] / np.linalg.norm(w, axis=1, keepdims=True)  # y and z swapped, as pbrt-v4
    u, v = equal_area_sphere_to_square(w)
    texel = np.clip((v * n).astype(int), 0, n - 1) * n + np.clip((u * n).astype(int), 0, n - 1)
    y = profile.texels[..., 0].astype(np.float64).reshape(-1)[texel]
    to_l = lp - p
    r2 = (to_l**2).sum(1)
    e = intensity[None, :] * (y * to_l[:, 1] / np.sqrt(r2) / r2)[:, None]
    expect = (rho / np.pi * e).reshape(size, size, -1, 3).mean(2)
    texel = texel.reshape(size, size, -1)
    keep = (texel == texel[..., :1]).all(2)  # one texel over the whole pixel
    assert keep.mean() > 0.3 and len(np.unique(texel[keep][:, 0])) >= 8
    r = render_full(sc, spp=8, device=device, seed=2, integrator="nee")
    assert r.info["nonfinite_samples"] == 0
    expect, r.image[~keep] = np.where(keep[..., None], expect, 0), 0
    assert_pixels(r, expect, "goniometric")


def test_directional_light_over_plane(device):
    """Radiance rho / pi * E cos(theta), the same at every pixel (no noise)."""
    dirn, irr, rho = np.array([0.3, -1.0, 0.2]), 2.0, 0.6
    sc = plane_scene([DirectionalLight(direction=tuple(dirn), irradiance=(irr,) * 3)], rho, size=16)
    cos = 1 / np.linalg.norm(dirn)
    r = render_full(sc, spp=4, device=device, seed=2, integrator="path")
    assert np.allclose(r.image, rho / np.pi * irr * cos, rtol=1e-4)


def sphere_under(env, integrator, albedo=1.0, size=16, max_depth=4, material=None):
    return Scene(**empty_mesh(), materials=[material or Material("ball", albedo=(albedo,) * 3)],
                 camera=Camera(eye=(0, 0, 5), look_at=(0, 0, 0), fov=30),
                 shapes=sphere_records(np.array([[0, 0, 0, 1]], np.float32)), shape_materials=np.array([0], np.int32),
                 settings=RenderSettings(width=size, height=size, max_depth=max_depth, integrator=integrator),
                 environment=env)


@pytest.mark.parametrize("integrator", ["path", "bsdf", "nee"])
def test_constant_environment_furnace(device, integrator):
    """A diffuse sphere of albedo 1 under a constant environment of radiance 1 renders 1."""
    r = render_full(sphere_under(Environment(radiance=(1.0, 1.0, 1.0)), integrator), spp=16, device=device, seed=4)
    assert r.info["nonfinite_samples"] == 0
    m = float(r.image.mean())
    se = float(r.image.std()) / np.sqrt(r.image.size)
    assert abs(m - 1.0) <= 4 * se + 1e-5, f"{integrator}: mean {m} (se {se:.2g})"


@pytest.mark.parametrize("material", [None, Material("gold", type="conductor", eta=(0.18, 0.42, 1.37),
                                                     k=(3.42, 2.35, 1.77), alpha=0.2)], ids=["diffuse", "rough gold"])
def test_environment_map_light_vs_bsdf_sampling(device, material):
    """A diffuse sphere, and a rough conductor, under an environment map: MIS (with the tables of
    MIS compensation, where BSDF sampling alone covers the map below its mean), BSDF sampling
    alone and light sampling alone (complete tables) agree (4 x 4-pixel tiles, 3 channels, 3
    pairs: |z| < 4.5); MIS has less variance than either technique alone (diffuse: 0.002 against
    0.005-0.01: which of the two is better depends on the map's bright spot, sharper with
    nearest-texel lookups than with bilinear ones)."""
    env = Environment(radiance=(1.0, 1.0, 1.0), image=env_map_image())
    res = {}
    for i, integ in enumerate(("path", "bsdf", "nee")):
        r = render_full(sphere_under(env, integ, albedo=0.8, max_depth=3, material=material), spp=64, device=device,
                        seed=30 + i)
        assert r.info["nonfinite_samples"] == 0
        var = r.film.variance_of_mean()
        k = 4
        m = r.image.astype(np.float64).reshape(4, k, 4, k, 3).mean(axis=(1, 3))
        v = var.reshape(4, k, 4, k, 3).sum(axis=(1, 3)) / (k * k) ** 2
        res[integ] = (m, v, var.mean())
    for a, b in (("path", "bsdf"), ("path", "nee"), ("bsdf", "nee")):
        z = (res[a][0] - res[b][0]) / np.sqrt(res[a][1] + res[b][1] + 1e-30)
        assert np.abs(z).max() < 4.5, f"{a} vs {b}: max |z| = {np.abs(z).max():.2f}"
    assert res["path"][2] < min(res["nee"][2], res["bsdf"][2])


# ----------------------------------------------------------------------------------- thin lens
def edge_scene(depth, aperture, focus, width=64, height=8):
    """An emitter of radiance 1 covering x > 0 of the plane z = -depth (nothing at x < 0)."""
    big = 1000.0
    v = np.array([[0, -big, -depth], [big, -big, -depth], [big, big, -depth], [0, big, -depth]], np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    return Scene(vertices=v, faces=f, face_materials=np.zeros(2, np.int32),
                 materials=[Material("lamp", albedo=(0, 0, 0), emission=(1, 1, 1))],
                 camera=Camera(eye=(0, 0, 0), look_at=(0, 0, -1), fov=40, aperture_radius=aperture,
                               focus_distance=focus),
                 settings=RenderSettings(width=width, height=height, max_depth=1))


def edge_profile(depth, aperture, focus, width=64, height=8, k=64):
    """Expected column values: the fraction of the lens's blur disk (radius aperture |1 - depth /
    focus| on the plane) on the emitting side, averaged over each pixel's footprint."""
    rec = Camera(eye=(0, 0, 0), look_at=(0, 0, -1), fov=40).record(width, height)
    sx = ((np.arange(width)[:, None] + (np.arange(k) + 0.5)[None, :] / k) / width * 2 - 1)
    x = depth * sx * float(rec["right"][0])
    r = aperture * abs(1 - depth / focus) if aperture > 0 else 0.0
    if r == 0:
        return (x > 0).mean(1)
    t = np.clip(x / r, -1, 1)
    return (1 - (np.arccos(t) - t * np.sqrt(1 - t * t)) / np.pi).mean(1)


def column_check(r, expect, label):
    img = r.image[..., 0].astype(np.float64)
    var = r.film.variance_of_mean()[..., 0]
    col = img.mean(0)
    se = np.sqrt(var.sum(0)) / img.shape[0]
    bad = np.abs(col - expect) > 4.5 * se + 2e-3
    assert not bad.any(), f"{label}: columns {np.flatnonzero(bad)} off: {col[bad]} vs {expect[bad]}"
    return col


def test_thin_lens_blur_and_focus(device):
    """Out of focus (plane at twice the focus distance), an edge blurs into the disk-overlap
    profile of the circle of confusion (radius aperture x |1 - depth / focus|, ~3 pixels here);
    in focus it stays as sharp as the pinhole's; aperture 0 is the pinhole bit for bit."""
    depth, focus, aperture = 4.0, 2.0, 1.0
    r = render_full(edge_scene(depth, aperture, focus), spp=64, device=device, seed=5)
    col = column_check(r, edge_profile(depth, aperture, focus), "out of focus")
    sharp = edge_profile(depth, 0.0, focus)
    assert np.abs(col - sharp).max() > 0.3  # visibly blurred
    r = render_full(edge_scene(focus, aperture, focus), spp=64, device=device, seed=6)
    column_check(r, edge_profile(focus, 0.0, focus), "in focus")
    a = render_full(edge_scene(depth, 0.0, focus), spp=2, device=device, seed=7).image
    b = render_full(edge_scene(depth, 0.0, None), spp=2, device=device, seed=7).image
    assert np.array_equal(a, b)
    column_check(render_full(edge_scene(depth, 0.0, focus), spp=16, device=device, seed=7),
                 edge_profile(depth, 0.0, focus), "pinhole")


# ----------------------------------------------------------------------------------- robustness
def test_extreme_parameters_finite(device):
    """Huge intensities, delta lights on glossy, mirror and glass surfaces, spots and projectors at
    their limits, an environment map of zeros, a huge aperture with a tiny focus distance: no NaN
    or Inf anywhere."""
    v = np.array([[-10, 0, -10], [-10, 0, 10], [10, 0, 10], [10, 0, -10]], np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    mats = [Material("plane", albedo=(0.5,) * 3), Material("glossy", type="conductor", alpha=1e-3),
            Material("mirror", type="conductor", alpha=0.0), Material("glass", type="dielectric", ior=1.5),
            Material("plastic", type="gltf", metallic=0.0, alpha=0.01)]
    sc = Scene(vertices=v, faces=f, face_materials=np.zeros(2, np.int32), materials=mats,
               shapes=sphere_records(np.array([[-2, 1, 0, 1], [0, 1, 0, 0.8], [2, 1, 0, 1], [0, 1, 2.5, 0.7]], np.float32)),
               shape_materials=np.array([1, 2, 3, 4], np.int32),
               camera=Camera(eye=(0, 3, 8), look_at=(0, 1, 0), fov=50, aperture_radius=100.0, focus_distance=1e-4),
               settings=RenderSettings(width=16, height=16, max_depth=6),
               lights=[PointLight(position=(0, 3, 1), intensity=(1e20,) * 3),
                       PointLight(position=(-2, 1, 0), intensity=(1.0,) * 3),  # inside a sphere
                       DirectionalLight(direction=(0, -1, 0), irradiance=(1e20, 0, 1e-30)),
                       # a needle of a spot (beam = cutoff: no ramp), one lighting everything, a projector grazing
                       # the plane (its depth z -> 0 there), one nearly 180 degrees wide
                       SpotLight(position=(0, 3, 1), intensity=(1e20,) * 3, cutoff_angle=0.01, beam_width=0.01,
                                 to_world=look_at_frame((0, 3, 1), (0, 0, 1), (0, 0, 1))),
                       SpotLight(position=(1, 2, 1), cutoff_angle=180, beam_width=0),
                       ProjectorLight(position=(0, 1e-3, 0), fov=90, to_world=look_at_frame((0, 1e-3, 0), (0, 1e-3, 1),
                                                                                          (0, 1, 0))),
                       ProjectorLight(position=(0, 2, 0), fov=179.99, scale=1e20,
                                      to_world=look_at_frame((0, 2, 0), (0, 0, 0), (0, 0, 1)))],
               environment=Environment(radiance=(1.0, 1.0, 1.0), image=np.zeros((4, 8, 3), np.float32)))
    for integ in ("path", "nee"):
        r = render_full(sc, spp=4, device=device, seed=1, integrator=integ)
        assert r.info["nonfinite_samples"] == 0
        assert np.all(np.isfinite(r.image))
        assert r.image.max() > 1e10
    dark = sphere_under(Environment(radiance=(1.0,) * 3, image=np.zeros((4, 8, 3), np.float32)), "path", size=8)
    r = render_full(dark, spp=4, device=device, seed=1)
    assert r.info["nonfinite_samples"] == 0 and np.all(r.image == 0)


def test_no_lights_warns(device):
    """A sphere beside a triangle (the kernel of tests/test_robustness.py's light-less meshes), no light."""
    ball = sphere_under(None, "path", size=4)
    sc = Scene(vertices=np.array([[-1, -1, -2], [1, -1, -2], [0, 1, -2]], np.float32),
               faces=np.array([[0, 1, 2]], np.int32), face_materials=np.array([0], np.int32),
               **{k: getattr(ball, k) for k in ("materials", "camera", "shapes", "shape_materials", "settings")})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        render_full(sc, spp=1, device=device, seed=1)
    assert any("no lights" in str(w.message) for w in caught)


def test_light_records():
    sc, rec = _env_light(env_map_image())
    assert rec["kind"][0] == abi.LIGHT_ENVIRONMENT and rec["prim"][0] == 16 and rec["material"][0] == 8
    assert np.isclose(rec["radius"][0], np.sqrt(3))
    assert abi.LIGHT.itemsize % 16 == 0 and abi.CAMERA.itemsize == 96


# ----------------------------------------------------------------------------------- scene format
def test_scene_format(tmp_path):
    from pyopencl_rt import load_scene
    from pyopencl_rt.imageio import write_exr
    from pyopencl_rt.scene.loaders import SceneError

    write_exr(tmp_path / "sky.exr", env_map_image())
    base = '[[shape]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1\n'
    (tmp_path / "a.toml").write_text(base + """
[camera]
eye = [0, 0, 5]
look_at = [0, 0, 0]
aperture_radius = 0.1
focus_distance = 4

[[light]]
type = "point"
position = [0, 3, 0]
intensity = [1, 2, 3]

[[light]]
type = "directional"
direction = [0, -2, 0]
irradiance = 2

[[light]]
type = "spot"
position = [1, 2, 3]
look_at = [1, 0, 3]
up = [0, 0, -1]
intensity = 4
cutoff_angle = 30
falloff = "smoothstep"

[[light]]
type = "projector"
position = [0, 2, 0]
look_at = [0, 0, 0]
up = [1, 0, 0]
fov = 60
scale = 2

[environment]
file = "sky.exr"
scale = 0.5
""")
    sc = load_scene(tmp_path / "a.toml")
    assert sc.camera.aperture_radius == 0.1 and sc.camera.focus_distance == 4
    assert sc.lights[0].intensity == (1, 2, 3) and sc.lights[1].direction == (0, -1, 0)
    assert sc.environment.image.shape == (8, 16, 3) and sc.environment.radiance == (0.5,) * 3
    spot, proj = sc.lights[2:]
    assert spot.beam() == 22.5 and spot.falloff == "smoothstep" and spot.intensity == (4, 4, 4)
    assert np.allclose(spot.frame(), [[-1, 0, 0], [0, 0, -1], [0, -1, 0]])  # x = y cross z, z down, y toward up
    assert proj.fov == 60 and proj.scale == 2 and proj.texture is None and np.allclose(proj.frame()[:, 2], (0, -1, 0))
    rec = sc.camera.record(8, 8)
    assert rec["lens_radius"] == np.float32(0.1) and rec["focus_distance"] == 4
    (tmp_path / "b.toml").write_text(base + "[environment]\nradiance = [0.2, 0.3, 0.4]\n")
    assert load_scene(tmp_path / "b.toml").environment.radiance == (0.2, 0.3, 0.4)
    spot = '[[light]]\ntype = "spot"\nposition = [0, 2, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, 1]\n'
    for bad, msg in (('[[light]]\ntype = "laser"\n', "unknown type"),
                     ('[[light]]\ntype = "spot"\nposition = [0, 2, 0]\n', "missing 'look_at'"),
                     (spot.replace("[0, 0, 1]", "[0, 1, 0]"), "parallel"),
                     (spot + "cutoff_angle = 20\nbeam_width = 25\n", "beam_width"),
                     (spot + 'falloff = "linear"\n', "falloff"),
                     (spot.replace('"spot"', '"projector"') + "fov = 180\n", "fov"),
                     ('[[light]]\ntype = "point"\n', "missing 'position'"),
                     ('[[light]]\ntype = "directional"\ndirection = [0, 0, 0]\n', "must not be zero"),
                     ('[environment]\nfile = "nope.exr"\n', "not found"),
                     ('[environment]\nradiance = -1\n', ">= 0"),
                     ('[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\naperture_radius = -1\n', "aperture_radius")):
        (tmp_path / "c.toml").write_text(base + bad)
        with pytest.raises(SceneError, match=msg):
            load_scene(tmp_path / "c.toml")


# ------------------------------------------------------------------------- against Mitsuba 3
def _spot_xml(tmp_path, flip=False) -> str:
    """A diffuse plane under a textured spot (cutoff 35, beam 20, a non-uniform to_world scale),
    an untextured spot with Mitsuba's defaults (cutoff 20, beam 3/4 of it), a textured projector
    (fov along y, an image 8 x 5) and a projector with Mitsuba's default focal length and a
    constant irradiance; ``flip``: the textures mirrored left to right."""
    from PIL import Image

    r = np.random.default_rng(11)
    for name, shape in (("spot.png", (6, 8, 3)), ("proj.png", (5, 8, 3))):
        texels = r.integers(20, 256, shape).astype(np.uint8)
        Image.fromarray(texels[:, ::-1] if flip else texels, "RGB").save(tmp_path / name)

    def bitmap(role, fname):
        return f'<texture name="{role}" type="bitmap"><string name="filename" value="{fname}"/></texture>'

    body = f"""
<integrator type="direct"/>
<sensor type="perspective"><float name="fov" value="70"/>
  <transform name="to_world"><lookat origin="0, -0.5, 6" target="0, 0, 0" up="0, 1, 0"/></transform>
  <sampler type="independent"><integer name="sample_count" value="64"/></sampler>
  <film type="hdrfilm"><integer name="width" value="48"/><integer name="height" value="32"/><rfilter type="box"/></film>
</sensor>
<shape type="rectangle"><transform name="to_world"><scale x="6" y="4"/></transform>
  <bsdf type="diffuse"><rgb name="reflectance" value="0.6"/></bsdf></shape>
<emitter type="spot"><rgb name="intensity" value="6, 5, 4"/>{bitmap("texture", "spot.png")}
  <float name="cutoff_angle" value="35"/><float name="beam_width" value="20"/>
  <transform name="to_world"><scale x="1.3" y="0.8"/><lookat origin="-3, 0.5, 2" target="-2.6, 0.2, 0" up="0, 1, 0"/></transform>
</emitter>
<emitter type="spot"><rgb name="intensity" value="2, 3, 4"/>
  <transform name="to_world"><lookat origin="-0.5, -1, 2.5" target="-0.3, -1.2, 0" up="1, 0, 0"/></transform>
</emitter>
<emitter type="projector">{bitmap("irradiance", "proj.png")}<float name="fov" value="50"/>
  <string name="fov_axis" value="y"/><float name="scale" value="0.8"/>
  <transform name="to_world"><lookat origin="2.6, 1.2, 2" target="2.4, 1.5, 0" up="0, 1, 0.3"/></transform>
</emitter>
<emitter type="projector"><rgb name="irradiance" value="0.3, 0.2, 0.1"/>
  <transform name="to_world"><lookat origin="1.5, -1.8, 3" target="1.5, -1.8, 0" up="0, 1, 0"/></transform>
</emitter>
"""
    return harness.write_mitsuba_scene(tmp_path / ("flipped.xml" if flip else "lights.xml"), body)


def test_spot_and_projector_match_mitsuba(tmp_path):
    """The XML scene above rendered by Mitsuba 3 (scalar_rgb, 8 batches of 64 spp: their spread is
    its variance) and by us (512 spp): every 8 x 8 tile within 4.5 sigma and the image mean within
    4 (measured: 1.1 and 0.7), so falloff, texture orientation, to_world and the projector's
    normalisation and fov are Mitsuba's.  With the textures mirrored, Mitsuba's image is many
    sigma from ours (measured: 34): the comparison sees the textures' orientation."""
    mi = harness.mitsuba()
    from pyopencl_rt.scene.loaders import load_scene

    theirs, their_var = harness.mitsuba_batches(mi, _spot_xml(tmp_path))
    flipped, flipped_var = harness.mitsuba_batches(mi, _spot_xml(tmp_path, flip=True))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # every element is read without a word
        scene = load_scene(_spot_xml(tmp_path))
    kinds = {type(lt).__name__ for lt in scene.lights}
    assert kinds == {"SpotLight", "ProjectorLight"} and scene.has_textures()
    r = render_full(scene, spp=512, device="cpu", seed=5)
    ours, var = r.image.astype(np.float64), r.film.variance_of_mean()
    z = harness.tile_z(ours, var, theirs, their_var)
    mean_z = (ours.mean((0, 1)) - theirs.mean((0, 1))) / np.sqrt((var + their_var).sum((0, 1))) * ours[..., 0].size
    assert (harness.tiles(theirs).max(-1) > 1e-3).mean() > 0.4 and z.max() < 4.5, np.round(z, 1)
    assert np.abs(mean_z).max() < 4.0, mean_z
    z_flip = harness.tile_z(ours, var, flipped, flipped_var)
    assert z_flip.max() > 8, np.round(z_flip, 1)


def test_pbrt_spot_and_projection(tmp_path):
    """pbrt-v4's spot (smoothstep falloff) and projection light, placed in the camera's frame
    (CoordSysTransform "camera") over a diffuse plane facing it: the spot's centre has rho / pi * I
    / d^2 and nothing lies beyond its cone; the projection light shows its 2 x 2 image (red, green
    over blue, white) upright and unmirrored, as pbrt-v4 projects it (its y flip: image rows from
    the top), each texel's colour at its centre, I = scale x texel there."""
    from PIL import Image

    from pyopencl_rt.scene.loaders import load_scene

    Image.fromarray(np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)).save(
        tmp_path / "quad.png")
    head = ('LookAt 0 0 5  0 0 0  0 1 0\nCamera "perspective" "float fov" 40\nPixelFilter "box"\n'
            'Film "rgb" "integer xresolution" 16 "integer yresolution" 16 "string filename" "x.exr"\n'
            'WorldBegin\nAttributeBegin\nCoordSysTransform "camera"\n')
    tail = ('AttributeEnd\nMaterial "diffuse" "rgb reflectance" [0.5 0.5 0.5]\n'
            'Shape "bilinearmesh" "point3 P" [-5 -5 0  5 -5 0  -5 5 0  5 5 0]\n')
    lights = {"spot": 'LightSource "spot" "rgb I" [2 2 2] "float coneangle" 10 "float conedeltaangle" 5\n',
              "projection": 'LightSource "projection" "string filename" "quad.png" "float fov" 30 '
                            '"float scale" 3\n'}
    images = {}
    for name, light in lights.items():
        (tmp_path / f"{name}.pbrt").write_text(head + light + tail)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = load_scene(tmp_path / f"{name}.pbrt")
        images[name] = render_full(scene, spp=4, device="cpu", seed=1, integrator="nee").image.astype(np.float64)
    spot = images["spot"][..., 0]
    centre = 0.5 / np.pi * 2 / 25  # on the axis, d = 5
    assert np.allclose(spot[7:9, 7:9], centre, rtol=5e-3)  # cos^3 over the pixels: 0.3%
    yy, xx = np.mgrid[0:16, 0:16] + 0.5 - 8
    angle = np.degrees(np.arctan(np.hypot(xx, yy) / 8 * np.tan(np.radians(20))))
    assert np.all(spot[angle > 11.5] == 0) and np.all(spot[angle < 8.5] > 0)  # pixels span 2.5 degrees
    proj = images["projection"]
    # texel centres at a quarter of the projected square (half width 8 tan 15 / tan 20 pixels)
    q = 8 * np.tan(np.radians(15)) / np.tan(np.radians(20)) / 2
    for (dy, dx), rgb in {(-q, -q): (1, 0, 0), (-q, q): (0, 1, 0), (q, -q): (0, 0, 1), (q, q): (1, 1, 1)}.items():
        y, x = int(8 + dy), int(8 + dx)
        got = proj[y, x] / (0.5 / np.pi * 3 / 25)
        assert np.allclose(got / got.max(), rgb, atol=0.25), (y, x, got)
    assert 0.85 < got.max() < 1.02, got  # white: scale x texel x cos^3 (0.97), blended a little (0.89)
    assert np.all(proj[0] == 0) and np.all(proj[:, 0] == 0)


def test_infinite_lights_take_pbrts_share_of_the_picks():
    """n infinitely distant lights with radiance: 1 / (n + 1) of the picks each, the others
    1 / (n + 1) together by power; without either kind, power alone; black lights never."""
    from pyopencl_rt.render.lights import selection_weights

    kinds = np.array([abi.LIGHT_TRIANGLE, abi.LIGHT_SPOT, abi.LIGHT_ENVIRONMENT, abi.LIGHT_DIRECTIONAL,
                      abi.LIGHT_POINT])
    w = selection_weights(kinds, [3.0, 1.0, 1e9, 5.0, 0.0])
    assert np.allclose(w / w.sum(), [0.25, 1 / 12, 1 / 3, 1 / 3, 0.0], rtol=1e-12)
    assert np.array_equal(selection_weights(kinds[:2], [3.0, 1.0]), [3.0, 1.0])
    assert np.array_equal(selection_weights(kinds[2:4], [1e9, 5.0]), [1e9, 5.0])
    w = selection_weights(kinds[:3], [3.0, 1.0, 0.0])  # an environment of zeros: never picked
    assert np.array_equal(w, [3.0, 1.0, 0.0])
