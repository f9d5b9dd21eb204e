"""pbrt-v4 materials, textures and spectra as ours (docs/SCENE_FORMAT.md, "pbrt-v4").

| pbrt-v4 | ours |
|---|---|
| ``diffuse`` | ``diffuse``: ``reflectance`` (default 0.5; an ``imagemap`` texture as its texture) |
| ``conductor`` | ``conductor``: ``eta``/``k`` (the named spectra ``metal-Au/Ag/Cu/Al/MgO/TiO2-eta/k`` as Mitsuba's conductors of those names; RGB as given; sampled spectra and ``.spd`` files: :func:`pbrt_spectra.sampled_rgb`) or ``reflectance`` (as F0, Schlick); default copper |
| ``dielectric`` (``thindielectric`` with a warning) | ``dielectric``: ``eta`` (default 1.5; the named glasses at their d-line index) |
| ``coateddiffuse`` | ``plastic`` (smooth coat) or ``roughplastic`` (GGX coat), ``nonlinear``: base ``reflectance``, IOR ``eta``, the coating's roughness (the layer's absorption aside: docs/SCENE_FORMAT.md) |
| ``coatedconductor`` | ``coatedconductor`` (pbrt-v4's layered BSDF, its random walk): ``interface.eta`` and ``interface.*roughness``, ``conductor.eta``/``conductor.k`` (or ``reflectance``) and ``conductor.*roughness``, ``thickness``, ``maxdepth``, ``nsamples``, ``albedo`` and ``g`` (a scattering coating) |
| ``interface`` (and ``""``, ``none``: pbrt-v4's old names) | no surface: its shapes only bound media (index-matched: pbrt_media.py) |
| ``mix`` | ``mix`` of the two named ``materials``, weight ``amount`` (a float or a texture; 1 is the second) |
| ``diffusetransmission`` | ``diffusetransmission``: ``reflectance`` (a texture too), ``transmittance`` (0.25 each), ``scale``; a transmittance texture is an error |
| others (``hair``, ``measured``, ``subsurface``) | an error naming the type (never replaced) |

Roughness: ``roughness``, or ``uroughness`` and ``vroughness`` (anisotropic where the material is;
a coating's mean, with a warning when they differ), becomes GGX alpha = sqrt(roughness) when
``remaproughness`` is true (the default), as pbrt-v4's ``TrowbridgeReitzDistribution::RoughnessToAlpha``,
else alpha = roughness.  A float texture of a conductor's, dielectric's or coateddiffuse's roughness
is remapped texel by texel into the material's textured alpha (``scalar_textures``).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..model import Material
from .builder import error_at
from .pbrt import MissingFile, pbrt_file, pbrt_path
from .pbrt_spectra import spectrum_file, spectrum_rgb

# pbrt-v4's named metal spectra (metal-X-eta, metal-X-k) by Mitsuba's conductor of the same
# measurement (mitsuba_metals.py: its spectra made RGB as Mitsuba's RGB variants make them);
# pbrt's brass (metal-CuZn) has no counterpart there and is refused
METALS = {"Au": "Au", "Ag": "Ag", "Cu": "Cu", "Al": "Al", "MgO": "MgO", "TiO2": "TiO2"}
GLASSES = {"glass-BK7": 1.5168, "glass-BAF10": 1.6700, "glass-FK51A": 1.4866, "glass-LASF9": 1.8503,
           "glass-F5": 1.6727, "glass-F10": 1.7283, "glass-F11": 1.7847}  # F5, F10, F11: Schott SF5, SF10, SF11


def equal_area_square_to_sphere(u, v):
    """pbrt-v4's equal-area octahedral map (Clarberg 2008): (u, v) in [0, 1]^2 to directions."""
    u, v = 2 * np.asarray(u, np.float64) - 1, 2 * np.asarray(v, np.float64) - 1
    up, vp = np.abs(u), np.abs(v)
    signed = 1 - (up + vp)
    r = 1 - np.abs(signed)
    with np.errstate(invalid="ignore", divide="ignore"):
        phi = np.where(r == 0, 1.0, (vp - up) / np.where(r == 0, 1.0, r) + 1) * np.pi / 4
    z = np.copysign(1 - r * r, signed)
    cos_phi, sin_phi = np.copysign(np.cos(phi), u), np.copysign(np.sin(phi), v)
    s = r * np.sqrt(np.maximum(2 - r * r, 0.0))
    return np.stack([cos_phi * s, sin_phi * s, z], -1)


def equal_area_sphere_to_square(d):
    """The inverse: unit directions (N, 3) to (u, v) in [0, 1]^2."""
    d = np.asarray(d, np.float64)
    x, y, z = np.abs(d[:, 0]), np.abs(d[:, 1]), np.abs(d[:, 2])
    r = np.sqrt(np.maximum(1 - z, 0.0))
    a, b = np.maximum(x, y), np.minimum(x, y)
    with np.errstate(invalid="ignore", divide="ignore"):
        b = np.where(a == 0, 0.0, b / np.where(a == 0, 1.0, a))
    phi = np.arctan(b) * 2 / np.pi
    phi = np.where(x < y, 1 - phi, phi)
    v = phi * r
    u = r - v
    neg = d[:, 2] < 0
    u, v = np.where(neg, 1 - v, u), np.where(neg, 1 - u, v)
    u, v = np.copysign(u, d[:, 0]), np.copysign(v, d[:, 1])
    return (u + 1) / 2, (v + 1) / 2


def _inverted(tex, invert: bool):
    """pbrt-v4's imagemap "invert": max(0, 1 - v) of the scaled value.  Applied to the linear
    texels, which filtering then mixes: the same as pbrt's inversion of the filtered value where the
    texels are at most 1 (above, pbrt clamps the filtered value and we each texel)."""
    if invert:
        tex.texels[..., :3] = np.maximum(0.0, 1.0 - tex.texels[..., :3])
    return tex


# pbrt-v4's roughness parameters; the materials that take them as float textures (the textured alpha of
# Material.scalar_textures; a coatedconductor its interface's, not its conductor's)
ROUGHNESS = ("roughness", "uroughness", "vroughness")
TEXTURED_ROUGHNESS = ("conductor", "dielectric", "thindielectric", "coateddiffuse")


def roughness_to_alpha(roughness, remap: bool):
    """pbrt-v4's RoughnessToAlpha (sqrt) where `remaproughness`, else the roughness, clamped to [0, 1]
    (a number or an array of texels)."""
    r = np.maximum(roughness, 0.0)
    return np.minimum(np.sqrt(r) if remap else r, 1.0)


class MaterialMapper:
    def __init__(self, importer):
        self.imp = importer
        self.named: dict[str, Material | None] = {}
        self.textures: dict[str, tuple] = {}  # name -> (rgb, Texture or None)
        self._default = None
        self._count = 0
        self._alpha_textures: dict = {}  # (id of a float texture, scale, remap) -> (it, its alpha texture)

    def default(self) -> Material:
        """pbrt-v4's material before any Material directive: diffuse, reflectance 0.5."""
        if self._default is None:
            self._default = Material(name="pbrt-default", albedo=(0.5, 0.5, 0.5))
        return self._default

    # -- textures --------------------------------------------------------------------------------

    def color(self, params, name, default):
        """(rgb, Texture or None) of a parameter that may name a texture."""
        p = params.get(name)
        if p is not None and p.type == "texture":
            tname = params.string(name, types=("texture",))
            if tname not in self.textures:
                raise error_at(p.pos, f'"texture {name}": no texture named "{tname}"')
            return self.textures[tname]
        return spectrum_rgb(self.imp, params, name, default), None

    def texture(self, d) -> None:
        tname, kind, cls = d.args
        p = d.params
        if kind not in ("spectrum", "float", "color"):
            raise error_at(d.pos, f'Texture "{tname}": the type must be "spectrum" or "float", got "{kind}"')
        if cls == "constant":
            value = self.color(p, "value", (1.0, 1.0, 1.0))
        elif cls == "imagemap":
            try:
                value = ((1.0, 1.0, 1.0), self._imagemap(d))
            except MissingFile as exc:  # the bench's probe: a grey stand-in, so the names resolve
                from . import pbrt

                if not pbrt.SKIP_MISSING_FILES:
                    raise
                pbrt.skipped_missing(exc)
                for q in p.items.values():
                    q.used = True
                value = ((0.5, 0.5, 0.5), None)
        elif cls == "checkerboard":
            value = ((1.0, 1.0, 1.0), self._checkerboard(d))
        elif cls == "scale":  # pbrt-v4's ScaleTexture: tex (default 1) times scale (default 1)
            value = self._compose(d, [self.color(p, "tex", (1.0,) * 3), self.color(p, "scale", (1.0,) * 3)],
                                  lambda t, s: t * s, floats=(1,))
        elif cls == "directionmix":
            value = self._direction_mix(d)
        elif cls == "mix":  # pbrt-v4's MixTexture: (1 - amount) tex1 + amount tex2 (0, 1, 0.5 by default)
            amount = self.color(p, "amount", (0.5,) * 3)
            value = self._compose(d, [self.color(p, "tex1", (0.0,) * 3), self.color(p, "tex2", (1.0,) * 3), amount],
                                  lambda a, b, w: (1.0 - w) * a + w * b, floats=(2,))
        else:
            raise error_at(d.pos, f'Texture "{tname}" "{cls}": texture class "{cls}" is not supported')
        self.textures[tname] = value

    def _direction_mix(self, d) -> tuple:
        """pbrt-v4's directionmix: tex1 weighted by |n . dir| (n the hit's geometric normal, dir
        (default +y) moved by the transform in effect and normalised), tex2 by the rest.  Of two
        constants it is a direction mix of two 1 x 1 images; each input keeps its mapping."""
        from ..textures import DirectionMix, Texture, texture_from_array

        p = d.params
        direction = self.imp.state.ctm[:3, :3] @ np.asarray(p.numbers("dir", ("vector3", "vector"), 3, [0.0, 1.0, 0.0]))
        if not np.linalg.norm(direction) > 0:
            raise error_at(d.pos, f'Texture "{d.args[0]}": "dir" is the zero vector')
        inputs = []
        for name, default in (("tex1", (0.0,) * 3), ("tex2", (1.0,) * 3)):
            rgb, tex = self.color(p, name, default)
            if isinstance(tex, Texture):
                if rgb != (1.0, 1.0, 1.0):  # (textures here carry their scale in the texels)
                    tex = dataclasses.replace(tex, texels=tex.texels * np.array([*rgb, 1.0], np.float32))
                inputs.append(tex)
            elif tex is None:
                inputs.append(texture_from_array(np.array([[[*rgb, 1.0]]], np.float32), name=f"{d.args[0]}.{name}"))
            else:
                raise error_at(d.pos, f'Texture "{d.args[0]}": a directionmix of a directionmix is not supported')
        return (1.0, 1.0, 1.0), DirectionMix(*inputs, direction=tuple(direction), name=d.args[0])

    def _compose(self, d, inputs, fn, floats=()) -> tuple:
        """A texture made of others by ``fn`` (pbrt-v4's scale and mix textures), as the pair
        (rgb, Texture or None) textures are here: of constants, the constant; otherwise baked
        texel by texel into an image with the lookup of the image inputs, which must share their
        size, wrap, filter and uv mapping (the first image's is used; another image is read at its
        mean, with a warning).  ``fn`` is linear in each input where the others are constant, so a
        bake with one image is exact; two images are combined texel by texel before the bilinear
        lookup (exact with point filtering).  A "float" texture, and the inputs at ``floats`` (scale's
        scale and mix's amount: float textures), read an image's first channel, as pbrt-v4's float textures do."""
        from ..textures import Texture

        tname, kind = d.args[0], d.args[1]
        images = [t for _, t in inputs if t is not None]
        if not images:
            out = fn(*(np.asarray(rgb, np.float64) for rgb, _ in inputs))
            return tuple(float(x) for x in out), None
        if any(not isinstance(t, Texture) for t in images):
            raise error_at(d.pos, f'Texture "{tname}": a directionmix inside a {d.args[2]} texture is not supported')
        base = images[0]
        lookup = base.lookup_key()
        arrays = []
        for k, (rgb, tex) in enumerate(inputs):
            grey = kind == "float" or k in floats
            if tex is None:
                value = np.asarray(rgb, np.float64)
                arrays.append(np.full(3, value[0]) if grey and kind == "float" else value)
                continue
            texels = tex.texels[..., :3].astype(np.float64)
            if grey:
                texels = np.repeat(texels[..., :1], 3, axis=-1)
            texels = texels * np.asarray(rgb, np.float64)
            if tex.lookup_key() != lookup:
                self.imp.warn(d.pos, f'Texture "{tname}": its image inputs differ in size or mapping; '
                                     f"'{tex.name}' is read at its mean")
                texels = texels.reshape(-1, 3).mean(0)
            arrays.append(texels)
        out = np.broadcast_to(fn(*arrays), base.texels.shape[:2] + (3,))
        texels = np.ones(base.texels.shape, np.float32)
        texels[..., :3] = out
        channels = 1 if kind == "float" else 3
        # (base's lookup: wrap, filter, to_uv, mapping and frame)
        return (1.0, 1.0, 1.0), dataclasses.replace(base, texels=np.ascontiguousarray(texels), srgb=False,
                                                    channels=channels, name=tname)

    def _mapping(self, d, image: bool) -> dict:
        """Texture.with_lookup's to_uv, mapping and frame for pbrt-v4's 2-D mapping of Texture ``d``
        (TextureMapping2D::Create): "uv" (s, t) = (uscale u + udelta, vscale v + vdelta) of the
        shape's uv; "planar" (udelta + v1 . x, vdelta + v2 . x), "spherical", "cylindrical" of the
        hit point x in the texture's space (the inverse of the transform in effect at the
        directive; textures.map_points).  An ``image`` is looked up at (s, 1 - t) (pbrt flips t:
        our v runs down the image as pbrt's image rows do), a checkerboard at (s / 2, t / 2)."""
        p = d.params
        mapping = p.string("mapping", "uv")
        if mapping == "uv":
            us, vs, ud, vd = (p.float(k, dflt) for k, dflt in (("uscale", 1.0), ("vscale", 1.0), ("udelta", 0.0),
                                                                ("vdelta", 0.0)))
            # the shape's uv here is (u, 1 - pbrt's v)
            return {"to_uv": (us, 0.0, ud, 0.0, vs, 1.0 - vs - vd) if image else
                    (us / 2, 0.0, ud / 2, 0.0, -vs / 2, (vs + vd) / 2)}
        if mapping not in ("planar", "spherical", "cylindrical"):
            raise error_at(p.items["mapping"].pos, f'Texture "{d.args[0]}": unknown mapping "{mapping}" (pbrt-v4 has '
                                                   "uv, spherical, cylindrical and planar)")
        ctm = self.imp.state.ctm
        if not abs(np.linalg.det(ctm[:3, :3])) > 1e-300:
            raise error_at(d.pos, f'Texture "{d.args[0]}": its transform is singular (the {mapping} mapping needs '
                                  "its inverse)")
        frame = np.linalg.inv(ctm)[:3]  # texture from world
        if mapping == "planar":
            vs = np.asarray(p.numbers("v1", ("vector3", "vector"), 3, [1.0, 0.0, 0.0]), np.float64)
            vt = np.asarray(p.numbers("v2", ("vector3", "vector"), 3, [0.0, 1.0, 0.0]), np.float64)
            rows = np.stack([vs @ frame, vt @ frame, np.zeros(4)])
            rows[:2, 3] += (p.float("udelta", 0.0), p.float("vdelta", 0.0))
            frame = rows
        to_uv = (1.0, 0.0, 0.0, 0.0, -1.0, 1.0) if image else (0.5, 0.0, 0.0, 0.0, 0.5, 0.0)
        return {"to_uv": to_uv, "mapping": mapping, "frame": tuple(frame.ravel())}

    def _imagemap(self, d):
        from ..textures import texture_from_array, texture_from_image

        p = d.params
        fname, path = pbrt_file(d, self.imp.path.parent, f'Texture "{d.args[0]}"',
                                needs=f'Texture "{d.args[0]}" "imagemap"')
        lookup = self._mapping(d, image=True)
        filt = p.string("filter", "bilinear")
        if filt not in ("point", "bilinear"):
            self.imp.warn(p.items["filter"].pos, f'Texture "{d.args[0]}": filter "{filt}": we filter bilinearly '
                                                 "(no mipmaps)")
        lookup["filter"] = "nearest" if filt == "point" else "bilinear"
        wrap = p.string("wrap", "repeat")
        if wrap not in ("repeat", "clamp"):
            self.imp.warn(p.items["wrap"].pos, f'Texture "{d.args[0]}": wrap "{wrap}": we repeat')
        lookup["wrap"] = "clamp" if wrap == "clamp" else "repeat"
        invert = bool(p.boolean("invert", False))
        encoding = p.string("encoding", "sRGB")
        s = p.float("scale", 1.0)
        where = f'{d.pos}: Texture "{d.args[0]}"'
        if path.suffix.lower() in (".exr", ".pfm"):
            from .images import read_hdr_image

            return _inverted(texture_from_array(read_hdr_image(path, where) * s, name=fname), invert).with_lookup(**lookup)
        if encoding not in ("sRGB", "linear"):
            self.imp.warn(p.items["encoding"].pos, f'Texture "{d.args[0]}": encoding "{encoding}" read as sRGB')
        try:
            tex = texture_from_image(path, srgb=encoding != "linear")
        except Exception as exc:
            raise error_at(where, f"cannot read '{fname}' ({type(exc).__name__}: {exc})") from None
        if s != 1.0:
            tex.texels[..., :3] *= s
        return _inverted(tex, invert).with_lookup(**lookup)

    def _checkerboard(self, d):
        from ..textures import texture_from_array

        p = d.params
        if p.integer("dimension", 2) != 2:
            self.imp.warn(p.items["dimension"].pos, f'Texture "{d.args[0]}": 3D checkerboards are not supported')
        c1, _ = self.color(p, "tex1", (1.0, 1.0, 1.0))
        c2, _ = self.color(p, "tex2", (0.0, 0.0, 0.0))
        # tex1 where floor(s) + floor(t) is even: a 2 x 2 image looked up nearest at (s / 2, t / 2), repeated
        img = np.array([[c1, c2], [c2, c1]], np.float32)
        return texture_from_array(img, name=d.args[0]).with_lookup(filter="nearest", **self._mapping(d, image=False))

    # -- materials -------------------------------------------------------------------------------

    def _alphas(self, p, prefix="") -> tuple:
        """(alpha along dp/du, alpha along the bitangent) of ``prefix``'s `roughness`, or of its
        `uroughness` and `vroughness` (pbrt-v4: each defaults to `roughness`, default 0), remapped
        as pbrt-v4's RoughnessToAlpha (sqrt) when `remaproughness` is true (the default).  A float
        texture's alpha is its Texture (:meth:`_alpha_texture`), the others numbers."""
        remap = p.boolean("remaproughness", True)

        def alpha(name, default):
            q = p.get(name)
            if q is not None and q.type == "texture":
                return self._alpha_texture(p, name, remap)
            return float(roughness_to_alpha(p.float(name, default), remap))

        r = alpha(prefix + "roughness", 0.0)
        return (alpha(prefix + "uroughness", 0.0) if prefix + "uroughness" in p else r,
                alpha(prefix + "vroughness", 0.0) if prefix + "vroughness" in p else r)

    def _alpha_texture(self, p, name, remap):
        """The alpha texture of a float texture parameter: each texel's first channel (pbrt-v4's float
        image textures read channel 0) times the texture's scale, as RoughnessToAlpha remaps it
        (sqrt where `remaproughness`), clamped to [0, 1]; a constant texture is its number.  The
        kernels multiply the material's alpha (1) by its R (Material.scalar_textures); the remap is
        applied to texels, before the bilinear lookup (pbrt-v4 remaps after it: the same at texel
        centres)."""
        from ..textures import Texture

        rgb, tex = self.color(p, name, (0.0,) * 3)
        if tex is None:
            return float(roughness_to_alpha(rgb[0], remap))
        if not isinstance(tex, Texture):
            raise error_at(p.items[name].pos, f'"texture {name}": a directionmix roughness is not supported')
        key = (id(tex), float(rgb[0]), remap)
        cached = self._alpha_textures.get(key)
        if cached is None:
            a = roughness_to_alpha(tex.texels[..., 0].astype(np.float64) * float(rgb[0]), remap)
            texels = np.ones(tex.texels.shape[:2] + (4,), np.float32)
            texels[..., :3] = a[..., None]
            cached = dataclasses.replace(tex, texels=np.ascontiguousarray(texels), srgb=False, channels=1,
                                         name=f"{tex.name}:alpha")
            self._alpha_textures[key] = (tex, cached)  # tex kept alive: its id stays its own
        else:
            cached = cached[1]
        return cached

    def _alpha(self, p, what, mat=None, prefix="") -> float:
        """The alpha of `roughness`, or of `uroughness` (along dp/du); a `vroughness` that differs sets
        mat.alpha_v (pbrt-v4's anisotropic Trowbridge-Reitz; without mat: their mean, with a warning).
        A texture (with mat only) goes to mat.scalar_textures ("alpha", "alpha_v") with the factor 1."""
        au, av = self._alphas(p, prefix)
        if mat is not None and not (isinstance(au, float) and isinstance(av, float)):
            def factor(a, slot):
                if isinstance(a, float):
                    return a
                mat.scalar_textures[slot] = a
                return 1.0

            alpha = factor(au, "alpha")
            if av is not au:
                mat.alpha_v = factor(av, "alpha_v")
            return alpha
        if au != av and mat is not None:
            mat.alpha_v = av
            return au
        if au != av:
            q = p.items.get(prefix + "uroughness", p.items.get(prefix + "vroughness"))
            self.imp.warn(q.pos, f"{what}: anisotropic roughness rendered isotropic")
            remap = p.boolean("remaproughness", True)
            ru, rv = (a * a if remap else a for a in (au, av))
            return min(math.sqrt(0.5 * (ru + rv)) if remap else 0.5 * (ru + rv), 1.0)
        return au

    def make(self, mtype: str, p, pos: str, what: str, name: str | None = None) -> Material | None:
        imp = self.imp
        self._count += 1
        mat = Material(name=name or f"{mtype}#{self._count}")
        transmittance = p.get("transmittance")
        if mtype == "diffusetransmission" and transmittance is not None and transmittance.type == "texture":
            raise error_at(p.items["transmittance"].pos, f'{what}: a "texture transmittance" is not supported')
        textured = ("displacement",) + (ROUGHNESS if mtype in TEXTURED_ROUGHNESS else ()) + \
            (tuple("interface." + r for r in ROUGHNESS) if mtype == "coatedconductor" else ())
        for q in list(p.items.values()):  # textures where we take a number (eta, a coat's roughness, ...)
            if q.type == "texture" and not q.name.endswith("reflectance") and q.name not in textured and \
                    not (mtype == "mix" and q.name == "amount"):
                imp.warn(q.pos, f'{what}: "texture {q.name}": textures are not supported here; using the default')
                q.used = True
                del p.items[q.name]
        if mtype == "diffuse":
            mat.albedo, mat.base_texture = self.color(p, "reflectance", (0.5, 0.5, 0.5))
        elif mtype == "conductor":
            self._conductor(mat, p, pos, what, "")
        elif mtype == "coatedconductor":
            self._coated_conductor(mat, p, pos, what)
        elif mtype in ("dielectric", "thindielectric"):
            mat.type = "dielectric"
            if mtype == "thindielectric":
                imp.warn(pos, f"{what}: approximated by a dielectric interface (a thin sheet refracts instead of "
                              "passing light straight through)")
            mat.ior = self._eta(p, what)
            mat.alpha = self._alpha(p, what, mat)
        elif mtype == "coateddiffuse":
            # pbrt's layered BSDF of a Lambertian base under a dielectric interface, no medium between
            # (albedo 0): our plastic (smooth coat) or roughplastic (GGX coat), whose closed form of
            # the light scattered back and forth under the coat (nonlinear: d / (1 - d F_dr)) is the
            # expectation pbrt's random walk estimates, but for its thin layer's absorption
            mat.albedo, mat.base_texture = self.color(p, "reflectance", (0.5, 0.5, 0.5))
            mat.ior = self._eta(p, what)
            if any(p.get(k) is not None and p.get(k).type == "texture" for k in ROUGHNESS):
                au, av = self._alphas(p)
                if au is not av:  # the coat (our roughplastic) is isotropic
                    raise error_at(pos, f"{what}: a textured roughness that differs along u and v is not supported")
                alpha = self._alpha(p, what, mat)  # the texture in mat.scalar_textures, alpha 1
            else:
                alpha = self._alpha(p, what)
            mat.type = "roughplastic" if alpha > 0 else "plastic"
            mat.alpha, mat.distribution, mat.nonlinear = alpha, "ggx", True
            mat.specular_reflectance = (1.0, 1.0, 1.0)
            albedo = spectrum_rgb(imp, p, "albedo", (0.0, 0.0, 0.0))
            if max(albedo) > 0:
                imp.warn(p.items["albedo"].pos, f"{what}: a scattering coating (albedo) is not supported")
            for key in ("thickness", "g", "maxdepth", "nsamples"):
                if key in p:
                    p.items[key].used = True
        elif mtype == "diffusetransmission":  # pbrt-v4's: scale times each of the two, clamped to [0, 1]
            mat.type = "diffusetransmission"
            scale = p.float("scale", 1.0)
            rgb, mat.base_texture = self.color(p, "reflectance", (0.25, 0.25, 0.25))
            if mat.base_texture is not None and scale > 1:
                raise error_at(pos, f"{what}: a reflectance texture with scale > 1 is not supported")
            t = spectrum_rgb(imp, p, "transmittance", (0.25, 0.25, 0.25))
            mat.albedo, mat.params["transmittance"] = (tuple(min(max(scale * c, 0.0), 1.0) for c in v)
                                                       for v in (rgb, t))
        elif mtype in ("interface", "", "none"):  # pbrt-v4's Material::Create: "" and "none" are "interface"
            return None
        elif mtype == "mix":
            return self._mix(mat, p, pos, what)
        else:
            raise error_at(pos, f'{what}: material type "{mtype}" is not supported')
        clipped = tuple(min(max(c, 0.0), 1.0) for c in mat.albedo)
        if clipped != tuple(mat.albedo):
            imp.warn(pos, f"{what}: reflectance {tuple(mat.albedo)} clamped to [0, 1]")
            mat.albedo = clipped
        if "displacement" in p:
            self._displacement(mat, p)
        fname = p.string("normalmap") if "normalmap" in p else None
        if fname:  # pbrt-v4's NormalMap(): linear RGB in the shading frame of dp/du
            from ..textures import texture_from_image

            path = pbrt_path(p.items["normalmap"].pos, imp.path.parent, fname, f"{what}: normal map")
            try:
                mat.normal_texture = texture_from_image(path, srgb=False)
                # against pbrt-v4's renders (BENCHMARKS, feature scene normalmap), its map's y runs opposite
                # to the frame's T of cl/scene/shading.h, and seen from behind it turns whole, as bump maps
                mat.normal_texture.texels[..., 1] = 1.0 - mat.normal_texture.texels[..., 1]
                mat.map_conventions = ("whole",)
            except Exception as exc:
                raise error_at(p.items["normalmap"].pos, f"{what}: cannot read normal map '{fname}' "
                                                         f"({type(exc).__name__}: {exc})") from None
        return mat

    def _displacement(self, mat, p) -> None:
        """pbrt-v4's bump mapping by a float "displacement" texture (its BumpMap): the shading frame's
        dp/du and dp/dv tilted along the normal by the texture's derivatives in (u, v), the normal their
        cross product.  Ours is Mitsuba's bumpmap (cl/scene/shading.h) with the bilinear lookup's
        derivative where pbrt takes a finite difference over the ray's footprint, and without pbrt's
        term of the displacement times the change of interpolated normals (0 on flat faces).  An
        image's channels are averaged, as pbrt-v4's float image textures average them.  A constant
        displacement tilts nothing; a normal map takes precedence, as in pbrt-v4."""
        from ..textures import Texture

        q = p.items["displacement"]
        q.used = True
        if q.type != "texture" or "normalmap" in p:
            return
        _, tex = self.color(p, "displacement", (0.0, 0.0, 0.0))
        if tex is None:
            return
        if not isinstance(tex, Texture):
            raise error_at(q.pos, '"texture displacement": a directionmix displacement is not supported')
        texels = tex.texels.copy()
        texels[..., :3] = texels[..., :3].mean(axis=-1, keepdims=True)
        mat.normal_texture = dataclasses.replace(tex, texels=texels, srgb=False, channels=1)
        mat.bump_map, mat.normal_scale, mat.map_conventions = True, 1.0, ("whole",)

    def _mix(self, mat, p, pos, what) -> Material:
        """pbrt-v4's MixMaterial: materials[1] with probability ``amount`` (default 0.5), else materials[0]."""
        from ..textures import scalar_texture

        names, q = p._values("materials", {"string"}, 2)
        if names is None:
            raise error_at(pos, f'{what} needs "string materials" [ "first" "second" ]')
        blend = []
        for n in names:
            if self.named.get(n) is None:
                raise error_at(q.pos, f'{what}: no material named "{n}" (MakeNamedMaterial; not an interface)')
            blend.append(self.named[n])
        mat.type, mat.blend = "mix", tuple(blend)
        amount = p.get("amount")
        if amount is not None and amount.type == "texture":
            rgb, texture = self.color(p, "amount", (0.5, 0.5, 0.5))
            mat.mix_weight = float(np.dot(rgb, (0.212671, 0.715160, 0.072169)))
            if texture is not None:
                mat.scalar_textures["mix_weight"] = scalar_texture(texture)
        else:
            mat.mix_weight = p.float("amount", 0.5)
        if not 0.0 <= mat.mix_weight <= 1.0:
            self.imp.warn(pos, f"{what}: amount {mat.mix_weight:g} clamped to [0, 1]")
            mat.mix_weight = min(max(mat.mix_weight, 0.0), 1.0)
        return mat

    def _eta(self, p, what, key="eta") -> float:
        q = p.get(key)
        if q is None:
            return 1.5
        if q.type == "spectrum" and len(q.values) == 1 and isinstance(q.values[0], str) and \
                spectrum_file(self.imp, q) is None:
            named = q.values[0]
            if named not in GLASSES:
                raise error_at(q.pos, f'{what}: unknown spectrum "{named}" (one of: {", ".join(GLASSES)})')
            self.imp.warn(q.pos, f"{what}: {named} rendered without dispersion, at its d-line index {GLASSES[named]}")
            return GLASSES[named]
        eta = p.float(key) if q.type in ("float", "integer") else spectrum_rgb(self.imp, p, key, (1.5,) * 3)[1]
        if not eta > 0:
            raise error_at(q.pos, f"{what}: eta must be > 0, got {eta:g}")
        return float(eta)

    def _coated_conductor(self, mat, p, pos, what) -> None:
        """pbrt-v4's coatedconductor as our coatedconductor (the same layered BSDF, estimated as pbrt
        does): `interface.eta` and the interface's roughness, the conductor's `conductor.eta` /
        `conductor.k` or `reflectance` (pbrt's eta 1 and matching k) and its roughness, `thickness`,
        `maxdepth`, `nsamples`, and a scattering coating's `albedo` and `g`."""
        from ..materials.coatedconductor import reflectance_to_index, set_coating_medium

        mat.ior = self._eta(p, what, "interface.eta")
        if "reflectance" in p and ("conductor.eta" in p or "conductor.k" in p):
            raise error_at(p.items["reflectance"].pos, f'{what}: give "reflectance" or "conductor.eta" / '
                                                       '"conductor.k", not both (as pbrt-v4)')
        self._conductor(mat, p, pos, what, "conductor.", reflectance_key="reflectance", per_texel=True)
        mat.type = "coatedconductor"
        if mat.eta is None:  # reflectance r: pbrt-v4's eta 1 and the k whose normal reflectance is r
            mat.eta, mat.k = reflectance_to_index(mat.f0)
        mat.alpha = self._alpha(p, what, mat, prefix="interface.")  # a texture: in mat.scalar_textures
        cu, cv = self._alphas(p, "conductor.")
        albedo = spectrum_rgb(self.imp, p, "albedo", (0.0, 0.0, 0.0))
        if min(albedo) < 0 or max(albedo) > 1:
            clamped = tuple(min(max(c, 0.0), 1.0) for c in albedo)
            self.imp.warn(p.items["albedo"].pos, f"{what}: albedo {tuple(albedo)} clamped to [0, 1]")
            albedo = clamped
        g = p.float("g", 0.0)
        if not -1 < g < 1:
            raise error_at(p.items["g"].pos, f"{what}: g must be in (-1, 1), got {g:g}")
        set_coating_medium(mat, albedo, g)
        thickness = p.float("thickness", 0.01)
        depth, samples = p.integer("maxdepth", 10), p.integer("nsamples", 1)
        if thickness < 0 or depth < 1 or samples < 1:
            raise error_at(pos, f"{what}: thickness must be >= 0 and maxdepth, nsamples >= 1")
        mat.params.update(conductor_alpha_u=cu, conductor_alpha_v=cv, thickness=thickness, max_depth=depth,
                          samples=samples)

    def _conductor(self, mat, p, pos, what, prefix, reflectance_key=None, per_texel=False) -> None:
        """The metal's index (mat.eta, mat.k) or its reflectance (mat.f0); a reflectance texture
        ``per_texel`` (a coatedconductor's: the kernels make the metal of each texel, albedo x
        texel) becomes mat.base_texture with mat.albedo its factor and f0 their mean, else its mean."""
        mat.type = "conductor"
        if not prefix:
            mat.alpha = self._alpha(p, what, mat)
        reflectance_key = reflectance_key or prefix + "reflectance"
        if reflectance_key in p:
            rgb, tex = self.color(p, reflectance_key, (1.0,) * 3)
            if tex is not None and per_texel:
                mat.base_texture, mat.albedo = tex, tuple(min(max(float(c), 0.0), 1.0) for c in rgb)
                rgb = tuple(float(c) for c in np.multiply(rgb, tex.mean_rgb()))
            elif tex is not None:
                rgb = tuple(float(c) for c in tex.mean_rgb())
                self.imp.warn(p.items[reflectance_key].pos, f"{what}: a reflectance texture is not supported "
                                                             f"here; using its mean")
            mat.f0 = tuple(min(max(c, 0.0), 1.0) for c in rgb)
            return
        from .mitsuba_metals import CONDUCTORS

        out = {}
        for part in ("eta", "k"):
            q = p.get(prefix + part)
            if q is None:
                out[part] = CONDUCTORS["Cu"][0 if part == "eta" else 1]  # pbrt's default: copper
            elif q.type == "spectrum" and len(q.values) == 1 and isinstance(q.values[0], str) and \
                    spectrum_file(self.imp, q) is None:
                named = q.values[0]
                metal = named[len("metal-"):].rsplit("-", 1)[0] if named.startswith("metal-") else None
                if metal not in METALS:
                    raise error_at(q.pos, f'{what}: spectrum "{named}" is not supported (the named metals we read: '
                                          f"{', '.join(f'metal-{m}-{part}' for m in METALS)})")
                out[part] = CONDUCTORS[METALS[metal]][0 if part == "eta" else 1]
            else:
                out[part] = spectrum_rgb(self.imp, p, prefix + part, (1.0,) * 3, conductor=True)
        mat.eta, mat.k = tuple(map(float, out["eta"])), tuple(map(float, out["k"]))
        if min(mat.eta) <= 0:
            raise error_at(p.items[prefix + "eta"].pos, f"{what}: eta must be > 0")
