"""Mitsuba 3 BSDFs and textures as our materials (docs/SCENE_FORMAT.md, "Mitsuba 3 XML").

| Mitsuba | ours |
|---|---|
| ``diffuse`` | ``diffuse`` (reflectance, a bitmap as its texture) |
| ``conductor``, ``roughconductor`` | ``conductor``: ``material`` (Mitsuba's named conductors, ``a-C`` to ``W``, in the RGB Mitsuba's RGB variants compute: mitsuba_metals.py), ``none`` (the default) as a perfect mirror times ``specular_reflectance``, or ``eta``/``k`` |
| ``dielectric``, ``roughdielectric``, ``thindielectric`` (a thin sheet) | ``dielectric`` of IOR ``int_ior / ext_ior``, tint ``specular_transmittance`` |
| ``plastic``, ``roughplastic`` | ``plastic``, ``roughplastic`` (Mitsuba's parameters; a texture of ``diffuse_reflectance``) |
| ``principled``, ``principledthin`` | ``principled``, ``principledthin`` (Mitsuba's parameters; textures of ``base_color`` and of up to 6 scalar parameters) |
| ``twosided`` | its nested BSDF, reflecting on both sides (diffuse, conductors and plastics alone reflect on the front side only, as Mitsuba's) |
| ``normalmap``, ``bumpmap`` | its nested BSDF with the map (``normal_texture``; ``scale``, ``flip_invalid_normals``, ``use_shadowing_function`` as Mitsuba reads them: cl/scene/shading.h) |
| ``mask`` | its nested BSDF as an alpha cut-out (``opacity``: a float or a texture; Material.masked), the nested BSDF one-sided unless a ``twosided`` |
| ``blendbsdf`` | ``mix`` of its two nested BSDFs (``weight``: a float, a texture's luminance or a ``mesh_attribute``) |

Textures: ``bitmap``, ``checkerboard``, ``rawconstant`` (a 1 x 1 texture of its value, unconverted)
and, as a BSDF's reflectance (diffuse ``reflectance``, plastic ``diffuse_reflectance``, principled
``base_color``, dielectric ``specular_transmittance``), ``mesh_attribute``: the shape's vertex or face
colours (``vertex_color``, ``face_color``, ...: Material.vertex_colors) times its ``scale``.

Rough conductors and dielectrics keep Mitsuba's distribution: Beckmann (the default) or GGX,
``alpha`` or anisotropic ``alpha_u``/``alpha_v`` (along dp/du and the bitangent, as Mitsuba's
sh_frame), each a number or a texture, with Mitsuba's separable shadowing-masking.  ``bitmap`` and
``checkerboard`` keep ``to_uv`` (the lookup's affine map); ``bitmap`` its ``wrap_mode`` and
``filter_type`` (Texture: the device looks them up as Mitsuba does, cl/scene/textures.h).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ...device import abi
from ..materials import MITSUBA_TYPES
from ..model import Material
from .builder import error_at
from .mitsuba_metals import CONDUCTORS
from .mitsuba_plugins import refusal
from .mitsuba_spectrum import spectrum_rgb

# Mitsuba's named indices of refraction (include/mitsuba/render/ior.h)
IOR = {
    "vacuum": 1.0, "helium": 1.000036, "hydrogen": 1.000132, "air": 1.000277, "carbon dioxide": 1.00045,
    "water": 1.3330, "acetone": 1.36, "ethanol": 1.361, "carbon tetrachloride": 1.461, "glycerol": 1.4729,
    "benzene": 1.501, "silicone oil": 1.52045, "bromine": 1.661, "water ice": 1.31, "fused quartz": 1.458,
    "pyrex": 1.470, "acrylic glass": 1.49, "polypropylene": 1.49, "bk7": 1.5046, "sodium chloride": 1.544,
    "amber": 1.55, "pet": 1.5750, "diamond": 2.419,
}
# Mitsuba's BSDFs that reflect on their front side only (outside a twosided): Material.one_sided,
# black seen from behind the shading normal (the inside of an open cylinder, the back of a disk;
# around a mask its back can be seen through the cut-out's holes)
ONE_SIDED = {"diffuse", "conductor", "roughconductor", "plastic", "roughplastic"}
# parameters that Mitsuba's plugins read with get_unbounded_texture (not clamped to [0, 1])
UNBOUNDED = {"eta", "k", "alpha", "alpha_u", "alpha_v"}


def spectrum_context(obj, name) -> str:
    """How Mitsuba's RGB variants make the <spectrum> ``name`` of ``obj`` RGB
    (mitsuba_spectrum.py): emitters ask for emission, eta/k/alpha for unbounded values, the
    rest (reflectances, transmittances, texture colours) for reflectances."""
    if obj.tag == "emitter":
        return "emission"
    return "unbounded" if name in UNBOUNDED else "reflectance"


@dataclass(frozen=True)
class MeshAttribute:
    """A ``mesh_attribute`` texture: the shape's attribute ``name`` (per vertex or per face)."""

    name: str
    scale: float = 1.0


def color_value(imp, obj, name, default, *, texture_ok=False, attribute_ok=False):
    """(linear RGB tuple, Texture or None) of the property ``name`` of ``obj``: an rgb, a
    spectrum or a float; a bitmap or checkerboard texture where ``texture_ok`` (the RGB is then
    1), else its mean with a warning; a mesh_attribute where ``attribute_ok`` (a MeshAttribute in
    place of the texture, the RGB its scale)."""
    p = obj.prop(name)
    if p is None:
        return tuple(float(x) for x in default), None
    if p.kind in ("rgb", "float", "integer"):
        v = p.value if isinstance(p.value, tuple) else (p.value,) * 3
        return tuple(float(x) for x in v), None
    if p.kind == "spectrum":
        rgb, raw = spectrum_rgb(p.value, spectrum_context(obj, name))
        if raw is not None:
            imp.warn(p.node.pos, f'{p.node.label()} of {obj.label()}: the spectrum\'s colour '
                                 f"{tuple(round(x, 4) for x in raw)} is out of gamut; clamped to "
                                 f"{tuple(round(x, 4) for x in rgb)}, as Mitsuba does")
        return rgb, None
    if p.kind != "object":
        raise error_at(p.node.pos, f'{obj.label()}: "{name}" must be a colour, got <{p.kind}>')
    tex_obj = p.value
    if tex_obj.tag == "spectrum":
        return _spectrum_object(imp, tex_obj), None
    if tex_obj.tag != "texture":
        raise error_at(p.node.pos, f'{obj.label()}: "{name}" must be a colour or a texture, got {tex_obj.label()}')
    texture = imp.bsdfs.texture(tex_obj)
    if texture is None:
        return tuple(float(x) for x in default), None
    if isinstance(texture, MeshAttribute):
        if attribute_ok:
            return (texture.scale,) * 3, texture
        raise error_at(p.node.pos, f'{tex_obj.label()} as "{name}" of {obj.label()}: a mesh attribute is not '
                                   "supported here")
    if texture_ok:
        return (1.0, 1.0, 1.0), texture
    raise error_at(p.node.pos, f'{tex_obj.label()} as "{name}" of {obj.label()}: a texture is not supported here')


def _spectrum_object(imp, spec):
    if spec.type == "uniform":
        v = spec.float("value", 1.0)
        imp.unused(spec)
        return (v, v, v)
    if spec.type == "d65":  # Mitsuba's RGB variants: color x scale (the D65 itself is their white)
        s = spec.float("scale", 1.0)
        color, _ = color_value(imp, spec, "color", (1.0, 1.0, 1.0))
        imp.unused(spec)
        return tuple(float(c) * s for c in color)
    if spec.type == "blackbody":
        from .builder import blackbody_rgb

        t = spec.float("temperature", 6500.0, positive=True)
        imp.warn(spec.node.pos, f"{spec.label()}: Mitsuba's RGB variants cannot render a black body (spectral "
                                "variants only); rendered as its RGB colour at luminance 1")
        imp.unused(spec)
        return blackbody_rgb(t)
    raise error_at(spec.node.pos, refusal(spec))


def _checker(c0, c1) -> np.ndarray:
    """Mitsuba's checkerboard as a 2 x 2 image looked up nearest, repeated: color0 where the
    fractional parts of u and v are on the same side of 1/2, color1 elsewhere (the texture's
    to_uv goes to the lookup; src/textures/checkerboard.cpp)."""
    c0, c1 = np.asarray(c0, np.float64), np.asarray(c1, np.float64)
    return np.array([[c0, c1], [c1, c0]])


def _two_sided(mat: Material) -> Material:
    """``mat`` reflecting on both sides (inside a twosided), a blend's materials too."""
    return dataclasses.replace(mat, one_sided=False, blend=tuple(_two_sided(m) for m in mat.blend))


class BsdfMapper:
    def __init__(self, importer):
        self.imp = importer
        self._materials: dict[int, Material] = {}
        self._textures: dict[int, object] = {}
        self._images: dict[tuple, object] = {}  # (path, raw) -> the Texture read from it (lookups share it)
        self.attributes: dict[int, str] = {}  # id(material) -> its mesh_attribute's name
        self._default = {}

    def default(self, black: bool = False) -> Material:
        """Mitsuba's BSDF of a shape without one: diffuse, reflectance 0.5, or 0 (``black``) for
        a shape that emits (src/render/shape.cpp)."""
        if black not in self._default:
            self._default[black] = Material(name="mitsuba-default-emitter" if black else "mitsuba-default",
                                            albedo=(0.0,) * 3 if black else (0.5,) * 3)
        return self._default[black]

    # -- textures --------------------------------------------------------------------------------

    def texture(self, obj, scalar=False):
        """The Texture of a <texture>; ``scalar``: as a scalar parameter reads it (Mitsuba's eval_1,
        which for a checkerboard swaps color0 and color1: src/textures/checkerboard.cpp)."""
        key = (id(obj), scalar and obj.type == "checkerboard")
        if key not in self._textures:
            self._textures[key] = self._make_texture(obj, swap=key[1])
        return self._textures[key]

    def _make_texture(self, obj, swap=False):
        from ..textures import IDENTITY_UV, affine_uv, texture_from_array, texture_from_image

        imp = self.imp
        to_uv = obj.transform("to_uv")
        uv_map = IDENTITY_UV if to_uv is None else affine_uv(to_uv)
        if obj.type == "rawconstant":
            p = obj.prop("value")
            if p is None or p.kind not in ("float", "integer", "rgb", "vector", "point"):
                raise error_at(obj.node.pos, f'{obj.label()} needs <float>, <rgb> or <vector name="value">')
            value = np.asarray(p.value, np.float32).reshape(-1)
            if len(value) not in (1, 3):
                raise error_at(p.node.pos, f"{obj.label()}: value must be 1 or 3 numbers")
            imp.unused(obj)
            return texture_from_array(np.broadcast_to(value, (3,)).reshape(1, 1, 3).copy(), name=obj.label())
        if obj.type == "mesh_attribute":
            attr = obj.string("name")
            if attr is None:
                raise error_at(obj.node.pos, f'{obj.label()} needs <string name="name">')
            scale = obj.float("scale", 1.0)
            imp.unused(obj)
            return MeshAttribute(attr, scale)
        if obj.type == "checkerboard":
            c0, _ = color_value(imp, obj, "color0", (0.4, 0.4, 0.4))
            c1, _ = color_value(imp, obj, "color1", (0.2, 0.2, 0.2))
            imp.unused(obj)
            if swap:
                c0, c1 = c1, c0
            texture = texture_from_array(_checker(c0, c1).astype(np.float32), name=obj.label()).with_lookup(
                filter="nearest", to_uv=uv_map)
            texture.mitsuba_mean = 0.5 * (float(np.mean(c0)) + float(np.mean(c1)))  # Mitsuba's mean()
            return texture
        if obj.type != "bitmap":
            raise error_at(obj.node.pos, refusal(obj))
        fname = obj.string("filename")
        if fname is None:
            raise error_at(obj.node.pos, f'{obj.label()} needs <string name="filename">')
        path = imp.resolve(fname, obj)
        filt = obj.choice("filter_type", ("bilinear", "nearest"), " (as Mitsuba)")
        wrap = obj.choice("wrap_mode", ("repeat", "mirror", "clamp"), " (as Mitsuba)")
        raw = bool(obj.boolean("raw", False))
        imp.unused(obj)
        where = f"{obj.node.pos}: {obj.label()}"
        image = self._images.get((str(path), raw))
        if image is None:
            if path.suffix.lower() in (".exr", ".pfm", ".hdr"):
                from .images import read_hdr_image

                image = texture_from_array(read_hdr_image(path, where), name=str(fname))
            else:
                try:
                    image = texture_from_image(path, srgb=not raw)
                except Exception as exc:
                    raise error_at(obj.node.pos, f"{obj.label()}: cannot read '{fname}' "
                                                 f"({type(exc).__name__}: {exc})") from None
            self._images[(str(path), raw)] = image
        return image.with_lookup(wrap=wrap, filter=filt, to_uv=uv_map)

    # -- BSDFs -----------------------------------------------------------------------------------

    def material(self, obj) -> Material:
        key = id(obj)
        if key not in self._materials:
            mat = self._make(obj)
            if isinstance(mat.base_texture, MeshAttribute):  # the shape's colours (mitsuba_scene.py)
                self.attributes[id(mat)] = mat.base_texture.name
                mat.base_texture, mat.vertex_colors = None, True
            self._materials[key] = mat
        return self._materials[key]

    def attribute(self, material: Material) -> str | None:
        """The mesh attribute whose colours ``material`` (one of ours) multiplies its reflectance by."""
        return self.attributes.get(id(material))

    def _nested(self, obj, what: str) -> Material:
        nested = obj.children_of("bsdf")
        if not nested:
            raise error_at(obj.node.pos, f"{obj.label()} needs a nested <bsdf>")
        if what:
            self.imp.warn(obj.node.pos, f"{obj.label()}: {what}; rendering its nested BSDF")
        return self.material(nested[0])

    def _ior(self, obj, name, default_name):
        p = obj.prop(name)
        if p is None:
            return IOR[default_name]
        if p.kind == "string":
            key = p.value.strip().lower()
            if key not in IOR:
                raise error_at(p.node.pos, f"{obj.label()}: unknown {name} '{p.value}' "
                                           f"(a number or one of: {', '.join(IOR)})")
            return IOR[key]
        value = obj.float(name, positive=True)
        return value

    def _alpha(self, obj, default, mat) -> float:
        """The distribution of a rough conductor or dielectric into mat (Mitsuba's
        MicrofacetDistribution): ``alpha``, or ``alpha_u`` / ``alpha_v`` (anisotropic: mat.alpha_v), each a
        number or a texture (its slot in mat.scalar_textures: "alpha" for alpha / alpha_u, "alpha_v";
        the factor is then 1), the ``distribution`` (Beckmann by default) and Mitsuba's separable
        shadowing-masking.  Returns mat.alpha."""
        imp = self.imp
        mat.masking = "separable"
        mat.distribution = self._distribution(obj)
        obj.used.add("sample_visible")

        def value(name, field):
            p = obj.props.get(name)
            if p is not None and p.kind == "object" and p.value.tag == "texture":
                return self._scalar(obj, mat, name, default, field=field)
            a = color_value(imp, obj, name, (default,) * 3)[0][0]
            if not 0 <= a <= 1:
                imp.warn(obj.node.pos, f"{obj.label()}: {name} {a:g} clamped to [0, 1]")
                a = min(max(a, 0.0), 1.0)
            return float(a)

        if obj.has("alpha_u") or obj.has("alpha_v"):
            if not (obj.has("alpha_u") and obj.has("alpha_v")) or obj.has("alpha"):
                raise error_at(obj.node.pos, f"{obj.label()}: give both alpha_u and alpha_v, and no alpha "
                                             "(Mitsuba refuses the others)")
            mat.alpha = value("alpha_u", "alpha")
            mat.alpha_v = value("alpha_v", "alpha_v")
        else:
            mat.alpha = value("alpha", "alpha")
        return mat.alpha

    def _make(self, obj) -> Material:
        imp, t = self.imp, obj.type
        name = obj.id or f"{t}@{obj.node.line}"
        if t == "twosided":
            nested = obj.children_of("bsdf")
            if len(nested) > 1 and nested[1] is not nested[0]:
                raise error_at(nested[1].node.pos, f"{obj.label()}: a different back-side BSDF is not supported")
            nested_mat = self._nested(obj, "")
            mat = _two_sided(nested_mat)
            if id(nested_mat) in self.attributes:
                self.attributes[id(mat)] = self.attributes[id(nested_mat)]
            if obj.id and "@" in mat.name:  # an anonymous nested BSDF takes the twosided's id
                mat.name = obj.id
            imp.unused(obj)
            return mat
        if t in ("normalmap", "bumpmap"):
            return self._mapped(obj, name)
        if t == "mask":
            return self._mask(obj, name)
        if t == "blendbsdf":
            return self._blend(obj, name)
        mat = Material(name=name)
        if t == "diffuse":
            mat.albedo, mat.base_texture = color_value(imp, obj, "reflectance", (0.5,) * 3, texture_ok=True,
                                                       attribute_ok=True)
        elif t in ("dielectric", "roughdielectric", "thindielectric"):
            self._dielectric(obj, mat)
        elif t in ("conductor", "roughconductor"):
            self._conductor(obj, mat)
        elif t in ("plastic", "roughplastic"):
            self._plastic(obj, mat)
        elif t in ("principled", "principledthin"):
            self._principled(obj, mat)
        elif t == "null":
            raise error_at(obj.node.pos, f"{obj.label()}: a null BSDF is supported as a shape's own BSDF only")
        elif t in MITSUBA_TYPES:  # a type that reads its own plugin (scene/materials/<name>.py)
            mat.type = MITSUBA_TYPES[t].name
            MITSUBA_TYPES[t].from_mitsuba(obj, mat, lambda key, default: color_value(
                imp, obj, key, default, texture_ok=True, attribute_ok=True))
        else:
            raise error_at(obj.node.pos, refusal(obj))
        mat.albedo = _clamp01(imp, obj, mat.albedo, "reflectance")
        mat.one_sided = mat.one_sided or t in ONE_SIDED  # black seen from behind, unless a twosided wraps it
        imp.unused(obj)
        return mat

    def _mapped(self, obj, name) -> Material:
        """normalmap / bumpmap: the nested BSDF's material with the map (Mitsuba 3's
        src/bsdfs/normalmap.cpp, bumpmap.cpp; cl/scene/shading.h)."""
        imp = self.imp
        nested = self._nested(obj, "")
        if obj.type == "normalmap":
            p = obj.prop("normalmap")
            tex_obj = p.value if p is not None and p.kind == "object" and p.value.tag == "texture" else None
            scale = 1.0
        else:
            named = [q.value for q in obj.props.values() if q.kind == "object" and q.value.tag == "texture"]
            for q in obj.props:
                if obj.props[q].kind == "object":
                    obj.used.add(q)
            tex_obj = (named + obj.children_of("texture") or [None])[0]
            scale = obj.float("scale", 1.0)
        if tex_obj is None:
            raise error_at(obj.node.pos, f"{obj.label()} needs a nested <texture>"
                                         + (' named "normalmap"' if obj.type == "normalmap" else ""))
        texture = self.texture(tex_obj)
        conventions = ("side",) + (("flip",) if obj.boolean("flip_invalid_normals", True) else ()) \
            + (("terminator",) if obj.boolean("use_shadowing_function", True) else ())
        imp.unused(obj)
        if texture is None or isinstance(texture, MeshAttribute):
            imp.warn(tex_obj.node.pos, f"{tex_obj.label()} in {obj.label()}: not a texture we can map; "
                                       "rendering the nested BSDF")
            return nested
        if nested.normal_texture is not None:
            imp.warn(obj.node.pos, f"{obj.label()}: a map over a mapped BSDF: only the outer map is applied")
        mat = dataclasses.replace(nested, name=obj.id or nested.name, normal_texture=texture,
                                  bump_map=obj.type == "bumpmap", normal_scale=float(scale), map_conventions=conventions)
        if id(nested) in self.attributes:
            self.attributes[id(mat)] = self.attributes[id(nested)]
        return mat

    def _mask(self, obj, name) -> Material:
        """Mitsuba's mask (src/bsdfs/mask.cpp): the nested BSDF with probability ``opacity`` (a float
        or a texture's luminance, default 0.5, clamped to [0, 1]), else a null, straight-through
        interaction (Material.masked; cl/render/path.h).  A nested BSDF that is not a twosided is
        one-sided, as Mitsuba's are: black seen from behind (the null part still lets light through)."""
        nested_objs = obj.children_of("bsdf")
        if len(nested_objs) > 1:
            raise error_at(nested_objs[1].node.pos, f"{obj.label()}: more than one nested BSDF (Mitsuba refuses it)")
        nested = self._nested(obj, "")
        if nested.masked:
            self.imp.warn(obj.node.pos, f"{obj.label()}: a mask around a mask: only the outer opacity is applied")
        mat = dataclasses.replace(nested, name=obj.id or nested.name, masked=True,
                                  scalar_textures=dict(nested.scalar_textures), params=dict(nested.params),
                                  one_sided=nested.one_sided or nested_objs[0].type in ONE_SIDED)
        mat.scalar_textures.pop("opacity", None)
        mat.opacity = min(max(float(self._scalar(obj, mat, "opacity", 0.5)), 0.0), 1.0)
        self.imp.unused(obj)
        if id(nested) in self.attributes:
            self.attributes[id(mat)] = self.attributes[id(nested)]
        return mat

    def _blend(self, obj, name) -> Material:
        """Mitsuba's blendbsdf (src/bsdfs/blendbsdf.cpp): (1 - weight) times the first nested BSDF plus
        weight times the second; ``weight`` (default 0.5, clamped to [0, 1]) a float, a texture (its
        luminance, eval_1) or a mesh_attribute (the shape's colours' luminance: Material.vertex_colors)."""
        nested = obj.children_of("bsdf")
        if len(nested) != 2:
            raise error_at(obj.node.pos, f"{obj.label()} needs two nested BSDFs, got {len(nested)} (as Mitsuba)")
        mat = Material(name=name, type="mix", blend=tuple(self.material(b) for b in nested))
        p = obj.prop("weight")
        attribute = None
        if p is not None and p.kind == "object" and p.value.tag == "texture" and p.value.type == "mesh_attribute":
            attr = self.texture(p.value, scalar=True)
            attribute, mat.vertex_colors, mat.mix_weight = attr.name, True, float(attr.scale)
            obj.used.add("weight")
        else:
            mat.mix_weight = float(self._scalar(obj, mat, "weight", 0.5, field="mix_weight"))
        if not 0.0 <= mat.mix_weight <= 1.0 and "mix_weight" not in mat.scalar_textures:
            self.imp.warn(obj.node.pos, f"{obj.label()}: weight {mat.mix_weight:g} clamped to [0, 1]")
            mat.mix_weight = min(max(mat.mix_weight, 0.0), 1.0)
        # the shape's colours: the weight's attribute, else a blended BSDF's (one attribute per shape)
        wanted = {a for a in [attribute] + [self.attribute(m) for m in mat.blend] if a is not None}
        if len(wanted) > 1:
            self.imp.warn(obj.node.pos, f"{obj.label()}: reads the mesh attributes {sorted(wanted)}; only "
                                        f'"{attribute or sorted(wanted)[0]}" is used')
        if wanted:
            self.attributes[id(mat)] = attribute or sorted(wanted)[0]
        self.imp.unused(obj)
        return mat

    def _dielectric(self, obj, mat) -> None:
        imp = self.imp
        mat.type = "dielectric"
        mat.thin = obj.type == "thindielectric"  # a sheet: straight through (cl/materials/dielectric.h)
        mat.ior = self._ior(obj, "int_ior", "bk7") / self._ior(obj, "ext_ior", "air")
        if obj.type == "roughdielectric":
            self._alpha(obj, 0.1, mat)
        refl, _ = color_value(imp, obj, "specular_reflectance", (1.0,) * 3)
        trans, tex = color_value(imp, obj, "specular_transmittance", (1.0,) * 3, texture_ok=True, attribute_ok=True)
        mat.tint, mat.base_texture = _clamp01(imp, obj, trans, "specular_transmittance"), tex
        if refl != (1.0, 1.0, 1.0) and refl != trans:
            raise error_at(obj.props["specular_reflectance"].node.pos,
                           f"{obj.label()}: a specular_reflectance other than 1 or the specular_transmittance is not "
                           "supported (one tint scales reflection and transmission)")

    def _conductor(self, obj, mat) -> None:
        imp = self.imp
        mat.type = "conductor"
        if obj.type == "roughconductor":
            self._alpha(obj, 0.1, mat)
        spec, _ = color_value(imp, obj, "specular_reflectance", (1.0,) * 3)
        if obj.has("eta") or obj.has("k"):
            mat.eta, _ = color_value(imp, obj, "eta", (0.0,) * 3)
            mat.k, _ = color_value(imp, obj, "k", (1.0,) * 3)
            if min(mat.eta) <= 0:  # eta 0: Mitsuba's perfect mirror
                mat.eta, mat.k, mat.f0 = None, None, _clamp01(imp, obj, spec, "specular_reflectance")
                return
        else:
            p = obj.prop("material")
            metal = "none" if p is None else str(p.value)
            if metal == "none":
                mat.f0 = _clamp01(imp, obj, spec, "specular_reflectance")
                return
            if metal not in CONDUCTORS:
                raise error_at(p.node.pos, f"{obj.label()}: unknown material '{metal}' (one of "
                                           f"{', '.join(CONDUCTORS)}, or none)")
            mat.eta, mat.k = CONDUCTORS[metal]
        if spec != (1.0, 1.0, 1.0):
            raise error_at(obj.props["specular_reflectance"].node.pos,
                           f"{obj.label()}: specular_reflectance with eta/k or a named material is not supported")

    def _plastic(self, obj, mat) -> None:
        """Mitsuba's plastic / roughplastic: the same parameters (src/bsdfs/plastic.cpp, roughplastic.cpp)."""
        imp = self.imp
        mat.type = obj.type
        mat.albedo, mat.base_texture = color_value(imp, obj, "diffuse_reflectance", (0.5,) * 3, texture_ok=True,
                                                   attribute_ok=True)
        if mat.base_texture is not None and getattr(mat.base_texture, "mitsuba_mean", None) is not None:
            mat.params["diffuse_mean"] = mat.base_texture.mitsuba_mean
        mat.ior = self._ior(obj, "int_ior", "polypropylene") / self._ior(obj, "ext_ior", "air")
        spec, _ = color_value(imp, obj, "specular_reflectance", (1.0,) * 3)
        mat.specular_reflectance = _clamp01(imp, obj, spec, "specular_reflectance")
        mat.nonlinear = bool(obj.boolean("nonlinear", False))
        if obj.type == "roughplastic":
            if mat.ior == 1.0:
                raise error_at(obj.node.pos, f"{obj.label()}: int_ior and ext_ior must differ (Mitsuba refuses them)")
            if obj.has("alpha_u") or obj.has("alpha_v"):
                raise error_at(obj.node.pos, f"{obj.label()}: anisotropic roughness (alpha_u, alpha_v) is not "
                                             "supported by roughplastic (Mitsuba refuses it too)")
            mat.alpha = obj.float("alpha", 0.1, minimum=0.0)
            mat.distribution = self._distribution(obj)
        obj.used.add("sample_visible")

    def _distribution(self, obj) -> str:
        dist = obj.string("distribution", "beckmann").lower()
        if dist not in ("beckmann", "ggx"):
            raise error_at(obj.props["distribution"].node.pos, f"{obj.label()}: unknown distribution '{dist}'")
        return dist

    def _scalar(self, obj, mat, name, default, *, field=None):
        """A scalar parameter of a principled BSDF: its value, or 1 with its texture (luminance)
        in mat.scalar_textures[field or name]."""
        from ..textures import scalar_texture

        p = obj.prop(name)
        if p is None:
            return default
        if p.kind in ("float", "integer"):
            return float(p.value)
        if p.kind == "object" and p.value.tag == "texture":
            texture = self.texture(p.value, scalar=True)
            if texture is None:
                return default
            if len(mat.scalar_textures) == abi.TEX_SLOTS:
                mean = float(scalar_texture(texture).texels[..., 0].mean())
                self.imp.warn(p.node.pos, f'{p.value.label()} as "{name}" of {obj.label()}: more than '
                                          f"{abi.TEX_SLOTS} textured parameters; using its mean {mean:.4g}")
                return mean
            mat.scalar_textures[field or name] = scalar_texture(texture)
            return 1.0
        rgb, _ = color_value(self.imp, obj, name, (default,) * 3)
        return float(np.dot(rgb, (0.212671, 0.715160, 0.072169)))

    def _principled(self, obj, mat) -> None:
        """Mitsuba's principled / principledthin: the same parameters (src/bsdfs/principled.cpp,
        principledthin.cpp); scalar textures through the material's texture slots."""
        from ..materials import principled, principledthin

        imp = self.imp
        thin = obj.type == "principledthin"
        module = principledthin if thin else principled
        mat.type = obj.type
        mat.albedo, mat.base_texture = color_value(imp, obj, "base_color", (0.5,) * 3, texture_ok=True,
                                                   attribute_ok=True)
        mat.params["roughness"] = self._scalar(obj, mat, "roughness", 0.5)
        for name in module.SCALARS:
            value = self._scalar(obj, mat, name, 0.0)
            if name == "metallic":
                mat.metallic = value
            else:
                mat.params[name] = value
        transmits = obj.has("spec_trans") and not (obj.props["spec_trans"].kind == "float"
                                                    and obj.props["spec_trans"].value == 0)
        if thin:
            mat.ior = self._scalar(obj, mat, "eta", 1.5, field="ior")
        else:
            if obj.has("eta") and obj.has("specular"):
                raise error_at(obj.node.pos, f'{obj.label()}: give "eta" or "specular", not both (as Mitsuba)')
            eta = obj.float("eta", positive=True) if obj.has("eta") else None
            specular = obj.float("specular", 0.5) if eta is None else None
            mat.ior = principled.principled_eta(eta, specular, transmits)
        rates = tuple(obj.float(r, 1.0, minimum=0.0) for r in module.RATES)
        mat.params["rates"] = rates + (0.0,) * (4 - len(rates))


def _clamp01(imp, obj, rgb, what) -> tuple:
    clipped = tuple(min(max(float(x), 0.0), 1.0) for x in rgb)
    if clipped != tuple(float(x) for x in rgb):
        imp.warn(obj.node.pos, f"{obj.label()}: {what} {tuple(rgb)} clamped to [0, 1]")
    return clipped
