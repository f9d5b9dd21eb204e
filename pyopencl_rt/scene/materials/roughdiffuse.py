"""`"roughdiffuse"` — rough diffuse reflection, the Oren-Nayar model (`cl/materials/roughdiffuse.h`;
Mitsuba 0.6's `roughdiffuse`, which Mitsuba XML files name too):

| key | type | default | meaning |
|---|---|---|---|
| `albedo` | [r, g, b] in [0, 1], or one number | 0.8 | the facets' diffuse reflectance |
| `albedo_texture` | image path | none | multiplies `albedo` (sRGB-decoded) |
| `alpha` | number >= 0 | 0.2 | the RMS slope of the grooves (Mitsuba's alpha; Oren and Nayar's sigma is alpha / sqrt(2) radians); 0 is Lambertian |
| `fast_approx` | boolean | false | Oren and Nayar's qualitative model instead of the full one (Mitsuba's `useFastApprox`) |

Rough surfaces such as plaster, clay or sand: brighter than Lambert's law toward a light behind the
viewer and at grazing angles, flatter overall.  The full model adds one interreflection between the
facets, whose share grows with the albedo squared.  Sampled cosine-weighted, as `diffuse`.  In a
Mitsuba XML file, `<bsdf type="roughdiffuse">` takes `reflectance` (a colour or a texture), `alpha`
and `use_fast_approx`, and is black from behind unless a `twosided` wraps it, as Mitsuba's.
"""
from __future__ import annotations

from ...device import abi
from . import diffuse

TOML_KEYS = diffuse.TOML_KEYS | {"alpha", "fast_approx"}
KERNEL_DEFINE = "HAS_MATERIAL_ROUGHDIFFUSE"
# alpha beyond this is the model's limit to 1e-6 (s2 / (s2 + 0.09) = 1 - 2e-7), and its square stays finite
MAX_ALPHA = 1e3
# Mitsuba XML: the plugin and the parameters it renders as Mitsuba does (scene/loaders/mitsuba_plugins.py)
MITSUBA_PLUGINS = {"roughdiffuse": ("reflectance", "alpha", "use_fast_approx")}


def read_toml(material, table) -> None:
    diffuse.read_toml(material, table)  # the facets' reflectance, as diffuse's
    material.alpha = table.number("alpha", 0.2, minimum=0.0)
    material.params["fast_approx"] = table.boolean("fast_approx", False)


def from_mitsuba(obj, material, color) -> None:
    """``<bsdf type="roughdiffuse">`` (``obj``, the XML loader's object): Mitsuba's reflectance
    (0.5; ``color(name, default)`` reads a colour or texture), alpha (0.2) and use_fast_approx
    (false); one-sided, as Mitsuba's BSDFs are."""
    material.albedo, material.base_texture = color("reflectance", (0.5,) * 3)
    material.alpha = obj.float("alpha", 0.2, minimum=0.0)
    material.params["fast_approx"] = bool(obj.boolean("use_fast_approx", False))
    material.one_sided = True


def pack(material, record) -> None:
    diffuse.pack(material, record)
    record["alpha"] = min(material.alpha, MAX_ALPHA)
    if material.params.get("fast_approx", False):
        record["flags"] |= abi.MATERIAL_FLAG_FAST_APPROX
