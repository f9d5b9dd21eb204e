"""The Mitsuba 3 plugins and parameters the XML loader takes: one definition, which the loader
checks every file against and docs/SCENE_FORMAT.md ("Mitsuba 3 plugin parameters") lists, table
for table (tests/scene/test_mitsuba_plugins.py keeps the two the same).

``HONOURED[tag][type]`` are the parameters each plugin renders as Mitsuba does;
``NEUTRAL[tag][type]`` are parameters that are read and
change nothing in the image Mitsuba makes either (output formats, clip planes a scene does not
reach, sampling choices that change the noise and not the mean).  A plugin type not listed here,
and a parameter that is in neither set, is refused with one line that names the plugin and the
parameter, as Mitsuba itself refuses a property that no plugin queries ("Unreferenced property").
"""
from __future__ import annotations

from ..lights import MITSUBA_TYPES as MITSUBA_LIGHTS
from ..materials import MITSUBA_TYPES

_SAMPLER = ("sample_count", "seed")
_SHAPE = ("to_world", "flip_normals", "interior", "exterior")
_ROUGH = ("distribution", "alpha", "alpha_u", "alpha_v")
_DIELECTRIC = ("int_ior", "ext_ior", "specular_reflectance", "specular_transmittance")
_CONDUCTOR = ("material", "eta", "k", "specular_reflectance")
_PLASTIC = ("diffuse_reflectance", "specular_reflectance", "int_ior", "ext_ior", "nonlinear")
_PRINCIPLED_SCALARS = ("roughness", "anisotropic", "spec_trans", "spec_tint", "sheen", "sheen_tint", "flatness")
_PATH = ("max_depth", "rr_depth", "hide_emitters")
_FOV = ("to_world", "fov", "fov_axis", "focal_length")
_MEDIUM = ("sigma_t", "albedo", "scale", "sample_emitters")

# the emitters that attach to a shape
SURFACE_EMITTERS = ("area", "directionalarea")

HONOURED: dict[str, dict[str, tuple[str, ...]]] = {
    "integrator": {
        "path": _PATH, "volpath": _PATH, "volpathmis": _PATH + ("use_spectral_mis",),
        # the same image as path in expectation (prb*: path replay's primal pass; ptracer: light tracing)
        "prb": _PATH, "prb_basic": _PATH, "prbvolpath": _PATH, "ptracer": _PATH,
        "direct": ("hide_emitters",), "aov": (), "moment": (),
    },
    "sensor": {
        "perspective": _FOV, "thinlens": _FOV + ("aperture_radius", "focus_distance"),
        "orthographic": ("to_world", "near_clip"),
    },
    "film": {"hdrfilm": ("width", "height")},
    "rfilter": {"box": (), "tent": ("radius",), "gaussian": ("stddev",), "mitchell": ("B", "C"), "catmullrom": (),
                "lanczos": ("lobes",)},
    "sampler": {t: _SAMPLER for t in ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")},
    "shape": {
        "obj": _SHAPE + ("filename", "face_normals", "flip_tex_coords"),
        "ply": _SHAPE + ("filename", "face_normals"),
        "serialized": _SHAPE + ("filename", "face_normals", "shape_index"),
        "sphere": _SHAPE + ("center", "radius"),
        "cylinder": _SHAPE + ("p0", "p1", "radius"),
        "rectangle": _SHAPE, "cube": _SHAPE, "disk": _SHAPE,
        "sdfgrid": _SHAPE + ("filename", "normals"),
        "shapegroup": (), "instance": ("to_world",),
    },
    "bsdf": {
        "diffuse": ("reflectance",),
        "dielectric": _DIELECTRIC, "thindielectric": _DIELECTRIC, "roughdielectric": _DIELECTRIC + _ROUGH,
        "conductor": _CONDUCTOR, "roughconductor": _CONDUCTOR + _ROUGH,
        "plastic": _PLASTIC, "roughplastic": _PLASTIC + ("distribution", "alpha"),
        "principled": ("base_color", "metallic", "clearcoat", "clearcoat_gloss", "eta", "specular")
        + _PRINCIPLED_SCALARS + ("main_specular_sampling_rate", "clearcoat_sampling_rate",
                                 "diffuse_reflectance_sampling_rate"),
        "principledthin": ("base_color", "eta", "diff_trans") + _PRINCIPLED_SCALARS
        + ("specular_reflectance_sampling_rate", "specular_transmittance_sampling_rate",
           "diffuse_transmittance_sampling_rate", "diffuse_reflectance_sampling_rate"),
        "twosided": (), "normalmap": ("normalmap", "flip_invalid_normals", "use_shadowing_function"),
        "bumpmap": ("scale", "flip_invalid_normals", "use_shadowing_function"),
        "mask": ("opacity",), "blendbsdf": ("weight",), "null": (),
    },
    "emitter": {
        "area": ("radiance", "sampling_weight"),
        "directionalarea": ("radiance", "sampling_weight"),
        "constant": ("radiance", "sampling_weight"),
        "envmap": ("filename", "scale", "to_world", "sampling_weight"),
    },
    "texture": {
        "bitmap": ("filename", "filter_type", "wrap_mode", "raw", "to_uv"),
        "checkerboard": ("color0", "color1", "to_uv"),
        "rawconstant": ("value",),
        "mesh_attribute": ("name", "scale"),
    },
    "spectrum": {"uniform": ("value",), "d65": ("color", "scale"), "blackbody": ("temperature",)},
    "medium": {"homogeneous": _MEDIUM, "heterogeneous": _MEDIUM},
    "phase": {"isotropic": (), "hg": ("g",)},
    "volume": {
        "gridvolume": ("filename", "filter_type", "wrap_mode", "to_world", "use_grid_bbox", "max_value"),
        "constvolume": ("value", "to_world"),
    },
}
# the BSDF plugins that material types read themselves (scene/materials/<name>.py, MITSUBA_PLUGINS)
HONOURED["bsdf"].update({plugin: t.mitsuba_plugins[plugin] for plugin, t in MITSUBA_TYPES.items()})
# the emitter plugins that light types read themselves (scene/lights/<name>.py, MITSUBA_PLUGINS)
HONOURED["emitter"].update({plugin: t.mitsuba_plugins[plugin] for plugin, t in MITSUBA_LIGHTS.items()})

NEUTRAL: dict[str, dict[str, tuple[str, ...]]] = {
    "integrator": {"direct": ("emitter_samples", "bsdf_samples", "shading_samples", "max_depth", "rr_depth"),
                   "aov": ("aovs",), "moment": ()},
    "sensor": {"perspective": ("near_clip", "far_clip", "shutter_open", "shutter_close", "srf"),
               "thinlens": ("near_clip", "far_clip", "shutter_open", "shutter_close", "srf"),
               "orthographic": ("far_clip", "shutter_open", "shutter_close", "srf")},
    "film": {"hdrfilm": ("pixel_format", "component_format", "file_format", "sample_border", "compensate",
                         "banner")},
    "sampler": {t: ("jitter", "scramble_seed", "strength") for t in HONOURED["sampler"]},
    "shape": {t: ("silhouette_sampling_weight",) for t in HONOURED["shape"] if t not in ("shapegroup", "instance")},
    "bsdf": {t: ("sample_visible",) for t in ("roughdielectric", "roughconductor", "roughplastic")},
    "emitter": {"envmap": ("mis_compensation",)},
    # format: the texels' storage precision (fp16 or the variant's float), 1e-3 at most
    "texture": {"bitmap": ("mip_filter_type", "accel", "format")},
    "spectrum": {"blackbody": ("wavelength_min", "wavelength_max")},
    "medium": {t: ("has_spectral_extinction",) for t in HONOURED["medium"]},
    "volume": {"gridvolume": ("raw", "accel")},
}


def refusal(obj) -> str:
    """The one line that refuses a plugin type the loader does not render."""
    known = ", ".join(HONOURED.get(obj.tag, {}))
    return f"{obj.label()}: {obj.tag} type \"{obj.type}\" is not supported (we render: {known})"


# plugins whose nested texture may have any name (Mitsuba's bumpmap takes its one texture whatever its name)
ANY_TEXTURE_NAME = {("bsdf", "bumpmap")}


def accepted(tag: str, plugin: str) -> frozenset | None:
    """The parameters the loader takes for ``<tag type="plugin">``; None for a plugin it does not
    render."""
    if plugin not in HONOURED.get(tag, {}):
        return None
    return frozenset(HONOURED[tag][plugin]) | frozenset(NEUTRAL.get(tag, {}).get(plugin, ()))
