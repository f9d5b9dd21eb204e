"""Textures and UVs (cl/scene/textures.h, pyopencl_rt/scene/textures.py) and the glTF / OBJ loaders that
bring them in (pyopencl_rt/scene/loaders/)."""
import json
import math
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt import load_scene
from pyopencl_rt.device import abi
from pyopencl_rt.render.api import render_full
from pyopencl_rt.scene.model import Camera, Material, RenderSettings, Scene
from pyopencl_rt.scene.textures import bilinear, lookup, pack_textures, srgb_to_linear, texture_from_array

import harness
from pyopencl_rt.scene.shapes.sphere import records as sphere_records

ROOT = Path(__file__).resolve().parents[2]

HARNESS = harness.Kernels(r"""
#include "scene/textures.h"
__kernel void h_tex(__global const Texture *textures, __global const float4 *data, __global const int *index,
                    __global const float2 *uv, __global float4 *out)
{
    const int i = get_global_id(0);
    out[i] = tex_sample(textures, data, index[i], uv[i]);
}
""")


def tex_lookup(runtime, textures, index, uv):
    table, data = pack_textures(textures)
    uv = np.ascontiguousarray(uv, np.float32)
    index = np.ascontiguousarray(np.broadcast_to(np.asarray(index, np.int32), (len(uv),)))
    return HARNESS(runtime, "h_tex", len(uv), table, data, index, uv, (len(uv), 4))


# ----------------------------------------------------------------------------- lookups
def test_bilinear_matches_reference(runtime, rng):
    """Bilinear, wrap-addressed lookups of a non-square, a 1x1 and a 1xN texture (packed
    together, so offsets matter) match the float64 reference, for uv inside [0, 1), outside it
    (wrap) and at texel centres and edges."""
    texs = [texture_from_array(rng.random((5, 7, 4)).astype(np.float32)),
            texture_from_array(np.array([[[0.25, 0.5, 0.75, 1.0]]], np.float32)),
            texture_from_array(rng.random((1, 9, 3)).astype(np.float32))]
    for i, t in enumerate(texs):
        uv = np.concatenate([rng.uniform(0, 1, (2000, 2)), rng.uniform(-5, 5, (2000, 2)),
                             (np.stack(np.meshgrid(np.arange(8) / 7, np.arange(6) / 5), -1).reshape(-1, 2))])
        got = tex_lookup(runtime, texs, i, uv)
        want = bilinear(t.texels, uv.astype(np.float32))
        assert np.abs(got - want).max() < 2e-5, f"texture {i}: max error {np.abs(got - want).max()}"
    # exact texel centres return the texels
    t = texs[0]
    y, x = np.indices((5, 7))
    uv = np.stack([(x + 0.5) / 7, (y + 0.5) / 5], -1).reshape(-1, 2)
    got = tex_lookup(runtime, texs, 0, uv)
    assert np.abs(got - t.texels.reshape(-1, 4)).max() < 2e-5
    # non-finite uv reads (0, 0)
    got = tex_lookup(runtime, texs, 0, np.array([[np.nan, np.inf]], np.float32))
    assert np.all(np.isfinite(got))


def test_wrap_filter_and_to_uv_match_reference(runtime, rng):
    """Every wrap mode (repeat, mirror, clamp) with either filter (bilinear, nearest) and an affine
    to_uv, on textures that share one image (packed once), matches the float64 reference for uv
    inside, outside and far outside [0, 1)."""
    base = texture_from_array(rng.random((5, 7, 4)).astype(np.float32))
    to_uv = (2.0, 0.3, -0.5, -0.2, 1.5, 0.25)
    texs = [base.with_lookup(wrap=w, filter=f, to_uv=to_uv) for w in ("repeat", "mirror", "clamp")
            for f in ("bilinear", "nearest")]
    table, data = pack_textures(texs)
    assert len(data) == 5 * 7 * 4 and np.all(table["offset"] == 0)  # one copy of the texels
    uv = np.concatenate([rng.uniform(0, 1, (1500, 2)), rng.uniform(-4, 4, (1500, 2)),
                         rng.uniform(-300, 300, (300, 2))]).astype(np.float32)
    for i, t in enumerate(texs):
        got = tex_lookup(runtime, texs, i, uv)
        want = lookup(t.texels, uv, t.wrap, t.filter, t.to_uv)
        err = np.abs(got - want).max(axis=1)
        # nearest: a coordinate within rounding of a texel edge may land on either side
        bad = err > (2e-4 if np.abs(uv).max() > 10 else 2e-5)
        assert bad.mean() < (0.002 if t.filter == "nearest" else 0.0005), (t.wrap, t.filter, err.max())


LANES = r"""
#include "scene/textures.h"
/* items i * PACKET_WIDTH .. + PACKET_WIDTH in the lanes of work-item i: texture index[k] at uv[k]
 * in the lanes where on[k]; out: tex_sample_lanes' RGB, then tex_sample's RGBA (one lookup) */
__kernel void h_tex_lanes(__global const Texture *textures, __global const float4 *data, __global const int *index,
                          __global const float2 *uv, __global const int *on, __global float *out)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    pint ti = PINT(0), live = PINT(0);
    pfloat u, v;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        PLANE_I(ti, k) = index[base + k];
        PLANE(u, k) = uv[base + k].x;
        PLANE(v, k) = uv[base + k].y;
        PLANE_I(live, k) = on[base + k] ? -1 : 0;
    }
    const TexHit h = {u, v, pv3_zero(), pv3_zero()};
    const pvec3 c = tex_sample_lanes(textures, data, ti, &h, live);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const float4 one = tex_sample(textures, data, index[base + k], uv[base + k]);
        vstore3(pv3_lane(c, k), 0, out + 7 * (base + k));
        vstore4(one, 0, out + 7 * (base + k) + 3);
    }
}
"""


@pytest.mark.parametrize("width", [8, 16])
def test_lanes_lookup_is_the_one_lookup(runtime, rng, width):
    """tex_sample_lanes (texture_material's lookup over the lanes, a texture at a time) gives in
    every lane of `on` the bits of tex_sample (the one lookup, which the reference tests above
    check), and 0 in the others: lanes reading different textures of every wrap mode and filter,
    with an affine to_uv, inside, outside and far outside [0, 1), and non-finite uv."""
    base = texture_from_array(rng.random((5, 7, 4)).astype(np.float32))
    texs = [base.with_lookup(wrap=w, filter=f, to_uv=(2.0, 0.3, -0.5, -0.2, 1.5, 0.25))
            for w in ("repeat", "mirror", "clamp") for f in ("bilinear", "nearest")]
    texs.append(texture_from_array(rng.random((3, 11, 4)).astype(np.float32)))
    table, data = pack_textures(texs)
    n = 64 * width
    uv = np.concatenate([rng.uniform(0, 1, (n // 2, 2)), rng.uniform(-4, 4, (n // 4, 2)),
                         rng.uniform(-300, 300, (n // 4, 2))]).astype(np.float32)
    uv[::97] = np.nan
    uv[1::89, 0] = np.inf
    # runs of one texture (the usual packet) and lanes of mixed textures
    index = np.where(np.arange(n) < n // 2, (np.arange(n) // width) % len(texs),
                     rng.integers(0, len(texs), n)).astype(np.int32)
    on = (rng.random(n) < 0.8).astype(np.int32)
    wide = harness.Kernels(LANES, defines={"PACKET_WIDTH": width}, local_size=16)
    out = wide(runtime, "h_tex_lanes", n // width, table, data, index, uv, on, (n, 7))
    lanes, one = out[:, :3], out[:, 3:6]
    assert np.all(np.isfinite(one))
    live = on.astype(bool)
    assert np.array_equal(lanes[live].view(np.uint32), one[live].view(np.uint32))
    assert np.all(lanes[~live] == 0)


def test_wrap_modes_closed_form():
    """The reference's wrap modes on a 1 x 4 ramp (texel x holds x), Dr.Jit's definitions: mirror
    repeats the edge texel once at each border, clamp continues it, repeat tiles; bilinear halfway
    between two texel centres averages them, nearest takes the texel holding the coordinate."""
    ramp = np.arange(4, dtype=np.float64).reshape(1, 4, 1)
    u = np.array([-0.125, 0.0625, 0.9375, 1.125, 1.375, -0.375])  # texel coordinates -0.5, 0.25, 3.75, 4.5, 5.5, -1.5
    uv = np.stack([u, np.full_like(u, 0.5)], -1)
    near = {w: lookup(ramp, uv, w, "nearest")[:, 0] for w in ("repeat", "mirror", "clamp")}
    assert list(near["repeat"]) == [3, 0, 3, 0, 1, 2]
    assert list(near["mirror"]) == [0, 0, 3, 3, 2, 1]
    assert list(near["clamp"]) == [0, 0, 3, 3, 3, 0]
    # bilinear at u = 0 (texel coordinate -0.5: halfway between texel -1 and 0) and u = 1
    at = np.array([[0.0, 0.5], [1.0, 0.5]])
    assert list(lookup(ramp, at, "repeat")[:, 0]) == [1.5, 1.5]
    assert list(lookup(ramp, at, "mirror")[:, 0]) == [0.0, 3.0]
    assert list(lookup(ramp, at, "clamp")[:, 0]) == [0.0, 3.0]
    # to_uv: u' = 2 u - 0.5, so u = 0.25 reads u' = 0 (bilinear, repeat: texels 3 and 0)
    assert lookup(ramp, [[0.25, 0.5]], to_uv=(2, 0, -0.5, 0, 1, 0))[0, 0] == 1.5


def test_srgb_decode():
    x = np.array([0, 0.02, 0.04045, 0.5, 1.0])
    want = [0, 0.02 / 12.92, 0.04045 / 12.92, ((0.5 + 0.055) / 1.055) ** 2.4, 1.0]
    assert np.allclose(srgb_to_linear(x), want, rtol=1e-12, atol=0)
    t = texture_from_array(np.array([[[0, 128, 255]]], np.uint8), srgb=True)
    assert np.allclose(t.texels[0, 0, :3], srgb_to_linear(np.array([0, 128, 255]) / 255.0), atol=1e-7)
    assert t.texels[0, 0, 3] == 1.0 and t.srgb
    g = texture_from_array(np.array([[7, 9]], np.uint16))  # grey 16-bit: linear, replicated
    assert np.allclose(g.texels[0, 1, :3], 9 / 65535) and g.channels == 1


# ----------------------------------------------------------------------------- rendering
def checker_plane_scene(rho, sky, tex, uv_scale=1.0, max_depth=3):
    v = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
    f = np.array([[0, 2, 1], [0, 3, 2]], np.int32)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)[f] * uv_scale
    return Scene(vertices=v, faces=f, face_materials=np.zeros(2, np.int32),
                 materials=[Material("plane", albedo=(1, 1, 1), base_texture=tex),
                            Material("sky", albedo=(0, 0, 0), emission=(sky,) * 3, two_sided=True)],
                 camera=Camera(eye=(0, 2, 0), look_at=(0, 0, 0.001), up=(0, 0, 1), fov=45),
                 shapes=sphere_records(np.array([[0, 0, 0, 1000]], np.float32)), shape_materials=np.array([1], np.int32),
                 settings=RenderSettings(width=32, height=32, max_depth=max_depth), uvs=uv)


def test_textured_plane_under_uniform_sky(device):
    """A diffuse plane whose albedo texture is a 2x2 checker of rho_a / rho_b (16x16 texels per
    cell, no filtering inside a cell) under a uniform sky L renders rho(u, v) L: the means of
    pixel blocks well inside each cell agree within 3 standard errors (+ float floor)."""
    ra, rb, sky = 0.2, 0.7, 2.0
    cells = np.where((np.indices((32, 32)) // 16).sum(0) % 2 == 0, ra, rb).astype(np.float32)
    tex = texture_from_array(np.repeat(cells[:, :, None], 3, 2))
    sc = checker_plane_scene(ra, sky, tex)
    for integrator in ("path", "nee"):
        r = render_full(sc, spp=32, device=device, seed=11, integrator=integrator)
        assert r.info["nonfinite_samples"] == 0
        img = r.image.astype(np.float64)
        # the plane spans x, z in [-1, 1]; u runs with x, v with z.  The camera looks down -y with
        # up = +z; find each pixel's (u, v) by projecting the pixel centres onto the plane.
        h, w = img.shape[:2]
        tan = math.tan(math.radians(45) / 2)
        px = ((np.arange(w) + 0.5) / w * 2 - 1) * tan * 2  # image x -> world
        pz = (1 - (np.arange(h) + 0.5) / h * 2) * tan * 2
        X, Z = np.meshgrid(px, pz)
        # camera right = forward x up = (0,-1,0) x (0,0,1) = (-1, 0, 0)
        X = -X
        u, v = (X + 1) / 2, (Z + 1) / 2
        inside = (np.abs(X) < 0.95) & (np.abs(Z) < 0.95)
        for cu in (0, 1):
            for cv in (0, 1):
                # texel rows are v, columns u; cell (row, col) = (cv, cu)
                rho = ra if (cu + cv) % 2 == 0 else rb
                sel = inside & (np.abs(u - (cu * 0.5 + 0.25)) < 0.17) & (np.abs(v - (cv * 0.5 + 0.25)) < 0.17)
                vals = img[sel].mean(axis=-1)  # a pixel's channels are one sample's, not three samples
                assert len(vals) > 20
                m, se = vals.mean(), vals.std() / math.sqrt(len(vals))
                assert abs(m - rho * sky) <= 3 * se + 2e-5 * rho * sky, (integrator, cu, cv, m, rho * sky, se)


def test_textured_emitter_nee_matches_bsdf(device):
    """A striped emission texture on a quad light over a diffuse floor: light sampling (which
    applies the texture at the sampled point) and BSDF sampling agree (tile z-tests)."""
    stripes = np.where((np.arange(8) // 2) % 2 == 0, 1.0, 0.1).astype(np.float32)
    tex = texture_from_array(np.repeat(np.tile(stripes, (8, 1))[:, :, None], 3, 2))
    v = np.array([[-3, 0, -3], [3, 0, -3], [3, 0, 3], [-3, 0, 3],
                  [-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5]], np.float32)
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7]], np.int32)
    uvq = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    uv = np.concatenate([uvq[[[0, 2, 1], [0, 3, 2]]], uvq[[[0, 1, 2], [0, 2, 3]]]])
    sc = Scene(vertices=v, faces=f, face_materials=np.array([0, 0, 1, 1], np.int32),
               materials=[Material("floor", albedo=(0.5,) * 3),
                          Material("lamp", albedo=(0, 0, 0), emission=(4,) * 3, emission_texture=tex)],
               camera=Camera(eye=(0, 3, 3), look_at=(0, 0, 0), fov=50),
               settings=RenderSettings(width=16, height=16, max_depth=2), uvs=uv)
    res = {}
    for i, integ in enumerate(("bsdf", "nee", "path")):
        r = render_full(sc, spp=128, device=device, seed=5 + i, integrator=integ)
        assert r.info["nonfinite_samples"] == 0
        var = r.film.variance_of_mean()
        m = r.image.astype(np.float64).reshape(4, 4, 4, 4, 3).mean(axis=(1, 3))
        vv = var.reshape(4, 4, 4, 4, 3).sum(axis=(1, 3)) / 16 ** 2
        res[integ] = (m, vv)
    for a, b in (("bsdf", "nee"), ("path", "nee")):
        (ma, va), (mb, vb) = res[a], res[b]
        z = (ma - mb) / np.sqrt(va + vb + 1e-12)
        assert np.abs(z).max() < 4.5, (a, b, np.abs(z).max())


# ----------------------------------------------------------------------------- glTF
def _pil(a):
    from PIL import Image

    return Image.fromarray(np.asarray(a, np.uint8))


def add_material_extensions(path, by_name):
    data = Path(path).read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    tree = json.loads(data[20:20 + jlen])
    rest = data[20 + jlen:]
    for m in tree.get("materials", []):
        if m.get("name") in by_name:
            m.setdefault("extensions", {}).update(by_name[m["name"]])
    j = json.dumps(tree).encode()
    j += b" " * (-len(j) % 4)
    body = struct.pack("<II", len(j), 0x4E4F534A) + j + rest
    Path(path).write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)


def write_test_glb(path, camera=True):
    import trimesh
    from trimesh.visual import TextureVisuals
    from trimesh.visual.material import PBRMaterial

    tex = _pil(np.full((4, 4, 3), 128))
    quad = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], faces=[[0, 1, 2], [0, 2, 3]],
                           process=False)
    quad.visual = TextureVisuals(uv=np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float), material=PBRMaterial(
        name="paint", baseColorFactor=[255, 128, 0, 255], metallicFactor=0.25, roughnessFactor=0.5,
        baseColorTexture=tex, metallicRoughnessTexture=_pil(np.full((2, 2, 3), 255))))
    lamp = trimesh.Trimesh(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]], process=False)
    lamp.visual = TextureVisuals(uv=np.zeros((3, 2)), material=PBRMaterial(
        name="lamp", emissiveFactor=[1.0, 0.5, 0.25], metallicFactor=0.0))
    glass = trimesh.Trimesh(vertices=[[0, 0, 1], [1, 0, 1], [0, 1, 1]], faces=[[0, 1, 2]], process=False)
    glass.visual = TextureVisuals(uv=np.zeros((3, 2)), material=PBRMaterial(name="glass", metallicFactor=0.0,
                                                                          roughnessFactor=0.0))
    sc = trimesh.Scene()
    sc.add_geometry(quad, node_name="quad", transform=trimesh.transformations.translation_matrix([2, 0, 0]))
    T = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 0, 1]) @ trimesh.transformations.scale_matrix(2)
    sc.add_geometry(lamp, node_name="lamp", transform=trimesh.transformations.translation_matrix([0, 0, -3]) @ T)
    sc.add_geometry(glass, node_name="glass")
    if camera:
        sc.camera = trimesh.scene.Camera(resolution=(64, 48), fov=(50 * 64 / 48, 50))
        sc.camera_transform = trimesh.transformations.translation_matrix([0.5, 0.5, 6])
    sc.export(path)
    add_material_extensions(path, {
        "lamp": {"KHR_materials_emissive_strength": {"emissiveStrength": 8.0}},
        "glass": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.33}}})
    return path


def test_gltf_import(tmp_path):
    p = write_test_glb(tmp_path / "t.glb")
    sc = load_scene(p)
    mats = {m.name: m for m in sc.materials}
    assert set(mats) == {"paint", "lamp", "glass"}
    paint, lamp, glass = mats["paint"], mats["lamp"], mats["glass"]
    assert paint.type == "gltf" and np.allclose(paint.albedo, (1, 128 / 255, 0), atol=1e-6)
    assert paint.metallic == pytest.approx(0.25) and paint.alpha == pytest.approx(0.25)
    assert paint.base_texture is not None and paint.base_texture.srgb
    assert np.allclose(paint.base_texture.texels[..., :3], srgb_to_linear(128 / 255), atol=1e-6)
    assert paint.mr_texture is not None and not paint.mr_texture.srgb
    assert np.allclose(lamp.emission, (8, 4, 2))
    assert glass.type == "dielectric" and glass.ior == pytest.approx(1.33) and glass.alpha == 0
    # world positions: node transforms applied
    for m_name, want in (("paint", [[2, 0, 0], [3, 0, 0], [3, 1, 0], [2, 1, 0]]),
                         ("lamp", [[0, 0, -3], [0, 2, -3], [-2, 0, -3]])):
        k = sc.materials.index(mats[m_name])
        used = np.unique(sc.faces[sc.face_materials == k])
        got = sc.vertices[used]
        for w in want:
            assert np.min(np.linalg.norm(got - np.array(w), axis=1)) < 1e-5, (m_name, w, got)
    # UVs: the quad's corners
    k = sc.materials.index(paint)
    fi = np.nonzero(sc.face_materials == k)[0]
    corners = sc.vertices[sc.faces[fi]].reshape(-1, 3)
    uvs = sc.uvs[fi].reshape(-1, 2)
    assert np.allclose(uvs[:, 0], corners[:, 0] - 2, atol=1e-6)
    # camera
    assert sc.camera.fov == pytest.approx(50, abs=1e-4)
    assert np.allclose(sc.camera.eye, (0.5, 0.5, 6)) and np.allclose(sc.camera.look_at, (0.5, 0.5, 5))
    assert sc.settings.width == round(sc.settings.height * 64 / 48)
    recs = sc.material_records()
    assert recs["tex_base"][k] >= 0 and recs["tex_mr"][k] >= 0 and recs["tex_emission"][k] == -1
    assert sc.material_defines().get("HAS_TEXTURES")


def _edit_glb(path, edit):
    data = Path(path).read_bytes()
    jlen = struct.unpack_from("<I", data, 12)[0]
    tree = json.loads(data[20:20 + jlen])
    edit(tree)
    j = json.dumps(tree).encode()
    j += b" " * (-len(j) % 4)
    body = struct.pack("<II", len(j), 0x4E4F534A) + j + data[20 + jlen:]
    Path(path).write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)


def test_gltf_samplers_and_texture_transform(tmp_path):
    """A glTF sampler's wrapS (MIRRORED_REPEAT) and magFilter (NEAREST) and KHR_texture_transform
    (offset, rotation, scale: translation x rotation x scale, the extension's matrix) become the
    texture's lookup; the metallic-roughness texture, without them, keeps the defaults."""
    p = write_test_glb(tmp_path / "t.glb")

    def edit(tree):
        paint = next(m for m in tree["materials"] if m.get("name") == "paint")
        info = paint["pbrMetallicRoughness"]["baseColorTexture"]
        info["extensions"] = {"KHR_texture_transform": {"offset": [0.25, -0.5], "rotation": 0.3, "scale": [2, 3]}}
        tree["samplers"] = [{"wrapS": 33648, "wrapT": 33648, "magFilter": 9728}]
        tree["textures"][info["index"]]["sampler"] = 0
        tree.setdefault("extensionsUsed", []).append("KHR_texture_transform")

    _edit_glb(p, edit)
    with __import__("warnings").catch_warnings():
        __import__("warnings").simplefilter("error")
        paint = next(m for m in load_scene(p).materials if m.name == "paint")
    t = paint.base_texture
    c, s_ = math.cos(0.3), math.sin(0.3)
    assert (t.wrap, t.filter) == ("mirror", "nearest")
    assert np.allclose(t.to_uv, (2 * c, 3 * s_, 0.25, -2 * s_, 3 * c, -0.5))
    m = np.array([[1, 0, 0.25], [0, 1, -0.5], [0, 0, 1]]) @ np.array([[c, s_, 0], [-s_, c, 0], [0, 0, 1]]) \
        @ np.diag([2, 3, 1])
    assert np.allclose(t.to_uv, m[:2].reshape(-1))
    assert (paint.mr_texture.wrap, paint.mr_texture.filter, paint.mr_texture.to_uv) == ("repeat", "bilinear",
                                                                                       (1, 0, 0, 0, 1, 0))


def test_toml_texture_tables_and_opacity(tmp_path):
    """TOML: a texture key takes a path or a table {file, wrap, filter, scale, offset, rotation}
    (the lookup's coordinates offset + R(rotation) (scale uv)); opacity / opacity_texture make an
    alpha cut-out (the texture's luminance, linear); unknown table keys are one-line errors."""
    from PIL import Image

    from pyopencl_rt.errors import UserError

    Image.fromarray(np.array([[0, 255], [255, 128]], np.uint8)).save(tmp_path / "a.png")
    head = harness.toml_tables(camera=dict(eye=[0, 0, 3], look_at=[0, 0, 0]))
    shape = '[[shape]]\ntype = "quad"\nmaterial = "m"\npoints = [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]\n'
    (tmp_path / "s.toml").write_text(head + '[materials.m]\nalbedo_texture = { file = "a.png", wrap = "clamp", '
                                     'filter = "nearest", scale = [2, 4], offset = [0.5, 0], rotation = 90 }\n'
                                     'opacity = 0.75\nopacity_texture = "a.png"\n' + shape)
    m = load_scene(tmp_path / "s.toml").materials[0]
    t = m.base_texture
    assert (t.wrap, t.filter) == ("clamp", "nearest") and np.allclose(t.to_uv, (0, -4, 0.5, 2, 0, 0), atol=1e-12)
    assert m.masked and m.opacity == 0.75
    o = m.scalar_textures["opacity"].texels[..., 0]
    assert np.allclose(o, [[0, 1], [1, 128 / 255]])  # linear data
    rec = m.record({id(t): 0, id(m.scalar_textures["opacity"]): 1})
    assert rec["flags"] & abi.MATERIAL_FLAG_MASK and rec["opacity"] == 0.75 and rec["tex_scalar"][0] == 1
    (tmp_path / "bad.toml").write_text(head + '[materials.m]\nalbedo_texture = { file = "a.png", warp = "clamp" }\n'
                                       + shape)
    with pytest.raises(UserError, match="unknown keys warp"):
        load_scene(tmp_path / "bad.toml")


def test_gltf_without_camera_is_framed(tmp_path):
    sc = load_scene(write_test_glb(tmp_path / "t.glb", camera=False))
    lo, hi = sc.vertices.min(0), sc.vertices.max(0)
    assert np.allclose(sc.camera.look_at, (lo + hi) / 2, atol=1e-5)


def test_obj_map_kd(tmp_path):
    from PIL import Image

    Image.fromarray(np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)).save(tmp_path / "c.png")
    (tmp_path / "m.mtl").write_text("newmtl tex\nKd 1 1 1\nmap_Kd -s 1 1 1 c.png\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                                    "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl tex\nf 1/1 2/2 3/3 4/4\n")
    sc = load_scene(tmp_path / "m.obj")
    m = sc.materials[0]
    assert m.base_texture is not None and m.base_texture.width == 2 and m.base_texture.srgb
    assert np.allclose(m.base_texture.texels[0, 0, :3], (1, 0, 0))
    # vt's v points up; flipped to the image's top-down convention
    assert np.allclose(sc.uvs[0], [[0, 1], [1, 1], [1, 0]])
    assert np.allclose(sc.uvs[1], [[0, 1], [1, 0], [0, 0]])


def test_toml_references_gltf_and_overrides(tmp_path):
    write_test_glb(tmp_path / "t.glb")
    (tmp_path / "s.toml").write_text(
        '[materials.lamp]\nemission = 3\n'
        '[[shape]]\ntype = "mesh"\nfile = "t.glb"\nuse_file_materials = true\ntranslate = [0, 1, 0]\n')
    sc = load_scene(tmp_path / "s.toml")
    names = {m.name: m for m in sc.materials}
    assert names["lamp"].emission == (3.0, 3.0, 3.0) and names["lamp"].type == "diffuse"
    assert names["paint"].base_texture is not None
    assert sc.uvs is not None and sc.uvs.shape == (len(sc.faces), 3, 2)


def test_cli_renders_glb(tmp_path):
    write_test_glb(tmp_path / "t.glb")
    out = subprocess.run([sys.executable, "-m", "pyopencl_rt.cli", "render", str(tmp_path / "t.glb"), "--spp", "2",
                          "--width", "16", "--height", "12", "-o", str(tmp_path / "o.exr")],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "o.exr").exists()


def test_textured_scene_renders(device):
    sc = load_scene(ROOT / "scenes" / "textured.toml")
    assert sc.has_textures()
    r = render_full(sc, spp=4, device=device, seed=1, width=40, height=30)
    assert r.info["nonfinite_samples"] == 0
    assert np.isfinite(r.image).all() and r.image.mean() > 0


def test_gltf_alpha_modes_are_intersection_cutouts(tmp_path):
    """glTF alphaMode MASK (alphaCutoff, default 0.5) and BLEND become cut-outs in the intersection
    (Material.cutout; BLEND stochastic, as pbrt-v4's alpha): alpha = baseColorFactor's alpha times
    the base texture's (an RGB texture has none); OPAQUE, and a MASK every texel passes, stay opaque."""
    p = write_test_glb(tmp_path / "t.glb")

    def edit(tree):
        for m in tree["materials"]:
            if m.get("name") == "paint":
                m["alphaMode"], m["alphaCutoff"] = "MASK", 0.5
                m["pbrMetallicRoughness"]["baseColorFactor"][3] = 0.4
            if m.get("name") == "glass":
                m["alphaMode"], m["alphaCutoff"] = "MASK", 0.3  # alpha 1 everywhere: every texel passes
            if m.get("name") == "lamp":
                m["alphaMode"] = "BLEND"
                m.setdefault("pbrMetallicRoughness", {})["baseColorFactor"] = [1, 1, 1, 0.6]

    _edit_glb(p, edit)
    mats = {m.name: m for m in load_scene(p).materials}
    paint, lamp, glass = mats["paint"], mats["lamp"], mats["glass"]
    assert paint.cutout and paint.alpha_cutoff == pytest.approx(0.5) and paint.opacity == pytest.approx(0.4)
    assert lamp.cutout and lamp.alpha_cutoff == 0.0 and lamp.opacity == pytest.approx(0.6)
    assert not glass.cutout
    rec = paint.record()
    assert rec["flags"] & abi.MATERIAL_FLAG_CUTOUT and rec["alpha_cutoff"] == pytest.approx(0.5)
