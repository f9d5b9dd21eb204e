"""The kernel ABI, declared once: everything host and device must agree on.

- :data:`STRUCTS`: the shared structs, as numpy structured dtypes;
- :data:`DEFINES`: the enums, sizes and queue counter slots, each ``NAME = define("NAME", value)``;
- :data:`WAVE_PARAMS`: the parameter list that every wavefront kernel shares, in order, each
  parameter saying where its value comes from (the scene, the settings or the run).

:func:`cl_header` generates from them the header prepended to every program build (struct
typedefs, ``#define`` s and the ``WAVE_PARAMS`` macro), so the kernels never restate them; the
host binds wavefront arguments by name (:class:`pyopencl_rt.device.kernel_args.KernelArgs`).
``tests/device/test_abi.py`` checks on every device that the compiled sizes, offsets, values and
kernel signatures equal these tables.  Struct fields are 4-byte scalars or arrays of them, so
numpy's packed layout and OpenCL's natural alignment agree byte for byte.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Every #define of the generated header (name -> int or float), in declaration order.
DEFINES: dict[str, int | float] = {}
# Defines a build may override with -D (the value here is the default): the header guards them.
OVERRIDABLE: set[str] = set()


def define(name: str, value, overridable: bool = False):
    """Record ``#define name value`` for the generated header and return ``value``."""
    if name in DEFINES:
        raise ValueError(f"{name} is defined twice")
    DEFINES[name] = value
    if overridable:
        OVERRIDABLE.add(name)
    return value


def define_enum(prefix: str, names) -> dict:
    """Record ``#define PREFIX_NAME k`` for the k-th of ``names`` and return {name: k}."""
    return {name: define(prefix + name.upper(), k) for k, name in enumerate(names)}


# ---------------------------------------------------------------------------------------------
# BVH node (64 bytes): a binary BVH whose nodes hold the boxes of *both* children (Aila & Laine 2009's
# layout), so a node fetch gives the traversal loop all it needs to test two boxes and pick the order; node 0: the root.
#
#   child_left / child_right : when the matching count is 0, index of the child node;
#                              when count > 0, the child is a leaf holding triangles
#                              [child, child + count) of the reordered triangle array.
#   count_left / count_right : 0 for an inner child, the number of triangles for a leaf,
#                              and -1 for an absent child (its box is empty: min=+inf, max=-inf).
# ---------------------------------------------------------------------------------------------
BVH_NODE = np.dtype(
    [
        ("bmin_left", np.float32, 3), ("child_left", np.int32),
        ("bmax_left", np.float32, 3), ("count_left", np.int32),
        ("bmin_right", np.float32, 3), ("child_right", np.int32),
        ("bmax_right", np.float32, 3), ("count_right", np.int32),
    ]
)
assert BVH_NODE.itemsize == 64

# A triangle as the traversal kernels read it: three vertices, each padded to a float4 (48 bytes).
TRIANGLE = np.dtype([("v0", np.float32, 4), ("v1", np.float32, 4), ("v2", np.float32, 4)])
assert TRIANGLE.itemsize == 48

# A material (464 bytes).  type selects the BSDF (cl/materials/dispatch.h dispatches on it; each type is
# documented at the top of cl/materials/<name>.h); every type may also emit.
#   albedo    diffuse, diffusetransmission: reflectance; gltf, principled, principledthin: base colour; plastic,
#             roughplastic: diffuse_reflectance
#   emission  emitted radiance (any type)
#   flags     bit 0: emission on both sides (default: only on the side the geometric normal
#             faces); bit 1: conductor Fresnel from `specular` as F0 (Schlick) instead of eta, k;
#             bit 2 (MATERIAL_FLAG_NONLINEAR): plastic, roughplastic: Mitsuba's `nonlinear`;
#             bit 3 (MATERIAL_FLAG_BECKMANN): roughplastic, conductor, dielectric: Beckmann (else GGX)
#             bit 4: tex_normal is a height (bump) map, not a tangent-space normal map; bit 5:
#             the reflectance (albedo, dielectric tint) is multiplied by the triangle's vertex
#             colours (tri_color); bits 6-8: the normal/bump map's Mitsuba conventions
#             (cl/scene/shading.h): flip normals that face away from the viewer, the shadowing
#             term of Estevez et al. 2019, directions on opposite sides of the two frames masked;
#             bit 9 (MATERIAL_FLAG_THIN): a thin dielectric sheet; bit 12
#             (MATERIAL_FLAG_ANISOTROPIC): the frame's x is dp/du; conductor, dielectric: alpha along
#             it, alpha_v along the bitangent; bit 13 (MATERIAL_FLAG_SEPARABLE): conductor, dielectric:
#             Mitsuba's separable shadowing-masking G1(wo) G1(wi) (else height-correlated)
#   specular  conductor: F0 (with MATERIAL_FLAG_CONDUCTOR_F0); dielectric: tint of both lobes;
#             plastic, roughplastic: specular_reflectance
#   alpha     microfacet roughness alpha (conductor, dielectric: alpha_u with
#             MATERIAL_FLAG_ANISOTROPIC; gltf: GGX; < 1e-3 is perfectly smooth);
#             roughplastic: the distribution's alpha (clamped to >= 1e-4, as Mitsuba's)
#   eta, k    conductor: complex index of refraction eta + i k per channel
#   metallic  gltf, principled
#   ior       dielectric: index of the inside relative to the outside; gltf: the dielectric's
#             index (F0 = ((ior - 1) / (ior + 1))^2); plastic, roughplastic, principled: the
#             relative index eta = int_ior / ext_ior; principledthin: the sheet's eta
# The fields after the texture indices serve the types of Mitsuba 3 (issue 24):
#   alpha_v      conductor, dielectric with MATERIAL_FLAG_ANISOTROPIC: the roughness along the
#                bitangent (else unused)
#   fdr          plastic: the internal diffuse Fresnel reflectance fdr_int (Egan & Hilgeman's fit
#                at 1 / eta); roughplastic: the rough interface's internal reflectance
#   spec_weight  plastic, roughplastic: the specular sampling weight s / (d + s) of the means of
#                specular_reflectance and diffuse_reflectance
#   roughness, anisotropic, spec_trans, spec_tint, sheen, sheen_tint, clearcoat,
#   clearcoat_gloss, flatness, diff_trans   principled, principledthin: Mitsuba's parameters
#   rates        principled: the sampling rates of the main specular lobe, the clearcoat and
#                the diffuse reflection (4th unused); principledthin: of the specular
#                reflection, specular transmission, diffuse transmission and diffuse reflection
#   table        a type's own block: roughplastic's external transmittance at cos(theta) = k / 63, k = 0..63
#                (Mitsuba's table, linearly interpolated); the COATED_*, MIX_*, DT_* entries of its header for
#                coatedconductor's layer, mix's weight and blended records, diffusetransmission's transmittance
MATERIAL_TYPES = define_enum("MATERIAL_", ("diffuse", "conductor", "dielectric", "gltf", "plastic", "roughplastic",
                                           "principled", "principledthin", "mix", "roughdiffuse", "coatedconductor",
                                           "diffusetransmission"))
(MATERIAL_DIFFUSE, MATERIAL_CONDUCTOR, MATERIAL_DIELECTRIC, MATERIAL_GLTF, MATERIAL_PLASTIC, MATERIAL_ROUGHPLASTIC,
 MATERIAL_PRINCIPLED, MATERIAL_PRINCIPLEDTHIN, MATERIAL_MIX, *_) = MATERIAL_TYPES.values()
MATERIAL_FLAG_TWO_SIDED = define("MATERIAL_FLAG_TWO_SIDED", 1)
MATERIAL_FLAG_CONDUCTOR_F0 = define("MATERIAL_FLAG_CONDUCTOR_F0", 2)
MATERIAL_FLAG_NONLINEAR = define("MATERIAL_FLAG_NONLINEAR", 4)
MATERIAL_FLAG_BECKMANN = define("MATERIAL_FLAG_BECKMANN", 8)
ROUGH_TRANSMITTANCE_RES = define("ROUGH_TRANSMITTANCE_RES", 64)  # entries of Material.table
TEX_SLOTS = define("TEX_SLOTS", 6)  # Material.tex_scalar
MATERIAL_FLAG_BUMP_MAP = define("MATERIAL_FLAG_BUMP_MAP", 16)
MATERIAL_FLAG_VERTEX_COLOR = define("MATERIAL_FLAG_VERTEX_COLOR", 32)
MATERIAL_FLAG_MAP_FLIP = define("MATERIAL_FLAG_MAP_FLIP", 64)
MATERIAL_FLAG_MAP_TERMINATOR = define("MATERIAL_FLAG_MAP_TERMINATOR", 128)
MATERIAL_FLAG_MAP_SIDE = define("MATERIAL_FLAG_MAP_SIDE", 256)
MATERIAL_FLAG_MAP_WHOLE = define("MATERIAL_FLAG_MAP_WHOLE", 65536)  # pbrt's maps seen from behind: cl/scene/shading.h
MATERIAL_FLAG_THIN = define("MATERIAL_FLAG_THIN", 512)  # dielectric: a thin sheet, Mitsuba's thindielectric
# MASK: Mitsuba's mask, met with probability `opacity` (cl/render/path.h); ONE_SIDED: black from behind (Mitsuba's
# BSDFs outside twosided); CUTOUT: a cut-out in the intersection, alpha `opacity`, `alpha_cutoff` (cl/scene/scene.h)
MATERIAL_FLAG_MASK, MATERIAL_FLAG_ONE_SIDED, MATERIAL_FLAG_CUTOUT = (
    define("MATERIAL_FLAG_MASK", 1024), define("MATERIAL_FLAG_ONE_SIDED", 2048), define("MATERIAL_FLAG_CUTOUT", 4096))
MATERIAL_FLAG_ANISOTROPIC = define("MATERIAL_FLAG_ANISOTROPIC", 8192)
MATERIAL_FLAG_SEPARABLE = define("MATERIAL_FLAG_SEPARABLE", 16384)
MATERIAL_FLAG_FAST_APPROX = define("MATERIAL_FLAG_FAST_APPROX", 32768)  # roughdiffuse: Oren-Nayar's qualitative model
MATERIAL = np.dtype(
    [("albedo", np.float32, 3), ("type", np.int32), ("emission", np.float32, 3), ("flags", np.int32),
     ("specular", np.float32, 3), ("alpha", np.float32), ("eta", np.float32, 3), ("metallic", np.float32),
     ("k", np.float32, 3), ("ior", np.float32),
     ("tex_base", np.int32), ("tex_mr", np.int32), ("tex_emission", np.int32), ("tex_normal", np.int32),
     ("alpha_v", np.float32), ("fdr", np.float32), ("spec_weight", np.float32), ("roughness", np.float32),
     ("anisotropic", np.float32), ("spec_trans", np.float32), ("spec_tint", np.float32), ("sheen", np.float32),
     ("sheen_tint", np.float32), ("clearcoat", np.float32), ("clearcoat_gloss", np.float32),
     ("flatness", np.float32), ("diff_trans", np.float32), ("rates", np.float32, 4),
     ("tex_scalar", np.int32, TEX_SLOTS), ("tex_params", np.int32),
     ("table", np.float32, ROUGH_TRANSMITTANCE_RES),
     ("normal_scale", np.float32), ("opacity", np.float32), ("alpha_cutoff", np.float32), ("pad2", np.int32)]
)
assert MATERIAL.itemsize == 464
# Texture indices (into the TEXTURE table; -1 = none), used only when the program is built with
# HAS_TEXTURES (cl/scene/textures.h):
#   tex_base      RGB multiplies albedo (diffuse, gltf baseColor, plastic diffuse_reflectance,
#                 principled base_color) or tint (dielectric)
#   tex_mr        glTF metallicRoughness: G multiplies roughness (alpha *= G^2), B multiplies metallic
#   tex_emission  RGB multiplies emission
#   tex_scalar    up to TEX_SLOTS textures of scalar parameters, the used slots first (-1 after
#                 them): slot k's R channel multiplies the parameter TEXP_* that bits 4k..4k+3 of
#                 tex_params name (the host stores such a texture's luminance in R, Mitsuba's eval_1)
# TEXP_<FIELD>: the Material field each multiplies (TEXP_ETA: ior)
_TEXP = define_enum("TEXP_", ("alpha", "roughness", "metallic", "anisotropic", "spec_trans", "spec_tint", "sheen",
                              "sheen_tint", "clearcoat", "clearcoat_gloss", "flatness", "diff_trans", "eta", "alpha_v"))
(TEXP_ALPHA, TEXP_ROUGHNESS, TEXP_METALLIC, TEXP_ANISOTROPIC, TEXP_SPEC_TRANS, TEXP_SPEC_TINT, TEXP_SHEEN,
 TEXP_SHEEN_TINT, TEXP_CLEARCOAT, TEXP_CLEARCOAT_GLOSS, TEXP_FLATNESS, TEXP_DIFF_TRANS, TEXP_ETA, TEXP_ALPHA_V) = \
    _TEXP.values()
_TEXP["opacity"] = TEXP_OPACITY = define("TEXP_OPACITY", len(_TEXP))  # Material.opacity (mask, cut-out)
_TEXP["mix_weight"] = TEXP_MIX_WEIGHT = define("TEXP_MIX_WEIGHT", len(_TEXP))  # a mix's weight (in its table)
TEXTURE_PARAMS = {k: "ior" if name == "eta" else name for name, k in _TEXP.items()}
#   tex_normal    a tangent-space normal map (RGB = (n + 1) / 2, relative to the shading frame), or
#                 with MATERIAL_FLAG_BUMP_MAP a height map (its luminance), perturbing the
#                 shading normal (HAS_NORMAL_MAPS, cl/scene/shading.h); normal_scale scales the
#                 normal map's x and y (glTF's normalTexture.scale) or the bump map's gradient
# A texture (112 bytes): texels [offset, offset + width * height) of the float4 texel buffer, row by row from the top
# (v = 0 the top row, as in glTF; OBJ's v is flipped at load), linear (sRGB images decoded at load: flags bit 0);
# channels: the source's (informative).  Looked up (cl/scene/textures.h, as Mitsuba's bitmap) at (a u + b v + c,
# d u + e v + f), to_uv = (a..f), of the hit's uv, or with mapping TEXTURE_MAP_PLANAR, _SPHERICAL, _CYLINDRICAL of the
# hit point through frame (3 x 4 rows: pbrt-v4's mappings); wrap TEXTURE_WRAP_*, filter TEXTURE_FILTER_*; texels
# shared.  TEXTURE_MAP_DIRECTION_MIX (pbrt-v4's directionmix, no texels): |ng . frame[0:3]| of record children[0]
# and the rest of children[1]; children -1 otherwise.
TEXTURE_FLAG_SRGB = define("TEXTURE_FLAG_SRGB", 1)
TEXTURE_WRAPS = define_enum("TEXTURE_WRAP_", ("repeat", "mirror", "clamp"))
TEXTURE_FILTERS = define_enum("TEXTURE_FILTER_", ("bilinear", "nearest"))
TEXTURE_MAPS = define_enum("TEXTURE_MAP_", ("uv", "planar", "spherical", "cylindrical", "direction_mix"))
TEXTURE_WRAP_REPEAT, TEXTURE_WRAP_MIRROR, TEXTURE_WRAP_CLAMP = TEXTURE_WRAPS.values()
TEXTURE_FILTER_BILINEAR, TEXTURE_FILTER_NEAREST = TEXTURE_FILTERS.values()
TEXTURE_MAP_UV, TEXTURE_MAP_PLANAR, TEXTURE_MAP_SPHERICAL, TEXTURE_MAP_CYLINDRICAL, TEXTURE_MAP_DIRECTION_MIX = TEXTURE_MAPS.values()
TEXTURE = np.dtype([("offset", np.int32), ("width", np.int32), ("height", np.int32), ("channels", np.int32),
                    ("flags", np.int32), ("wrap", np.int32), ("filter", np.int32), ("mapping", np.int32),
                    ("to_uv", np.float32, 6), ("children", np.int32, 2), ("frame", np.float32, 12)])
assert TEXTURE.itemsize == 112

# Participating media (cl/render/media.h; pyopencl_rt/scene/media.py packs them).  A medium (64 bytes):
#   type      MEDIUM_TYPE_HOMOGENEOUS (sigma_t everywhere) or MEDIUM_TYPE_GRID (sigma_t times its density grid, inside the
#             grid's box only: vacuum elsewhere)
#   sigma_t   extinction per channel [1 / scene unit], any scale folded in; a grid medium's multiplies its density
#   albedo    single-scattering albedo sigma_s / sigma_t (unless albedo_grid >= 0)
#   majorant  per channel, >= sigma_t(x) at every x of the medium (homogeneous: sigma_t itself)
#   phase     PHASE_ISOTROPIC, or PHASE_HG with asymmetry g (g > 0 scatters forward, as in Mitsuba and pbrt)
#   density_grid, albedo_grid: indices into the MEDIUM_GRID table (-1: none)
#   flags     MEDIUM_FLAG_SAMPLE_EMITTERS: next-event estimation at its scattering events (Mitsuba's
#             sample_emitters, on by default)
MEDIUM_TYPE_HOMOGENEOUS = define("MEDIUM_TYPE_HOMOGENEOUS", 0)
MEDIUM_TYPE_GRID = define("MEDIUM_TYPE_GRID", 1)
PHASE_ISOTROPIC = define("PHASE_ISOTROPIC", 0)
PHASE_HG = define("PHASE_HG", 1)
MEDIUM_FLAG_SAMPLE_EMITTERS = define("MEDIUM_FLAG_SAMPLE_EMITTERS", 1)
MEDIUM = np.dtype([("sigma_t", np.float32, 3), ("type", np.int32), ("albedo", np.float32, 3), ("phase", np.int32),
                   ("majorant", np.float32, 3), ("g", np.float32), ("density_grid", np.int32),
                   ("albedo_grid", np.int32), ("flags", np.int32), ("pad", np.int32)])
assert MEDIUM.itemsize == 64
# A 3-D grid of a medium (80 bytes): values [offset, offset + nx ny nz channels) of the grid_data buffer,
# texel (x, y, z) channel c at offset + ((z ny + y) nx + x) channels + c (the order of Mitsuba's .vol files).  The
# grid fills the unit cube of its local space, texel centres at ((x + 0.5) / nx, ...); to_local maps world points
# to local ones (row-major 3 x 4).  channels: 1 (a value for every channel) or 3 (RGB).
#   filter    GRID_TRILINEAR (between texel centres) or GRID_NEAREST
#   outside   GRID_CLAMP: beyond the outer texel centres the edge texels continue (Mitsuba's clamp); GRID_ZERO:
#             texels beyond the grid are 0 (pbrt-v4's SampledGrid)
#   max_value the largest value of any channel
GRID_TRILINEAR = define("GRID_TRILINEAR", 0)
GRID_NEAREST = define("GRID_NEAREST", 1)
GRID_CLAMP = define("GRID_CLAMP", 0)
GRID_ZERO = define("GRID_ZERO", 1)
MEDIUM_GRID = np.dtype([("offset", np.int32), ("nx", np.int32), ("ny", np.int32), ("nz", np.int32),
                        ("channels", np.int32), ("filter", np.int32), ("outside", np.int32), ("max_value", np.float32),
                        ("to_local", np.float32, 12)])
assert MEDIUM_GRID.itemsize == 80
# How a surface bounds media (16 bytes; tri_interface / shape_interface index it, -1: an ordinary surface in
# whatever medium the ray is in).  interior, exterior: media (MEDIUM_VACUUM: none); flags:
#   MEDIUM_IF_TRANSITION  crossing the surface enters `exterior` along the front side's normal (dot(d, ng) > 0),
#                         else `interior` (Mitsuba's target_medium); without it the ray keeps its medium
#   MEDIUM_IF_NULL        index-matched: no surface scattering, the ray goes straight on (Mitsuba's null BSDF,
#                         pbrt's "interface" material)
MEDIUM_VACUUM = define("MEDIUM_VACUUM", -1)
MEDIUM_IF_TRANSITION = define("MEDIUM_IF_TRANSITION", 1)
MEDIUM_IF_NULL = define("MEDIUM_IF_NULL", 2)
MEDIUM_INTERFACE = np.dtype([("interior", np.int32), ("exterior", np.int32), ("flags", np.int32), ("pad", np.int32)])
assert MEDIUM_INTERFACE.itemsize == 16

# An analytic shape (128 bytes): its type (cl/shapes/<name>.h, scene/shapes/<name>.py), the parameters it names.
SHAPE_TYPES = define_enum("SHAPE_", ("sphere", "disk", "cylinder"))
SHAPE = np.dtype([("params", np.float32, 28), ("type", np.int32), ("pad", np.int32, 3)])

# An emitter that next-event estimation samples (144 bytes; cl/render/lights.h documents each kind).
#   kind: LIGHT_TRIANGLE (prim = original face index) or LIGHT_SHAPE (prim = shape index),
#         LIGHT_DIRECTIONAL_AREA (prim as a triangle's, rgb its radiance, emitted along its normal alone),
#         LIGHT_POINT, LIGHT_DIRECTIONAL, LIGHT_SPOT, LIGHT_PROJECTOR (delta lights: sampled, never
#         hit) or LIGHT_ENVIRONMENT (prim = the map's width, material = its height; 0 x 0 = constant
#         radiance; cells: its sampling cells per texel along each axis)
#   pmf: the light sampler's probability of it (a light in the BVH: the tree's); alias, alias_prob: its alias entry
#   p:      point, spot, projector: position; directional, environment: the scene's bounding sphere's centre
#   radius: directional, environment: radius of the scene's bounding sphere (shadow-ray length)
#   dir:    directional: unit direction of travel; projector: to_world's image of local +z
#   rgb:    point, spot: intensity [W/sr] (a spot's on its axis); directional: irradiance on a
#           perpendicular surface; environment: radiance or the map's scale; projector: see lights.h
#   spot, projector (cl/render/lights.h has the formulas): texture (-1: none), flags
#   (LIGHT_SPOT_SMOOTHSTEP: pbrt-v4's falloff; LIGHT_PROJECTOR_COS3: Mitsuba's normalisation), frame
#   (the rows of the world-to-light 3x3 map), cone (cos cutoff, cos beam, cutoff [rad], 1 /
#   (cutoff - beam) [1/rad]), uv_scale (local (x, y, z) -> texture (0.5 + uv_scale (x, y) / z))
# The environment map's buffer (env_map): a header of ENV_MAP_HEADER floats, then the H x W RGB
# texels row by row from the top.  Header: the rows of the 3x3 world-to-map rotation at floats 0-2,
# 4-6 and 8-10 (directions are turned into the map's frame before (u, v) is taken), and at 3 and 7
# the row coordinate of v: y = v * v_scale + v_offset (H, -0.5: rows centred in [0, 1]; H - 1, 0:
# the first and last rows on the poles, Mitsuba's envmap); the texels are interpolated bilinearly.
ENV_MAP_HEADER = define("ENV_MAP_HEADER", 16)
LIGHT_TYPES = define_enum("LIGHT_", ("triangle", "shape", "point", "directional", "environment", "spot", "projector",
                                     "directional_area", "goniometric"))  # cl/lights/<name>.h each, but the surfaces
(LIGHT_TRIANGLE, LIGHT_SHAPE, LIGHT_POINT, LIGHT_DIRECTIONAL, LIGHT_ENVIRONMENT, LIGHT_SPOT, LIGHT_PROJECTOR,
 LIGHT_DIRECTIONAL_AREA, LIGHT_GONIOMETRIC) = LIGHT_TYPES.values()
TRIANGLE_LIGHTS = (LIGHT_TRIANGLE, LIGHT_DIRECTIONAL_AREA)  # their prim is a triangle
DELTA_LIGHTS = (LIGHT_POINT, LIGHT_DIRECTIONAL, LIGHT_SPOT, LIGHT_PROJECTOR, LIGHT_DIRECTIONAL_AREA, LIGHT_GONIOMETRIC)
LIGHT_SPOT_SMOOTHSTEP = define("LIGHT_SPOT_SMOOTHSTEP", 1)
LIGHT_PROJECTOR_COS3 = define("LIGHT_PROJECTOR_COS3", 1)
LIGHT = np.dtype([("kind", np.int32), ("prim", np.int32), ("pmf", np.float32), ("alias_prob", np.float32),
                  ("alias", np.int32), ("material", np.int32), ("area", np.float32), ("cells", np.int32),
                  ("p", np.float32, 3), ("radius", np.float32), ("dir", np.float32, 3), ("texture", np.int32),
                  ("rgb", np.float32, 3), ("flags", np.int32), ("frame", np.float32, 9), ("cone", np.float32, 4),
                  ("uv_scale", np.float32, 2), ("trail", np.int32)])
assert LIGHT.itemsize == 144

# The camera (96 bytes), perspective (pinhole or thin lens) or orthographic.  A pixel (x, y) with
# jitter (jx, jy) (from the pixel's top-left corner) maps to the film position sx = (x+jx)/W*2-1,
# sy = 1-(y+jy)/H*2 in [-1, 1]^2 (outside it for a filter wider than the pixel).
#   PROJECTION_PERSPECTIVE: the direction forward + sx * right + sy * up from origin, where right
#     and up are already scaled by tan(fov/2) (and the aspect ratio, for right);
#   PROJECTION_ORTHOGRAPHIC: the direction forward (unit) from origin + sx * right + sy * up, right
#     and up being the half width and half height of the region the film sees.
# Thin lens when lens_radius > 0 (either projection): the ray leaves a point of the lens disk
# (radius lens_radius, spanned by the unit right and up) toward the pinhole ray's point at distance
# focus_distance along forward.
# The jitter is drawn from the pixel reconstruction filter (cl/render/filter.h; filter importance sampling): filter is
# a FILTER_* method, filter_radius its half widths along x and y in pixels, filter_weight the magnitude of every
# sample's weight (1 for filters without negative lobes; the sign is that of the filter where the sample fell);
# FILTER_TABULATED: filter_knots knots per axis in filter_cdf and filter_segments segments along each axis (else 0;
# pyopencl_rt/render/filters.py lays the tables out: per axis FILTER_MAX_SEGMENTS records of FILTER_SEGMENT_FLOATS,
# then the knots as (x, f) pairs).
PROJECTION_PERSPECTIVE = define("PROJECTION_PERSPECTIVE", 0)
PROJECTION_ORTHOGRAPHIC = define("PROJECTION_ORTHOGRAPHIC", 1)
PROJECTIONS = {"perspective": PROJECTION_PERSPECTIVE, "orthographic": PROJECTION_ORTHOGRAPHIC}
# how the jitter is drawn: uniform over [-r, r] (box), by inverting the tent's CDF in closed form,
# or from a tabulated CDF of |f| (gaussian, mitchell, lanczos: pyopencl_rt/render/filters.py)
FILTER_BOX = define("FILTER_BOX", 0)
FILTER_TENT = define("FILTER_TENT", 1)
FILTER_TABULATED = define("FILTER_TABULATED", 2)
FILTER_MAX_SEGMENTS = define("FILTER_MAX_SEGMENTS", 64)  # stretches of one sign along an axis
FILTER_SEGMENT_FLOATS = define("FILTER_SEGMENT_FLOATS", 5)  # u at its start, cells per unit u, first, last, negative
CAMERA = np.dtype(
    [("origin", np.float32, 3), ("width", np.int32), ("forward", np.float32, 3), ("height", np.int32),
     ("right", np.float32, 3), ("lens_radius", np.float32), ("up", np.float32, 3), ("focus_distance", np.float32),
     ("projection", np.int32), ("filter", np.int32), ("filter_knots", np.int32), ("filter_weight", np.float32),
     ("filter_radius", np.float32, 2), ("filter_segments", np.int32, 2)]
)
assert CAMERA.itemsize == 96

# A 4-wide BVH node (128 bytes; pyopencl_rt/accel/bvh_wide.py builds it, cl/accel/bvh_wide.h traverses it):
# the boxes of up to four children in structure-of-arrays form (each field is one float4, so one
# slab test covers all four), then per child slot:
#   child : float4 offset into the wide buffer of the child node (count 0) or of its first
#           Tri4 packet (count > 0); 0 for an absent child
#   count : 0 = inner node, > 0 = leaf of `count` Tri4 packets, -1 = absent (box +inf / -inf)
def _wide_node(lanes: int) -> np.dtype:
    return np.dtype([(f"{b}_{c}", np.float32, lanes) for b in ("bmin", "bmax") for c in "xyz"]
                    + [("child", np.int32, lanes), ("count", np.int32, lanes)])


def _tri_packet(lanes: int) -> np.dtype:
    return np.dtype([(f"v{k}{c}", np.float32, lanes) for k in range(3) for c in "xyz"] + [("tri", np.int32, lanes)])


WIDE_NODE = _wide_node(4)
assert WIDE_NODE.itemsize == 128

# Four triangles in structure-of-arrays form (160 bytes): vertex k's coordinate c of the four
# lanes in v{k}{c}, and each lane's index into the binary BVH's reordered triangle array in tri
# (-1 for a padding lane, whose vertices are NaN so that it can never hit).
TRI4 = _tri_packet(4)
assert TRI4.itemsize == 160

# The 8-wide layout (cl/accel/bvh_wide8.h, for AVX2 CPUs): the same records with eight lanes, each
# field one float8/int8, so a node (256 bytes) is one 8-lane slab test and a Tri8 packet (320
# bytes) one 8-lane triangle test.  Offsets in child are in float8 (32-byte) units of the buffer.
WIDE8_NODE = _wide_node(8)
assert WIDE8_NODE.itemsize == 256
TRI8 = _tri_packet(8)
assert TRI8.itemsize == 320

# An instance of a shape group in the two-level BVH (112 bytes; cl/accel/instances.h): world-to-object and
# object-to-world 3x4 rows, its group's BVH (bytes into blas_nodes) and first triangle, its instance_motion (-1: none).
INSTANCE = np.dtype([("world_to_object", np.float32, 12), ("object_to_world", np.float32, 12),
                     ("blas_offset", np.int32), ("tri_offset", np.int32), ("motion", np.int32), ("pad", np.int32)])
assert INSTANCE.itemsize == 112
from .light_node import LIGHT_NODE  # noqa: E402  (the light BVH's node record, documented there)
from .motion_record import MOTION  # noqa: E402  (a moving instance's way, documented there)
# Registry of every shared struct: name -> dtype.  Add new shared structs here.
STRUCTS: dict[str, np.dtype] = {
    "BVHNode": BVH_NODE, "Material": MATERIAL, "Shape": SHAPE, "Instance": INSTANCE, "Motion": MOTION,
    "Light": LIGHT, "LightNode": LIGHT_NODE, "Camera": CAMERA,
    "WideNode": WIDE_NODE, "Tri4": TRI4, "Wide8Node": WIDE8_NODE, "Tri8": TRI8, "Texture": TEXTURE,
    "Medium": MEDIUM, "MediumGrid": MEDIUM_GRID, "MediumInterface": MEDIUM_INTERFACE,
}


# ---------------------------------------------------------------------------------------------
# The hit encoding (Hit.prim, hit_prim[]): prim >= 0 is a triangle (index into the BVH-reordered
# triangle array), PRIM_MISS a miss, and shape s is PRIM_SHAPE_FIRST - s (cl/scene/shapes.h).
PRIM_MISS = define("PRIM_MISS", -1)
PRIM_SHAPE_FIRST = define("PRIM_SHAPE_FIRST", -2)

# Sizes.  The stacks are bounded by the builders' depth limits (accel/bvh.py, accel/bvh_wide.py
# check them), and kept small because PoCL holds a private copy per work-item of a work-group.
BVH_STACK_SIZE = define("BVH_STACK_SIZE", 64)    # cl/accel/bvh.h: one entry per level
WIDE_STACK_SIZE = define("WIDE_STACK_SIZE", 96)  # cl/accel/bvh_wide.h: up to 3 entries per wide level
TRI4_UNITS = define("TRI4_UNITS", TRI4.itemsize // 16)  # float4s per Tri4 packet
# cl/accel/bvh_wide8.h: up to 7 entries per 8-wide level, which descends >= 3 binary levels (<= 20 levels)
WIDE8_STACK_SIZE = define("WIDE8_STACK_SIZE", 144)
TRI8_UNITS = define("TRI8_UNITS", TRI8.itemsize // 32)  # float8s per Tri8 packet
# Node boxes grow by this fraction of the scene's largest coordinate (cl/accel/intersect.h,
# "Conservative on purpose"); the host pads, the kernels rely on it.
BOX_PAD_RELATIVE = define("BOX_PAD_RELATIVE", 2.0**-20)
# Work-group size of every wavefront launch: shade.cl sizes its local arrays with it.
WAVE_LOCAL_SIZE = define("WAVE_LOCAL_SIZE", 64, overridable=True)
# Passes a render may have: the kernels number them with a 32-bit int (first_pass, pass), so
# --spp, a scene's spp and a checkpoint's pass count are refused beyond it (not a define).
MAX_PASSES = 2**31 - 1

# Slots of the wavefront's counters[] buffer.  The first three are the per-iteration queue
# lengths, zeroed by the host before every extend (shade.cl indexes a 3-entry array with them);
# the ring's per-pass completion counts start at COUNTER_PASS_DONE.
COUNTER_QUEUE_OUT = define("COUNTER_QUEUE_OUT", 0)  # paths that continue (queue_out)
COUNTER_SHADOW = define("COUNTER_SHADOW", 1)        # shadow rays queued by shade (shadow_q)
COUNTER_TERM = define("COUNTER_TERM", 2)            # finished paths (term_q)
COUNTER_NONFINITE = define("COUNTER_NONFINITE", 3)  # samples dropped as NaN/inf, over the whole run
# rays traced by the megakernel (cl/megakernel/path.cl) since the counters were last cleared: the
# wavefront counts them on the host from its queue lengths
COUNTER_RAYS_EXTEND = define("COUNTER_RAYS_EXTEND", 4)
COUNTER_RAYS_SHADOW = define("COUNTER_RAYS_SHADOW", 5)
COUNTER_PASS_DONE = define("COUNTER_PASS_DONE", 8)
COUNTERS = {"queue_out": COUNTER_QUEUE_OUT, "shadow": COUNTER_SHADOW, "term": COUNTER_TERM,
            "nonfinite": COUNTER_NONFINITE, "rays_extend": COUNTER_RAYS_EXTEND, "rays_shadow": COUNTER_RAYS_SHADOW}
ITERATION_COUNTERS = 3
assert sorted((COUNTER_QUEUE_OUT, COUNTER_SHADOW, COUNTER_TERM)) == list(range(ITERATION_COUNTERS))
assert max(COUNTERS.values()) < COUNTER_PASS_DONE
assert COUNTER_RAYS_SHADOW == COUNTER_RAYS_EXTEND + 1  # the megakernel copies the two as one pair

# Samplers (cl/render/sampler.h: SAMPLER, or the kernels' `sampler`, is one of these).
# SOBOL_LOG2_ROUND: the Sobol sampler gives each pixel a block of 2^SOBOL_LOG2_ROUND consecutive
# indices of one sequence per 2^((32 - SOBOL_LOG2_ROUND) / 2)-pixel-square tile (the Morton order
# of pbrt-v4's ZSobol); passes beyond a block start a new, independently scrambled round.
SAMPLERS = define_enum("SAMPLER_", ("independent", "sobol", "stratified"))
SAMPLER_INDEPENDENT, SAMPLER_SOBOL, SAMPLER_STRATIFIED = SAMPLERS.values()
# the estimators, in the order of scene.model.INTEGRATORS ("path", "bsdf", "nee"): a kernel argument
INTEGRATOR_MIS, INTEGRATOR_BSDF, INTEGRATOR_NEE = define_enum("INTEGRATOR_", ("mis", "bsdf", "nee")).values()
SOBOL_LOG2_ROUND = define("SOBOL_LOG2_ROUND", 16, overridable=True)

# The per-sample AOVs (compiled with HAS_AOVS; cl/render/aov.h): AOV_FLOATS floats per path in
# aov_path and per pixel and pass in aov_ring, at these offsets.  albedo and normal are those of
# the first non-delta hit (albedo times the throughput of the delta bounces before it), position
# and depth those of the first hit, and hit is 1 when the camera ray hit something (the host
# divides position and depth by the summed hits).  Positions are relative to the camera.
AOV_ALBEDO = define("AOV_ALBEDO", 0)
AOV_NORMAL = define("AOV_NORMAL", 3)
AOV_POSITION = define("AOV_POSITION", 6)
AOV_DEPTH = define("AOV_DEPTH", 9)
AOV_HIT = define("AOV_HIT", 10)
AOV_PENDING = define("AOV_PENDING", 11)  # aov_path only: 1 until the first non-delta hit is recorded
AOV_FLOATS = define("AOV_FLOATS", 12)

# ---------------------------------------------------------------------------------------------
# The wavefront kernels' shared parameter list.
_SCALAR_NUMPY = {"int": np.int32, "uint": np.uint32, "float": np.float32}
_VECTOR_SIZE = {"float2": 8, "float4": 16}
PARAM_SOURCES = ("scene", "settings", "run")


@dataclass(frozen=True)
class Param:
    """One kernel parameter.

    kind      "const" (``__global const ctype *``), "global" (``__global ctype *``) or
              "scalar" (``const ctype``)
    per_slot  path state and queues: ctype elements per wave slot (the host allocates
              ``per_slot * wave_size`` of them)
    launch    set at every launch (the queues that swap, the per-stage scalars, 0 unless given)
              rather than once when the wavefront is set up
    source    "scene" (in a checkpoint's scene key: render/scene_inputs.py), "settings" (the render
              key hashes them) or "run" (path state, queues, counters, films)
    """

    name: str
    kind: str
    ctype: str
    doc: str = ""
    per_slot: int = 0
    launch: bool = False
    source: str = ""

    def __post_init__(self):
        if self.kind not in ("const", "global", "scalar"):
            raise ValueError(f"{self.name}: unknown kind {self.kind!r}")
        if self.source not in PARAM_SOURCES:
            raise ValueError(f"{self.name}: source {self.source!r} is not one of {PARAM_SOURCES}")
        if self.kind == "scalar" and self.ctype not in _SCALAR_NUMPY:
            raise ValueError(f"{self.name}: scalar of unsupported type {self.ctype!r}")

    @property
    def itemsize(self) -> int:
        """Bytes of one ctype element."""
        if self.ctype in STRUCTS:
            return STRUCTS[self.ctype].itemsize
        return _VECTOR_SIZE.get(self.ctype) or np.dtype(_SCALAR_NUMPY[self.ctype]).itemsize

    def scalar(self, value):
        """``value`` as the numpy scalar that pyopencl passes by value for this parameter."""
        return _SCALAR_NUMPY[self.ctype](value)


def _scene(name, kind, ctype, doc=""):
    return Param(name, kind, ctype, doc, source="scene")


def _path(name, ctype, per_slot, doc=""):
    return Param(name, "global", ctype, doc, per_slot=per_slot, source="run")


# In the order of the kernels' signatures; the host binds by name, so the order is free, but
# every kernel takes the whole list (the host sets the fixed arguments once, on every kernel).
WAVE_PARAMS: tuple[Param, ...] = (
    # the scene, uploaded once
    _scene("nodes", "const", "BVHNode", "binary BVH nodes, or the wide BVH blob with BVH_WIDE"),
    _scene("tris", "const", "float4", "the binary layout's reordered triangles, 3 vertices each (wide: a dummy)"),
    # what shading reads of a triangle (MESH_PARAMS): the scene's vertices (3 floats) and faces (3 indices)
    _scene("vertices", "const", "float"), _scene("faces", "const", "int"),
    _scene("prim_ids", "const", "int", "the face of each reordered triangle"),
    _scene("tri_material", "const", "int", "material per reordered triangle"),
    _scene("tri_light", "const", "int", "light per reordered triangle, -1 if none"),
    _scene("shape_nodes", "const", "BVHNode", "the analytic shapes' BVH (leaves: one shape each)"),
    _scene("shapes", "const", "Shape"), _scene("shape_material", "const", "int"),
    _scene("shape_light", "const", "int", "light per shape, -1 if none"),
    _scene("materials", "const", "Material"),
    _scene("lights", "const", "Light"), _scene("light_nodes", "const", "LightNode", "the light BVH (LIGHT_TREE)"),
    _scene("camera", "const", "Camera"), _scene("camera_motion", "const", "Motion", "its way (HAS_CAMERA_MOTION)"),
    # path state, structure of arrays indexed by wave slot
    _path("ray_o", "float", 3, "origin of the path's next ray"),
    _path("ray_d", "float", 3, "its direction"),
    _path("throughput", "float", 3, "path throughput (beta)"),
    _path("radiance", "float", 3, "radiance gathered so far (L)"),
    _path("path_pixel", "int", 1, "the sample's pixel"),
    _path("path_pass", "int", 1, "the sample's pass"),
    _path("path_depth", "int", 1, "segments so far"),
    _path("path_pdf", "float", 1, "BSDF pdf of the last bounce, 0 after a camera or delta bounce"),
    _path("path_eta_scale", "float", 1, "product of eta^2 over the refractions so far (Russian roulette)"),
    _path("path_nref", "float", 3, "the normal at the last scattering vertex (LIGHT_TREE: the light pmf at a hit)"),
    _path("path_weight", "float", 1, "the camera sample's filter weight (+-filter_weight), applied at accumulate"),
    _path("hit_t", "float", 1, "closest hit of ray_o/ray_d (extend)"),
    _path("hit_prim", "int", 1, "its primitive (PRIM_MISS, triangle or SHAPE_PRIM)"),
    _path("hit_u", "float", 1, "its barycentrics"), _path("hit_v", "float", 1),
    _path("hit_inst", "int", 1, "the instance of a triangle hit in a two-level group (reordered), -1 if none"),
    _path("sh_o", "float", 3, "shadow ray origin (shade -> shadow)"),
    _path("sh_d", "float", 3, "shadow ray, t in (0, 1)"),
    _path("sh_contrib", "float", 3, "radiance the light sample adds if unoccluded"),
    # textures (cl/scene/textures.h); 16-byte dummies without HAS_TEXTURES
    _scene("tri_uv", "const", "float2", "3 UVs per reordered triangle"),
    _scene("textures", "const", "Texture"), _scene("tex_data", "const", "float4", "texels of every texture"),
    # shading normals and vertex colours (cl/scene/shading.h); 16-byte dummies without
    # HAS_SHADING_NORMALS / HAS_VERTEX_COLORS
    _scene("face_normal", "const", "float", "9 per face (through prim_ids): its corners' unit normals (0: flat)"),
    _scene("tri_color", "const", "float", "9 per reordered triangle: its corners' linear RGB colours"),
    # queues of slot indices and their counters
    Param("queue_in", "global", "int", "active paths of this iteration", per_slot=1, launch=True, source="run"),
    Param("queue_out", "global", "int", "paths that continue", per_slot=1, launch=True, source="run"),
    Param("shadow_q", "global", "int", "paths with a shadow ray", per_slot=1, source="run"),
    Param("term_q", "global", "int", "finished paths", per_slot=1, source="run"),
    Param("free_q", "global", "int", "stack of free slots", per_slot=1, source="run"),
    Param("counters", "global", "int", "COUNTER_* slots, then one per ring pass", source="run"),
    Param("pass_ring", "global", "float", "ring_size passes of n_pixels RGB sums", source="run"),
    # adaptive sampling (render/adaptive.py): the pixels that take samples, when n_listed > 0
    Param("pixel_list", "const", "int", "n_pixels entries, the first n_listed in use", source="run"),
    # AOVs (HAS_AOVS; AOV_* offsets): 16-byte dummies without them
    Param("aov_path", "global", "float", "the path's AOVs so far", per_slot=AOV_FLOATS, source="run"),
    Param("aov_ring", "global", "float", "ring_size passes of n_pixels x AOV_FLOATS", source="run"),
    # the environment map and its sampling CDFs (cl/render/lights.h); dummies without HAS_ENVIRONMENT
    _scene("env_map", "const", "float"),
    _scene("env_cdf", "const", "float"),
    # the pixel filter's tables (FILTER_TABULATED, cl/render/filter.h); a dummy otherwise
    Param("filter_cdf", "const", "float", "per axis: the segments, then filter_knots (x, f) pairs", source="settings"),
    # fixed scalars
    _scene("n_lights", "scalar", "int"),
    _scene("light_tree", "scalar", "int", "1: lights of trail >= 0 are in the light BVH (read with LIGHT_TREE_RUNTIME)"),
    Param("n_pixels", "scalar", "int", source="settings"),
    Param("ring_size", "scalar", "int", "passes in flight at most", source="run"),
    Param("max_depth", "scalar", "int", "path segments, < 0 for no limit", source="settings"),
    Param("rr_depth", "scalar", "int", "segments before Russian roulette", source="settings"),
    Param("integrator", "scalar", "int", "INTEGRATOR_MIS, _BSDF (BSDF sampling only) or _NEE (light sampling only)",
          source="settings"),
    _scene("env_light", "scalar", "int", "the environment light's row in the light table, -1 if none"),
    Param("seed", "scalar", "uint", source="settings"),
    Param("sampler", "scalar", "int", "SAMPLER_*, where no SAMPLER is compiled in", source="settings"),
    _scene("max_component", "scalar", "float", "Film maxcomponentvalue (+inf: none), where MAX_COMPONENT_RUNTIME"),
    # per-stage scalars (each stage reads the ones its .cl file names)
    Param("n_items", "scalar", "int", "work-items with work: new paths, or active paths", launch=True, source="run"),
    Param("first_pass", "scalar", "int", "generate: pass of the first new sample", launch=True, source="run"),
    Param("first_pixel", "scalar", "int", "generate: its pixel (the next ones follow)", launch=True, source="run"),
    Param("queue_base", "scalar", "int", "generate: active-queue length before", launch=True, source="run"),
    Param("free_base", "scalar", "int", "generate, accumulate: free-stack length before", launch=True, source="run"),
    Param("n_listed", "scalar", "int", "generate, path: samples go to pixel_list[0..n_listed); 0: every pixel",
          launch=True, source="run"),
)
# Participating media (cl/render/volpath.h, compiled with HAS_MEDIA): every kernel takes them, 16-byte dummies
# without media; the buffers are pyopencl_rt/scene/media.py:pack_media's, tri_interface reordered as tri_material is.
MEDIA_PARAMS: tuple[Param, ...] = (
    _scene("media", "const", "Medium", "participating media (cl/render/media.h)"),
    _scene("medium_grids", "const", "MediumGrid", "their density and albedo grids"),
    _scene("grid_data", "const", "float", "the grids' values"),
    _scene("medium_interfaces", "const", "MediumInterface", "how surfaces bound media"),
    _scene("tri_interface", "const", "int", "medium interface per reordered triangle, -1 if none"),
    _scene("shape_interface", "const", "int", "medium interface per shape, -1 if none"),
    _scene("camera_medium", "scalar", "int", "the medium the camera is in, MEDIUM_VACUUM if none"),
    _scene("spectral_mis", "scalar", "int", "1: spectral MIS over the channels (read with SPECTRAL_MIS_RUNTIME)"),
    # the wavefront's per-path media state (PathState's HAS_MEDIA fields): allocated with HAS_MEDIA in the
    # wavefront schedule only, 16-byte dummies otherwise (the megakernel keeps them in registers)
    _path("vol_medium", "int", 1, "the medium the path's ray is in, MEDIUM_VACUUM if none"),
    _path("vol_channel", "int", 1, "its hero channel"),
    _path("vol_rng", "uint", 1, "its tracking stream (media.h medium_uniform; the shadow stage draws from it too)"),
    _path("vol_r", "float", 3, "its spectral-MIS ratios, mean 1"),
    _path("vol_ref", "float", 3, "its last scattering vertex (light_pdf's reference point)"),
    _path("sh_medium", "int", 1, "the medium the shadow ray starts in (shade -> shadow)"),
)
# Two-level instances (cl/accel/instances.h, compiled with HAS_INSTANCES): 16-byte dummies without.
INSTANCE_PARAMS: tuple[Param, ...] = (
    _scene("tlas", "const", "BVHNode", "binary BVH over the instances' world boxes (leaves: ranges of instances)"),
    _scene("instances", "const", "Instance", "the instances in the TLAS's leaf order"),
    _scene("blas_nodes", "const", "BVHNode", "every two-level group's BVH in the device's layout, one after another"),
    _scene("instance_motion", "const", "Motion", "the moving instances' ways (read with HAS_MOTION)"),
)
WAVE_PARAMS = WAVE_PARAMS + MEDIA_PARAMS + INSTANCE_PARAMS
WAVE_PARAM = {p.name: p for p in WAVE_PARAMS}
assert len(WAVE_PARAM) == len(WAVE_PARAMS)

def cl_header() -> str:
    """The OpenCL C declarations of this module's tables, prepended to every program
    (:mod:`.cl_header` writes them)."""
    from . import cl_header as header

    return header.cl_header(STRUCTS, DEFINES, OVERRIDABLE, WAVE_PARAMS, MATERIAL_TYPES)
