"""The orthographic camera and the pixel reconstruction filters (issue 24; cl/render/filter.h,
pyopencl_rt/render/filters.py), against closed forms and against Mitsuba 3.

* the pixel offsets each filter draws, against the filter itself (its definition in Mitsuba 3 and
  pbrt-v4, written out again below in float64), by a chi-square test over 2-D bins; each
  sample's sign and weight;
* a scene of constant radiance renders as exactly that constant for every filter without
  negative lobes, and as +-(the constant times the weight) sample by sample for the others;
* a sharp edge against its analytic convolution with the filter (float64 quadrature);
* the orthographic projection of a point (a small sphere's centroid) in closed form;
* the same image bit for bit at 1, 8 and 16 lanes, in the megakernel and the wavefront, with and
  without AOVs;
* XML scenes rendered by us and by Mitsuba 3 (scalar_rgb) at test time: a gaussian filter, a
  Mitchell filter and the orthographic sensor agree in mean and per pixel within a coarse
  tolerance.
Statistical tests use a significance level of ALPHA = 1e-4 with fixed seeds."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.device import abi
from pyopencl_rt.render import filters, megakernel
from pyopencl_rt.render.settings import ImageSettings
from pyopencl_rt.scene.pixel_filter import PixelFilter

import harness
from harness import lane_renders as renders, mitsuba

ALPHA = 1e-4
SCENES = Path(__file__).resolve().parents[2] / "scenes"

# the filters as Mitsuba 3 and pbrt-v4 define them (their defaults, and some other parameters)
FILTERS = {
    "box": PixelFilter("box"),
    "box-wide": PixelFilter("box", (1.0, 0.75)),
    "tent-mitsuba": PixelFilter("tent", (1.0, 1.0)),
    "tent-pbrt": PixelFilter("tent", (2.0, 1.5)),
    "gaussian-mitsuba": PixelFilter("gaussian", (2.0, 2.0), sigma=0.5),
    "gaussian-pbrt": PixelFilter("gaussian", (1.5, 1.5), sigma=0.5),
    "gaussian-narrow": PixelFilter("gaussian", (1.0, 0.6), sigma=0.25),
    "mitchell": PixelFilter("mitchell", (2.0, 2.0)),
    "catmull-rom": PixelFilter("mitchell", (2.0, 1.5), b=0.0, c=0.5),
    "lanczos-mitsuba": PixelFilter("lanczos", (3.0, 3.0), tau=3.0),
    "lanczos-pbrt": PixelFilter("lanczos", (4.0, 4.0), tau=3.0),
}


def reference(flt: PixelFilter, x, axis: int) -> np.ndarray:
    """The filter along ``axis`` in float64, from Mitsuba 3's src/rfilters/*.cpp and pbrt-v4's
    filters.h (written apart from pyopencl_rt/render/filters.py on purpose)."""
    x = np.asarray(x, np.float64)
    r = flt.radius[axis]
    if flt.type == "box":
        v = np.ones_like(x)
    elif flt.type == "tent":
        v = 1.0 - np.abs(x) / r
    elif flt.type == "gaussian":
        v = np.exp(-x * x / (2 * flt.sigma ** 2)) - math.exp(-r * r / (2 * flt.sigma ** 2))
    elif flt.type == "mitchell":
        t, b, c = np.abs(2 * x / r), flt.b, flt.c
        v = np.where(t < 1, (12 - 9 * b - 6 * c) * t ** 3 + (-18 + 12 * b + 6 * c) * t ** 2 + (6 - 2 * b),
                     (-b - 6 * c) * t ** 3 + (6 * b + 30 * c) * t ** 2 + (-12 * b - 48 * c) * t + (8 * b + 24 * c)) / 6
    else:
        px = np.pi * x
        with np.errstate(invalid="ignore", divide="ignore"):
            v = np.where(x == 0, 1.0, np.sin(px) / px * np.sin(px / flt.tau) / (px / flt.tau))
    return np.where(np.abs(x) <= r, v, 0.0)


def integrate(flt, axis, edges, absolute=True, pieces=64) -> np.ndarray:
    """The integral of |f| (or f) over each interval of ``edges``: Gauss-Legendre of order 8 on
    ``pieces`` sub-intervals of each (|f| has kinks where f changes sign)."""
    t, w = np.polynomial.legendre.leggauss(8)
    sub = np.linspace(edges[:-1], edges[1:], pieces + 1, axis=1)  # (bins, pieces + 1)
    lo, hi = sub[:, :-1, None], sub[:, 1:, None]
    values = reference(flt, (lo + hi) / 2 + (hi - lo) / 2 * t, axis)
    values = np.abs(values) if absolute else values
    return ((values * w).sum(-1) * (hi - lo)[..., 0] / 2).sum(-1)


# ----------------------------------------------------------------------------- the offsets drawn
OFFSETS = harness.Kernels(r"""
#include "render/filter.h"
/* per sample: jitter x, y (pixels from the corner), negative along x, along y, weight */
__kernel void h_filter(__global const Camera *camera, __global const float *table, __global const float *u,
                       __global float *out)
{
    const int i = get_global_id(0);
    const Camera cam = *camera;
    pint nx, ny;
    const pfloat jx = filter_jitter(&cam, table, 0, PFLOAT(u[2 * i]), &nx);
    const pfloat jy = filter_jitter(&cam, table, 1, PFLOAT(u[2 * i + 1]), &ny);
    __global float *o = out + 5 * i;
    o[0] = jx; o[1] = jy; o[2] = nx ? 1.0f : 0.0f; o[3] = ny ? 1.0f : 0.0f; o[4] = filter_weight(&cam, nx, ny);
}
""")


def draw_offsets(runtime, flt, u):
    camera = np.zeros(1, abi.CAMERA)
    table = filters.apply(camera[0], flt)
    out = OFFSETS(runtime, "h_filter", len(u), camera=camera, table=table, u=u, out=(len(u), 5))
    return out, camera[0]


@pytest.mark.parametrize("name", list(FILTERS))
def test_offsets_follow_the_filter(runtime, rng, name):
    """1e6 offsets in 24 x 24 bins over [-rx, rx] x [-ry, ry] against the integrals of
    |f(x) f(y)| (chi-square); each sample negative where f is (but within 1e-4 of a sign change)
    and weighted sign(f) * (int |f| / int f) per axis, the integrals by quadrature."""
    flt = FILTERS[name]
    n = 1_000_000
    out, camera = draw_offsets(runtime, flt, harness.uniforms(rng, (n, 2)))
    rx, ry = flt.radius
    x, y = out[:, 0].astype(np.float64) - 0.5, out[:, 1].astype(np.float64) - 0.5
    assert np.all(np.abs(x) <= rx * (1 + 1e-6)) and np.all(np.abs(y) <= ry * (1 + 1e-6))
    ex, ey = np.linspace(-rx, rx, 25), np.linspace(-ry, ry, 25)
    observed = np.histogram2d(np.clip(x, -rx, rx), np.clip(y, -ry, ry), bins=(ex, ey))[0]
    mx, my = integrate(flt, 0, ex), integrate(flt, 1, ey)
    harness.assert_chi2(observed, n * np.outer(mx / mx.sum(), my / my.sum()), ALPHA, name)
    for axis, offsets in ((0, x), (1, y)):
        f = reference(flt, offsets, axis)
        clear = np.abs(f) > 1e-4
        assert np.array_equal(out[clear, 2 + axis] == 1, f[clear] < 0), (name, axis)
    norms = [integrate(flt, a, np.array([-r, r]), pieces=8192)[0] /
             integrate(flt, a, np.array([-r, r]), False, pieces=8192)[0] for a, r in enumerate(flt.radius)]
    weight = np.prod(norms)
    assert camera["filter_weight"] == pytest.approx(weight, rel=1e-6)
    sign = np.where((out[:, 2] == 1) != (out[:, 3] == 1), -1.0, 1.0)
    assert np.array_equal(out[:, 4], (sign * np.float32(weight)).astype(np.float32))
    if flt.type in ("box", "tent", "gaussian"):
        assert camera["filter_weight"] == 1.0 and np.all(out[:, 4] == 1.0)


@pytest.mark.parametrize("name", [n for n, f in FILTERS.items() if f.type not in ("box", "tent")])
def test_tables_step_response(name):
    """The density a tabulated filter draws (each cell its segment's equal share of the mass, |f|
    linear across it) times sign f times int |f|, integrated from -r: the filter's step response
    (float64 quadrature) within 1e-4 of int f (measured 2e-6 to 9e-5)."""
    flt = FILTERS[name]
    for axis in (0, 1):
        segments, knots = filters.axis_table(flt, axis)
        x, f = knots[:, 0], np.abs(knots[:, 1])
        mass = np.empty(len(x) - 1)
        ends = np.append(segments[1:, 0], 1.0)
        for (start, _, first, last, _), end in zip(segments, ends):
            mass[int(first):int(last) + 1] = (end - start) / (last - first + 1)
        t = np.linspace(0.0, 1.0, 65)
        xs = x[:-1, None] + t * np.diff(x)[:, None]  # 64 pieces per cell
        line = f[:-1, None] + t * np.diff(f)[:, None]
        density = line * (mass / ((f[:-1] + f[1:]) / 2 * np.diff(x)))[:, None]
        mid = (xs[:, 1:] + xs[:, :-1]) / 2
        pieces = (density[:, 1:] + density[:, :-1]) / 2 * np.diff(xs, axis=1) * np.sign(reference(flt, mid, axis))
        r = flt.radius[axis]
        total, absolute = (integrate(flt, axis, np.array([-r, r]), a, pieces=8192)[0] for a in (False, True))
        edges = np.append(xs[:, :-1].ravel(), r)
        drawn = np.cumsum(pieces.ravel() * absolute)
        exact = np.cumsum(integrate(flt, axis, edges, absolute=False, pieces=2))
        assert np.abs(drawn - exact).max() < 1e-4 * total, (name, axis, np.abs(drawn - exact).max() / total)


def test_box_jitter_is_the_sample():
    """The box of radius 0.5 (the default) jitters by the sample itself, bit for bit: images
    rendered before the filters existed are unchanged."""
    camera = np.zeros((), abi.CAMERA)
    filters.apply(camera, PixelFilter())
    assert camera["filter"] == abi.FILTER_BOX and camera["filter_radius"].tolist() == [0.5, 0.5]
    assert (np.float32(0.5) - camera["filter_radius"][0]) == 0 and 2 * camera["filter_radius"][0] == 1


def test_filter_settings_round_trip_and_checks(tmp_path):
    """A filter travels through ImageSettings' dict (checkpoints, Dask, the sidecar), a bad one is
    one clear error, and a checkpoint made with another filter is refused."""
    from pyopencl_rt.errors import UsageError
    from pyopencl_rt.render import checkpoint
    from pyopencl_rt.render.film import Film

    scene = rt.load_scene(SCENES / "cornell-box.toml")
    scene.settings.filter = FILTERS["lanczos-pbrt"]
    settings = ImageSettings.resolve(scene, width=8, height=8)
    assert settings.filter == FILTERS["lanczos-pbrt"]
    assert ImageSettings.from_dict(settings.as_dict()) == settings
    assert settings.as_dict()["filter"]["radius"] == [4.0, 4.0]
    for bad, message in ((PixelFilter("cubic"), "unknown pixel filter 'cubic'"),
                         (PixelFilter("box", (0.0, 1.0)), "radius x must be in"),
                         ({"type": "gaussian", "sigma": -1}, "sigma and tau must be > 0"),
                         ({"type": "box", "radius": [1]}, "radius must be two numbers"),
                         ({"type": "box", "width": 1}, "unknown pixel filter keys")):
        with pytest.raises(UsageError, match=message):
            ImageSettings.resolve(scene, filter=bad)
    path = checkpoint.save(tmp_path / "c.ckpt.npz", Film(8, 8), scene, settings)
    other = ImageSettings.resolve(scene, width=8, height=8, filter=PixelFilter())
    with pytest.raises(checkpoint.CheckpointError, match="filter"):
        checkpoint.load(path, scene, other)
    assert checkpoint.load(path, scene, settings)[0].passes == 0


# ----------------------------------------------------------------------------- scenes
def toml_scene(tmp_path, text, name="s.toml"):
    (tmp_path / name).write_text(text)
    return rt.load_scene(tmp_path / name)


CONSTANT = """
[camera]
eye = [0, 0, 0]
look_at = [0, 0, -1]
fov = 60
[film]
width = 12
height = 8
[render]
max_depth = 1
[environment]
radiance = 0.7
[[shape]]
type = "sphere"
center = [0, 0, 50]
radius = 0.01
"""


@pytest.mark.parametrize("name", ["box-wide", "tent-pbrt", "gaussian-mitsuba", "gaussian-pbrt", "mitchell",
                                  "lanczos-mitsuba"])
def test_constant_radiance(device, tmp_path, name):
    """Every ray sees 0.7: a filter without negative lobes gives every pixel exactly 0.7 (each
    sample's weight is 1); one with negative lobes gives each sample +-0.7 * filter_weight, negative
    as often as the filter's negative mass says (binomial test), and the image 0.7 on average."""
    flt = FILTERS[name]
    scene = toml_scene(tmp_path, CONSTANT)
    scene.settings.filter = flt
    if flt.type in ("box", "tent", "gaussian"):
        r = rt.render_full(scene, device=device, spp=16, seed=1)
        assert np.all(r.image == np.float32(0.7)), name
        return
    w = filters.weight(flt)
    r = rt.render_full(scene, device=device, spp=1, seed=1, width=64, height=64)
    values = r.film.sum[:, 0]
    magnitude = np.float32(np.float32(0.7) * np.float32(w))
    assert np.all(np.isin(values.astype(np.float32), [magnitude, -magnitude])), name
    neg = [float(integrate(flt, a, np.array([-rr, rr]), True)[0] - integrate(flt, a, np.array([-rr, rr]), False)[0])
           / 2 / integrate(flt, a, np.array([-rr, rr]), True)[0] for a, rr in enumerate(flt.radius)]
    p = neg[0] * (1 - neg[1]) + neg[1] * (1 - neg[0])  # one axis negative, not both
    from scipy import stats

    k = int(np.count_nonzero(values < 0))
    assert stats.binomtest(k, len(values), p).pvalue > ALPHA, (k, len(values), p)
    r = rt.render_full(scene, device=device, spp=256, seed=2, width=16, height=16)
    mean, err = r.image[..., 0].mean(), np.sqrt(r.film.variance_of_mean()[..., 0].sum()) / r.image[..., 0].size
    assert abs(mean - 0.7) < 4.5 * err + 1e-6, (mean, err)


EDGE = """
[camera]
type = "orthographic"
eye = [0, 0, 5]
look_at = [0, 0, 0]
extent = 8        # 8 pixels high: a pixel is one unit
[film]
width = 24
height = 8
[render]
max_depth = 1
[materials.lamp]
albedo = 0
emission = 1
[[shape]]             # the half plane x > EDGE_X, facing the camera
type = "quad"
material = "lamp"
points = [[EDGE_X, -60, 0], [60, -60, 0], [60, 60, 0], [EDGE_X, 60, 0]]
"""
EDGE_X = 0.05  # near a pixel's border, where the box and the other filters differ most
# measured (seed 3, PoCL CPU): box, tent, gaussian 1.5e-4 at most; mitchell 6e-4, catmull-rom 1.6e-3;
# lanczos 6e-3 (its weights are +-1.85); all noise, shrinking with the samples
EDGE_TOLERANCE = {"box": 1e-3, "tent": 1e-3, "gaussian": 1e-3, "mitchell": 4e-3, "lanczos": 0.015}


@pytest.mark.parametrize("name", ["box-wide", "tent-mitsuba", "tent-pbrt", "gaussian-mitsuba", "gaussian-pbrt",
                                  "gaussian-narrow", "mitchell", "catmull-rom", "lanczos-mitsuba", "lanczos-pbrt"])
def test_edge_is_the_filters_convolution(device, tmp_path, name):
    """An emitter's straight edge at x = 0.05 seen by an orthographic camera of one unit per pixel:
    each column's mean (over its 8 rows, 2048 samples a pixel) is the filter's convolution with
    the step, int_{0.05 - x_c}^{r} f / int f (float64 quadrature, x_c the column's centre), within
    EDGE_TOLERANCE (absolute, of a step of height 1: the noise of 16384 Sobol samples, larger with
    negative lobes)."""
    flt = FILTERS[name]
    scene = toml_scene(tmp_path, EDGE.replace("EDGE_X", str(EDGE_X)))
    scene.settings.filter = flt
    r = rt.render_full(scene, device=device, spp=2048, seed=3)
    ours = r.image[..., 0].astype(np.float64).mean(axis=0)
    rx = flt.radius[0]
    total = integrate(flt, 0, np.array([-rx, rx]), absolute=False)[0]
    centres = np.arange(24) + 0.5 - 12
    lower = np.clip(EDGE_X - centres, -rx, rx)
    expected = np.array([integrate(flt, 0, np.array([lo, rx]), absolute=False)[0] for lo in lower]) / total
    assert np.abs(ours - expected).max() < EDGE_TOLERANCE[flt.type], (name, np.round(ours - expected, 4))
    if flt.type != "box":  # the box's image is a different one: the test sees the filter
        box = np.clip(centres + 0.5 - EDGE_X, 0, 1)
        assert np.abs(box - expected).max() > 2 * EDGE_TOLERANCE[flt.type]


def test_orthographic_projection_of_a_point(device, tmp_path):
    """A small emissive sphere seen by an orthographic camera looking obliquely, with a tilted up
    and a wide film: the centroid of its disk is the point's projection in closed form,
    ((p - eye) . right / half width + 1) W / 2, (1 - (p - eye) . up / half height) H / 2, and the
    disk's area is pi r^2 in pixels (the film's extent, aspect and square pixels)."""
    eye, target, up = np.array([1.0, 2.0, 6.0]), np.array([0.2, -0.3, 0.0]), np.array([0.3, 1.0, 0.1])
    extent, W, H, radius = 3.0, 48, 32, 0.2
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, fwd)
    p = target + 0.7 * right - 0.4 * true_up + 2.0 * fwd  # off centre, behind the look-at point
    scene = toml_scene(tmp_path, f"""
[camera]
type = "orthographic"
eye = {eye.tolist()}
look_at = {target.tolist()}
up = {up.tolist()}
extent = {extent}
[film]
width = {W}
height = {H}
[render]
max_depth = 1
[materials.lamp]
albedo = 0
emission = 1
[[shape]]
type = "sphere"
material = "lamp"
center = {p.tolist()}
radius = {radius}
""")
    img = rt.render_full(scene, device=device, spp=256, seed=4).image[..., 0].astype(np.float64)
    half_h, half_w = extent / 2, extent / 2 * W / H
    u = (np.dot(p - eye, right) / half_w + 1) * W / 2
    v = (1 - np.dot(p - eye, true_up) / half_h) * H / 2
    ys, xs = np.mgrid[0:H, 0:W] + 0.5
    assert (img * xs).sum() / img.sum() == pytest.approx(u, abs=0.02)
    assert (img * ys).sum() / img.sum() == pytest.approx(v, abs=0.02)
    assert img.sum() == pytest.approx(math.pi * (radius * H / extent) ** 2, rel=0.01)
    # parallel rays: the eye moved back along the view changes nothing (the same hits)
    far = dataclasses.replace(scene.camera, eye=tuple(eye - 40 * fwd), look_at=tuple(target - 40 * fwd))
    scene.camera = far
    img_far = rt.render_full(scene, device=device, spp=256, seed=4).image[..., 0]
    assert np.abs(img_far - img).max() < 1e-6


# ----------------------------------------------------------------------------- lanes and schedules
@pytest.mark.parametrize("width_set", harness.width_sets())
def test_lanes_are_bit_identical(device, monkeypatch, width_set):
    """Every filter, with the orthographic camera and with the thin lens: the film sums at the lane
    widths are the one-path megakernel's bit for bit (the tables are read with gathers, the
    weights multiply each lane's radiance)."""
    widths = harness.widths_of(device, width_set)
    base = rt.load_scene(SCENES / "mitsuba-cbox.toml")
    ortho = dataclasses.replace(base.camera, projection="orthographic", extent=1.7)
    lens = dataclasses.replace(base.camera, aperture_radius=0.05, focus_distance=3.0)
    for name, camera in (("box", ortho), ("tent-pbrt", ortho), ("gaussian-mitsuba", lens), ("mitchell", ortho),
                         ("lanczos-pbrt", lens), ("catmull-rom", ortho)):
        scene = dataclasses.replace(base, camera=camera,
                                    settings=dataclasses.replace(base.settings, filter=FILTERS[name]))
        results = renders(scene, device, monkeypatch, widths=widths, spp=3, seed=7,
                          width=20, height=14)
        for width, r in results.items():
            assert r.info["lanes"] == int(width)
            assert np.array_equal(r.film.sum, results["0"].film.sum), (name, width)
            assert np.array_equal(r.film.sum_sq, results["0"].film.sum_sq), (name, width)


def test_wavefront_megakernel_and_aovs_agree(device, monkeypatch):
    """A filter with negative lobes and the orthographic camera: the wavefront (its weight waits in
    path_weight) renders the megakernel's image bit for bit, and asking for AOVs leaves it so."""
    monkeypatch.setenv(megakernel.LANES_ENV, "0")
    scene = rt.load_scene(SCENES / "cornell-spheres.toml")
    scene.camera = dataclasses.replace(scene.camera, projection="orthographic", extent=600.0)
    scene.settings.filter = FILTERS["mitchell"]
    options = dict(device=device, spp=2, seed=9, width=16, height=12)
    mk = rt.render_full(scene, kernel_mode="megakernel", **options)
    wf = rt.render_full(scene, kernel_mode="wavefront", **options)
    aov = rt.render_full(scene, kernel_mode="wavefront", aovs=("albedo", "normal"), **options)
    assert np.array_equal(mk.film.sum, wf.film.sum) and np.array_equal(wf.film.sum, aov.film.sum)
    assert (mk.film.sum < 0).any()  # a negative lobe's samples reached the film
    assert "albedo" in aov.layers and np.all(aov.layers["albedo"] >= 0)


# ----------------------------------------------------------------------------- against Mitsuba 3
SHAPES = """
    <emitter type="constant"><rgb name="radiance" value="0.2"/></emitter>
    <shape type="rectangle">
        <transform name="to_world"><scale x="0.8" y="0.5"/><rotate z="1" angle="27"/></transform>
        <emitter type="area"><rgb name="radiance" value="1.0, 0.6, 0.2"/></emitter>
    </shape>
    <shape type="sphere"><point name="center" x="0.5" y="0.45" z="0.3"/><float name="radius" value="0.25"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.5, 0.8"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="0.3, 0.9, 0.4"/></emitter>
    </shape>
"""
PERSPECTIVE = """<sensor type="perspective"><float name="fov" value="45"/>
        <transform name="to_world"><lookat origin="0.3, -0.4, 3" target="0.1, 0.1, 0" up="0, 1, 0"/></transform>"""
ORTHOGRAPHIC = """<sensor type="orthographic"><float name="near_clip" value="0.5"/>
        <transform name="to_world"><scale x="1.3" y="1.3"/>
            <lookat origin="-2, -1.5, 2.5" target="0.1, 0.1, 0" up="0, 0, 1"/></transform>"""


@pytest.mark.parametrize("sensor,rfilter", [(PERSPECTIVE, ""), (PERSPECTIVE, '<rfilter type="mitchell"/>'),
                                            (ORTHOGRAPHIC, '<rfilter type="box"/>'),
                                            (ORTHOGRAPHIC, '<rfilter type="tent"/>')],
                         ids=["perspective-gaussian", "perspective-mitchell", "orthographic-box", "orthographic-tent"])
def test_agrees_with_mitsuba(tmp_path, sensor, rfilter):
    """The same XML (emitters with sharp edges over a dim sky, 40 x 24 pixels, max_depth 2) rendered
    by Mitsuba (scalar_rgb, 8 batches of 128 spp; sample_border, so that its edge pixels are
    filtered over the whole footprint as ours are) and by us (1024 spp): the image means within
    4.5 standard errors and 0.2%, and every pixel within 0.03 + 5 standard errors (measured: the
    means within 1.1 standard errors and 0.04%, every pixel within 0.026).  Mitsuba's scalar
    variants evaluate the filter as a 31-step staircase (rfilter.h) and average with the ratio
    estimator, hence the coarse tolerance; rendered with a box instead of Mitsuba's filter, edge
    pixels differ by 0.13 to 0.17."""
    mi = mitsuba()
    film = (f'<film type="hdrfilm"><integer name="width" value="40"/><integer name="height" value="24"/>'
            f'<boolean name="sample_border" value="true"/>{rfilter}</film>')
    xml = (f'<scene version="3.0.0"><integrator type="path"><integer name="max_depth" value="2"/></integrator>'
           f'{sensor}{film}<sampler type="independent"/></sensor>{SHAPES}</scene>')
    path = tmp_path / "s.xml"
    path.write_text(xml)
    mscene = mi.load_file(str(path))
    batches = np.stack([np.asarray(mi.render(mscene, seed=i, spp=128), np.float64) for i in range(8)])
    theirs, their_var = batches.mean(0), batches.var(0, ddof=1) / len(batches)
    scene = rt.load_scene(path)
    assert scene.warnings == []
    r = rt.render_full(scene, device="cpu", spp=1024, seed=5)
    ours, our_var = r.image.astype(np.float64), r.film.variance_of_mean()
    sigma = np.sqrt(our_var + their_var)
    mean_sigma = np.sqrt((our_var + their_var).sum((0, 1))) / (40 * 24)
    mean_diff = ours.mean((0, 1)) - theirs.mean((0, 1))
    assert np.all(np.abs(mean_diff) < 4.5 * mean_sigma + 0.002 * theirs.mean((0, 1))), (mean_diff, mean_sigma)
    excess = np.abs(ours - theirs) - (0.03 + 5 * sigma)
    assert excess.max() < 0, f"worst pixel {np.unravel_index(excess.argmax(), excess.shape)}: {excess.max():.3f}"
