"""The in-memory scene: what every loader produces and what the renderer consumes.

Units are whatever the scene file uses; radiance and albedo are linear RGB.  Emission is
one-sided (the side the triangle's geometric normal (v1 - v0) x (v2 - v0) faces, or the outside
of a sphere, a disk's front) unless the material is two-sided, as for Mitsuba's and pbrt's area lights.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..device import abi
from ..device.host_memory import aligned_empty
from .camera import FOV_AXES, PROJECTIONS, Camera, vertical_fov  # noqa: F401 (re-exported)
from .lights import (DirectionalLight, Environment, PointLight, ProjectorLight, SpotLight,  # noqa: F401
                     light_type, look_at_frame)
from .materials import REGISTRY, MaterialType
from .materials.mix import BLENDED
from .pixel_filter import PixelFilter
from .shapes import transformed as shapes_moved

INTEGRATORS = ("path", "bsdf", "nee")
assert [INTEGRATORS.index(k) for k in ("path", "bsdf", "nee")] == [abi.INTEGRATOR_MIS, abi.INTEGRATOR_BSDF,
                                                             abi.INTEGRATOR_NEE]  # the kernel argument
# where the random numbers come from (cl/render/sampler.h), the default first
SAMPLERS = ("sobol", "stratified", "independent")
LIGHT_SAMPLERS = ("power", "uniform", "bvh")  # RenderSettings.light_sampler (render/lights.py)
assert set(SAMPLERS) == set(abi.SAMPLERS)
# AOV layers a render can write beside the beauty (pyopencl_rt/render/aovs.py documents them)
AOVS = ("albedo", "normal", "depth", "position", "variance", "spp")
# the rules of Mitsuba's normalmap and bumpmap wrappers a material's map may follow (Material)
MAP_CONVENTIONS = {"flip": abi.MATERIAL_FLAG_MAP_FLIP, "terminator": abi.MATERIAL_FLAG_MAP_TERMINATOR,
                   "side": abi.MATERIAL_FLAG_MAP_SIDE, "whole": abi.MATERIAL_FLAG_MAP_WHOLE}
MITSUBA_MAP = ("flip", "terminator", "side")  # Mitsuba's defaults


@dataclass
class Material:
    """A material; ``type`` names a registered material type (:mod:`pyopencl_rt.scene.materials`,
    where each type's module says which of these parameters it uses).  Every type may emit.
    """

    name: str = "default"
    albedo: tuple = (0.8, 0.8, 0.8)
    emission: tuple = (0.0, 0.0, 0.0)
    two_sided: bool = False
    # the emission leaves along the geometric normal alone (Mitsuba's directionalarea; cl/render/lights.h):
    # only next-event estimation sees it, a hit sees no emission
    emission_directional: bool = False
    type: str = "diffuse"
    alpha: float = 0.0  # GGX alpha (the scene format's roughness squared)
    metallic: float = 0.0
    ior: float = 1.5
    f0: tuple = (1.0, 1.0, 1.0)
    eta: tuple | None = None
    k: tuple | None = None
    tint: tuple = (1.0, 1.0, 1.0)
    # Image textures (pyopencl_rt.scene.textures.Texture; None = none), looked up at the hit's UV on
    # triangles (analytic shapes have no UVs and use the factors alone).  base_texture multiplies albedo
    # (diffuse, gltf) or tint (dielectric); mr_texture is glTF's metallicRoughness (G scales the
    # roughness, B the metallic); emission_texture multiplies emission.
    base_texture: object = None
    mr_texture: object = None
    emission_texture: object = None
    # The Mitsuba 3 types (plastic, roughplastic, principled, principledthin): the coat's
    # specular_reflectance, `nonlinear`, the microfacet distribution ("ggx" or "beckmann"), the
    # parameters of the MATERIAL fields they alone use (by field name: "roughness", "sheen",
    # "rates", ...), and textures of scalar parameters by the MATERIAL field they multiply
    # (abi.TEXTURE_PARAMS: "alpha", "roughness", "metallic", ...; at most abi.TEX_SLOTS), whose
    # R channel holds the value (the luminance of a colour image, as Mitsuba's eval_1).
    specular_reflectance: tuple = (1.0, 1.0, 1.0)
    nonlinear: bool = False
    thin: bool = False  # dielectric: a thin sheet (Mitsuba's thindielectric), light passes straight through
    distribution: str = "ggx"
    # conductor, dielectric: the roughness along the bitangent (alpha is then the roughness along the
    # tangent, dp/du; None: isotropic), and the shadowing-masking term: "correlated" (Smith's
    # height-correlated G2, pbrt-v4's) or "separable" (G1(wo) G1(wi), Mitsuba's)
    alpha_v: float | None = None
    masking: str = "correlated"
    params: dict = field(default_factory=dict)
    scalar_textures: dict = field(default_factory=dict)

    # A normal map (a tangent-space normal per texel, RGB = (n + 1) / 2, in the shading frame
    # whose tangent is dp/du: Mitsuba's normalmap, pbrt-v4's normalmap, glTF's normalTexture) or,
    # with bump_map, a height map (Mitsuba's bumpmap: its luminance's gradient tilts the
    # normal); normal_scale multiplies the normal map's x and y, or the height map's gradient.
    # map_conventions: which of Mitsuba's wrappers' rules apply (cl/scene/shading.h): "flip"
    # (flip_invalid_normals), "terminator" (use_shadowing_function) and "side" (directions on
    # opposite sides of the shading and perturbed frames give 0), a subset of MAP_CONVENTIONS; "whole"
    # (pbrt-v4's maps: seen from behind, the tilted normal is negated whole, not mirrored).
    normal_texture: object = None
    bump_map: bool = False
    normal_scale: float = 1.0
    map_conventions: tuple = ()
    # the reflectance (albedo; a dielectric's tint) is multiplied by the triangles' interpolated
    # vertex colours (Scene.colors): Mitsuba's mesh_attribute texture, glTF's COLOR_0, PLY colours
    vertex_colors: bool = False
    # An alpha cut-out (Mitsuba's mask BSDF): ``masked`` surfaces are met with probability
    # ``opacity`` (times scalar_textures["opacity"], the texture's luminance as Mitsuba's eval_1
    # reads it; clamped to [0, 1]), else the path goes straight through in a null, delta bounce
    # that counts toward max_depth (cl/render/path.h); shadow rays see them opaque, as Mitsuba's.
    masked: bool = False
    opacity: float = 1.0
    # one-sided (Mitsuba's BSDFs outside a twosided): nothing is reflected seen from behind the
    # shading normal; ours are two-sided otherwise
    one_sided: bool = False
    # An alpha cut-out in the intersection (pbrt-v4's shape "alpha", glTF's alphaMode MASK /
    # BLEND): a triangle hit whose alpha (``opacity`` times scalar_textures["opacity"]'s R) is below
    # ``alpha_cutoff`` (> 0, glTF's MASK) or, with alpha_cutoff 0, below a hash of the ray (pbrt-v4's
    # stochastic alpha) is no hit, for paths and shadow rays alike (cl/scene/scene.h); analytic shapes
    # are opaque.  Not with participating media (the scene warns).
    cutout: bool = False
    alpha_cutoff: float = 0.0
    # mix (Mitsuba's blendbsdf, pbrt's mix): the two blended Materials (each also in Scene.materials,
    # which Scene adds) and the weight of the second (times scalar_textures["mix_weight"], or with
    # vertex_colors the interpolated colours' luminance)
    blend: tuple = ()
    mix_weight: float = 0.5


    def textures(self) -> list:
        return [t for t in (self.base_texture, self.mr_texture, self.emission_texture, self.normal_texture,
                            *self.scalar_textures.values()) if t is not None]

    def mean_emission(self) -> np.ndarray:
        """Emission averaged over the emission texture (the light sampler's power estimate)."""
        e = np.asarray(self.emission, np.float64)
        if self.emission_texture is not None:
            e = e * self.emission_texture.mean_rgb()
        return e

    @property
    def is_emissive(self) -> bool:
        return max(self.emission) > 0.0

    @property
    def is_anisotropic(self) -> bool:
        """Roughness along the tangent and the bitangent that differ, or a texture of either (principled,
        principledthin: a non-zero or textured `anisotropic`): the BSDF's frame follows dp/du."""
        if self.type in ("principled", "principledthin"):
            return float(self.params.get("anisotropic", 0.0)) != 0.0 or "anisotropic" in self.scalar_textures
        params = self.params
        if self.type == "coatedconductor" and params.get("conductor_alpha_u") != params.get("conductor_alpha_v"):
            return True  # the metal under the coating is anisotropic
        return self.type in ("conductor", "dielectric", "coatedconductor") and (
            (self.alpha_v is not None and float(self.alpha_v) != float(self.alpha))
            or "alpha_v" in self.scalar_textures)

    @property
    def roughness(self) -> float:
        """Perceptual roughness sqrt(alpha)."""
        return float(np.sqrt(self.alpha))

    @property
    def material_type(self) -> MaterialType:
        """The registered type this material's ``type`` names."""
        if self.type not in REGISTRY:
            raise ValueError(f"material {self.name!r}: unknown type {self.type!r}")
        return REGISTRY[self.type]

    def mitsuba_bsdf(self) -> dict:
        """The Mitsuba 3 BSDF of this material (ValueError for a type without one)."""
        to_mitsuba = self.material_type.to_mitsuba
        if to_mitsuba is None:
            raise ValueError(f"material {self.name!r}: type {self.type!r} is not exported to Mitsuba yet")
        return to_mitsuba(self)

    def record(self, texture_index: dict | None = None, material_index: dict | None = None) -> np.ndarray:
        """The MATERIAL struct; ``texture_index`` maps id(texture) to its index in the scene's
        texture table (without it, or for a texture not in it, no texture is used);
        ``material_index`` id(material) to its index in the scene's materials (a mix's blended
        materials; without it they are -1)."""
        material_type = self.material_type
        rec = np.zeros((), abi.MATERIAL)
        rec["type"] = material_type.type_id
        rec["emission"] = (0.0, 0.0, 0.0) if self.emission_directional else self.emission
        rec["flags"] = abi.MATERIAL_FLAG_TWO_SIDED if self.two_sided else 0
        material_type.pack(self, rec)
        ti = texture_index or {}
        for fld, tex in (("tex_base", self.base_texture), ("tex_mr", self.mr_texture),
                         ("tex_emission", self.emission_texture), ("tex_normal", self.normal_texture)):
            rec[fld] = ti.get(id(tex), -1) if tex is not None else -1
        rec["tex_scalar"] = -1
        param_ids = {name: k for k, name in abi.TEXTURE_PARAMS.items()}
        slot = 0
        for name, tex in self.scalar_textures.items():
            if name not in param_ids:
                raise ValueError(f"material {self.name!r}: no texture slot for parameter {name!r}")
            if tex is None or id(tex) not in ti:
                continue
            if slot == abi.TEX_SLOTS:
                raise ValueError(f"material {self.name!r}: more than {abi.TEX_SLOTS} textured parameters")
            rec["tex_scalar"][slot] = ti[id(tex)]
            rec["tex_params"] |= param_ids[name] << (4 * slot)
            slot += 1
        rec["normal_scale"] = self.normal_scale
        rec["opacity"] = min(max(float(self.opacity), 0.0), 1.0) if self.masked or self.cutout else 0.0  # with a flag only
        rec["alpha_cutoff"] = float(self.alpha_cutoff) if self.cutout else 0.0
        if self.type == "mix":  # the blended records' indices in its block (scene/materials/mix.py)
            rec["table"][BLENDED] = [(material_index or {}).get(id(m), -1) for m in self.blend]
            if material_index is not None and min(rec["table"][BLENDED]) < 0:
                raise ValueError(f"material {self.name!r}: a material it blends is not among the scene's materials")
        flags = int(rec["flags"]) | (abi.MATERIAL_FLAG_VERTEX_COLOR if self.vertex_colors else 0)
        flags |= (abi.MATERIAL_FLAG_MASK if self.masked else 0) | (abi.MATERIAL_FLAG_ONE_SIDED if self.one_sided else 0)
        flags |= abi.MATERIAL_FLAG_CUTOUT if self.cutout else 0
        if self.normal_texture is not None:
            flags |= abi.MATERIAL_FLAG_BUMP_MAP if self.bump_map else 0
            for name in self.map_conventions:
                flags |= MAP_CONVENTIONS[name]
        rec["flags"] = flags
        return rec


@dataclass
class RenderSettings:
    width: int = 512
    height: int = 512
    spp: int = 64
    max_depth: int = 8
    integrator: str = "path"
    seed: int = 0
    rr_depth: int = 5  # Russian roulette starts after this many bounces (Mitsuba's default; docs/SAMPLING.md)
    sampler: str = "sobol"  # one of SAMPLERS
    adaptive: bool = False  # adaptive sampling (render/adaptive.py): spp a pixel's maximum (with a target) or the mean
    target_error: float | None = None  # with adaptive: a pixel stops at this relative error
    aovs: tuple = ()  # AOV layers written beside the beauty (names of AOVS)
    filter: PixelFilter = PixelFilter()  # the pixel reconstruction filter
    # participating media (cl/render/media.h): weigh a path's chromatic distance samples by the
    # balance heuristic over the channels (Mitsuba's volpathmis, pbrt-v4) or by the hero channel's
    # pdf alone (Mitsuba's volpath)
    spectral_mis: bool = True
    # how next-event estimation picks a light (render/lights.py, one of LIGHT_SAMPLERS): "power" in
    # proportion to its power (pbrt-v4's "power"), "uniform" each emitter with probability
    # sampling_weight / sum (Mitsuba 3's rule, pbrt-v4's "uniform"), an emitter's share split over
    # its triangles by area, "bvh" by importance to the shading point (the light BVH,
    # render/light_tree.py; pbrt-v4's "bvh")
    light_sampler: str = "power"
    # pbrt-v4's Film "maxcomponentvalue": each camera sample's radiance scaled down so that its
    # largest CIE XYZ component (pbrt's cie1931 sensor RGB) is at most this; None: no clamp
    max_component_value: float | None = None
    # a 3 x 3 colour matrix (9 floats, row-major) applied to the finished image, rgb -> M . rgb:
    # pbrt-v4's Film "whitebalance" (scene/loaders/pbrt_film.py); None: the identity
    color_matrix: tuple | None = None


@dataclass
class Instance:
    """One instance of a shape group (Mitsuba's shapegroup / instance, pbrt-v4's ObjectBegin /
    ObjectInstance): the group's name and its 4x4 to_world.  A flattened instance (blas -1) added
    its own moved copy of the group's shapes to the Scene's arrays (faces[first_face:first_face +
    n_faces], the analytic shapes likewise); a two-level one (blas >= 0) adds nothing: it draws
    Scene.blas_groups[blas], whose faces are in the group's own space, moved by to_world at
    render time (pyopencl_rt/accel/instances.py).  A moving one (pbrt-v4's ActiveTransform; two-level
    always) has ``to_world_end``, its to_world at the end of the motion (Scene.motion_time; the way
    between them: accel/motion.py, interpolated about ``motion_pivot``, None: the origin; in the
    world about ``motion_pivot_world`` where the world has moved since, None: the same point);
    None: it does not move."""

    group: str
    to_world: np.ndarray
    first_face: int = 0
    n_faces: int = 0
    first_shape: int = 0
    n_shapes: int = 0
    blas: int = -1
    to_world_end: np.ndarray | None = None
    motion_pivot: tuple | None = None
    motion_pivot_world: tuple | None = None

    def pivots(self):
        """(pivot, world pivot) of Motion, or None: about the origin."""
        if self.motion_pivot is None:
            return None
        return self.motion_pivot, self.motion_pivot if self.motion_pivot_world is None else self.motion_pivot_world

    @property
    def moves(self) -> bool:
        return self.to_world_end is not None


@dataclass
class BlasGroup:
    """A shape group that two-level instances share: its faces, in the group's own space, are
    faces[first_face:first_face + n_faces] of the Scene (after every world face), each drawn
    only through the instances that name it; one bottom-level BVH is built over them."""

    name: str
    first_face: int
    n_faces: int


def _translated(vertices, offset) -> np.ndarray:
    """float32 (V, 3) ``vertices + offset``, computed in float64 a chunk at a time (no float64 copy
    of a mesh of millions of vertices), into a page-aligned array that a CPU device reads in place
    (device/host_memory.py)."""
    v = np.asarray(vertices).reshape(-1, 3)
    out = aligned_empty(v.shape, np.float32)
    step = 1 << 20
    for lo in range(0, len(v), step):
        out[lo:lo + step] = v[lo:lo + step].astype(np.float64) + offset
    return out


@dataclass
class Scene:
    vertices: np.ndarray  # (V, 3) float32, world space
    faces: np.ndarray  # (F, 3) int32
    face_materials: np.ndarray  # (F,) int32 index into materials
    materials: list  # list[Material]
    camera: Camera = field(default_factory=Camera)
    # the analytic shapes (spheres, disks, tubes: pyopencl_rt/scene/shapes/): (S,) abi.SHAPE records, their type
    # and parameters in float32, as the kernels read them; and the material of each
    shapes: np.ndarray = field(default_factory=lambda: np.zeros(0, abi.SHAPE))
    shape_materials: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    settings: RenderSettings = field(default_factory=RenderSettings)
    source: str = "<memory>"
    # lights besides emissive surfaces: PointLight / DirectionalLight / SpotLight / ProjectorLight,
    # and one Environment or None
    lights: list = field(default_factory=list)
    environment: Environment | None = None
    # the world position of these coordinates' origin (camera_relative moves it to the camera): the
    # textures looked up by the world's hit point (pbrt's planar, spherical, cylindrical) add it back
    world_origin: tuple = (0.0, 0.0, 0.0)
    # per-face texture coordinates (F, 3, 2) float32 (corner k of face f), or None (all 0)
    uvs: np.ndarray | None = None
    # per-corner shading normals (F, 3, 3) float32 in world space, or None: the triangles'
    # normals are interpolated across them (a face whose three are 0 is shaded flat); and
    # per-corner linear RGB colours (F, 3, 3), or None, for materials with vertex_colors
    normals: np.ndarray | None = None
    colors: np.ndarray | None = None
    # the file format it was read from ("mitsuba-xml", "pbrt-v4", ...; None: not recorded) and
    # every warning its loader gave (one line each), for the JSON sidecar
    format: str | None = None
    warnings: list = field(default_factory=list)
    # participating media (pyopencl_rt.scene.media): the media, the one the camera is in (an index
    # into media, -1: vacuum), the medium interfaces, and the interface of each face and shape
    # ((F,) and (S,) int32 indices into interfaces, -1: an ordinary surface; None: all -1)
    media: list = field(default_factory=list)
    camera_medium: int = -1
    interfaces: list = field(default_factory=list)
    face_interfaces: np.ndarray | None = None
    shape_interfaces: np.ndarray | None = None
    # the shape-group instances the file had (Instance records): flattened ones are in the arrays
    # above; two-level ones draw the blas_groups (BlasGroup records: faces at the end of the arrays,
    # in their group's own space)
    instances: list = field(default_factory=list)
    blas_groups: list = field(default_factory=list)
    # motion blur: each ray's time sample u in [0, 1) (uniform over the shutter) puts a moving
    # instance at s = clamp(a + b u, 0, 1) of its way from to_world to to_world_end, (a, b) this;
    # a moving camera: its frame's camera-to-world 4x4 matrices at the start and the end (the
    # camera record is the start's; accel/motion.py interpolates), or None
    motion_time: tuple = (0.0, 1.0)
    camera_motion: tuple | None = None
    # True: the corner normals are used as given, not each made unit length: their lengths weigh the
    # interpolation (which the kernels normalise), as an unevenly scaled instance's normals need
    normals_as_given: bool = False
    # True: the normals hold face_normals()'s values already (unit corners, 0 where a face is flat),
    # made so once where the scene is assembled (Scene.make_normals_unit), and used as they are by
    # face_normals() and, in place, by a CPU device's render (a second normalisation of a unit
    # float32 vector may move its last bit: it is not idempotent, so it is done once)
    normals_unit: bool = False
    # emitters made of several primitives (a Mitsuba shape with an area emitter): per face and per
    # shape the index of its emitter (-1: none; None: all -1), and each emitter's sampling_weight
    # (Mitsuba's).  With light_sampler "uniform" an emitter's faces share its pick probability by
    # area; an emissive face or shape without an emitter index is an emitter by itself, weight 1
    face_emitters: np.ndarray | None = None
    shape_emitters: np.ndarray | None = None
    emitter_weights: list = field(default_factory=list)

    def __post_init__(self):
        self.add_blended_materials()

    def add_blended_materials(self) -> None:
        """Appends to ``materials`` the materials that mixes blend and that are not in it yet
        (nested mixes too), so that each has a record."""
        if not isinstance(self.materials, list):
            return
        known = {id(m) for m in self.materials}
        k = 0
        while k < len(self.materials):
            for m in getattr(self.materials[k], "blend", ()):
                if id(m) not in known:
                    known.add(id(m))
                    self.materials.append(m)
            k += 1

    def textures(self) -> list:
        """The distinct textures the materials use, in order of first use, then the lights' (spot
        and projector textures)."""
        from .textures import with_inputs

        return with_inputs([*(t for m in self.materials for t in m.textures()), *self.light_textures()])

    def light_textures(self) -> list:
        return [t for t in (getattr(lt, "texture", None) for lt in self.lights or []) if t is not None]

    def has_textures(self) -> bool:
        return (len(self.faces) > 0 and any(m.textures() for m in self.materials)) or bool(self.light_textures())

    def has_shading_normals(self) -> bool:
        """Some face has a (non-zero) vertex normal: the kernels interpolate them."""
        if self.normals is None or len(self.faces) == 0:
            return False
        from .meshops import any_shading_normal

        return any_shading_normal(self.normals, len(self.faces), self.normals_as_given)

    def has_anisotropy(self) -> bool:
        """Some material has anisotropic roughness: the kernels compute the tangent (dp/du)."""
        return any(m.is_anisotropic for m in self.materials)

    def has_normal_maps(self) -> bool:
        return len(self.faces) > 0 and any(m.normal_texture is not None for m in self.materials)

    def has_vertex_colors(self) -> bool:
        return len(self.faces) > 0 and any(m.vertex_colors for m in self.materials)

    def camera_relative(self) -> "Scene":
        """The scene translated (in float64) so that the camera sits at the origin.

        Float32 positions far from the origin are coarse: at 1e5 an ulp is 0.0078, so the spawn
        offsets (a few hundred ulps) and the hit points' rounding grow to millimetres in a metre-
        sized scene (docs/ROBUSTNESS.md measures the effect).  Rendering relative to the camera
        keeps the coordinates that matter small.
        Returns self when the camera is already at the origin."""
        import copy

        eye = np.asarray(self.camera.eye, np.float64)
        if not eye.any():
            return self
        s = copy.copy(self)
        s.vertices = _translated(self.vertices, -eye)
        if self.blas_groups:  # two-level groups stay in their own space; their instances move
            from .instances import camera_shifted, group_vertices

            g = group_vertices(self)
            s.vertices[g], s.instances = self.vertices[g], camera_shifted(self, eye)
        shift = np.eye(4)  # the move as a 4x4 map, for what moves by one (shapes, camera motion, lights, media)
        shift[:3, 3] = -eye
        if len(self.shapes):
            s.shapes = shapes_moved(self.shapes, shift)
        s.camera = dataclasses.replace(self.camera, eye=(0.0, 0.0, 0.0),
                                       look_at=tuple(np.asarray(self.camera.look_at, np.float64) - eye))
        if self.camera_motion is not None:
            s.camera_motion = tuple(shift @ np.asarray(m, np.float64) for m in self.camera_motion)
        s.world_origin = tuple(float(x) for x in np.asarray(self.world_origin, np.float64) + eye)
        s.lights = [light_type(lt).transformed(lt, shift) for lt in self.lights]
        if self.media:
            s.media = [m.transformed(shift) for m in self.media]
        return s

    def has_media(self) -> bool:
        """Whether the scene has media or index-matched surfaces (what the volumetric integrator renders)."""
        return bool(self.media) or any(mi.null for mi in self.interfaces)

    def face_interface_array(self) -> np.ndarray:
        """(F,) int32 interface index per face (-1: none)."""
        if self.face_interfaces is None:
            return np.full(len(self.faces), -1, np.int32)
        return np.asarray(self.face_interfaces, np.int32).reshape(len(self.faces))

    def shape_interface_array(self) -> np.ndarray:
        """(S,) int32 interface index per analytic shape (-1: none)."""
        if self.shape_interfaces is None:
            return np.full(len(self.shapes), -1, np.int32)
        return np.asarray(self.shape_interfaces, np.int32).reshape(len(self.shapes))

    def _per_corner(self, values, k: int, missing: float) -> np.ndarray:
        """(F, 3, k) float32 per-corner values (``missing`` where the scene has none; NaN as 0)."""
        if values is None:
            return np.full((len(self.faces), 3, k), missing, np.float32)
        v = np.asarray(values, np.float32).reshape(len(self.faces), 3, k)
        return np.where(np.isfinite(v), v, np.float32(0))

    def face_uvs(self) -> np.ndarray:
        """(F, 3, 2) float32 texture coordinates (zeros where the scene has none)."""
        return self._per_corner(self.uvs, 2, 0.0)

    def face_normals(self, prim=None, out=None) -> np.ndarray:
        """(F, 3, 3) float32 unit shading normals per corner (zeros where the scene has none;
        a non-finite or zero normal becomes 0: that face is shaded flat); with normals_as_given,
        the normals with their lengths.  ``prim`` (face indices): those faces' only, in that order
        (face_normals()[prim] without the whole array; the renderer's BVH order).  One parallel
        pass (scene/meshops.py), into ``out`` where given (the renderer's mapped device buffer)."""
        if self.normals is None:
            shape = (len(self.faces) if prim is None else len(prim), 3, 3)
            if out is None:
                return np.zeros(shape, np.float32)
            out[...] = 0.0
            return out
        from ..host_stages import host_stage
        from .meshops import unit_corner_normals

        if self.normals_unit and not self.normals_as_given:
            n = np.asarray(self.normals, np.float32).reshape(len(self.faces), 3, 3)
            if prim is None and out is None:
                view = n.view()
                view.flags.writeable = False  # the scene's own array
                return view
            if prim is None:
                out[...] = n
                return out
            return np.take(n, prim, axis=0, out=out)
        with host_stage("normals"):
            return unit_corner_normals(self.normals, len(self.faces), self.normals_as_given, prim, out)

    def make_normals_unit(self) -> None:
        """Write face_normals()'s values into the scene's own normals (float32, C-contiguous, in
        place: no second array of a big mesh's) and set normals_unit; nothing with normals_as_given."""
        from .meshops import unit_corner_normals

        if self.normals is None or self.normals_as_given or self.normals_unit:
            return
        n = self.normals
        if not (isinstance(n, np.ndarray) and n.dtype == np.float32 and n.flags.c_contiguous and n.flags.writeable):
            own = aligned_empty(np.shape(n), np.float32)  # a copy of its own to write (aligned() may return n)
            own[...] = n
            n = self.normals = own
        n = n.reshape(len(self.faces), 3, 3)
        unit_corner_normals(n, len(self.faces), False, out=n)
        self.normals_unit = True

    def face_colors(self) -> np.ndarray:
        """(F, 3, 3) float32 linear RGB per corner (1 where the scene has none; NaN as 0)."""
        return self._per_corner(self.colors, 3, 1.0)

    def material_records(self) -> np.ndarray:
        recs = np.zeros(max(1, len(self.materials)), abi.MATERIAL)
        for f in ("tex_base", "tex_mr", "tex_emission", "tex_normal", "tex_scalar"):
            recs[f] = -1
        index = {id(t): i for i, t in enumerate(self.textures())}
        materials = {id(m): i for i, m in enumerate(self.materials)}
        for i, m in enumerate(self.materials):
            recs[i] = m.record(index, materials)
        return recs

    def material_defines(self) -> dict:
        """Preprocessor defines that compile only the material types this scene uses
        (MATERIALS_SELECTED + HAS_MATERIAL_<TYPE>; see cl/materials/dispatch.h)."""
        defines = {"MATERIALS_SELECTED": True}
        for m in self.materials:
            if m.material_type.kernel_define:
                defines[m.material_type.kernel_define] = True
        if self.has_textures():
            defines["HAS_TEXTURES"] = True  # cl/scene/textures.h
        if self.has_shading_normals():
            defines["HAS_SHADING_NORMALS"] = True  # cl/scene/shading.h
        if self.has_normal_maps():
            defines["HAS_NORMAL_MAPS"] = True
        if self.has_vertex_colors():
            defines["HAS_VERTEX_COLORS"] = True
        if len(self.faces) and any(m.cutout for m in self.materials):
            if self.media:
                import warnings

                warnings.warn("alpha cut-outs in the intersection (pbrt alpha, glTF alphaMode) are not rendered in "
                              "scenes with participating media: the surfaces are opaque", stacklevel=2)
            else:
                defines["HAS_CUTOUTS"] = True  # cl/scene/scene.h
        if self.has_anisotropy():
            defines["HAS_ANISOTROPY"] = True  # cl/scene/shading.h: the frame's tangent
        return defines
