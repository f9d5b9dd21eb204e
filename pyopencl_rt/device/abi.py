"""One definition of every struct shared between host and device.

Each layout is a numpy structured dtype; :func:`cl_struct` turns it into the matching OpenCL C
``typedef struct``, and :func:`cl_header` concatenates them into the header that is prepended to
every program build.  Fields are 4-byte scalars or arrays of them, so numpy's packed layout and
OpenCL's natural alignment agree byte for byte (checked by ``tests/test_layout.py``).
"""
from __future__ import annotations

import numpy as np

# ---------------------------------------------------------------------------------------------
# BVH node (64 bytes).  A binary BVH in which each node stores the boxes of *both* children
# (the layout of Aila & Laine 2009), so one node fetch gives the traversal loop everything it needs to
# test two boxes and decide the order.  Node 0 is the root.
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

# A material (96 bytes).  type selects the BSDF (cl/bsdf.h dispatches on it; each type is
# documented at the top of cl/materials/<name>.h); every type may also emit.
#   albedo    diffuse: reflectance; gltf: baseColor
#   emission  emitted radiance (any type)
#   flags     bit 0: emission on both sides (default: only on the side the geometric normal
#             faces); bit 1: conductor Fresnel from `specular` as F0 (Schlick) instead of eta, k
#   specular  conductor: F0 (with MATERIAL_FLAG_CONDUCTOR_F0); dielectric: tint of both lobes
#   alpha     GGX roughness alpha (conductor, dielectric, gltf); < 1e-3 is perfectly smooth
#   eta, k    conductor: complex index of refraction eta + i k per channel
#   metallic  gltf
#   ior       dielectric: index of the inside relative to the outside; gltf: the dielectric's
#             index (F0 = ((ior - 1) / (ior + 1))^2)
# The type and flag constants are #defined again in cl/bsdf.h (tests/test_materials.py checks
# that they agree).
MATERIAL_DIFFUSE = 0
MATERIAL_CONDUCTOR = 1
MATERIAL_DIELECTRIC = 2
MATERIAL_GLTF = 3
MATERIAL_TYPES = {"diffuse": MATERIAL_DIFFUSE, "conductor": MATERIAL_CONDUCTOR,
                  "dielectric": MATERIAL_DIELECTRIC, "gltf": MATERIAL_GLTF}
MATERIAL_FLAG_TWO_SIDED = 1
MATERIAL_FLAG_CONDUCTOR_F0 = 2
MATERIAL = np.dtype(
    [("albedo", np.float32, 3), ("type", np.int32), ("emission", np.float32, 3), ("flags", np.int32),
     ("specular", np.float32, 3), ("alpha", np.float32), ("eta", np.float32, 3), ("metallic", np.float32),
     ("k", np.float32, 3), ("ior", np.float32),
     ("tex_base", np.int32), ("tex_mr", np.int32), ("tex_emission", np.int32), ("tex_pad", np.int32)]
)
assert MATERIAL.itemsize == 96
# Texture indices (into the TEXTURE table; -1 = none), used only when the program is built with
# HAS_TEXTURES (cl/textures.h):
#   tex_base      RGB multiplies albedo (diffuse, gltf baseColor) or tint (dielectric)
#   tex_mr        glTF metallicRoughness: G multiplies roughness (alpha *= G^2), B multiplies metallic
#   tex_emission  RGB multiplies emission

# A texture (32 bytes): texels [offset, offset + width * height) of the float4 texel buffer, row
# by row from the top of the image (v = 0 is the top row, as in glTF; OBJ's v is flipped at load),
# already linear (sRGB images that hold colours are decoded at load: flags bit 0 records that).
# channels: the source image's channel count (informative).
TEXTURE_FLAG_SRGB = 1
TEXTURE = np.dtype([("offset", np.int32), ("width", np.int32), ("height", np.int32), ("channels", np.int32),
                    ("flags", np.int32), ("pad0", np.int32), ("pad1", np.int32), ("pad2", np.int32)])
assert TEXTURE.itemsize == 32

# A sphere (16 bytes): centre and radius.
SPHERE = np.dtype([("center", np.float32, 3), ("radius", np.float32)])

# An emitter that next-event estimation samples (80 bytes; cl/lights.h documents each kind).
#   kind: LIGHT_TRIANGLE (prim = original face index) or LIGHT_SPHERE (prim = sphere index),
#         LIGHT_POINT, LIGHT_DIRECTIONAL (delta lights: sampled, never hit) or LIGHT_ENVIRONMENT
#         (prim = the map's width, material = its height; 0 x 0 = constant radiance)
#   pmf: probability that the light sampler picks this light (proportional to power)
#   alias, alias_prob: Walker/Vose alias table entry for O(1) sampling
#   p:      point: position; directional, environment: centre of the scene's bounding sphere
#   radius: directional, environment: radius of the scene's bounding sphere (shadow-ray length)
#   dir:    directional: unit direction in which the light travels
#   rgb:    point: intensity [W/sr]; directional: irradiance on a perpendicular surface;
#           environment: radiance (constant) or the map's scale
LIGHT_TRIANGLE = 0
LIGHT_SPHERE = 1
LIGHT_POINT = 2
LIGHT_DIRECTIONAL = 3
LIGHT_ENVIRONMENT = 4
LIGHT = np.dtype([("kind", np.int32), ("prim", np.int32), ("pmf", np.float32), ("alias_prob", np.float32),
                  ("alias", np.int32), ("material", np.int32), ("area", np.float32), ("pad", np.int32),
                  ("p", np.float32, 3), ("radius", np.float32), ("dir", np.float32, 3), ("pad1", np.int32),
                  ("rgb", np.float32, 3), ("pad2", np.int32)])
assert LIGHT.itemsize == 80

# The camera (64 bytes): pinhole or thin lens.  A pixel (x, y) with jitter (jx, jy) in [0,1)^2 maps to the
# direction forward + ((x+jx)/W*2-1) * right + (1-(y+jy)/H*2) * up, where right and up are
# already scaled by tan(fov/2) (and the aspect ratio, for right).  Thin lens when lens_radius > 0:
# the ray leaves a point of the lens disk (radius lens_radius, spanned by the unit right and up)
# toward the pinhole ray's point at distance focus_distance along forward.
CAMERA = np.dtype(
    [("origin", np.float32, 3), ("width", np.int32), ("forward", np.float32, 3), ("height", np.int32),
     ("right", np.float32, 3), ("lens_radius", np.float32), ("up", np.float32, 3), ("focus_distance", np.float32)]
)
assert CAMERA.itemsize == 64

_CL_SCALAR = {
    np.dtype(np.float32): "float",
    np.dtype(np.int32): "int",
    np.dtype(np.uint32): "uint",
}


def cl_struct(name: str, dtype: np.dtype) -> str:
    """Return ``typedef struct {...} name;`` for a structured dtype of 4-byte fields."""
    lines = []
    for field in dtype.names:
        ftype, offset = dtype.fields[field][:2]
        base, shape = (ftype.subdtype if ftype.subdtype else (ftype, ()))
        if base not in _CL_SCALAR:
            raise TypeError(f"{name}.{field}: unsupported base type {base}")
        count = int(np.prod(shape)) if shape else 0
        suffix = f"[{count}]" if count else ""
        lines.append(f"    {_CL_SCALAR[base]} {field}{suffix};  /* offset {offset} */")
    body = "\n".join(lines)
    return f"typedef struct {{\n{body}\n}} {name};  /* {dtype.itemsize} bytes */\n"


# A 4-wide BVH node (128 bytes; pyopencl_rt/bvh_wide.py builds it, cl/bvh_wide.h traverses it):
# the boxes of up to four children in structure-of-arrays form (each field is one float4, so one
# slab test covers all four), then per child slot:
#   child : float4 offset into the wide buffer of the child node (count 0) or of its first
#           Tri4 packet (count > 0); 0 for an absent child
#   count : 0 = inner node, > 0 = leaf of `count` Tri4 packets, -1 = absent (box +inf / -inf)
WIDE_NODE = np.dtype(
    [(f"{b}_{c}", np.float32, 4) for b in ("bmin", "bmax") for c in "xyz"]
    + [("child", np.int32, 4), ("count", np.int32, 4)]
)
assert WIDE_NODE.itemsize == 128

# Four triangles in structure-of-arrays form (160 bytes): vertex k's coordinate c of the four
# lanes in v{k}{c}, and each lane's index into the binary BVH's reordered triangle array in tri
# (-1 for a padding lane, whose vertices are NaN so that it can never hit).
TRI4 = np.dtype([(f"v{k}{c}", np.float32, 4) for k in range(3) for c in "xyz"] + [("tri", np.int32, 4)])
assert TRI4.itemsize == 160

# Registry of every shared struct: name -> dtype.  Add new shared structs here.
STRUCTS: dict[str, np.dtype] = {
    "BVHNode": BVH_NODE,
    "Material": MATERIAL,
    "Sphere": SPHERE,
    "Light": LIGHT,
    "Camera": CAMERA,
    "WideNode": WIDE_NODE,
    "Tri4": TRI4,
    "Texture": TEXTURE,
}


def cl_header() -> str:
    """OpenCL C declarations of every shared struct, generated from the dtypes above."""
    return "/* generated from pyopencl_rt/layout.py: do not edit */\n" + "\n".join(
        cl_struct(name, dt) for name, dt in STRUCTS.items()
    )
