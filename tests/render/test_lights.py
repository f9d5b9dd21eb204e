"""Point, directional and environment lights, and the thin-lens camera, on every available device.

Closed forms where they exist (a point or directional light over a diffuse plane, a white
furnace under a constant environment, the blur of an edge seen through a thin lens), the
environment map's importance sampling against the luminance distribution (chi-square, as in
tests/render/test_sampling.py: tests/harness.py's chi2_test), and light sampling against BSDF sampling under an environment map
(tile-wise z-tests).  Robustness: no NaN or Inf for extreme parameters."""
import warnings

import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.render.lights import LUMINANCE, environment_tables, other_lights
from pyopencl_rt.render.api import render_full
from pyopencl_rt.scene.model import Camera, DirectionalLight, Environment, Material, PointLight, RenderSettings, Scene

import harness

ALPHA = 1e-4

HARNESS = harness.Kernels(r"""
#include "render/lights.h"

/* out per item: wi (3), pdf of the sample, env_pdf(wi), Le.x, Le.y, Le.z */
__kernel void h_env_sample(__global const Light *lt, __global const float *env_map, __global const float *env_cdf,
                           __global const float *u, __global float *out)
{
    const int i = get_global_id(0);
    float3 wi;
    float pdf;
    const float3 Le = env_sample(lt, env_map, env_cdf, vload2(i, u), &wi, &pdf);
    __global float *o = out + 8 * i;
    o[0] = wi.x; o[1] = wi.y; o[2] = wi.z; o[3] = pdf;
    o[4] = env_pdf(lt, env_cdf, wi);
    o[5] = Le.x; o[6] = Le.y; o[7] = Le.z;
}

/* out per direction: env_pdf, radiance.x */
__kernel void h_env_eval(__global const Light *lt, __global const float *env_map, __global const float *env_cdf,
                         __global const float *w, __global float *out)
{
    const int i = get_global_id(0);
    const float3 d = load3(w, i);
    out[2 * i] = env_pdf(lt, env_cdf, d);
    out[2 * i + 1] = env_radiance(lt, env_map, d).x;
}
""", defines={"HAS_ENVIRONMENT": True})


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
    sc = Scene(**empty_mesh(), materials=[Material()], spheres=np.array([[0, 0, 0, 1]], np.float32),
               sphere_materials=np.array([0], np.int32), environment=Environment(radiance=scale, image=img))
    recs, _ = other_lights(sc)
    return sc, recs


def uv_of(w):
    u = np.mod(np.arctan2(-w[:, 0], w[:, 2]) / (2 * np.pi), 1.0)
    v = np.arccos(np.clip(w[:, 1], -1, 1)) / np.pi
    return u, v


def test_env_map_sampling_chi2(runtime):
    """1M samples of the environment map on the device: their texels (each split 2 x 2, to see
    uniformity inside texels too) follow luminance x solid angle (chi-square, p > 1e-4); the
    sample's pdf equals env_pdf() of its direction and p(u, v) / (2 pi^2 sin theta); Le is the
    texel's radiance; zero texels are never drawn; env_pdf integrates to 1 over the sphere."""
    img = env_map_image()
    tm, cdf, _ = environment_tables(img)
    _, light = _env_light(img)
    h, w = img.shape[:2]
    n = 1_000_000
    rng = np.random.default_rng(3)
    u = rng.random((n, 2), dtype=np.float32)
    u = np.minimum(u, np.float32(1 - 2**-24))
    out = HARNESS(runtime, "h_env_sample", n, light, tm.reshape(-1), cdf, u, (n, 8))
    wi, pdf, pdf_eval, le = out[:, :3], out[:, 3].astype(np.float64), out[:, 4].astype(np.float64), out[:, 5:]
    assert np.all(np.isfinite(out))
    ok = pdf > 0
    assert ok.mean() > 0.9999
    wi, pdf, pdf_eval, le = wi[ok], pdf[ok], pdf_eval[ok], le[ok]
    assert np.allclose(np.linalg.norm(wi, axis=1), 1, atol=1e-5)
    uu, vv = uv_of(wi.astype(np.float64))
    col = np.minimum((uu * w).astype(int), w - 1)
    row = np.minimum((vv * h).astype(int), h - 1)
    # away from texel borders (float rounding may land a sample in the neighbour), pdfs agree
    inner = (np.abs(uu * w - np.round(uu * w)) > 1e-3) & (np.abs(vv * h - np.round(vv * h)) > 1e-3)
    assert np.allclose(pdf[inner], pdf_eval[inner], rtol=2e-3)
    assert np.allclose(le[inner], img[row[inner], col[inner]], rtol=1e-6)
    assert not np.any((img[row[inner], col[inner]] == 0).all(axis=1)), "a black texel was sampled"
    # the density the pdf claims: luminance x sin(theta_centre) per texel, normalised in (u, v)
    lum = img.astype(np.float64) @ LUMINANCE
    f = lum * np.sin(np.pi * (np.arange(h) + 0.5) / h)[:, None]
    sin_t = np.sqrt(np.maximum(0.0, 1 - wi[:, 1].astype(np.float64) ** 2))
    claimed = pdf * 2 * np.pi**2 * sin_t / (h * w)
    assert np.allclose(claimed[inner], (f / f.sum())[row[inner], col[inner]], rtol=2e-3)
    # chi-square on 2 x 2 sub-texels; expected: luminance x the texel's exact solid angle (the
    # sin(theta_centre) weight is exactly proportional to it), spread evenly over (u, v) within
    sub_c = np.minimum((uu * 2 * w).astype(int), 2 * w - 1)
    sub_r = np.minimum((vv * 2 * h).astype(int), 2 * h - 1)
    observed = np.bincount(sub_r * 2 * w + sub_c, minlength=4 * h * w)
    th = np.pi * np.arange(h + 1) / h
    omega = (np.cos(th[:-1]) - np.cos(th[1:]))[:, None] * np.full(w, 2 * np.pi / w)
    weight = np.repeat(np.repeat(lum * omega, 2, 0), 2, 1)
    expected = weight.reshape(-1) / weight.sum() * ok.sum()
    assert observed[expected == 0].sum() <= 1e-5 * n  # only by float rounding at texel borders
    nz = expected > 0
    harness.assert_chi2(observed[nz], expected[nz], ALPHA, "environment map")
    # normalisation: E[pdf(w) 4 pi] over uniform directions = 1
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ev = HARNESS(runtime, "h_env_eval", n, light, tm.reshape(-1), cdf, d.astype(np.float32), (n, 2))
    vals = ev[:, 0].astype(np.float64) * 4 * np.pi
    assert abs(vals.mean() - 1) < 5 * vals.std() / np.sqrt(n) + 1e-4


def test_env_map_of_zeros_and_constant(runtime):
    """A map of zeros samples uniformly in (u, v) with finite pdfs and zero radiance; a constant
    environment (no map) samples the sphere uniformly, pdf 1 / (4 pi)."""
    img = np.zeros((4, 8, 3), np.float32)
    tm, cdf, mean = environment_tables(img)
    assert mean == 0 and np.all(np.isfinite(cdf))
    _, light = _env_light(img)
    u = np.random.default_rng(1).random((4096, 2), dtype=np.float32)
    out = HARNESS(runtime, "h_env_sample", 4096, light, tm.reshape(-1), cdf, u, (4096, 8))
    assert np.all(np.isfinite(out)) and np.all(out[:, 5:] == 0)
    const = light.copy()
    const["prim"] = 0
    const["material"] = 0
    out = HARNESS(runtime, "h_env_sample", 4096, const, tm.reshape(-1), cdf, u, (4096, 8))
    assert np.allclose(out[:, 3], 1 / (4 * np.pi)) and np.allclose(out[:, 4], 1 / (4 * np.pi))


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


def test_directional_light_over_plane(device):
    """Radiance rho / pi * E cos(theta), the same at every pixel (no noise)."""
    dirn, irr, rho = np.array([0.3, -1.0, 0.2]), 2.0, 0.6
    sc = plane_scene([DirectionalLight(direction=tuple(dirn), irradiance=(irr,) * 3)], rho, size=16)
    cos = 1 / np.linalg.norm(dirn)
    r = render_full(sc, spp=4, device=device, seed=2, integrator="path")
    assert np.allclose(r.image, rho / np.pi * irr * cos, rtol=1e-4)


def sphere_under(env, integrator, albedo=1.0, size=16, max_depth=4):
    return Scene(**empty_mesh(), materials=[Material("ball", albedo=(albedo,) * 3)],
                 camera=Camera(eye=(0, 0, 5), look_at=(0, 0, 0), fov=30),
                 spheres=np.array([[0, 0, 0, 1]], np.float32), sphere_materials=np.array([0], np.int32),
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


def test_environment_map_light_vs_bsdf_sampling(device):
    """A diffuse sphere under an environment map: MIS, BSDF sampling alone and light sampling
    alone agree (4 x 4-pixel tiles, 3 channels, 3 pairs: |z| < 4.5); light sampling has less
    variance than BSDF sampling."""
    env = Environment(radiance=(1.0, 1.0, 1.0), image=env_map_image())
    res = {}
    for i, integ in enumerate(("path", "bsdf", "nee")):
        r = render_full(sphere_under(env, integ, albedo=0.8, max_depth=3), spp=64, device=device, seed=30 + i)
        assert r.info["nonfinite_samples"] == 0
        var = r.film.variance_of_mean()
        k = 4
        m = r.image.astype(np.float64).reshape(4, k, 4, k, 3).mean(axis=(1, 3))
        v = var.reshape(4, k, 4, k, 3).sum(axis=(1, 3)) / (k * k) ** 2
        res[integ] = (m, v, var.mean())
    for a, b in (("path", "bsdf"), ("path", "nee"), ("bsdf", "nee")):
        z = (res[a][0] - res[b][0]) / np.sqrt(res[a][1] + res[b][1] + 1e-30)
        assert np.abs(z).max() < 4.5, f"{a} vs {b}: max |z| = {np.abs(z).max():.2f}"
    assert res["nee"][2] < res["bsdf"][2]


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
    """Huge intensities, delta lights on glossy, mirror and glass surfaces, an environment map of
    zeros, a huge aperture with a tiny focus distance: no NaN or Inf anywhere."""
    v = np.array([[-10, 0, -10], [-10, 0, 10], [10, 0, 10], [10, 0, -10]], np.float32)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    mats = [Material("plane", albedo=(0.5,) * 3), Material("glossy", type="conductor", alpha=1e-3),
            Material("mirror", type="conductor", alpha=0.0), Material("glass", type="dielectric", ior=1.5),
            Material("plastic", type="gltf", metallic=0.0, alpha=0.01)]
    sc = Scene(vertices=v, faces=f, face_materials=np.zeros(2, np.int32), materials=mats,
               spheres=np.array([[-2, 1, 0, 1], [0, 1, 0, 0.8], [2, 1, 0, 1], [0, 1, 2.5, 0.7]], np.float32),
               sphere_materials=np.array([1, 2, 3, 4], np.int32),
               camera=Camera(eye=(0, 3, 8), look_at=(0, 1, 0), fov=50, aperture_radius=100.0, focus_distance=1e-4),
               settings=RenderSettings(width=16, height=16, max_depth=6),
               lights=[PointLight(position=(0, 3, 1), intensity=(1e20,) * 3),
                       PointLight(position=(-2, 1, 0), intensity=(1.0,) * 3),  # inside a sphere
                       DirectionalLight(direction=(0, -1, 0), irradiance=(1e20, 0, 1e-30))],
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
    sc = sphere_under(None, "path", size=4)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        render_full(sc, spp=1, device=device, seed=1)
    assert any("no lights" in str(w.message) for w in caught)


def test_light_records():
    sc, rec = _env_light(env_map_image())
    assert rec["kind"][0] == abi.LIGHT_ENVIRONMENT and rec["prim"][0] == 16 and rec["material"][0] == 8
    assert np.isclose(rec["radius"][0], np.sqrt(3))
    assert abi.LIGHT.itemsize % 16 == 0 and abi.CAMERA.itemsize == 64


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

[environment]
file = "sky.exr"
scale = 0.5
""")
    sc = load_scene(tmp_path / "a.toml")
    assert sc.camera.aperture_radius == 0.1 and sc.camera.focus_distance == 4
    assert sc.lights[0].intensity == (1, 2, 3) and sc.lights[1].direction == (0, -1, 0)
    assert sc.environment.image.shape == (8, 16, 3) and sc.environment.radiance == (0.5,) * 3
    rec = sc.camera.record(8, 8)
    assert rec["lens_radius"] == np.float32(0.1) and rec["focus_distance"] == 4
    (tmp_path / "b.toml").write_text(base + "[environment]\nradiance = [0.2, 0.3, 0.4]\n")
    assert load_scene(tmp_path / "b.toml").environment.radiance == (0.2, 0.3, 0.4)
    for bad, msg in (('[[light]]\ntype = "spot"\n', "unknown type"),
                     ('[[light]]\ntype = "point"\n', "missing 'position'"),
                     ('[[light]]\ntype = "directional"\ndirection = [0, 0, 0]\n', "must not be zero"),
                     ('[environment]\nfile = "nope.exr"\n', "not found"),
                     ('[environment]\nradiance = -1\n', ">= 0"),
                     ('[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\naperture_radius = -1\n', "aperture_radius")):
        (tmp_path / "c.toml").write_text(base + bad)
        with pytest.raises(SceneError, match=msg):
            load_scene(tmp_path / "c.toml")
