"""TOML scene files: the format is docs/SCENE_FORMAT.md; a summary::

    [camera]                      # optional; without it a camera frames the whole scene
    eye = [278, 273, -800]        # required in [camera]
    look_at = [278, 273, 0]       # required in [camera]
    up = [0, 1, 0]                # default [0, 1, 0]
    fov = 39.3077                 # vertical field of view in degrees, default 40
    type = "perspective"          # or "orthographic", with extent = the view's height (default 2)

    [film]
    width = 512                   # pixels, default 512
    height = 512                  # pixels, default 512
    aovs = ["albedo", "normal"]   # AOV layers of the EXR (pyopencl_rt/render/aovs.py), default none
    filter = {type = "gaussian", sigma = 0.5}  # pixel filter, default {type = "box"} (radius 0.5)

    [render]
    spp = 64                      # samples per pixel, default 64
    max_depth = 8                 # path length limit, default 8
    integrator = "path"           # "path" | "bsdf" | "nee", default "path"
    seed = 0                      # default 0
    rr_depth = 5                  # Russian roulette starts after this many bounces, default 5
    sampler = "sobol"             # "sobol" | "stratified" | "independent", default "sobol"
    adaptive = false              # adaptive sampling (spp: a pixel's maximum, or the mean), default false
    target_error = 0.02           # with adaptive: a pixel stops at this relative error, default none
    light_sampler = "power"       # how lights are picked: "power" | "uniform" | "bvh", default "power"

    [materials.white]             # one table per material, referred to by NAME
    type = "diffuse"              # a type of pyopencl_rt.scene.materials (default "diffuse"),
    albedo = [0.725, 0.71, 0.68]  #   whose module documents its keys
    emission = [0, 0, 0]          # linear RGB radiance >= 0 (or one number), default 0; any type
    two_sided = false             # emit from both sides, default false
    emission_directional = false  # emit along the face's normal alone (Mitsuba's directionalarea: a
                                  #   parallel beam, seen by light sampling alone), default false
    opacity = 1.0                 # an alpha cut-out: met with this probability (times opacity_texture's
                                  #   luminance), else passed straight through; default: opaque

    [media.fog]                   # participating media (toml_media.py), referred to by NAME
    sigma_t = [0.5, 1.0, 2.0]     #   from shapes' interior / exterior and [camera] medium

    [[shape]]                     # one table per shape, numbered #1, #2, ... in messages
    type = "quad"                 # "mesh" | "quad" | "triangle" | "box" | "sphere" | "disk" | "cylinder"
    material = "white"            # default: the built-in "default" material (albedo 0.8)
    points = [[0,0,0], [1,0,0], [1,1,0], [0,1,0]]

Shape keys:

* ``mesh``: ``file`` (relative to the scene file; any format trimesh loads),
  ``use_file_materials = true`` (OBJ and glTF: take the file's materials; a ``[materials.NAME]``
  with the same name overrides one, ``material`` is used for faces without ``usemtl``).
* ``quad``: ``points``: four corners in order, split into triangles (p0, p1, p2) and
  (p0, p2, p3); the emitting/front side is that of the normal (p1 - p0) x (p2 - p0), i.e. the
  corners run counter-clockwise seen from the front (right-hand rule).
* ``triangle``: ``points``: three corners; front side (p1 - p0) x (p2 - p0).
* ``box``: ``size`` (3-vector or number, default 1) centred on ``center`` (default origin);
  faces point outwards.
* ``sphere``: ``center``, ``radius``; emits outwards. No transforms.
* ``disk``: ``center``, ``normal`` (its front), ``radius`` (default 1), ``flip_normals``; emits
  on its front.  No transforms.
* ``cylinder``: ``p0``, ``p1``, ``radius`` (default 1), ``flip_normals``: an open tube, emitting
  outwards (inwards flipped).  No transforms.  (The analytic shapes: each type's module in scene/shapes/.)

Triangle shapes (mesh, quad, triangle, box) take an optional transform: ``scale`` (number or
3-vector), ``rotate`` (``{axis = [x, y, z], angle = DEGREES}`` or a list of them, applied in
order), ``translate`` (3-vector), applied in that order (scale, rotate, translate); or instead
``matrix``, a 4x4 affine matrix (rows) applied to column vectors [x, y, z, 1].  A transform that
mirrors (negative determinant) keeps each face's front side on the transformed normal's side.
``flip_normals = true`` swaps the front side of every face of the shape.
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from ...device import abi
from ...errors import UserError
from ...imageio import read_exr
from ..materials import REGISTRY
from ..mesh import MeshError, flatten, load_trimesh
from ..model import (AOVS, FOV_AXES, INTEGRATORS, LIGHT_SAMPLERS, SAMPLERS, Camera, Environment, Material, PROJECTIONS,
                     RenderSettings, Scene)
from ..pixel_filter import FILTERS, PixelFilter
from ..shapes import REGISTRY as ANALYTIC_SHAPES, records as shape_records
from .assembly import DEFAULT_FOV, frame_scene, transform_normals, triangle_scene
from .gltf import read_gltf
from .meshfile import ply_extras, trimesh_uvs
from .obj import obj_with_materials
from .toml_lights import read_lights
from .toml_media import SHAPE_KEYS, Interfaces, camera_medium, read_media
from .values import (ErrorContext, SceneError, TableReader, check_boolean, check_choice, check_color,
                     check_integer, check_keys, check_number, check_points, check_vector, describe,
                     one_line)

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    try:
        import tomli as tomllib
    except ModuleNotFoundError:
        tomllib = None

SHAPE_TYPES = ("mesh", "quad", "triangle", "box", *ANALYTIC_SHAPES)  # the analytic ones: scene/shapes/

_TOP_KEYS = {"camera", "film", "render", "materials", "shape", "light", "environment", "media"}
_CAMERA_KEYS = {"eye", "look_at", "up", "fov", "fov_axis", "aperture_radius", "focus_distance", "type", "extent",
                "medium"}
_ENVIRONMENT_KEYS = {"radiance", "file", "scale"}
_FILM_KEYS = {"width", "height", "aovs", "filter"}
# each pixel filter's keys, and its radius when none is given (Mitsuba 3's: gaussian 4 sigma, lanczos tau)
_FILTER_KEYS = {"box": {"type", "radius"}, "tent": {"type", "radius"}, "gaussian": {"type", "radius", "sigma"},
                "mitchell": {"type", "radius", "b", "c"}, "lanczos": {"type", "radius", "tau"}}
_RENDER_KEYS = {"spp", "max_depth", "integrator", "seed", "rr_depth", "sampler", "adaptive", "target_error",
                "light_sampler"}
# the keys of every [materials.NAME]; each type adds its own (MaterialType.toml_keys)
MATERIAL_COMMON_KEYS = frozenset({"type", "emission", "two_sided", "emission_texture", "opacity", "opacity_texture",
                                  "emission_directional"})
_TRANSFORM_KEYS = {"translate", "scale", "rotate", "matrix", "flip_normals"}
_SHAPE_KEYS = {
    "mesh": {"type", "material", "file", "use_file_materials"} | _TRANSFORM_KEYS,
    "quad": {"type", "material", "points"} | _TRANSFORM_KEYS,
    "triangle": {"type", "material", "points"} | _TRANSFORM_KEYS,
    "box": {"type", "material", "size", "center"} | _TRANSFORM_KEYS,
    **{name: {"type", "material"} | t.toml_keys for name, t in ANALYTIC_SHAPES.items()},
}
_SHAPE_KEYS = {k: v | SHAPE_KEYS for k, v in _SHAPE_KEYS.items()}  # participating media (toml_media.py)


def _read_material(ctx, where, name, spec) -> Material:
    if not isinstance(spec, dict):
        raise ctx.error(where, f"must be a table, got {describe(spec)}")
    material_type = REGISTRY[check_choice(ctx, where, "type", spec.get("type", "diffuse"), REGISTRY)]
    check_keys(ctx, where, spec, MATERIAL_COMMON_KEYS | material_type.toml_keys)
    emission = check_vector(ctx, where, "emission", spec.get("emission", 0.0), allow_scalar=True)
    if emission.min() < 0:
        raise ctx.error(where, f"'emission' must not be negative, got {emission.tolist()}")
    two_sided = check_boolean(ctx, where, "two_sided", spec.get("two_sided", False))
    material = Material(name=name, emission=tuple(float(x) for x in emission), two_sided=two_sided,
                        type=material_type.name,
                        emission_directional=check_boolean(ctx, where, "emission_directional",
                                                           spec.get("emission_directional", False)))
    table = TableReader(ctx, where, spec)
    material.emission_texture = table.texture("emission_texture", srgb=True)
    material_type.read_toml(material, table)
    if "opacity" in spec or "opacity_texture" in spec:  # an alpha cut-out, as Mitsuba's mask
        from ..textures import scalar_texture

        material.masked = True
        material.opacity = table.number("opacity", 1.0, minimum=0.0, maximum=1.0)
        opacity = table.texture("opacity_texture", srgb=False)
        if opacity is not None:
            material.scalar_textures["opacity"] = scalar_texture(opacity)
    return material


def _read_materials(ctx, table):
    if not isinstance(table, dict):
        raise ctx.error("materials", f"must be tables written [materials.NAME], got {describe(table)}")
    materials: list[Material] = []
    index: dict[str, int] = {}
    for name, spec in table.items():
        index[name] = len(materials)
        materials.append(_read_material(ctx, f"[materials.{name}]", name, spec))
    for m in materials:  # a mix's two materials, by name
        if m.type == "mix":
            names = m.params.pop("materials")
            for n in names:
                if n not in index:
                    raise ctx.error(f"[materials.{m.name}]", f"'materials': unknown material '{n}' "
                                                             f"(materials: {', '.join(index)})")
                if n == m.name:
                    raise ctx.error(f"[materials.{m.name}]", "'materials': a mix cannot blend itself")
            m.blend = tuple(materials[index[n]] for n in names)
    return materials, index


def load_toml_scene(path: Path, name: str) -> Scene:
    ctx = ErrorContext(name)
    if tomllib is None:  # pragma: no cover - Python 3.10 without tomli
        raise ctx.error("", "reading TOML scene files needs Python >= 3.11 or the 'tomli' package")
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ctx.error("", f"not valid TOML: {exc}") from None
    except OSError as exc:
        raise ctx.error("", f"cannot read ({exc.strerror or exc})") from None
    for key in doc:
        if key not in _TOP_KEYS:
            hint = " (did you mean [[shape]]?)" if key in ("shapes", "shape_") else ""
            raise ctx.error("", f"unknown key '{key}' (expected one of: {', '.join(sorted(_TOP_KEYS))}){hint}")

    settings = _read_settings(ctx, doc.get("film", {}), doc.get("render", {}))
    materials, material_index = _read_materials(ctx, doc.get("materials", {}))
    media, media_index = read_media(ctx, path, doc.get("media", {}))
    interfaces = Interfaces(ctx, media_index)
    interface_for = interfaces.index

    shapes = doc.get("shape", [])
    if not isinstance(shapes, list):
        raise ctx.error("shape", "must be an array of tables written [[shape]]")
    if not shapes:
        raise ctx.error("", "defines no shapes (add [[shape]] tables)")

    def material_for(where, table) -> int:
        """The index of the shape's material; the built-in "default" is added on first use (an
        index-matched shape's: a black one, never evaluated)."""
        if table.get("index_matched") is True and "material" not in table:
            if "index-matched" not in material_index:
                material_index["index-matched"] = len(materials)
                materials.append(Material(name="index-matched", albedo=(0.0, 0.0, 0.0)))
            return material_index["index-matched"]
        mname = table.get("material", "default")
        if not isinstance(mname, str):
            raise ctx.error(where, f"'material' must be a material name, got {describe(mname)}")
        if mname not in material_index:
            if mname != "default":
                known = ", ".join(sorted(material_index)) or "none defined"
                raise ctx.error(where, f"unknown material '{mname}' (materials: {known})")
            material_index["default"] = len(materials)
            materials.append(Material())
        return material_index[mname]

    tri_vertices, tri_faces, tri_mats, tri_uvs, tri_normals, tri_colors, tri_ifaces = [], [], [], [], [], [], []
    n_vertices = 0
    analytic, shape_mats, shape_ifaces = [], [], []  # the analytic shapes (scene/shapes/)
    for number, table in enumerate(shapes, 1):
        where = f"[[shape]] #{number}"
        if not isinstance(table, dict):
            raise ctx.error(where, f"must be a table, got {describe(table)}")
        stype = table.get("type")
        if stype is None:
            raise ctx.error(where, f"missing 'type' (one of: {', '.join(SHAPE_TYPES)})")
        check_choice(ctx, where, "type", stype, SHAPE_TYPES)
        where = f"[[shape]] #{number} ({stype})"
        check_keys(ctx, where, table, _SHAPE_KEYS[stype])

        if stype in ANALYTIC_SHAPES:
            shape = ANALYTIC_SHAPES[stype]
            p = shape.read_toml(TableReader(ctx, where, table))
            _check_reach(ctx, where, float(shape.reach(p)[0]), "it reaches")
            analytic.append(shape_records(shape, p))
            shape_mats.append(material_for(where, table))
            shape_ifaces.append(interface_for(where, table))
            continue

        face_mat = None
        uvc = None  # per-corner texture coordinates (F, 3, 2), None = zeros
        nrm = col = None  # per-corner shading normals and colours of a mesh file, or None
        if stype == "mesh":
            v, f, face_mat, uvc, nrm, col = _read_mesh_shape(ctx, where, path, table, materials, material_index,
                                                             material_for)
        elif stype == "quad":
            if "points" not in table:
                raise ctx.error(where, "missing 'points' (four corners [[x,y,z], ...])")
            v = check_points(ctx, where, "points", table["points"], 4)
            f = np.array([[0, 1, 2], [0, 2, 3]], np.int64)
            uvc = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)[f]  # p0..p3 -> uv corners
        elif stype == "triangle":
            if "points" not in table:
                raise ctx.error(where, "missing 'points' (three corners [[x,y,z], ...])")
            v = check_points(ctx, where, "points", table["points"], 3)
            f = np.array([[0, 1, 2]], np.int64)
            uvc = np.array([[[0, 0], [1, 0], [0, 1]]], np.float32)
        else:  # box
            import trimesh

            size = check_vector(ctx, where, "size", table.get("size", 1.0), allow_scalar=True)
            if not (size > 0).all():
                raise ctx.error(where, f"'size' must be > 0 in every axis, got {size.tolist()}")
            centre = check_vector(ctx, where, "center", table.get("center", [0.0, 0.0, 0.0]))
            box = trimesh.creation.box(extents=size)
            v = np.asarray(box.vertices, np.float64) + centre
            f = np.asarray(box.faces, np.int64)

        if stype in ("quad", "triangle"):
            areas = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
            if not (areas > 0).all():
                raise ctx.error(where, "degenerate: its corners do not span an area (repeated or collinear points)")

        def reverse(a):
            return a[:, ::-1] if a is not None else None

        matrix = _shape_transform(ctx, where, table)
        if matrix is not None:
            v = v @ matrix[:3, :3].T + matrix[:3, 3]
            nrm = transform_normals(matrix, nrm)
            if np.linalg.det(matrix[:3, :3]) < 0:
                f, uvc, nrm, col = f[:, ::-1], reverse(uvc), reverse(nrm), reverse(col)
        finite = v[np.isfinite(v).all(axis=1)]  # a mesh file's NaN vertices are dropped, with a warning
        _check_reach(ctx, where, np.abs(finite).max() if len(finite) else 0.0, "its vertices reach")
        if check_boolean(ctx, where, "flip_normals", table.get("flip_normals", False)):
            f, uvc, col = f[:, ::-1], reverse(uvc), reverse(col)
            nrm = -reverse(nrm) if nrm is not None else None
        if face_mat is None:
            face_mat = np.full(len(f), material_for(where, table), np.int32)
        tri_vertices.append(v)
        tri_uvs.append(np.zeros((len(f), 3, 2), np.float32) if uvc is None else np.asarray(uvc, np.float32))
        tri_normals.append(nrm)
        tri_colors.append(col)
        tri_faces.append(f + n_vertices)
        tri_mats.append(face_mat)
        tri_ifaces.append(np.full(len(f), interface_for(where, table), np.int32))
        n_vertices += len(v)

    def corners(parts, fill):  # per-corner arrays of the shapes that have them, `fill` elsewhere
        if all(a is None for a in parts):
            return None
        return np.concatenate([np.full((len(f), 3, 3), fill, np.float32) if a is None else np.asarray(a, np.float32)
                               for a, f in zip(parts, tri_faces)])

    normals = colors = None
    if tri_faces:
        normals, colors = corners(tri_normals, 0.0), corners(tri_colors, 1.0)
        vertices, faces = np.concatenate(tri_vertices), np.concatenate(tri_faces)
        face_mat, uvs, face_ifaces = np.concatenate(tri_mats), np.concatenate(tri_uvs), np.concatenate(tri_ifaces)
    else:
        vertices, faces, face_mat, uvs = np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int32), None
        face_ifaces = np.zeros(0, np.int32)
    scene = triangle_scene(
        vertices, faces, face_mat, materials, name, uvs, normals=normals, colors=colors, settings=settings,
        shapes=np.concatenate(analytic) if analytic else np.zeros(0, abi.SHAPE),
        shape_materials=np.asarray(shape_mats, np.int32),
        face_interfaces=face_ifaces if interfaces.list else None,
    )
    if media or interfaces.list:
        scene.media, scene.interfaces = media, interfaces.list
        scene.shape_interfaces = np.asarray(shape_ifaces, np.int32)
    if "camera" in doc:
        scene.camera = _read_camera(ctx, doc["camera"])
        scene.camera_medium = camera_medium(ctx, doc["camera"], media_index)
    else:
        frame_scene(scene)
    scene.lights = read_lights(ctx, doc.get("light", []))
    if "environment" in doc:
        scene.environment = _read_environment(ctx, path, doc["environment"])
    return scene


def _check_reach(ctx, where, reach, what):
    """Geometry within GEOMETRY_LIMIT of the origin (scene/validate.py says why)."""
    from ..validate import GEOMETRY_LIMIT

    if not reach <= GEOMETRY_LIMIT:
        raise ctx.error(where, f"{what} {reach:.3g} from the origin, beyond {GEOMETRY_LIMIT:.3g}: the float32 kernels "
                               "cannot intersect it (scale the scene down)")


def _read_environment(ctx, scene_path: Path, table):
    where = "[environment]"
    if not isinstance(table, dict):
        raise ctx.error(where, f"must be a table, got {describe(table)}")
    check_keys(ctx, where, table, _ENVIRONMENT_KEYS)
    if "file" in table:
        if "radiance" in table:
            raise ctx.error(where, "give 'radiance' (a constant) or 'file' (a map, with 'scale'), not both")
        fname = table["file"]
        if not isinstance(fname, str):
            raise ctx.error(where, f"'file' must be a file name, got {describe(fname)}")
        path = (scene_path.parent / fname)
        if not path.is_file():
            raise ctx.error(where, f"environment map '{fname}' not found (looked for {path})")
        try:
            image = read_exr(path)
        except UserError as exc:
            raise ctx.error(where, one_line(str(exc))) from None
        image = np.asarray(image, np.float32)
        if image.ndim != 3 or image.shape[2] != 3:
            raise ctx.error(where, f"environment map '{fname}' must be an RGB image, got shape {image.shape}")
        if not np.isfinite(image).all() or (image < 0).any():
            warnings.warn(f"{ctx.name}: {where}: '{fname}' has negative or non-finite texels; they are treated as 0",
                          stacklevel=3)
        return Environment(radiance=check_color(ctx, where, "scale", table.get("scale", 1.0)), image=image,
                           source=str(path))
    if "scale" in table:
        raise ctx.error(where, "'scale' multiplies a map: use it with 'file' (or give 'radiance')")
    return Environment(radiance=check_color(ctx, where, "radiance", table.get("radiance", 1.0)))


def _read_settings(ctx, film, render) -> RenderSettings:
    s = RenderSettings()
    check_keys(ctx, "[film]", film, _FILM_KEYS)
    check_keys(ctx, "[render]", render, _RENDER_KEYS)
    if "width" in film:
        s.width = check_integer(ctx, "[film]", "width", film["width"], minimum=1, maximum=65536)
    if "height" in film:
        s.height = check_integer(ctx, "[film]", "height", film["height"], minimum=1, maximum=65536)
    if "aovs" in film:
        aovs = film["aovs"]
        if not isinstance(aovs, list):
            raise ctx.error("[film]", f"'aovs' must be a list of names ({', '.join(AOVS)}), got {describe(aovs)}")
        s.aovs = tuple(check_choice(ctx, "[film]", "AOV", a, AOVS) for a in aovs)
    if "filter" in film:
        s.filter = _read_filter(ctx, film["filter"])
    if "spp" in render:
        s.spp = check_integer(ctx, "[render]", "spp", render["spp"], minimum=1)
    if "max_depth" in render:
        s.max_depth = check_integer(ctx, "[render]", "max_depth", render["max_depth"], minimum=1)
    if "rr_depth" in render:
        s.rr_depth = check_integer(ctx, "[render]", "rr_depth", render["rr_depth"], minimum=0)
    if "seed" in render:
        s.seed = check_integer(ctx, "[render]", "seed", render["seed"], minimum=0, maximum=2**32 - 1)
    if "integrator" in render:
        s.integrator = check_choice(ctx, "[render]", "integrator", render["integrator"], INTEGRATORS)
    if "sampler" in render:
        s.sampler = check_choice(ctx, "[render]", "sampler", render["sampler"], SAMPLERS)
    if "light_sampler" in render:
        s.light_sampler = check_choice(ctx, "[render]", "light_sampler", render["light_sampler"], LIGHT_SAMPLERS)
    if "adaptive" in render:
        s.adaptive = check_boolean(ctx, "[render]", "adaptive", render["adaptive"])
    if "target_error" in render:
        s.target_error = check_number(ctx, "[render]", "target_error", render["target_error"], positive=True)
    return s


def _read_filter(ctx, value) -> PixelFilter:
    """[film] filter: a filter's name, or a table of its type and parameters."""
    where = "[film] filter"
    if isinstance(value, str):
        value = {"type": value}
    if not isinstance(value, dict):
        raise ctx.error(where, f"must be a filter's name or a table such as {{type = \"gaussian\", sigma = 0.5}}, "
                               f"got {describe(value)}")
    ftype = check_choice(ctx, where, "type", value.get("type", "box"), FILTERS)
    check_keys(ctx, where, value, _FILTER_KEYS[ftype])
    sigma = check_number(ctx, where, "sigma", value.get("sigma", 0.5), positive=True)
    tau = check_number(ctx, where, "tau", value.get("tau", 3.0), positive=True)
    b = check_number(ctx, where, "b", value.get("b", 1.0 / 3.0))
    c = check_number(ctx, where, "c", value.get("c", 1.0 / 3.0))
    default_radius = {"box": 0.5, "tent": 1.0, "gaussian": 4.0 * sigma, "mitchell": 2.0, "lanczos": tau}[ftype]
    radius = check_vector(ctx, where, "radius", value.get("radius", default_radius), n=2, allow_scalar=True)
    try:
        return PixelFilter(ftype, tuple(float(r) for r in radius), sigma, b, c, tau).checked()
    except ValueError as exc:
        raise ctx.error(where, str(exc)) from None


def _read_camera(ctx, table) -> Camera:
    where = "[camera]"
    check_keys(ctx, where, table, _CAMERA_KEYS)
    for req in ("eye", "look_at"):
        if req not in table:
            raise ctx.error(where, f"missing '{req}' (or leave out [camera] to frame the scene automatically)")
    eye = check_vector(ctx, where, "eye", table["eye"])
    look_at = check_vector(ctx, where, "look_at", table["look_at"])
    up = check_vector(ctx, where, "up", table.get("up", [0.0, 1.0, 0.0]))
    projection = check_choice(ctx, where, "type", table.get("type", "perspective"), PROJECTIONS)
    if projection == "orthographic" and ("fov" in table or "fov_axis" in table) \
            or projection == "perspective" and "extent" in table:
        key = ("fov" if "fov" in table else "fov_axis") if projection == "orthographic" else "extent"
        raise ctx.error(where, f"'{key}' is not a key of {'an' if key != 'extent' else 'a'} {projection} camera")
    fov = check_number(ctx, where, "fov", table.get("fov", DEFAULT_FOV))
    if not 0 < fov < 180:
        raise ctx.error(where, f"'fov' must be between 0 and 180 degrees, got {fov:g}")
    fov_axis = check_choice(ctx, where, "fov_axis", table.get("fov_axis", "y"), FOV_AXES)
    extent = check_number(ctx, where, "extent", table.get("extent", 2.0), positive=True)
    forward = look_at - eye
    if not np.linalg.norm(forward) > 0:
        raise ctx.error(where, "'eye' and 'look_at' are the same point")
    if not np.linalg.norm(np.cross(forward / np.linalg.norm(forward), up)) > 1e-9:
        raise ctx.error(where, "'up' must not be zero or parallel to the viewing direction look_at - eye")
    aperture = check_number(ctx, where, "aperture_radius", table.get("aperture_radius", 0.0), minimum=0.0)
    focus = None
    if "focus_distance" in table:
        focus = check_number(ctx, where, "focus_distance", table["focus_distance"], positive=True)
    return Camera(
        eye=tuple(float(x) for x in eye), look_at=tuple(float(x) for x in look_at),
        up=tuple(float(x) for x in up), fov=float(fov), fov_axis=fov_axis, aperture_radius=float(aperture),
        focus_distance=focus,
        projection=projection, extent=float(extent),
    )


def rotation_matrix(axis, angle_degrees) -> np.ndarray:
    """3x3 right-handed rotation by ``angle_degrees`` about ``axis`` (Rodrigues)."""
    axis = np.asarray(axis, np.float64)
    axis = axis / np.linalg.norm(axis)
    a = math.radians(angle_degrees)
    x, y, z = axis
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * (k @ k)


def _shape_transform(ctx, where, table) -> np.ndarray | None:
    """4x4 matrix from the shape's transform keys, or None."""
    trs = [k for k in ("translate", "scale", "rotate") if k in table]
    if "matrix" in table:
        if trs:
            raise ctx.error(where, f"give either 'matrix' or translate/scale/rotate, not both ('{trs[0]}')")
        m = table["matrix"]
        if not isinstance(m, list) or len(m) != 4:
            raise ctx.error(where, f"'matrix' must be 4 rows of 4 numbers, got {describe(m)}")
        rows = [check_vector(ctx, where, f"matrix[{i}]", r, 4) for i, r in enumerate(m)]
        matrix = np.stack(rows)
        if not np.allclose(matrix[3], [0, 0, 0, 1]):
            raise ctx.error(where, f"'matrix' must be affine: its last row must be [0, 0, 0, 1], got {matrix[3].tolist()}")
        if abs(np.linalg.det(matrix[:3, :3])) < 1e-12:
            raise ctx.error(where, "'matrix' is singular (it flattens the shape)")
        return matrix
    if not trs:
        return None
    m3 = np.eye(3)
    if "scale" in table:
        s = check_vector(ctx, where, "scale", table["scale"], allow_scalar=True)
        if (s == 0).any():
            raise ctx.error(where, f"'scale' must not be 0 in any axis, got {s.tolist()}")
        m3 = np.diag(s) @ m3
    if "rotate" in table:
        rot = table["rotate"]
        steps = rot if isinstance(rot, list) else [rot]
        if not steps:
            raise ctx.error(where, "'rotate' is an empty list")
        for i, step in enumerate(steps):
            key = "rotate" if not isinstance(rot, list) else f"rotate[{i}]"
            if not isinstance(step, dict):
                raise ctx.error(where, f"'{key}' must be {{axis = [x, y, z], angle = DEGREES}}, got {describe(step)}")
            for k in step:
                if k not in ("axis", "angle"):
                    raise ctx.error(where, f"'{key}': unknown key '{k}' (expected axis, angle)")
            if "axis" not in step or "angle" not in step:
                raise ctx.error(where, f"'{key}' needs both 'axis' and 'angle' (degrees)")
            axis = check_vector(ctx, where, f"{key}.axis", step["axis"])
            if not np.linalg.norm(axis) > 0:
                raise ctx.error(where, f"'{key}.axis' must not be zero")
            angle = check_number(ctx, where, f"{key}.angle", step["angle"])
            m3 = rotation_matrix(axis, angle) @ m3
    matrix = np.eye(4)
    matrix[:3, :3] = m3
    if "translate" in table:
        matrix[:3, 3] = check_vector(ctx, where, "translate", table["translate"])
    return matrix


def _read_mesh_shape(ctx, where, scene_path: Path, table, materials, material_index, material_for):
    if "file" not in table:
        raise ctx.error(where, "missing 'file' (a mesh path relative to the scene file)")
    fname = table["file"]
    if not isinstance(fname, str) or not fname:
        raise ctx.error(where, f"'file' must be a path, got {describe(fname)}")
    mesh_path = scene_path.parent / Path(fname).expanduser()
    if not mesh_path.exists():
        raise ctx.error(where, f"mesh file '{fname}' not found (looked for {mesh_path})")
    if mesh_path.is_dir():
        raise ctx.error(where, f"mesh file '{fname}' is a folder ({mesh_path})")
    use_file = check_boolean(ctx, where, "use_file_materials", table.get("use_file_materials", False))
    suffix = mesh_path.suffix.lower()
    uvs = normals = colors = None
    if suffix in (".gltf", ".glb"):
        try:
            g = read_gltf(mesh_path, f"{ctx.name}: {where}: {fname}")
        except UserError as exc:
            raise SceneError(one_line(str(exc))) from None
        v, f, uvs, normals, colors = g.vertices, g.faces, g.uvs, g.normals, g.colors
    if use_file:
        if suffix not in (".obj", ".gltf", ".glb"):
            raise ctx.error(where, f"use_file_materials is only supported for OBJ and glTF files, not '{fname}'")
        fallback_index = material_for(where, table)
        overrides = {n: materials[i] for n, i in material_index.items()}
        if suffix == ".obj":
            try:
                v, f, local_mat, local_materials, uvs, normals = obj_with_materials(
                    mesh_path, f"{ctx.name}: {where}: {fname}", overrides, fallback=materials[fallback_index])
            except SceneError as exc:
                raise SceneError(one_line(str(exc))) from None
        else:  # glTF: a [materials.NAME] with a glTF material's name replaces it
            local_mat = g.face_materials
            local_materials = [overrides.get(m.name, m) for m in g.materials]
        # map the OBJ's material list into the scene's, reusing entries already there
        remap = np.empty(max(1, len(local_materials)), np.int32)
        for i, mat in enumerate(local_materials):
            for j, existing in enumerate(materials):
                if existing is mat:
                    remap[i] = j
                    break
            else:
                remap[i] = len(materials)
                materials.append(mat)
        face_mat = remap[local_mat] if len(local_mat) else np.zeros(0, np.int32)
    elif suffix not in (".gltf", ".glb"):
        try:
            loaded = load_trimesh(mesh_path)
            v, f = flatten(loaded, name=str(mesh_path))
        except MeshError as exc:
            raise ctx.error(where, str(exc)) from None
        uvs = trimesh_uvs(loaded, v, f)
        normals = ply_extras(loaded, f).normals
        face_mat = None
    else:
        face_mat = None
    if len(f) == 0:
        raise ctx.error(where, f"mesh file '{fname}' contains no triangles")
    return np.asarray(v, np.float64), np.asarray(f, np.int64), face_mat, uvs, normals, colors


