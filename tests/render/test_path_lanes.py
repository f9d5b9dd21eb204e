"""Paths in SIMD lanes: the one integrator (cl/render/path.h, over cl/render/lanes.h) compiled at
8 or 16 lanes (the CPU megakernel, cl/megakernel/path.cl) renders the same samples as at one lane,
so the same image bit for bit and the same rays, for every material, light, texture, shape,
integrator, sampler, depth and camera option (a scene that mixes them all, and the scenes of
scenes/); it is chosen for every scene where the packets can traverse the device's BVH; and its
building blocks give the scalar code's bits lane by lane (length/normalize with their rescaling
fallbacks, nextafter, sqrt, min/max with NaN).  The sampler's lanes: tests/render/test_sampler.py;
the packet traversal: tests/accel/test_bvh_packet.py."""
import dataclasses
import platform
from pathlib import Path

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.device import abi
from pyopencl_rt.errors import UserError
from pyopencl_rt.render import megakernel
from pyopencl_rt.render.film import Film
from pyopencl_rt.render.wavefront import Wavefront

import harness
from harness import lane_renders as renders

SCENES = Path(__file__).resolve().parents[2] / "scenes"


# ----------------------------------------------------------------------------- which kernel
def test_selection(device, monkeypatch):
    """On a CPU device of an x86 host (PoCL, Intel's CPU runtime: the lane code is portable OpenCL C)
    the megakernel runs every scene in lanes (spheres, every material, textures, every light), not
    the wavefront; at the width pyopencl_rt/device/isa.py's rule gives for the implementation
    (tests/device/test_isa.py); $PYOPENCL_RT_LANES = 0 turns it off, 8 or 16 sets the width where
    the implementation builds it alike, anything else is one clear error.  Other devices never
    get it."""
    from pyopencl_rt.device import isa

    monkeypatch.delenv(megakernel.LANES_ENV, raising=False)
    builds = harness.lane_kernels_build_on(device)
    assert isa.x86_cpu(device) == builds
    rule = isa.lane_rule(device) if builds else None
    expected = rule.default if builds else 0
    for name, lanes in (("mitsuba-cbox", expected), ("cornell-box", expected), ("cornell-spheres", expected),
                        ("veach-mis", expected), ("textured", expected), ("cornell-jensen", expected)):
        wf = Wavefront(rt.load_scene(SCENES / f"{name}.toml"), device, width=8, height=8, kernel_mode="megakernel")
        assert wf.lane_width == lanes, name
        assert ("PACKET_WIDTH" in wf.features) == bool(lanes), name
        assert wf.description()["lanes_reason"].startswith(f"{lanes} lanes" if lanes else "one path"), name
    scene = rt.load_scene(SCENES / "mitsuba-cbox.toml")
    assert Wavefront(scene, device, width=8, height=8, kernel_mode="wavefront").lane_width == 0
    for value in ("0", "8", "16"):
        monkeypatch.setenv(megakernel.LANES_ENV, value)
        lanes = 0 if value == "0" or not builds else int(value) if int(value) in rule.widths else expected
        assert Wavefront(scene, device, width=8, height=8, kernel_mode="megakernel").lane_width == lanes, value
    monkeypatch.setenv(megakernel.LANES_ENV, "4")
    with pytest.raises(UserError, match="PYOPENCL_RT_LANES"):
        Wavefront(scene, device, width=8, height=8, kernel_mode="megakernel")
    monkeypatch.setenv(megakernel.LANES_ENV, "16")
    monkeypatch.setattr(platform, "machine", lambda: "aarch64")  # not on an ARM host
    assert Wavefront(scene, device, width=8, height=8, kernel_mode="megakernel").lane_width == 0


# ----------------------------------------------------------------------------- same samples
# every material, shape and light type: the lanes of one packet hit different ones
MIXED_SCENE = Path(__file__).with_name("mixed_scene.toml")


def mixed_scene(tmp_path, environment=True):
    """MIXED_SCENE with an environment map (a gradient with a bright spot) written beside it."""
    from pyopencl_rt.imageio import write_exr

    from PIL import Image

    text = MIXED_SCENE.read_text()
    Image.fromarray((np.indices((8, 8)).sum(0) % 2 * 200 + 30).astype(np.uint8)).save(tmp_path / "rough.png")
    if environment:
        sky = np.zeros((16, 32, 3), np.float32)
        sky[:, :] = np.linspace(0.05, 0.4, 16, dtype=np.float32)[:, None, None]
        sky[3, 20] = [40.0, 30.0, 20.0]
        write_exr(tmp_path / "sky.exr", sky)
        text += '[environment]\nfile = "sky.exr"\n'
    (tmp_path / "mixed.toml").write_text(text)
    return rt.load_scene(tmp_path / "mixed.toml")


def test_same_image_and_rays(device, monkeypatch, tmp_path):
    """A scene of every material, shape and light type (and an environment map): the film sums bit
    for bit and the same numbers of rays at every lane count the device builds."""
    harness.assert_same_lanes(renders(mixed_scene(tmp_path), device, monkeypatch, widths=harness.lane_widths(device), spp=4, seed=3,
                        width=40, height=30))


@pytest.mark.stress
@pytest.mark.parametrize("sampler", sorted(set(abi.SAMPLERS) - {"sobol"}))
def test_other_samplers(device, monkeypatch, sampler):
    """The other samplers (the default, sobol: above) draw the same numbers in lanes
    (tests/render/test_sampler.py compares them sample by sample, at every width, in make test):
    here the Cornell box, a small kernel, with the consumption of a whole path.  In make stress:
    two megakernels of their own per sampler (one path per work-item and the users' width)."""
    scene = rt.load_scene(SCENES / "mitsuba-cbox.toml")
    harness.assert_same_lanes(renders(scene, device, monkeypatch, widths=("0", harness.forced_lanes(device)), spp=4, seed=3,
                        width=32, height=24, sampler=sampler))


@pytest.mark.parametrize("name", ["mitsuba-cbox", "cornell-spheres", "veach-mis", "textured", "cornell-jensen",
                                  "textured-sky", "materials"])
def test_same_image_on_the_scenes(device, monkeypatch, name):
    """Every scene of scenes/ (triangles, spheres, conductors, glass, textures with emission
    textures, the glTF material)."""
    wide = harness.forced_lanes(device)
    scene = rt.load_scene(SCENES / f"{name}.toml")
    harness.assert_same_lanes(renders(scene, device, monkeypatch, widths=("0", wide), spp=2, seed=1, width=32, height=24))


def test_shading_normals_maps_and_vertex_colors(device, monkeypatch):
    """Interpolated vertex normals (and flat faces beside them), a normal map and a bump map
    (over the lanes, under Mitsuba's rules and under none) and vertex colours, on every material
    type, anisotropic rough ones under the maps (their tangent frames; cl/scene/shading.h): the same
    bits at every width."""
    from scenes_small import shading_scene

    wide = harness.forced_lanes(device)
    scene = shading_scene()
    assert {"HAS_SHADING_NORMALS", "HAS_NORMAL_MAPS", "HAS_VERTEX_COLORS", "HAS_ANISOTROPY"} <= set(
        scene.material_defines())
    harness.assert_same_lanes(renders(scene, device, monkeypatch, widths=("0", wide), spp=4, seed=2, width=32, height=24))


@pytest.mark.parametrize("integrator", ["bsdf", "nee"])
def test_integrators(device, monkeypatch, tmp_path, integrator):
    """BSDF sampling only and light sampling only (the MIS integrator: above)."""
    wide = harness.forced_lanes(device)
    harness.assert_same_lanes(renders(mixed_scene(tmp_path), device, monkeypatch, widths=("0", wide), spp=2, seed=8, width=24,
                        height=16, integrator=integrator))


@pytest.mark.parametrize("options", [{"max_depth": 1}, {"max_depth": 2}, {"max_depth": 3, "rr_depth": 1},
                                     {"max_depth": -1, "rr_depth": 2}])
def test_depths_and_roulette(device, monkeypatch, options):
    """Emitters seen directly only, direct light only, short paths rouletted from the first
    bounce, unbounded paths ended by roulette alone."""
    wide = harness.forced_lanes(device)
    scene = rt.load_scene(SCENES / "mitsuba-cbox.toml")
    harness.assert_same_lanes(renders(scene, device, monkeypatch, widths=("0", wide), spp=4, seed=5, width=32, height=24,
                        **options))


def test_thin_lens_two_sided_light_and_ior(device, monkeypatch):
    """A thin-lens camera, a two-sided emitter, a diffuse
    surface with an ior (the eta scale of roulette) and a 1 x 1 image."""
    wide = harness.forced_lanes(device)
    scene = rt.load_scene(SCENES / "cornell-box.toml")
    scene.camera = dataclasses.replace(scene.camera, aperture_radius=20.0)
    materials = [dataclasses.replace(m, two_sided=True) if max(m.emission) > 0 else m for m in scene.materials]
    materials[0] = dataclasses.replace(materials[0], ior=1.5)
    scene.materials = materials
    harness.assert_same_lanes(renders(scene, device, monkeypatch, widths=("0", wide), spp=6, seed=2, width=24, height=20))
    harness.assert_same_lanes(renders(scene, device, monkeypatch, widths=("0", wide), spp=9, seed=2, width=1, height=1))


def test_small_waves_and_adaptive_pixel_lists(device, monkeypatch):
    """Launches that end inside a work-item's block (a wave smaller than a pass), and adaptive
    sampling's pixel lists (listed passes, results in launch order)."""
    wide = harness.forced_lanes(device)
    scene = rt.load_scene(SCENES / "mitsuba-cbox.toml")
    films = {}
    for width in ("0", wide):
        monkeypatch.setenv(megakernel.LANES_ENV, width)
        wf = Wavefront(scene, device, width=30, height=20, seed=4, kernel_mode="megakernel", wave_size=333)
        film = Film(30, 20)
        wf.run(film, passes=3)
        films[width] = film
    assert np.array_equal(films["0"].sum, films[wide].sum)
    adaptive = renders(scene, device, monkeypatch, widths=("0", wide), spp=64, seed=1, width=24, height=16,
                       adaptive=True, target_error=0.05)
    assert adaptive[wide].film.counts.min() < adaptive[wide].film.counts.max()  # pixel lists were used
    assert np.array_equal(adaptive["0"].film.counts, adaptive[wide].film.counts)
    harness.assert_same_lanes(adaptive)


# ----------------------------------------------------------------------------- building blocks
LANES = harness.Kernels(r"""
#include "render/lanes.h"
/* length, normalize, nextafter toward +-inf, sqrt, fmin/fmax: lanes, then the scalar code */
__kernel void h_math(__global const float *a, __global const float *b, __global float *out)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    pvec3 v;
    pfloat x, y;
    for (int j = 0; j < PACKET_WIDTH; ++j) {
        pv3_set_lane(&v, j, load3(a, base + j));
        PLANE(x, j) = a[3 * (base + j)];
        PLANE(y, j) = b[base + j];
    }
    const pint all = PINT(-1);
    const pfloat len = pv3_length(v, all);
    const pvec3 nv = pv3_normalize(v, all);
    const pfloat up = pnextafter_inf(x, y > 0.0f), sq = psqrt(pabs(x)), lo = pfmin(x, y), hi = pfmax(x, y);
    for (int j = 0; j < PACKET_WIDTH; ++j) {
        const float3 s = load3(a, base + j);
        const float xs = a[3 * (base + j)], ys = b[base + j];
        const float3 ns = normalize(s);
        __global float *o = out + 16 * (base + j);
        o[0] = PLANE(len, j); o[1] = PLANE(nv.x, j); o[2] = PLANE(nv.y, j); o[3] = PLANE(nv.z, j);
        o[4] = PLANE(up, j); o[5] = PLANE(sq, j); o[6] = PLANE(lo, j); o[7] = PLANE(hi, j);
        o[8] = length(s); o[9] = ns.x; o[10] = ns.y; o[11] = ns.z;
        o[12] = nextafter(xs, ys > 0.0f ? INFINITY : -INFINITY); o[13] = sqrt(fabs(xs)); o[14] = fmin(xs, ys);
        o[15] = fmax(xs, ys);
    }
}
""", defines={"PACKET_WIDTH": 16})


def test_lane_math_equals_scalar(device, runtime, rng):
    """Bit for bit, including vectors whose squared length under- or overflows (the scalar code
    rescales: the lanes take its result), zeros, denormals, infinities and NaN."""
    harness.require_lane_kernels(device)
    n = 16 * 256
    scale = 10.0 ** rng.uniform(-30, 30, (n, 1))
    a = (rng.normal(size=(n, 3)) * scale).astype(np.float32)
    a[:16] = [[0, 0, 0], [1e-38, 0, 0], [1e-45, 0, 0], [-0.0, 0, 0], [np.inf, 1, 0], [np.nan, 0, 1], [3e38, 3e38, 0],
              [-1e-30, 2e-30, 0], [1, 1, 1], [-2, 0, 0], [5e-20, 5e-20, 5e-20], [1e20, -1e20, 1e19],
              [np.float32(1.17549435e-38), 0, 0], [-3.4e38, 0, 0], [0.5, 0, 0], [7, 8, 9]]
    b = np.where(rng.random(n) < 0.5, -1.0, 1.0).astype(np.float32) * rng.uniform(0, 2, n).astype(np.float32)
    b[:8] = [np.nan, 0.0, -0.0, np.inf, -np.inf, 1.0, -1.0, np.nan]
    out = LANES(runtime, "h_math", n // 16, a=a, b=b, out=(n, 16))
    assert np.array_equal(out[:, :8].view(np.uint32), out[:, 8:].view(np.uint32))
