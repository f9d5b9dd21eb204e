"""pbrt-v4's texture mappings of the hit point (planar, spherical, cylindrical) and its directionmix
texture (cl/scene/textures.h tex_map_lanes, tex_sample_lanes; pyopencl_rt/scene/textures.py
map_points, DirectionMix): the kernel's lookups against the float64 reference, and pbrt scenes'
albedo against the reference at the hit points the position and normal AOVs give."""
from __future__ import annotations

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.errors import UserError
from pyopencl_rt.scene.textures import DirectionMix, lookup, map_points, pack_textures, texture_from_array

import harness

AT = r"""
#include "scene/textures.h"
/* item i (PACKET_WIDTH per work-item, one per lane): texture index[i] at uv[i], the point p[i] and
 * the normal ng[i] where on[i]; out: tex_sample_lanes' RGB */
__kernel void h_tex_at(__global const Texture *textures, __global const float4 *data, __global const int *index,
                       __global const float2 *uv, __global const float *p, __global const float *ng,
                       __global const int *on, __global float *out)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    pint ti = PINT(0), live = PINT(0);
    TexHit h;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const int i = base + k;
        PLANE_I(ti, k) = index[i];
        PLANE(h.u, k) = uv[i].x;
        PLANE(h.v, k) = uv[i].y;
        PLANE(h.p.x, k) = p[3 * i];
        PLANE(h.p.y, k) = p[3 * i + 1];
        PLANE(h.p.z, k) = p[3 * i + 2];
        PLANE(h.ng.x, k) = ng[3 * i];
        PLANE(h.ng.y, k) = ng[3 * i + 1];
        PLANE(h.ng.z, k) = ng[3 * i + 2];
        PLANE_I(live, k) = on[i] ? (PACKET_WIDTH == 1 ? 1 : -1) : 0;
    }
    const pvec3 c = tex_sample_lanes(textures, data, ti, &h, live);
    for (int k = 0; k < PACKET_WIDTH; ++k)
        vstore3(pv3_lane(c, k), 0, out + 3 * (base + k));
}
"""


def reference(t, uv, p, ng) -> np.ndarray:
    """The float64 lookup of Texture or DirectionMix ``t`` at hits (uv, p, ng)."""
    if isinstance(t, DirectionMix):
        amt = np.abs(ng @ np.asarray(t.direction))[:, None]
        return amt * reference(t.first, uv, p, ng) + (1 - amt) * reference(t.second, uv, p, ng)
    st = uv if t.mapping == "uv" else map_points(t.mapping, t.frame, p)
    return lookup(t.texels[..., :3], st, t.wrap, t.filter, t.to_uv)


def _textures(rng):
    """Every mapping with either filter and wrap, under random frames, and direction mixes of them."""
    img = texture_from_array(rng.random((5, 7, 4)).astype(np.float32))
    texs = []
    for mapping in ("uv", "planar", "spherical", "cylindrical"):
        for wrap, filt in (("repeat", "bilinear"), ("clamp", "nearest"), ("mirror", "bilinear")):
            frame = np.concatenate([rng.normal(size=(3, 3)), rng.normal(size=(3, 1))], 1) if mapping != "uv" else ()
            texs.append(img.with_lookup(wrap=wrap, filter=filt, to_uv=(1.0, 0.2, 0.1, -0.3, -1.0, 1.0), mapping=mapping,
                                        frame=np.ravel(frame)))
    texs.append(DirectionMix(texs[3], texs[0], direction=rng.normal(size=3), name="mix-planar-uv"))
    texs.append(DirectionMix(texs[6], texs[9], direction=(0.0, 1.0, 0.0), name="mix-spherical-cylindrical"))
    return texs


def test_lookups_of_the_hit_point_match_the_reference(runtime, rng):
    """uv, planar, spherical and cylindrical lookups (each under a random 3 x 4 frame, bilinear and
    nearest, repeat, clamp and mirror, an affine to_uv after the mapping) and direction mixes of them,
    at 6144 random hits (points in [-2, 2]^3, unit normals): within 2e-5 of the float64 reference
    (nearest lookups: but for the 0.5% of hits within rounding of a texel edge); and over 8 lanes the
    one-lane bits."""
    texs = _textures(rng)
    table, data = pack_textures(texs)
    assert list(table["mapping"][:12:3]) == [0, 1, 2, 3] and list(table["children"][12]) == [3, 0]
    n = 6144  # a multiple of the harness's groups (16 work-items) at either width
    index = np.tile(np.arange(len(texs)), n // len(texs) + 1)[:n].astype(np.int32)
    uv = rng.uniform(-2, 2, (n, 2)).astype(np.float32)
    p = rng.uniform(-2, 2, (n, 3)).astype(np.float32)
    ng = rng.normal(size=(n, 3))
    ng = (ng / np.linalg.norm(ng, axis=1, keepdims=True)).astype(np.float32)
    on = np.ones(n, np.int32)
    outs = {}
    for width in (1, 8):
        kernels = harness.Kernels(AT, defines={"PACKET_WIDTH": width}, local_size=16)
        outs[width] = kernels(runtime, "h_tex_at", n // width, table, data, index, uv, p.ravel(), ng.ravel(), on, (n, 3))
    assert np.array_equal(outs[1].view(np.uint32), outs[8].view(np.uint32))
    for i, t in enumerate(texs):
        sel = index == i
        want = reference(t, uv[sel].astype(np.float64), p[sel].astype(np.float64), ng[sel].astype(np.float64))
        err = np.abs(outs[1][sel] - want).max(axis=1)
        nearest = getattr(t, "filter", "") == "nearest" or isinstance(t, DirectionMix)
        assert (err > 2e-5).mean() <= (0.005 if nearest else 0.0), (t.name, t.mapping, err.max())


# -- pbrt scenes ------------------------------------------------------------------------------------------

CAMERA = """LookAt 2.2 1.8 -3.2  0 0 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 64 "integer yresolution" 64
Sampler "independent" "integer pixelsamples" 4
WorldBegin
LightSource "infinite" "rgb L" [0.5 0.5 0.5]
"""


def _ramp_png(tmp_path):
    """A smooth 8 x 8 image (linear ramps in x and y, a third channel of both), so that an AOV averaged
    over a pixel is the lookup at the averaged hit point, to the second order."""
    from PIL import Image

    x, y = np.meshgrid(np.linspace(0.1, 0.9, 8), np.linspace(0.2, 0.8, 8))
    img = np.stack([x, y, 0.5 * (x + y)], -1)
    path = tmp_path / "ramp.png"
    Image.fromarray(np.round(img * 255).astype(np.uint8)).save(path)
    return path


def _render(path, **kw):
    scene, warned = harness.load_warned(path)
    assert warned == [], warned
    r = rt.render_full(scene, device="cpu", seed=2, aovs="albedo,position,normal", spp=16, **kw)
    return scene, {k: np.asarray(v, np.float64) for k, v in r.layers.items()}


@pytest.mark.parametrize("mapping,shape,extra", [
    ("planar", 'Shape "trianglemesh" "point3 P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "integer indices" [0 1 2 0 2 3]',
     '"vector3 v1" [0.4 0.1 0.2] "vector3 v2" [-0.1 0.3 0.1] "float udelta" 0.2 "float vdelta" -0.1'),
    ("spherical", 'Shape "sphere" "float radius" 1', ""),
    ("cylindrical", 'Shape "cylinder" "float radius" 0.8 "float zmin" -0.7 "float zmax" 0.7', ""),
])
def test_pbrt_mappings_render_the_lookup_at_the_hit(tmp_path, mapping, shape, extra):
    """A pbrt scene: a diffuse shape whose reflectance is an image under ``mapping``, the texture
    defined under a transform of its own (turned, moved and scaled: its inverse takes world points
    into the texture's space): the albedo AOV of every pixel that sees the shape is the reference
    lookup (pbrt-v4's mapping, then its image at (s, 1 - t)) at the pixel's mean hit point, where
    that lookup is smooth over the pixel (within 0.05 of its centre half a pixel away; at least 70%:
    not on the seam of phi, where it jumps between the image's edges, nor near a pole): the median
    within 0.002 (measured: 2e-4) and fewer than 5% beyond 0.02 (where phi turns fast within a
    pixel); and the image is not the uv lookup's (the mapping is used: mean difference above 0.05;
    with the frame not moved along with the scene it was 0.2 to 0.4)."""
    png = _ramp_png(tmp_path)
    text = CAMERA + f"""AttributeBegin
Translate 0.3 -0.2 0.1
Rotate 35 1 1 0
Scale 1.5 0.8 1.2
Texture "t" "spectrum" "imagemap" "string filename" "{png.name}" "string wrap" "clamp" "string mapping" "{mapping}" {extra}
AttributeEnd
Material "diffuse" "texture reflectance" "t"
AttributeBegin
Rotate -20 0 1 0
{shape}
AttributeEnd
"""
    path = tmp_path / f"{mapping}.pbrt"
    path.write_text(text)
    scene, aov = _render(path)
    tex = scene.materials[0].base_texture
    assert tex.mapping == mapping
    def ref(points):
        return lookup(tex.texels[..., :3], map_points(mapping, tex.frame, points.reshape(-1, 3)), tex.wrap,
                      tex.filter, tex.to_uv).reshape(points.shape)

    seen = np.linalg.norm(aov["normal"], axis=-1) > 0.99  # the shape fills the pixel (the AOVs average)
    seen[0], seen[-1], seen[:, 0], seen[:, -1] = False, False, False, False
    pos = np.where(np.isfinite(aov["position"]), aov["position"], 0.0)  # (inf where nothing was hit)
    want = ref(pos)
    # where the lookup is smooth over the pixel (at the midpoints toward its four neighbours within
    # 0.05 of its centre's: not on the seam of phi, where it jumps between the image's edges, nor at a pole)
    smooth = seen.copy()
    for axis, step in ((0, 1), (0, -1), (1, 1), (1, -1)):
        mid = 0.5 * (pos + np.roll(pos, step, axis=axis))
        smooth &= np.roll(seen, step, axis=axis) & (np.abs(ref(mid) - want).max(-1) < 0.05)
    assert smooth.sum() > 0.7 * seen.sum() > 250, (smooth.sum(), seen.sum())
    err = np.abs(aov["albedo"] - want).max(-1)[smooth]
    assert np.median(err) < 0.002 and (err > 0.02).mean() < 0.05, (np.quantile(err, [0.5, 0.95, 1.0]),
                                                                     (err > 0.02).mean())
    got = aov["albedo"][seen]
    by_uv = (tmp_path / f"{mapping}-uv.pbrt")
    by_uv.write_text(text.replace(f'"string mapping" "{mapping}" {extra}', ""))
    _, uv_aov = _render(by_uv)
    assert np.abs(uv_aov["albedo"][seen] - got).mean() > 0.05


def test_pbrt_direction_mix_weighs_by_the_geometric_normal(tmp_path):
    """pbrt-v4's directionmix of two colours along dir (0, 1, 0) turned by the texture's transform
    (30 degrees about z), on a box turned 25 degrees about y: where a pixel sees one face, its albedo
    AOV is amt tex1 + (1 - amt) tex2 (the three channels give the same amt, to 1e-4) with amt one of
    |n . dir| of the box's six face normals n in pbrt's world (to 1e-4), and the faces seen give at
    least three values of it; the kernels' weight is |ng . dir| of the same normal and direction in
    our frame (the normal AOV), to 1e-4."""
    box = ('Shape "trianglemesh" "point3 P" [-1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1  -1 -1 1  1 -1 1  1 1 1  -1 1 1] '
           '"integer indices" [0 2 1 0 3 2  4 5 6 4 6 7  0 1 5 0 5 4  3 7 6 3 6 2  0 4 7 0 7 3  1 2 6 1 6 5]')
    path = tmp_path / "dirmix.pbrt"
    path.write_text(CAMERA + f"""AttributeBegin
Rotate 30 0 0 1
Texture "d" "spectrum" "directionmix" "rgb tex1" [0.9 0.2 0.1] "rgb tex2" [0.1 0.3 0.8]
AttributeEnd
Material "diffuse" "texture reflectance" "d"
AttributeBegin
Rotate 25 0 1 0
Scale 0.7 0.7 0.7
{box}
AttributeEnd
""")
    scene, aov = _render(path)
    mix = scene.materials[0].base_texture
    assert isinstance(mix, DirectionMix)
    tex1, tex2 = np.array([0.9, 0.2, 0.1]), np.array([0.1, 0.3, 0.8])
    n = aov["normal"]
    seen = np.linalg.norm(n, axis=-1) > 0.999  # one face in the whole pixel (averaged normals are shorter)
    assert seen.sum() > 300
    amt = (aov["albedo"][seen] - tex2) / (tex1 - tex2)
    assert np.ptp(amt, axis=1).max() < 1e-4
    amt = amt.mean(axis=1)
    turn = np.radians(25)
    faces = np.array([[np.cos(turn), 0, -np.sin(turn)], [0, 1, 0], [np.sin(turn), 0, np.cos(turn)]])  # Ry(25) axes
    direction = np.array([-np.sin(np.radians(30)), np.cos(np.radians(30)), 0.0])
    expected = np.abs(faces @ direction)
    nearest = np.abs(amt[:, None] - expected[None, :]).min(axis=1)
    assert nearest.max() < 1e-4, (nearest.max(), expected)
    assert len(set(np.round(amt, 3))) >= 3
    assert np.abs(amt - np.abs(n[seen] @ np.asarray(mix.direction))).max() < 1e-4


def test_pbrt_direction_mix_under_a_coating(tmp_path):
    """A directionmix as a coateddiffuse's reflectance (our plastic, whose sampling weight takes the mean
    luminance of its diffuse texture, Mitsuba's rule): the mix has no image of its own, so the weight
    takes the mean of its two inputs; kroken's magazines render so (an AttributeError before)."""
    path = tmp_path / "coated-dirmix.pbrt"
    path.write_text(CAMERA + """Texture "d" "spectrum" "directionmix" "rgb tex1" [0.9 0.2 0.1] "rgb tex2" [0.1 0.3 0.8]
Material "coateddiffuse" "texture reflectance" "d" "float roughness" 0
Shape "sphere"
""")
    scene, aov = _render(path)
    mat = scene.materials[0]
    lum = np.array([0.212671, 0.715160, 0.072169])
    d = np.mean(mat.albedo) * (0.5 * (np.array([0.9, 0.2, 0.1]) + np.array([0.1, 0.3, 0.8]))) @ lum
    s = np.mean(mat.specular_reflectance)
    assert isinstance(mat.base_texture, DirectionMix)
    assert np.isclose(mat.record()["spec_weight"], s / (d + s), rtol=1e-6)
    assert np.isfinite(aov["albedo"]).all() and aov["albedo"].max() > 0.1


@pytest.mark.parametrize("use", ["displacement", "mix amount"])
def test_a_point_mapped_texture_where_lookups_take_uv_is_one_line(tmp_path, use):
    """A planar-mapped texture as a bump map (pbrt's displacement) or as a mix material's amount (both
    looked up by uv alone in the kernels): one line naming the material and the use."""
    png = _ramp_png(tmp_path)
    tex = f'Texture "t" "float" "imagemap" "string filename" "{png.name}" "string mapping" "planar"\n'
    if use == "displacement":
        mat = 'Material "diffuse" "texture displacement" "t"'
        what = "normal or bump map"
    else:
        mat = ('MakeNamedMaterial "a" "string type" "diffuse"\nMakeNamedMaterial "b" "string type" "conductor"\n'
               'Material "mix" "string materials" ["a" "b"] "texture amount" "t"')
        what = "blend weight"
    path = tmp_path / "bad.pbrt"
    path.write_text(CAMERA + tex + mat + '\nShape "sphere"\n')
    with pytest.raises(UserError) as caught:
        scene, _ = harness.load_warned(path)
        rt.render_full(scene, device="cpu", spp=1, width=8, height=8)
    message = str(caught.value)
    assert "\n" not in message and "planar texture" in message and what in message, message


def _rotation(degrees, axis) -> np.ndarray:
    """pbrt's Rotate: by ``degrees`` about ``axis``, counter-clockwise looking down it (Rodrigues)."""
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    t = np.radians(degrees)
    cross = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.cos(t) * np.eye(3) + np.sin(t) * cross + (1 - np.cos(t)) * np.outer(a, a)
    return m


@pytest.mark.parametrize("mapping", ["planar", "spherical", "cylindrical"])
def test_pbrt_mapping_frames_are_the_inverse_of_the_texture_transform(tmp_path, mapping):
    """The loader's frame against one made here from the file's numbers: the inverse of Translate,
    Rotate, Scale in effect at the Texture directive (a camera with pbrt's `Scale -1 1 1`, which our
    world does not mirror), planar's rows v1 and v2 of it plus udelta and vdelta."""
    text = ('Scale -1 1 1\nLookAt 0 0 -5  0 0 0  0 1 0\nCamera "perspective"\nWorldBegin\nAttributeBegin\n'
            'Translate 0.3 -0.2 0.1\nRotate 35 1 1 0\nScale 1.5 0.8 1.2\n'
            f'Texture "t" "spectrum" "checkerboard" "string mapping" "{mapping}" '
            '"vector3 v1" [0.4 0.1 0.2] "vector3 v2" [-0.1 0.3 0.1] "float udelta" 0.2 "float vdelta" -0.1\n'
            'AttributeEnd\nMaterial "diffuse" "texture reflectance" "t"\n'
            'Shape "trianglemesh" "point3 P" [-1 -1 0  1 -1 0  1 1 0] "integer indices" [0 1 2]\n')
    if mapping != "planar":  # (pbrt reads v1, v2, udelta, vdelta for planar alone)
        text = text.replace('"vector3 v1" [0.4 0.1 0.2] "vector3 v2" [-0.1 0.3 0.1] "float udelta" 0.2 '
                            '"float vdelta" -0.1', "")
    path = tmp_path / "f.pbrt"
    path.write_text(text)
    scene, _ = harness.load_warned(path)
    translate = np.eye(4)
    translate[:3, 3] = (0.3, -0.2, 0.1)
    to_world = translate @ _rotation(35, (1, 1, 0)) @ np.diag([1.5, 0.8, 1.2, 1.0])
    want = np.linalg.inv(to_world)[:3]
    if mapping == "planar":
        want = np.stack([np.array([0.4, 0.1, 0.2]) @ want, np.array([-0.1, 0.3, 0.1]) @ want, np.zeros(4)])
        want[:2, 3] += (0.2, -0.1)
    tex = scene.materials[0].base_texture
    assert tex.mapping == mapping and np.allclose(np.reshape(tex.frame, (3, 4)), want, atol=1e-9)
