"""Motion blur (pbrt-v4's TransformTimes / ActiveTransform): a moving shape or object instance is a
two-level instance that the kernels move along pbrt-v4's way between its two transforms at each
ray's time sample (cl/accel/instances.h, pyopencl_rt/accel/motion.py).  Checked against a float64
closed form of the time-averaged coverage of a black quad sliding, turning or stretching in front
of a white sky (each sample is 0 or 1: a binomial z-test per pixel), for each mapping of the
shutter onto the motion and both schedules; the split M = T R S and its interpolation against
matrices written out here; the loader's two transforms; and what we cannot move is one error line."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.scene.loaders import load_scene

from harness import load_error, load_warned
from pyopencl_rt.render.settings import FEATURES_ENV

W, H, SPP = 32, 8, 256
FOV = 12.0  # degrees, across the film's shorter side (pbrt's rule): its height
HALF = 5.0 * math.tan(math.radians(FOV / 2)) * W / H  # the film's half width on the plane z = 0, 5 away

QUAD = ('Shape "trianglemesh" "integer indices" [0 1 2  2 3 0]\n'
        '    "point3 P" [-0.5 -0.5 0  0.5 -0.5 0  0.5 0.5 0  -0.5 0.5 0]')


def scene_text(motion: str, camera: str = "", times: str = "", instance: bool = False) -> str:
    """A black unit quad at the origin, moved by ``motion`` at the end time, under a white sky, seen
    from z = 5 (a 32 x 8 film over 2 HALF x HALF / 2 of the plane z = 0 around the origin)."""
    body = (f'ObjectBegin "q"\n{QUAD}\nObjectEnd\nAttributeBegin\n  ActiveTransform EndTime\n  {motion}\n'
            '  ActiveTransform All\n  ObjectInstance "q"\nAttributeEnd\n') if instance else \
        f'AttributeBegin\n  ActiveTransform EndTime\n  {motion}\n  ActiveTransform All\n  {QUAD}\nAttributeEnd\n'
    return f"""{times}
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" [ {FOV} ] {camera}
Film "rgb" "integer xresolution" [ {W} ] "integer yresolution" [ {H} ]
PixelFilter "box"
Sampler "independent" "integer pixelsamples" [ {SPP} ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
{body}"""


def expected_rows(shift_of_time, t0: float, t1: float) -> np.ndarray:
    """(W,) float64: the sky's share of each pixel of a row through the quad, the quad's x offset at
    time t being shift_of_time(t), t uniform in [t0, t1] (pbrt's image: world +x on the left)."""
    xs = (np.arange(W * 64) + 0.5) / (W * 64)  # the film's x, 64 points a pixel
    world_x = -(2.0 * xs - 1.0) * HALF
    times = t0 + (np.arange(512) + 0.5) / 512 * (t1 - t0)
    shift = np.array([shift_of_time(t) for t in times])
    covered = np.abs(world_x[:, None] - shift[None, :]) <= 0.5
    return 1.0 - covered.mean(axis=1).reshape(W, 64).mean(axis=1)


def clamp01(x):
    return min(max(x, 0.0), 1.0)


CASES = {
    # name: (motion, camera params, TransformTimes, x offset at time t, shutter)
    "default": ("Translate 1 0 0", "", "", lambda t: t, (0.0, 1.0)),
    "shutter": ("Translate 1.2 0 0", '"float shutteropen" 0.25 "float shutterclose" 0.75', "",
                lambda t: 1.2 * t, (0.25, 0.75)),
    "held-at-the-end": ("Translate -1 0 0", '"float shutteropen" 0.5 "float shutterclose" 1.5',
                        "TransformTimes 0 1", lambda t: -clamp01(t), (0.5, 1.5)),
    "transform-times": ("Translate 1 0 0", "", "TransformTimes 0 2", lambda t: t / 2, (0.0, 1.0)),
    # the quad stays and the camera moves 1 along world +x: the quad slides by -t in its view
    "camera": ("Translate 0 0 0", "", "ActiveTransform EndTime\nTranslate 1 0 0\nActiveTransform All",
               lambda t: -t, (0.0, 1.0)),
}


def write(tmp_path, text, name="s.pbrt") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("case,mode,instance", [
    ("default", "megakernel", False), ("default", "wavefront", False), ("shutter", "megakernel", False),
    ("held-at-the-end", "megakernel", True), ("transform-times", "wavefront", True),
    ("camera", "megakernel", False), ("camera", "wavefront", False)])
def test_a_sliding_quad_covers_each_pixel_for_its_share_of_the_shutter(tmp_path, monkeypatch, case, mode, instance):
    """The middle rows (inside the quad's height) against the closed form: each sample sees the
    sky (1, times the exposure time) or the quad (0), so each pixel's mean is binomial; every pixel within 5 sigma (at
    least 1/SPP of variance), and the whole row's mean within 4 sigma of the sum."""
    import pyopencl_rt as rt

    motion, camera, times, shift, shutter = CASES[case]
    if case != "camera":  # moving instances: the scene's own small program builds in a third of the time
        monkeypatch.setenv(FEATURES_ENV, "scene")  # of the suite's every-feature one (which a camera shares)
    scene, warned = load_warned(write(tmp_path, scene_text(motion, camera, times, instance)))
    assert warned == [] and (any(i.moves for i in scene.instances) or scene.camera_motion is not None)
    r = rt.render_full(scene, spp=SPP, device="cpu", seed=3, kernel_mode=mode)
    got = r.image[H // 2 - 1:H // 2 + 1, :, 0].astype(np.float64)  # rows within |y| < 0.14 of the quad's 0.5
    share = expected_rows(shift, *shutter)
    exposure = shutter[1] - shutter[0]  # pbrt's film records radiance times the exposure time
    want = exposure * share
    sigma = exposure * np.sqrt(np.maximum(share * (1 - share), 1.0 / SPP) / SPP)
    z = (got - want) / sigma
    assert np.abs(z).max() < 5.0, (case, np.round(got, 3), np.round(want, 3))
    total_sigma = math.sqrt((sigma ** 2).sum() * 2)
    assert abs((got - want).sum()) < 4 * total_sigma
    # the blur is there: a static quad's row is 0 or 1 away from its two edge pixels
    assert ((share > 0.05) & (share < 0.95)).sum() > 4


BAR = ('Shape "trianglemesh" "integer indices" [0 1 2  2 3 0]\n'
       '    "point3 P" [-1.5 -0.1 0  1.5 -0.1 0  1.5 0.1 0  -1.5 0.1 0]')


def expected_image(covered, t0: float, t1: float, n: int = 12, times: int = 256) -> np.ndarray:
    """(H, W) float64: the sky's share of each pixel, ``covered(x, y, t)`` (arrays) saying where the
    shape is at time t, t uniform in [t0, t1]; n x n points a pixel (pbrt's image: world +x on the
    left, +y up)."""
    half_h = HALF * H / W
    fx = (np.arange(W * n) + 0.5) / (W * n)
    fy = (np.arange(H * n) + 0.5) / (H * n)
    x = -(2.0 * fx - 1.0) * HALF
    y = -(2.0 * fy - 1.0) * half_h
    yy, xx = np.meshgrid(y, x, indexing="ij")
    seen = np.zeros_like(xx)
    for t in t0 + (np.arange(times) + 0.5) / times * (t1 - t0):
        seen += covered(xx, yy, t)
    share = 1.0 - seen / times
    return share.reshape(H, n, W, n).mean(axis=(1, 3))


def turning_bar(x, y, t):
    """The 3 x 0.2 bar turned by 90 t degrees about z (slerp: the angle linear in time)."""
    a = np.radians(90.0 * t)
    u, v = x * np.cos(a) + y * np.sin(a), -x * np.sin(a) + y * np.cos(a)
    return (np.abs(u) <= 1.5) & (np.abs(v) <= 0.1)


def stretching_quad(x, y, t):
    """The unit quad stretched along x from 1 to 2 wide (S interpolated linearly)."""
    return (np.abs(x) <= 0.5 * (1.0 + t)) & (np.abs(y) <= 0.5)


@pytest.mark.parametrize("motion,covered,mode", [
    ("Rotate 90 0 0 1", turning_bar, "megakernel"), ("Rotate 90 0 0 1", turning_bar, "wavefront"),
    ("Scale 2 1 1", stretching_quad, "megakernel")])
def test_a_turning_or_stretching_shape_covers_each_pixel_for_its_share(tmp_path, monkeypatch, motion, covered, mode):
    """Rotation by slerp and stretch by a linear S, every pixel of the film against the closed
    form (binomial, 5 sigma; the image's sum within 4 sigma)."""
    import pyopencl_rt as rt

    monkeypatch.setenv(FEATURES_ENV, "scene")  # the sliding quads' programs

    text = scene_text(motion).replace(QUAD, BAR) if covered is turning_bar else scene_text(motion)
    scene, warned = load_warned(write(tmp_path, text))
    assert warned == [] and any(i.moves for i in scene.instances)
    r = rt.render_full(scene, spp=SPP, device="cpu", seed=5, kernel_mode=mode)
    got = r.image[..., 0].astype(np.float64)
    want = expected_image(covered, 0.0, 1.0)
    sigma = np.sqrt(np.maximum(want * (1 - want), 1.0 / SPP) / SPP)
    z = (got - want) / sigma
    assert np.abs(z).max() < 5.0, (np.round(got, 2), np.round(want, 2))
    assert abs((got - want).sum()) < 4 * math.sqrt((sigma ** 2).sum())
    assert ((want > 0.05) & (want < 0.95)).sum() > 8  # blurred


def test_the_split_and_the_way_between_two_transforms():
    """M = T R S as pbrt-v4 splits it (T the translation, R the rotation of the polar decomposition,
    S the rest), against a transform built from known parts; slerp halfway between two turns about
    z is the turn by the mean angle; T and S halfway are the means; a box's bounds hold every point
    of a turning box's way."""
    from pyopencl_rt.accel.motion import Motion, decompose, rotation

    def rz(deg):
        a = math.radians(deg)
        return np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])

    m = np.eye(4)
    m[:3, :3] = rz(40.0) @ np.diag([2.0, 3.0, 4.0])
    m[:3, 3] = (1.0, 2.0, 3.0)
    t, q, s = decompose(m)
    assert np.allclose(t, (1.0, 2.0, 3.0)) and np.allclose(s, np.diag([2.0, 3.0, 4.0]), atol=1e-9)
    assert np.allclose(rotation(q), rz(40.0), atol=1e-9)
    a, b = np.eye(4), np.eye(4)
    a[:3, :3], b[:3, :3] = rz(10.0), rz(130.0) @ np.diag([3.0, 1.0, 1.0])
    b[:3, 3] = (4.0, 0.0, -2.0)
    way = Motion(a, b)
    half = way.at(0.5)
    assert np.allclose(half[:3, :3], rz(70.0) @ np.diag([2.0, 1.0, 1.0]), atol=1e-9)
    assert np.allclose(half[:3, 3], (2.0, 0.0, -1.0))
    assert np.allclose(way.at(0.0), a) and np.allclose(way.at(1.0), b)
    box = np.array([[-1.0, -0.5, -0.2], [1.0, 0.5, 0.2]])
    lo, hi = way.bounds(box, steps=8)
    corners = np.array([[x, y, z] for x in box[:, 0] for y in box[:, 1] for z in box[:, 2]])
    for s_ in np.linspace(0.0, 1.0, 1001):
        p = corners @ way.at(s_)[:3, :3].T + way.at(s_)[:3, 3]
        assert (p >= lo).all() and (p <= hi).all(), s_


def test_a_pivot_moves_with_the_world_alone():
    """About a pivot c (pbrt-v4 turns an object instance about its render space's origin, the
    camera): the ends are the two transforms; halfway, a half turn about z maps c + r to c + r'
    (r turned by the half angle); and moving the world by a translation W (camera-relative
    rendering) while the instance's own space stays is the same way, moved: Motion(W M0, W M1,
    c, W c).at(s) = W Motion(M0, M1, c).at(s)."""
    from pyopencl_rt.accel.motion import Motion

    a, b = np.eye(4), np.eye(4)
    b[:3, :3] = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 degrees about z
    b[:3, 3] = (1.0, -1.0, 0.0)  # = turning about c = (1, 0, 0) at the end
    c = (1.0, 0.0, 0.0)
    way = Motion(a, b, c)
    assert np.allclose(way.at(0.0), a) and np.allclose(way.at(1.0), b)
    half = way.at(0.5)
    r = np.array([2.0, 0.5, 0.3]) - c
    c45 = math.cos(math.pi / 4)
    turned = np.array([[c45, -c45, 0.0], [c45, c45, 0.0], [0.0, 0.0, 1.0]]) @ r
    assert np.allclose(half[:3, :3] @ (r + c) + half[:3, 3], turned + c)
    shift = np.eye(4)
    shift[:3, 3] = (-3.0, 2.0, 7.0)
    moved = Motion(shift @ a, shift @ b, c, np.add(c, shift[:3, 3]))
    for s_ in (0.0, 0.3, 0.5, 1.0):
        assert np.allclose(moved.at(s_), shift @ way.at(s_)), s_


MOTION_KERNEL = r"""
#include "accel/instances.h"
__kernel void motion_at(__global const Motion *ways, __global const int *way, __global const float *u,
                        __global float *out)
{
    const int i = get_global_id(0);
    float m[12], w[12];
    motion_matrices(ways + way[i], u[i], m, w);
    for (int k = 0; k < 12; ++k) {
        out[24 * i + k] = m[k];
        out[24 * i + 12 + k] = w[k];
    }
}
"""


def test_the_kernels_way_is_the_hosts(runtime):
    """cl/accel/instances.h motion_matrices (float32) against accel/motion.py (float64) on the
    records of turning, stretching, sliding and pivoted ways at times across the shutter (and
    outside the transforms' times, held at the ends): M and M^-1 within 2e-6 of their scale."""
    import harness
    from pyopencl_rt.accel.instances import TwoLevelBVH

    rng = np.random.default_rng(7)

    def affine():
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        m = np.eye(4)
        m[:3, :3] = q * np.sign(np.linalg.det(q)) @ np.diag(rng.uniform(0.3, 2.0, 3))
        m[:3, 3] = rng.normal(size=3) * 3
        return m

    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    ends = [(affine(), affine(), None), (affine(), affine(), ((1.0, 2.0, 3.0), (-2.0, 0.5, 4.0))),
            (np.eye(4), np.diag([2.0, 0.5, 1.0, 1.0]), None)]
    slide = affine()
    slid = slide.copy()
    slid[:3, 3] += (0.5, -1.0, 2.0)
    ends.append((slide, slid, None))
    bvh = TwoLevelBVH(v, np.array([[0, 1, 2]]), 0, [(0, 1)], [(m0, 0) for m0, _, _ in ends],
                      ends=[m1 for _, m1, _ in ends], motion_time=(-0.25, 1.5), pivots=[p for _, _, p in ends])
    recs = bvh.motion_records()
    ways = [bvh.motion[i] for i in bvh.order]
    u = np.tile(np.array([0.0, 0.1, 0.4, 0.75, 0.99], np.float32), len(recs))
    which = np.repeat(np.arange(len(recs), dtype=np.int32), 5)
    kernels = harness.Kernels(MOTION_KERNEL, defines={"HAS_INSTANCES": 1, "HAS_MOTION": 1}, local_size=1)
    out = kernels(runtime, "motion_at", len(u), recs, which, u, np.zeros(24 * len(u), np.float32)).reshape(-1, 2, 3, 4)
    for k in range(len(u)):
        s_ = min(max(-0.25 + 1.5 * float(u[k]), 0.0), 1.0)
        want = ways[which[k]].at(s_)
        scale = np.abs(want).max()
        assert np.abs(out[k, 0] - want[:3]).max() < 2e-6 * scale, (k, s_)
        inv = np.linalg.inv(want)
        assert np.abs(out[k, 1] - inv[:3]).max() < 2e-6 * np.abs(inv).max() * np.linalg.cond(want[:3, :3]), (k, s_)


def test_the_loader_keeps_pbrts_two_transforms(tmp_path):
    """killeroo-moving's structure: transforms before ActiveTransform apply to both times, those
    after ActiveTransform StartTime to the start alone, AttributeEnd restores both and the active
    set; a shape whose two transforms agree is drawn as ever (flattened, not moving)."""
    text = ("WorldBegin\nAttributeBegin\n  Scale 0.5 0.5 0.5\n  Translate 100 200 -140\n"
            "  ActiveTransform StartTime\n  Translate 35 35 35\n"
            f"  AttributeBegin\n    {QUAD}\n  AttributeEnd\n"
            "  AttributeBegin\n    ActiveTransform EndTime\n    Translate 30 0 0\n    ActiveTransform All\n"
            f"    Translate -200 0 0\n    {QUAD}\n  AttributeEnd\n"
            f"  ActiveTransform All\n  Translate 0 0 0\nAttributeEnd\n{QUAD}\n")
    scene = load_scene(write(tmp_path, text))
    moving = [i for i in scene.instances if i.moves]
    assert len(moving) == 2 and len(scene.blas_groups) == 2
    base = np.diag([0.5, 0.5, 0.5, 1.0])
    base[:3, 3] = 0.5 * np.array([100.0, 200.0, -140.0])
    # pbrt mirrors x (its LookAt-free default camera sees the world as is here: no mirror without a Camera)
    first, second = moving
    start1, end1 = base.copy(), base.copy()
    start1[:3, 3] += 0.5 * np.array([35.0, 35.0, 35.0])
    start2, end2 = start1.copy(), end1.copy()
    start2[:3, 3] += 0.5 * np.array([-200.0, 0.0, 0.0])
    end2[:3, 3] += 0.5 * np.array([30.0 - 200.0, 0.0, 0.0])
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0]) if scene.instances and not np.allclose(
        first.to_world[0, 0], 0.5) else np.eye(4)
    for inst, start, end in ((first, start1, end1), (second, start2, end2)):
        assert np.allclose(inst.to_world, mirror @ start @ mirror), inst.to_world
        assert np.allclose(inst.to_world_end, mirror @ end @ mirror), inst.to_world_end
    assert scene.motion_time == (0.0, 1.0)
    # the quad after the block is the world's (no instance), at the identity
    assert len(scene.faces) == 6
    assert [i.motion_pivot for i in moving] == [None, None]  # shapes: no pivot (any gives their way)
    # an object instance turns about the camera's position (pbrt-v4's render space), the world's
    # mirror applied (LookAt from (1, 2, 5): our camera sees pbrt's image with x mirrored)
    scene = load_scene(write(tmp_path, scene_text("Rotate 30 0 0 1", instance=True).replace(
        "LookAt 0 0 5", "LookAt 1 2 5"), "i.pbrt"))
    (inst,) = [i for i in scene.instances if i.moves]
    assert np.allclose(np.linalg.norm(np.subtract(inst.motion_pivot, scene.camera.eye)), 0.0)


@pytest.mark.parametrize("text,message", [
    (scene_text("Scale -1 1 1"), r"a motion from a transform to its mirror image is not supported"),
    ('WorldBegin\nActiveTransform EndTime\nTranslate 1 0 0\nLightSource "point"\n' + QUAD,
     r'LightSource "point": a moving light'),
    ('WorldBegin\nActiveTransform EndTime\nTranslate 1 0 0\nShape "sphere"\n', r'motion blur of an analytic sphere'),
    ('WorldBegin\nActiveTransform EndTime\nTranslate 1 0 0\nAreaLightSource "diffuse"\n' + QUAD,
     r'a moving area light'),
    ('WorldBegin\nMakeNamedMedium "m" "string type" "homogeneous"\nAttributeBegin\nMediumInterface "m" ""\n' + QUAD
     + '\nAttributeEnd\nActiveTransform EndTime\nTranslate 1 0 0\n' + QUAD,
     r':10: Shape "trianglemesh": motion blur in a scene with participating media'),
    ('WorldBegin\nMakeNamedMedium "m" "string type" "homogeneous"\nAttributeBegin\nActiveTransform EndTime\n'
     'Translate 1 0 0\n' + QUAD + '\nAttributeEnd\nMediumInterface "m" ""\n' + QUAD,
     r'motion blur in a scene with participating media'),
    ('WorldBegin\nActiveTransform Sometimes\n' + QUAD, r'ActiveTransform "Sometimes": expected StartTime'),
    ('TransformTimes 1 0\nWorldBegin\n' + QUAD, r'TransformTimes: the end time 0 is before the start time 1'),
    ('TransformTimes 1 1\nWorldBegin\nActiveTransform EndTime\nTranslate 1 0 0\n' + QUAD,
     r'a moving shape needs TransformTimes with the end after the start'),
])
def test_what_cannot_move_is_one_error_line(tmp_path, text, message):
    msg = load_error(write(tmp_path, text))
    assert re.search(message, msg), msg


def test_embree_and_the_exports_refuse_a_moving_scene(tmp_path):
    """The Embree intersector renders the flattened scene, which cannot move: one UserError line."""
    import pyopencl_rt as rt
    from pyopencl_rt.errors import UserError

    scene = load_scene(write(tmp_path, scene_text("Translate 1 0 0")))
    with pytest.raises(UserError, match="motion blur .* not with the Embree intersector"):
        rt.render_full(scene, spp=1, device="cpu", intersector="embree")


def test_the_resume_key_sees_the_motion(tmp_path):
    """A checkpoint of the moving scene does not resume into the same scene moving elsewhere, or over
    another shutter."""
    from pyopencl_rt.render.checkpoint import scene_hash

    keys = {scene_hash(load_scene(write(tmp_path, scene_text(m, c), f"s{k}.pbrt")))
            for k, (m, c) in enumerate([("Translate 1 0 0", ""), ("Translate 1.5 0 0", ""),
                                        ("Translate 1 0 0", '"float shutterclose" 0.5')])}
    assert len(keys) == 3
