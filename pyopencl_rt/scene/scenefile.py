"""Scene files in, :class:`~pyopencl_rt.scene.Scene` out.

``load_scene(path)`` reads

* a **TOML scene file** (``.toml``), described below and in ``docs/SCENE_FORMAT.md``;
* an **OBJ file** (``.obj``) with its MTL materials: ``Kd`` becomes the albedo, ``Ke`` the
  emission, one material per face (``usemtl``); ``Ks``, ``Ns``, ``Ni``, ``d``/``Tr``, ``illum``
  and the PBR extension's ``Pr``/``Pm`` choose glossy, metal and glass materials (see
  :func:`parse_mtl`); a camera framing the scene and default settings;
* a **glTF 2.0 file** (``.gltf`` / ``.glb``, read by :mod:`pyopencl_rt.gltf`) with its PBR
  materials, textures, UVs and camera (or the framing camera);
* **any other mesh file** trimesh reads (PLY, STL, OFF, ...) with one default diffuse
  material (albedo 0.8) and the framing camera.

OBJ ``vt`` / ``map_Kd`` / ``map_Ke`` and TOML ``*_texture`` keys give textures
(:mod:`pyopencl_rt.textures`; docs/SCENE_FORMAT.md, "Textures and UVs").

Every problem with the input raises a :class:`SceneError` (a :class:`~pyopencl_rt.errors.UserError`)
whose message is one line and starts with the scene file's name.

TOML scene format (summary; the full reference is ``docs/SCENE_FORMAT.md``)::

    [camera]                      # optional; without it a camera frames the whole scene
    eye = [278, 273, -800]        # required in [camera]
    look_at = [278, 273, 0]       # required in [camera]
    up = [0, 1, 0]                # default [0, 1, 0]
    fov = 39.3077                 # vertical field of view in degrees, default 40

    [film]
    width = 512                   # pixels, default 512
    height = 512                  # pixels, default 512

    [render]
    spp = 64                      # samples per pixel, default 64
    max_depth = 8                 # path length limit, default 8
    integrator = "path"           # "path" | "bsdf" | "nee", default "path"
    seed = 0                      # default 0
    rr_depth = 3                  # Russian roulette starts after this many bounces, default 3

    [materials.white]             # one table per material, referred to by NAME
    type = "diffuse"              # "diffuse" (default) | "conductor" | "dielectric" | "gltf"
    albedo = [0.725, 0.71, 0.68]  # linear RGB in [0, 1] (or one number for grey), default 0.8
    emission = [0, 0, 0]          # linear RGB radiance >= 0 (or one number), default 0; any type
    two_sided = false             # emit from both sides, default false

    [materials.gold]              # rough metal: roughness (alpha = roughness^2) or alpha, and
    type = "conductor"            #   metal = "gold" | "silver" | "copper" | "aluminium",
    metal = "gold"                #   or eta = [...] and k = [...], or f0 = [...];
    roughness = 0.3               #   default: a perfect mirror (f0 = 1, roughness 0)

    [materials.glass]             # ior (inside / outside, default 1.5), roughness, tint
    type = "dielectric"

    [materials.plastic]           # glTF metallic-roughness: base_color, metallic, roughness, ior
    type = "gltf"

    [[shape]]                     # one table per shape, numbered #1, #2, ... in messages
    type = "quad"                 # "mesh" | "quad" | "triangle" | "box" | "sphere"
    material = "white"            # default: the built-in "default" material (albedo 0.8)
    points = [[0,0,0], [1,0,0], [1,1,0], [0,1,0]]

Shape keys:

* ``mesh``: ``file`` (relative to the scene file; any format trimesh loads),
  ``use_file_materials = true`` (OBJ only: take the MTL materials; a ``[materials.NAME]``
  with the same name overrides one, ``material`` is used for faces without ``usemtl``).
* ``quad``: ``points``: four corners in order, split into triangles (p0, p1, p2) and
  (p0, p2, p3); the emitting/front side is that of the normal (p1 - p0) x (p2 - p0), i.e. the
  corners run counter-clockwise seen from the front (right-hand rule).
* ``triangle``: ``points``: three corners; front side (p1 - p0) x (p2 - p0).
* ``box``: ``size`` (3-vector or number, default 1) centred on ``center`` (default origin);
  faces point outwards.
* ``sphere``: ``center``, ``radius``; emits outwards. No transforms.

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

from ..errors import UserError
from .mesh import MeshError, check_triangles, flatten, load_trimesh
from .model import CONDUCTORS, INTEGRATORS, Camera, Material, RenderSettings, Scene

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    try:
        import tomli as tomllib
    except ModuleNotFoundError:
        tomllib = None

__all__ = ["load_scene", "SceneError", "framing_camera", "parse_obj", "parse_mtl"]

MATERIAL_TYPES = ("diffuse", "conductor", "dielectric", "gltf")
SHAPE_TYPES = ("mesh", "quad", "triangle", "box", "sphere")
DEFAULT_FOV = 40.0

_TOP_KEYS = {"camera", "film", "render", "materials", "shape", "light", "environment"}
_CAMERA_KEYS = {"eye", "look_at", "up", "fov", "aperture_radius", "focus_distance"}
LIGHT_TYPES = ("point", "directional")
_LIGHT_KEYS = {"point": {"type", "position", "intensity"}, "directional": {"type", "direction", "irradiance"}}
_ENVIRONMENT_KEYS = {"radiance", "file", "scale"}
_FILM_KEYS = {"width", "height"}
_RENDER_KEYS = {"spp", "max_depth", "integrator", "seed", "rr_depth"}
_MATERIAL_COMMON_KEYS = {"type", "emission", "two_sided", "emission_texture"}
_ROUGHNESS_KEYS = {"roughness", "alpha"}
_MATERIAL_KEYS = {
    "diffuse": _MATERIAL_COMMON_KEYS | {"albedo", "albedo_texture"},
    "conductor": _MATERIAL_COMMON_KEYS | _ROUGHNESS_KEYS | {"metal", "eta", "k", "f0"},
    "dielectric": _MATERIAL_COMMON_KEYS | _ROUGHNESS_KEYS | {"ior", "tint"},
    "gltf": _MATERIAL_COMMON_KEYS | _ROUGHNESS_KEYS | {"base_color", "metallic", "ior", "base_color_texture",
                                                       "metallic_roughness_texture"},
}
_TRANSFORM_KEYS = {"translate", "scale", "rotate", "matrix", "flip_normals"}
_SHAPE_KEYS = {
    "mesh": {"type", "material", "file", "use_file_materials"} | _TRANSFORM_KEYS,
    "quad": {"type", "material", "points"} | _TRANSFORM_KEYS,
    "triangle": {"type", "material", "points"} | _TRANSFORM_KEYS,
    "box": {"type", "material", "size", "center"} | _TRANSFORM_KEYS,
    "sphere": {"type", "material", "center", "radius"},
}


class SceneError(UserError):
    """A scene file that cannot be loaded; the message is one line naming the file."""


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


# --------------------------------------------------------------------------------------------
# entry point


def load_scene(path) -> Scene:
    """Load a ``.toml`` scene file, an ``.obj`` (+ ``.mtl``) file or any mesh trimesh reads."""
    p = Path(path)
    name = str(path)
    if not p.exists():
        raise SceneError(f"{name}: no such file")
    if p.is_dir():
        raise SceneError(f"{name}: is a folder, not a scene file")
    suffix = p.suffix.lower()
    try:
        if suffix == ".toml":
            return _load_toml(p, name)
        if suffix == ".obj":
            return _load_obj_scene(p, name)
        if suffix in (".gltf", ".glb"):
            return _load_gltf_scene(p, name)
        return _load_mesh_scene(p, name)
    except SceneError:
        raise
    except UserError as exc:  # MeshError from mesh.py: already names the file, make sure it is one line
        raise type(exc)(_one_line(str(exc))) from None


# --------------------------------------------------------------------------------------------
# OBJ / MTL


def parse_mtl(path, name: str | None = None) -> dict:
    """{material name: Material} from an MTL file.

    ``Kd`` -> albedo (clamped to [0, 1]), ``Ke`` -> emission; then the material's type:

    * ``d`` < 1, ``Tr`` > 0 or ``illum`` 4, 6, 7 or 9 (transparency / refraction): a dielectric
      of IOR ``Ni`` (default 1.5);
    * ``Pm`` given (the PBR extension): ``gltf`` with baseColor ``Kd``, metallic ``Pm``;
    * ``illum 3`` (ray-traced reflection) with ``Kd`` = 0 and ``Ks`` > 0: a conductor with
      F0 = ``Ks`` (Schlick);
    * ``illum 2`` (highlights) with ``Ks`` > 0: ``gltf`` plastic (metallic 0, baseColor ``Kd``,
      IOR ``Ni`` or 1.5);
    * anything else: diffuse.

    Roughness: ``Pr`` (perceptual, alpha = Pr^2) if given, else from the Phong exponent ``Ns``
    by Walter et al.'s (2007) correspondence alpha = sqrt(2 / (Ns + 2)); without either, 0
    (smooth) for glass and mirrors and 1 for gltf.
    """
    name = name or str(path)
    materials: dict[str, Material] = {}
    props: dict[str, dict] = {}
    current = None
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise SceneError(f"{name}: cannot read ({exc.strerror or exc})") from None
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        key, _, rest = line.partition(" ")
        key = key.strip()
        rest = rest.strip()
        if key == "newmtl":
            current = Material(name=rest or f"material{len(materials)}")
            materials[current.name] = current
            props[current.name] = {}
        elif key in ("Kd", "Ke", "Ks") and current is not None:
            fields = rest.split()
            if fields and fields[0] in ("spectral", "xyz"):
                warnings.warn(f"{name}:{lineno}: '{key} {fields[0]}' is not supported; ignored", stacklevel=3)
                continue
            try:
                values = [float(f) for f in fields]
            except ValueError:
                raise SceneError(f"{name}:{lineno}: {key} needs numbers, got '{rest}'") from None
            if len(values) == 1:
                values = values * 3
            if len(values) != 3 or not all(math.isfinite(v) for v in values):
                raise SceneError(f"{name}:{lineno}: {key} needs 1 or 3 finite numbers, got '{rest}'")
            if key in ("Kd", "Ks"):
                clipped = tuple(min(max(v, 0.0), 1.0) for v in values)
                if clipped != tuple(values):
                    warnings.warn(f"{name}:{lineno}: {key} {rest} clamped to [0, 1]", stacklevel=3)
                if key == "Kd":
                    current.albedo = clipped
                else:
                    props[current.name]["Ks"] = clipped
            else:
                if min(values) < 0:
                    raise SceneError(f"{name}:{lineno}: Ke must not be negative, got '{rest}'")
                current.emission = tuple(values)
        elif key in ("map_Kd", "map_Ke") and current is not None:
            # options (-s, -o, -bm ...) are ignored: the file name is the last field
            fields = rest.split()
            if not fields:
                raise SceneError(f"{name}:{lineno}: {key} needs an image file")
            tex_path = Path(path).parent / fields[-1].replace("\\", "/")
            if not tex_path.exists():
                warnings.warn(f"{name}:{lineno}: texture '{fields[-1]}' not found ({tex_path}); ignored", stacklevel=3)
                continue
            try:
                tex = _load_texture(tex_path)
            except Exception as exc:
                raise SceneError(f"{name}:{lineno}: cannot read texture '{fields[-1]}' ({type(exc).__name__}: {exc})") from None
            if key == "map_Kd":
                current.base_texture = tex
            else:
                current.emission_texture = tex
        elif key in ("Ns", "Ni", "d", "Tr", "illum", "Pr", "Pm") and current is not None:
            try:
                value = float(rest.split()[0])
            except (ValueError, IndexError):
                raise SceneError(f"{name}:{lineno}: {key} needs a number, got '{rest}'") from None
            if not math.isfinite(value):
                raise SceneError(f"{name}:{lineno}: {key} needs a finite number, got '{rest}'")
            props[current.name][key] = value
    for mname, mat in materials.items():
        _mtl_type(mat, props[mname])
    return materials


def _mtl_type(mat: Material, p: dict) -> None:
    """Choose the material type from the MTL statements (see parse_mtl)."""
    ks = p.get("Ks", (0.0, 0.0, 0.0))
    illum = int(p["illum"]) if "illum" in p else None
    opacity = p.get("d", 1.0 - p.get("Tr", 0.0))
    ior = p.get("Ni", 1.5)
    if not ior > 0:
        ior = 1.5
    if "Pr" in p:
        alpha = min(max(p["Pr"], 0.0), 1.0) ** 2
    elif "Ns" in p:
        alpha = min(1.0, math.sqrt(2.0 / (max(p["Ns"], 0.0) + 2.0)))
    else:
        alpha = None
    if opacity < 1.0 or illum in (4, 6, 7, 9):
        mat.type, mat.ior, mat.alpha = "dielectric", ior, alpha or 0.0
    elif "Pm" in p:
        mat.type, mat.metallic, mat.ior = "gltf", min(max(p["Pm"], 0.0), 1.0), ior
        mat.alpha = 1.0 if alpha is None else alpha
    elif illum == 3 and max(mat.albedo) == 0.0 and max(ks) > 0.0:
        mat.type, mat.f0, mat.alpha = "conductor", ks, alpha or 0.0
    elif illum == 2 and max(ks) > 0.0:
        mat.type, mat.metallic, mat.ior = "gltf", 0.0, ior
        mat.alpha = 1.0 if alpha is None else alpha


def parse_obj(path, name: str | None = None, *, with_uvs: bool = False):
    """(vertices (V,3) float64, faces (F,3) int64, face material names list[str|None], mtllib paths),
    and with ``with_uvs`` a fifth item: per-corner texture coordinates (F, 3, 2) float32 from
    ``vt`` (v flipped to the top-down image convention of pyopencl_rt.textures), or None when
    the file has none (corners without a ``vt`` index get (0, 0)).

    Polygons are fan-triangulated (as trimesh does); negative (relative) indices and
    ``v/vt/vn`` forms are accepted; only ``v``, ``vt``, ``f``, ``usemtl`` and ``mtllib`` matter.
    """
    name = name or str(path)
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise SceneError(f"{name}: cannot read ({exc.strerror or exc})") from None
    text = text.replace("\\\r\n", " ").replace("\\\n", " ")
    vertex_text: list[str] = []
    vertex_lines: list[int] = []
    corners: list[int] = []  # 3 raw OBJ indices per triangle
    uv_text: list[str] = []
    uv_corners: list[int] = []  # 3 resolved vt indices per triangle (-1: none)
    tri_nv: list[int] = []  # vertices defined when the face was read (for relative indices)
    tri_line: list[int] = []
    tri_mtl: list[int] = []
    mtl_names: list[str | None] = [None]
    mtl_lookup = {None: 0}
    current = 0
    mtllibs: list[str] = []
    for lineno, raw in enumerate(text.splitlines(), 1):
        if "#" in raw:
            raw = raw.split("#", 1)[0]
        key, _, rest = raw.strip().partition(" ")
        if key == "v":
            fields = rest.split()
            if len(fields) < 3:
                raise SceneError(f"{name}:{lineno}: a vertex needs 3 coordinates, got '{raw.strip()}'")
            vertex_text.append(rest if len(fields) == 3 else " ".join(fields[:3]))
            vertex_lines.append(lineno)
        elif key == "vt":
            fields = rest.split()
            uv_text.append(" ".join((fields + ["0", "0"])[:2]))
        elif key == "f":
            toks = rest.split()
            if "/" in rest:
                if with_uvs:
                    tidx = []
                    for t in toks:
                        parts = t.split("/")
                        try:
                            k = int(parts[1]) if len(parts) > 1 and parts[1] else 0
                        except ValueError:
                            raise SceneError(f"{name}:{lineno}: bad face '{raw.strip()}'") from None
                        k = len(uv_text) + k if k < 0 else k - 1
                        tidx.append(k if 0 <= k < len(uv_text) else -1)
                    for k in range(1, len(tidx) - 1):
                        uv_corners.extend((tidx[0], tidx[k], tidx[k + 1]))
                toks = [t.split("/", 1)[0] for t in toks]
            elif with_uvs:
                uv_corners.extend([-1] * (3 * max(len(toks) - 2, 0)))
            try:
                idx = list(map(int, toks))
            except ValueError:
                raise SceneError(f"{name}:{lineno}: bad face '{raw.strip()}'") from None
            n = len(idx)
            if n < 3:
                raise SceneError(f"{name}:{lineno}: a face needs at least 3 vertices, got '{raw.strip()}'")
            if n == 3:
                corners.extend(idx)
            else:
                first = idx[0]
                for k in range(1, n - 1):
                    corners.extend((first, idx[k], idx[k + 1]))
            nv = len(vertex_text)
            tri_nv.extend([nv] * (n - 2))
            tri_line.extend([lineno] * (n - 2))
            tri_mtl.extend([current] * (n - 2))
        elif key == "usemtl":
            mname = rest.strip() or None
            if mname not in mtl_lookup:
                mtl_lookup[mname] = len(mtl_names)
                mtl_names.append(mname)
            current = mtl_lookup[mname]
        elif key == "mtllib":
            rest = rest.strip()
            if (Path(path).parent / rest).exists() or " " not in rest:
                mtllibs.append(rest)
            else:
                mtllibs.extend(rest.split())
    try:
        v = np.array(" ".join(vertex_text).split(), dtype=np.float64).reshape(-1, 3)
    except ValueError:
        for lineno, t in zip(vertex_lines, vertex_text):
            try:
                [float(x) for x in t.split()]
            except ValueError:
                raise SceneError(f"{name}:{lineno}: bad vertex 'v {t}'") from None
        raise
    f = np.asarray(corners, np.int64).reshape(-1, 3)
    if len(f):
        nv = np.asarray(tri_nv, np.int64)[:, None]
        resolved = np.where(f < 0, nv + f, f - 1)
        bad = (resolved < 0) | (resolved >= nv) | (f == 0)
        if bad.any():
            row, col = np.argwhere(bad)[0]
            raise SceneError(f"{name}:{tri_line[row]}: face index {f[row, col]} refers to no vertex defined before it")
        f = resolved
    names = [mtl_names[i] for i in tri_mtl]
    if not with_uvs:
        return v, f, names, mtllibs
    uvs = None
    if uv_text and uv_corners:
        try:
            table = np.array(" ".join(uv_text).split(), dtype=np.float64).reshape(-1, 2)
        except ValueError:
            raise SceneError(f"{name}: bad texture coordinate (vt)") from None
        table = np.vstack([table, [[0.0, 1.0]]])  # index -1: (0, 0) after the flip below
        uvs = table[np.asarray(uv_corners, np.int64).reshape(-1, 3)]
        uvs[..., 1] = 1.0 - uvs[..., 1]
        uvs = uvs.astype(np.float32)
    return v, f, names, mtllibs, uvs


def _obj_with_materials(path: Path, name: str, overrides: dict | None = None, fallback: Material | None = None):
    """vertices, faces, face material indices (into the returned list), materials list, uvs
    ((F, 3, 2) or None)."""
    vertices, faces, face_names, mtllibs, uvs = parse_obj(path, name, with_uvs=True)
    library: dict[str, Material] = {}
    libraries_missing = False
    for lib in mtllibs:
        lib_path = path.parent / lib
        if not lib_path.exists():
            libraries_missing = True
            warnings.warn(f"{name}: material library '{lib}' not found ({lib_path}); using default materials", stacklevel=3)
            continue
        library.update(parse_mtl(lib_path, str(lib_path)))
    overrides = overrides or {}
    materials: list[Material] = []
    index: dict[str | None, int] = {}
    missing = []
    for mname in dict.fromkeys(face_names):  # in order of first use
        if mname is None:
            mat = fallback or Material()
        elif mname in overrides:
            mat = overrides[mname]
        elif mname in library:
            mat = library[mname]
        else:
            missing.append(mname)
            mat = Material(name=mname)
        index[mname] = len(materials)
        materials.append(mat)
    if missing and not libraries_missing:
        warnings.warn(f"{name}: materials {', '.join(map(repr, missing))} not defined in any MTL; using albedo 0.8", stacklevel=3)
    face_mat = np.fromiter((index[n] for n in face_names), np.int32, count=len(face_names))
    return vertices, faces, face_mat, materials, uvs


def _load_obj_scene(p: Path, name: str) -> Scene:
    vertices, faces, face_mat, materials, uvs = _obj_with_materials(p, name)
    if len(faces) == 0:
        raise SceneError(f"{name}: contains no faces")
    uvs = _kept_uvs(vertices, faces, uvs)
    v32, f32, face_mat = _checked(vertices, faces, face_mat, name)
    if not materials:
        materials = [Material()]
    scene = Scene(vertices=v32, faces=f32, face_materials=face_mat, materials=materials, source=name, uvs=uvs)
    scene.camera = framing_camera(*_bounds(scene), scene.settings.width, scene.settings.height)
    return scene


def _load_mesh_scene(p: Path, name: str) -> Scene:
    vertices, faces = flatten(load_trimesh(p), name=name)
    if len(faces) == 0:
        raise SceneError(f"{name}: contains no triangles")
    scene = Scene(
        vertices=vertices, faces=faces, face_materials=np.zeros(len(faces), np.int32),
        materials=[Material()], source=name,
    )
    scene.camera = framing_camera(*_bounds(scene), scene.settings.width, scene.settings.height)
    return scene


def _load_texture(path):
    from .textures import texture_from_image

    return texture_from_image(path, srgb=True)


def _kept_uvs(vertices, faces, uvs):
    """uvs (F, 3, 2) for the faces that _checked keeps (those with finite vertices), or None."""
    if uvs is None:
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        finite = np.isfinite(np.asarray(vertices, np.float64).astype(np.float32)).all(axis=1)
    faces = np.asarray(faces, np.int64)
    keep = finite[faces].all(axis=1) if len(faces) else np.zeros(0, bool)
    return np.ascontiguousarray(np.asarray(uvs, np.float32)[keep])


def _read_gltf(path: Path, name: str):
    from .gltf import load_gltf

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        g = load_gltf(path, name)
    for w in caught:
        warnings.warn(w.message, stacklevel=4)
    return g


def _load_gltf_scene(p: Path, name: str) -> Scene:
    """A glTF 2.0 file (.gltf / .glb) with its materials, textures and camera (pyopencl_rt/gltf.py);
    without a camera in the file, one that frames the scene."""
    g = _read_gltf(p, name)
    if len(g.faces) == 0:
        raise SceneError(f"{name}: contains no triangles")
    uvs = _kept_uvs(g.vertices, g.faces, g.uvs)
    v32, f32, face_mat = _checked(g.vertices, g.faces, g.face_materials, name)
    scene = Scene(vertices=v32, faces=f32, face_materials=face_mat, materials=g.materials or [Material()],
                  source=name, uvs=uvs)
    if g.aspect_ratio and g.aspect_ratio > 0:
        st = scene.settings
        st.width = max(1, int(round(st.height * float(g.aspect_ratio))))
    scene.camera = g.camera or framing_camera(*_bounds(scene), scene.settings.width, scene.settings.height)
    return scene


def _checked(vertices, faces, face_mat, name):
    """check_triangles, keeping face_materials aligned with faces it may drop."""
    faces = np.asarray(faces, np.int64)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        v32, f32 = check_triangles(vertices, faces, name)
    for w in caught:
        warnings.warn(w.message, stacklevel=3)
    face_mat = np.asarray(face_mat, np.int32)
    if len(f32) != len(faces):
        with np.errstate(over="ignore", invalid="ignore"):
            finite = np.isfinite(np.asarray(vertices, np.float64).astype(np.float32)).all(axis=1)
        keep = finite[faces].all(axis=1)
        face_mat = face_mat[keep]
    return v32, f32, np.ascontiguousarray(face_mat)


# --------------------------------------------------------------------------------------------
# framing camera


def _bounds(scene: Scene):
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    if len(scene.faces):
        used = scene.vertices[np.unique(scene.faces)].astype(np.float64)
        lo = np.minimum(lo, used.min(axis=0))
        hi = np.maximum(hi, used.max(axis=0))
    if len(scene.spheres):
        s = scene.spheres.astype(np.float64)
        lo = np.minimum(lo, (s[:, :3] - s[:, 3:4]).min(axis=0))
        hi = np.maximum(hi, (s[:, :3] + s[:, 3:4]).max(axis=0))
    if not np.isfinite(lo).all():
        lo = hi = np.zeros(3)
    return lo, hi


def framing_camera(lo, hi, width: int = 512, height: int = 512, fov: float = DEFAULT_FOV) -> Camera:
    """A camera looking along -z at the centre of the box [lo, hi], far enough back that the
    box's bounding sphere fits the narrower of the vertical and horizontal fields of view."""
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    centre = (lo + hi) / 2
    radius = float(np.linalg.norm(hi - lo)) / 2
    if not radius > 0:
        radius = 1.0
    half_v = math.radians(fov) / 2
    half_h = math.atan(math.tan(half_v) * width / height)
    half = min(half_v, half_h)
    distance = 1.05 * radius / math.sin(half)
    eye = centre + np.array([0.0, 0.0, distance])
    return Camera(
        eye=tuple(float(x) for x in eye), look_at=tuple(float(x) for x in centre),
        up=(0.0, 1.0, 0.0), fov=float(fov),
    )


# --------------------------------------------------------------------------------------------
# TOML


class _Ctx:
    """Error helper: every message is '<file>: <where>: <what>'."""

    def __init__(self, name: str):
        self.name = name

    def error(self, where: str, what: str) -> SceneError:
        prefix = f"{self.name}: {where}: " if where else f"{self.name}: "
        return SceneError(_one_line(prefix + what))


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _describe(x) -> str:
    if isinstance(x, bool):
        return f"boolean {str(x).lower()}"
    if isinstance(x, str):
        return f"string {x!r}"
    if isinstance(x, list):
        return f"a list of {len(x)}"
    if isinstance(x, dict):
        return "a table"
    return f"{type(x).__name__} {x!r}"


def _check_keys(ctx: _Ctx, where: str, table, allowed: set):
    if not isinstance(table, dict):
        raise ctx.error(where, f"must be a table, got {_describe(table)}")
    for key in table:
        if key not in allowed:
            raise ctx.error(where, f"unknown key '{key}' (expected one of: {', '.join(sorted(allowed))})")


def _number(ctx, where, key, value, *, minimum=None, positive=False, maximum=None) -> float:
    if not _is_number(value) or not math.isfinite(value):
        raise ctx.error(where, f"'{key}' must be a number, got {_describe(value)}")
    value = float(value)
    if positive and not value > 0:
        raise ctx.error(where, f"'{key}' must be > 0, got {value:g}")
    if minimum is not None and value < minimum:
        raise ctx.error(where, f"'{key}' must be >= {minimum:g}, got {value:g}")
    if maximum is not None and value > maximum:
        raise ctx.error(where, f"'{key}' must be <= {maximum:g}, got {value:g}")
    return value


def _integer(ctx, where, key, value, *, minimum=None, maximum=None) -> int:
    if not isinstance(value, int) or isinstance(value, bool):
        raise ctx.error(where, f"'{key}' must be an integer, got {_describe(value)}")
    if minimum is not None and value < minimum:
        raise ctx.error(where, f"'{key}' must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise ctx.error(where, f"'{key}' must be <= {maximum}, got {value}")
    return value


def _boolean(ctx, where, key, value) -> bool:
    if not isinstance(value, bool):
        raise ctx.error(where, f"'{key}' must be true or false, got {_describe(value)}")
    return value


def _vector(ctx, where, key, value, n=3, *, allow_scalar=False) -> np.ndarray:
    if allow_scalar and _is_number(value):
        value = [value] * n
    if not isinstance(value, list) or len(value) != n or not all(_is_number(x) for x in value):
        shape = f"{n} numbers" + (" or one number" if allow_scalar else "")
        raise ctx.error(where, f"'{key}' must be a list of {shape}, got {_describe(value)}")
    arr = np.asarray(value, np.float64)
    if not np.isfinite(arr).all():
        raise ctx.error(where, f"'{key}' must be finite, got {value}")
    return arr


def _points(ctx, where, key, value, n) -> np.ndarray:
    if not isinstance(value, list) or len(value) != n:
        raise ctx.error(where, f"'{key}' must be a list of {n} points [x, y, z], got {_describe(value)}")
    return np.stack([_vector(ctx, where, f"{key}[{i}]", p) for i, p in enumerate(value)])


def _load_toml(p: Path, name: str) -> Scene:
    ctx = _Ctx(name)
    if tomllib is None:  # pragma: no cover - Python 3.10 without tomli
        raise ctx.error("", "reading TOML scene files needs Python >= 3.11 or the 'tomli' package")
    try:
        with open(p, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ctx.error("", f"not valid TOML: {exc}") from None
    except OSError as exc:
        raise ctx.error("", f"cannot read ({exc.strerror or exc})") from None
    for key in doc:
        if key not in _TOP_KEYS:
            hint = " (did you mean [[shape]]?)" if key in ("shapes", "shape_") else ""
            raise ctx.error("", f"unknown key '{key}' (expected one of: {', '.join(sorted(_TOP_KEYS))}){hint}")

    settings = _parse_settings(ctx, doc.get("film", {}), doc.get("render", {}))
    materials, material_index = _parse_materials(ctx, doc.get("materials", {}))

    shapes = doc.get("shape", [])
    if not isinstance(shapes, list):
        raise ctx.error("shape", "must be an array of tables written [[shape]]")
    if not shapes:
        raise ctx.error("", "defines no shapes (add [[shape]] tables)")

    def material_for(where, table) -> int:
        if "material" not in table:
            if "default" not in material_index:
                material_index["default"] = len(materials)
                materials.append(Material())
            return material_index["default"]
        mname = table["material"]
        if not isinstance(mname, str):
            raise ctx.error(where, f"'material' must be a material name, got {_describe(mname)}")
        if mname not in material_index:
            if mname == "default":
                material_index["default"] = len(materials)
                materials.append(Material())
            else:
                known = ", ".join(sorted(material_index)) or "none defined"
                raise ctx.error(where, f"unknown material '{mname}' (materials: {known})")
        return material_index[mname]

    tri_vertices, tri_faces, tri_mats, tri_uvs = [], [], [], []
    n_vertices = 0
    spheres, sphere_mats = [], []
    for number, table in enumerate(shapes, 1):
        where = f"[[shape]] #{number}"
        if not isinstance(table, dict):
            raise ctx.error(where, f"must be a table, got {_describe(table)}")
        stype = table.get("type")
        if stype is None:
            raise ctx.error(where, f"missing 'type' (one of: {', '.join(SHAPE_TYPES)})")
        if not isinstance(stype, str) or stype not in SHAPE_TYPES:
            shown = repr(stype) if isinstance(stype, str) else _describe(stype)
            raise ctx.error(where, f"unknown type {shown} (expected one of: {', '.join(SHAPE_TYPES)})")
        where = f"[[shape]] #{number} ({stype})"
        _check_keys(ctx, where, table, _SHAPE_KEYS[stype])

        if stype == "sphere":
            for req in ("center", "radius"):
                if req not in table:
                    raise ctx.error(where, f"missing '{req}'")
            centre = _vector(ctx, where, "center", table["center"])
            radius = _number(ctx, where, "radius", table["radius"], positive=True)
            spheres.append([*centre, radius])
            sphere_mats.append(material_for(where, table))
            continue

        face_mat = None
        uvc = None  # per-corner texture coordinates (F, 3, 2), None = zeros
        if stype == "mesh":
            v, f, face_mat, uvc = _mesh_shape(ctx, where, p, table, materials, material_index, material_for)
        elif stype == "quad":
            if "points" not in table:
                raise ctx.error(where, "missing 'points' (four corners [[x,y,z], ...])")
            v = _points(ctx, where, "points", table["points"], 4)
            f = np.array([[0, 1, 2], [0, 2, 3]], np.int64)
            uvc = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)[f]  # p0..p3 -> uv corners
        elif stype == "triangle":
            if "points" not in table:
                raise ctx.error(where, "missing 'points' (three corners [[x,y,z], ...])")
            v = _points(ctx, where, "points", table["points"], 3)
            f = np.array([[0, 1, 2]], np.int64)
            uvc = np.array([[[0, 0], [1, 0], [0, 1]]], np.float32)
        else:  # box
            import trimesh

            size = _vector(ctx, where, "size", table.get("size", 1.0), allow_scalar=True)
            if not (size > 0).all():
                raise ctx.error(where, f"'size' must be > 0 in every axis, got {size.tolist()}")
            centre = _vector(ctx, where, "center", table.get("center", [0.0, 0.0, 0.0]))
            box = trimesh.creation.box(extents=size)
            v = np.asarray(box.vertices, np.float64) + centre
            f = np.asarray(box.faces, np.int64)

        if stype in ("quad", "triangle"):
            areas = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
            if not (areas > 0).all():
                raise ctx.error(where, "degenerate: its corners do not span an area (repeated or collinear points)")

        matrix = _transform(ctx, where, table)
        if matrix is not None:
            v = v @ matrix[:3, :3].T + matrix[:3, 3]
            if np.linalg.det(matrix[:3, :3]) < 0:
                f = f[:, ::-1]
                uvc = uvc[:, ::-1] if uvc is not None else None
        if _boolean(ctx, where, "flip_normals", table.get("flip_normals", False)):
            f = f[:, ::-1]
            uvc = uvc[:, ::-1] if uvc is not None else None
        if face_mat is None:
            face_mat = np.full(len(f), material_for(where, table), np.int32)
        tri_vertices.append(v)
        tri_uvs.append(np.zeros((len(f), 3, 2), np.float32) if uvc is None else np.asarray(uvc, np.float32))
        tri_faces.append(f + n_vertices)
        tri_mats.append(face_mat)
        n_vertices += len(v)

    if tri_faces:
        vertices = np.concatenate(tri_vertices)
        faces = np.concatenate(tri_faces)
        face_mat = np.concatenate(tri_mats)
        uvs = _kept_uvs(vertices, faces, np.concatenate(tri_uvs))
    else:
        uvs = None
        vertices = np.zeros((0, 3))
        faces = np.zeros((0, 3), np.int64)
        face_mat = np.zeros(0, np.int32)
    v32, f32, face_mat = _checked(vertices, faces, face_mat, name)
    scene = Scene(
        vertices=v32, faces=f32, face_materials=face_mat, materials=materials or [Material()],
        spheres=np.asarray(spheres, np.float32).reshape(-1, 4),
        sphere_materials=np.asarray(sphere_mats, np.int32),
        settings=settings, source=name, uvs=uvs,
    )
    if "camera" in doc:
        scene.camera = _parse_camera(ctx, doc["camera"])
    else:
        scene.camera = framing_camera(*_bounds(scene), settings.width, settings.height)
    scene.lights = _parse_lights(ctx, doc.get("light", []))
    if "environment" in doc:
        scene.environment = _parse_environment(ctx, p, doc["environment"])
    return scene


def _color(ctx, where, key, value) -> tuple:
    c = _vector(ctx, where, key, value, allow_scalar=True)
    if (c < 0).any():
        raise ctx.error(where, f"'{key}' must be >= 0, got {c.tolist()}")
    return tuple(float(x) for x in c)


def _parse_lights(ctx, lights) -> list:
    from .model import DirectionalLight, PointLight

    if not isinstance(lights, list):
        raise ctx.error("light", "must be an array of tables written [[light]]")
    out = []
    for number, table in enumerate(lights, 1):
        where = f"[[light]] #{number}"
        if not isinstance(table, dict):
            raise ctx.error(where, f"must be a table, got {_describe(table)}")
        ltype = table.get("type")
        if not isinstance(ltype, str) or ltype not in LIGHT_TYPES:
            shown = "missing 'type'" if ltype is None else f"unknown type {ltype!r}"
            raise ctx.error(where, f"{shown} (expected one of: {', '.join(LIGHT_TYPES)})")
        where = f"[[light]] #{number} ({ltype})"
        _check_keys(ctx, where, table, _LIGHT_KEYS[ltype])
        if ltype == "point":
            if "position" not in table:
                raise ctx.error(where, "missing 'position'")
            out.append(PointLight(position=tuple(float(x) for x in _vector(ctx, where, "position", table["position"])),
                                  intensity=_color(ctx, where, "intensity", table.get("intensity", 1.0))))
        else:
            if "direction" not in table:
                raise ctx.error(where, "missing 'direction' (the way the light travels)")
            d = _vector(ctx, where, "direction", table["direction"])
            if not np.linalg.norm(d) > 0:
                raise ctx.error(where, "'direction' must not be zero")
            out.append(DirectionalLight(direction=tuple(float(x) for x in d / np.linalg.norm(d)),
                                        irradiance=_color(ctx, where, "irradiance", table.get("irradiance", 1.0))))
    return out


def _parse_environment(ctx, scene_path: Path, table):
    from .model import Environment

    where = "[environment]"
    if not isinstance(table, dict):
        raise ctx.error(where, f"must be a table, got {_describe(table)}")
    _check_keys(ctx, where, table, _ENVIRONMENT_KEYS)
    if "file" in table:
        if "radiance" in table:
            raise ctx.error(where, "give 'radiance' (a constant) or 'file' (a map, with 'scale'), not both")
        fname = table["file"]
        if not isinstance(fname, str):
            raise ctx.error(where, f"'file' must be a file name, got {_describe(fname)}")
        path = (scene_path.parent / fname)
        if not path.is_file():
            raise ctx.error(where, f"environment map '{fname}' not found (looked for {path})")
        from ..imageio import read_exr

        try:
            image = read_exr(path)
        except UserError as exc:
            raise ctx.error(where, _one_line(str(exc))) from None
        image = np.asarray(image, np.float32)
        if image.ndim != 3 or image.shape[2] != 3:
            raise ctx.error(where, f"environment map '{fname}' must be an RGB image, got shape {image.shape}")
        if not np.isfinite(image).all() or (image < 0).any():
            warnings.warn(f"{ctx.name}: {where}: '{fname}' has negative or non-finite texels; they are treated as 0",
                          stacklevel=3)
        return Environment(radiance=_color(ctx, where, "scale", table.get("scale", 1.0)), image=image,
                           source=str(path))
    if "scale" in table:
        raise ctx.error(where, "'scale' multiplies a map: use it with 'file' (or give 'radiance')")
    return Environment(radiance=_color(ctx, where, "radiance", table.get("radiance", 1.0)))


def _parse_settings(ctx, film, render) -> RenderSettings:
    s = RenderSettings()
    _check_keys(ctx, "[film]", film, _FILM_KEYS)
    _check_keys(ctx, "[render]", render, _RENDER_KEYS)
    if "width" in film:
        s.width = _integer(ctx, "[film]", "width", film["width"], minimum=1, maximum=65536)
    if "height" in film:
        s.height = _integer(ctx, "[film]", "height", film["height"], minimum=1, maximum=65536)
    if "spp" in render:
        s.spp = _integer(ctx, "[render]", "spp", render["spp"], minimum=1)
    if "max_depth" in render:
        s.max_depth = _integer(ctx, "[render]", "max_depth", render["max_depth"], minimum=1)
    if "rr_depth" in render:
        s.rr_depth = _integer(ctx, "[render]", "rr_depth", render["rr_depth"], minimum=0)
    if "seed" in render:
        s.seed = _integer(ctx, "[render]", "seed", render["seed"], minimum=0, maximum=2**32 - 1)
    if "integrator" in render:
        integ = render["integrator"]
        if not isinstance(integ, str) or integ not in INTEGRATORS:
            shown = repr(integ) if isinstance(integ, str) else _describe(integ)
            raise ctx.error("[render]", f"unknown integrator {shown} (expected one of: {', '.join(INTEGRATORS)})")
        s.integrator = integ
    return s


def _rgb01(ctx, where, key, value) -> tuple:
    v = _vector(ctx, where, key, value, allow_scalar=True)
    if v.min() < 0 or v.max() > 1:
        raise ctx.error(where, f"'{key}' components must lie in [0, 1], got {v.tolist()}")
    return tuple(float(x) for x in v)


def _alpha(ctx, where, spec) -> float:
    """GGX alpha from 'roughness' (perceptual, alpha = roughness^2) or 'alpha'; default 0."""
    if "roughness" in spec and "alpha" in spec:
        raise ctx.error(where, "give 'roughness' or 'alpha', not both")
    if "alpha" in spec:
        return _number(ctx, where, "alpha", spec["alpha"], minimum=0.0, maximum=1.0)
    return _number(ctx, where, "roughness", spec.get("roughness", 0.0), minimum=0.0, maximum=1.0) ** 2


def _parse_material(ctx, where, mname, spec) -> Material:
    if not isinstance(spec, dict):
        raise ctx.error(where, f"must be a table, got {_describe(spec)}")
    mtype = spec.get("type", "diffuse")
    if not isinstance(mtype, str) or mtype not in MATERIAL_TYPES:
        shown = repr(mtype) if isinstance(mtype, str) else _describe(mtype)
        raise ctx.error(where, f"unknown type {shown} (expected one of: {', '.join(MATERIAL_TYPES)})")
    _check_keys(ctx, where, spec, _MATERIAL_KEYS[mtype])
    emission = _vector(ctx, where, "emission", spec.get("emission", 0.0), allow_scalar=True)
    if emission.min() < 0:
        raise ctx.error(where, f"'emission' must not be negative, got {emission.tolist()}")
    two_sided = _boolean(ctx, where, "two_sided", spec.get("two_sided", False))
    mat = Material(name=mname, emission=tuple(float(x) for x in emission), two_sided=two_sided, type=mtype)
    mat.emission_texture = _texture_key(ctx, where, spec, "emission_texture", srgb=True)
    if mtype == "diffuse":
        mat.albedo = _rgb01(ctx, where, "albedo", spec.get("albedo", 0.8))
        mat.base_texture = _texture_key(ctx, where, spec, "albedo_texture", srgb=True)
        return mat
    mat.alpha = _alpha(ctx, where, spec)
    if mtype == "conductor":
        given = [k for k in ("metal", "f0") if k in spec] + (["eta/k"] if "eta" in spec or "k" in spec else [])
        if len(given) > 1:
            raise ctx.error(where, f"give only one of 'metal', 'eta' and 'k', or 'f0' (got {', '.join(given)})")
        if "metal" in spec:
            metal = spec["metal"]
            if not isinstance(metal, str) or metal not in CONDUCTORS:
                shown = repr(metal) if isinstance(metal, str) else _describe(metal)
                raise ctx.error(where, f"unknown metal {shown} (expected one of: {', '.join(CONDUCTORS)})")
            mat.eta, mat.k = CONDUCTORS[metal]
        elif "eta" in spec or "k" in spec:
            if "eta" not in spec or "k" not in spec:
                raise ctx.error(where, "'eta' and 'k' (the complex index of refraction eta + i k) go together")
            eta = _vector(ctx, where, "eta", spec["eta"], allow_scalar=True)
            k = _vector(ctx, where, "k", spec["k"], allow_scalar=True)
            if not (eta > 0).all():
                raise ctx.error(where, f"'eta' must be > 0, got {eta.tolist()}")
            if k.min() < 0:
                raise ctx.error(where, f"'k' must not be negative, got {k.tolist()}")
            mat.eta, mat.k = tuple(float(x) for x in eta), tuple(float(x) for x in k)
        else:
            mat.f0 = _rgb01(ctx, where, "f0", spec.get("f0", 1.0))
    elif mtype == "dielectric":
        mat.ior = _number(ctx, where, "ior", spec.get("ior", 1.5), positive=True)
        mat.tint = _rgb01(ctx, where, "tint", spec.get("tint", 1.0))
    else:  # gltf
        mat.albedo = _rgb01(ctx, where, "base_color", spec.get("base_color", 1.0))
        mat.metallic = _number(ctx, where, "metallic", spec.get("metallic", 1.0), minimum=0.0, maximum=1.0)
        mat.ior = _number(ctx, where, "ior", spec.get("ior", 1.5), positive=True)
        if "roughness" not in spec and "alpha" not in spec:
            mat.alpha = 1.0  # glTF's default roughnessFactor
        mat.base_texture = _texture_key(ctx, where, spec, "base_color_texture", srgb=True)
        mat.mr_texture = _texture_key(ctx, where, spec, "metallic_roughness_texture", srgb=False)
    return mat


def _texture_key(ctx, where, spec, key, *, srgb):
    """The image file named by spec[key] (relative to the scene file) as a Texture, or None."""
    if key not in spec:
        return None
    fname = spec[key]
    if not isinstance(fname, str) or not fname:
        raise ctx.error(where, f"'{key}' must be an image file path, got {_describe(fname)}")
    path = Path(ctx.name).parent / Path(fname).expanduser()
    if not path.is_file():
        raise ctx.error(where, f"{key} '{fname}' not found (looked for {path})")
    from .textures import texture_from_image

    try:
        return texture_from_image(path, srgb=srgb)
    except Exception as exc:
        raise ctx.error(where, f"cannot read {key} '{fname}' ({type(exc).__name__}: {exc})") from None


def _parse_materials(ctx, table):
    if not isinstance(table, dict):
        raise ctx.error("materials", f"must be tables written [materials.NAME], got {_describe(table)}")
    materials: list[Material] = []
    index: dict[str, int] = {}
    for mname, spec in table.items():
        index[mname] = len(materials)
        materials.append(_parse_material(ctx, f"[materials.{mname}]", mname, spec))
    return materials, index


def _parse_camera(ctx, table) -> Camera:
    where = "[camera]"
    _check_keys(ctx, where, table, _CAMERA_KEYS)
    for req in ("eye", "look_at"):
        if req not in table:
            raise ctx.error(where, f"missing '{req}' (or leave out [camera] to frame the scene automatically)")
    eye = _vector(ctx, where, "eye", table["eye"])
    look_at = _vector(ctx, where, "look_at", table["look_at"])
    up = _vector(ctx, where, "up", table.get("up", [0.0, 1.0, 0.0]))
    fov = _number(ctx, where, "fov", table.get("fov", DEFAULT_FOV))
    if not 0 < fov < 180:
        raise ctx.error(where, f"'fov' must be between 0 and 180 degrees, got {fov:g}")
    forward = look_at - eye
    if not np.linalg.norm(forward) > 0:
        raise ctx.error(where, "'eye' and 'look_at' are the same point")
    if not np.linalg.norm(np.cross(forward / np.linalg.norm(forward), up)) > 1e-9:
        raise ctx.error(where, "'up' must not be zero or parallel to the viewing direction look_at - eye")
    aperture = _number(ctx, where, "aperture_radius", table.get("aperture_radius", 0.0), minimum=0.0)
    focus = None
    if "focus_distance" in table:
        focus = _number(ctx, where, "focus_distance", table["focus_distance"], positive=True)
    return Camera(
        eye=tuple(float(x) for x in eye), look_at=tuple(float(x) for x in look_at),
        up=tuple(float(x) for x in up), fov=float(fov), aperture_radius=float(aperture), focus_distance=focus,
    )


def rotation_matrix(axis, angle_degrees) -> np.ndarray:
    """3x3 right-handed rotation by ``angle_degrees`` about ``axis`` (Rodrigues)."""
    axis = np.asarray(axis, np.float64)
    axis = axis / np.linalg.norm(axis)
    a = math.radians(angle_degrees)
    x, y, z = axis
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + math.sin(a) * k + (1 - math.cos(a)) * (k @ k)


def _transform(ctx, where, table) -> np.ndarray | None:
    """4x4 matrix from the shape's transform keys, or None."""
    trs = [k for k in ("translate", "scale", "rotate") if k in table]
    if "matrix" in table:
        if trs:
            raise ctx.error(where, f"give either 'matrix' or translate/scale/rotate, not both ('{trs[0]}')")
        m = table["matrix"]
        if not isinstance(m, list) or len(m) != 4:
            raise ctx.error(where, f"'matrix' must be 4 rows of 4 numbers, got {_describe(m)}")
        rows = [_vector(ctx, where, f"matrix[{i}]", r, 4) for i, r in enumerate(m)]
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
        s = _vector(ctx, where, "scale", table["scale"], allow_scalar=True)
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
                raise ctx.error(where, f"'{key}' must be {{axis = [x, y, z], angle = DEGREES}}, got {_describe(step)}")
            for k in step:
                if k not in ("axis", "angle"):
                    raise ctx.error(where, f"'{key}': unknown key '{k}' (expected axis, angle)")
            if "axis" not in step or "angle" not in step:
                raise ctx.error(where, f"'{key}' needs both 'axis' and 'angle' (degrees)")
            axis = _vector(ctx, where, f"{key}.axis", step["axis"])
            if not np.linalg.norm(axis) > 0:
                raise ctx.error(where, f"'{key}.axis' must not be zero")
            angle = _number(ctx, where, f"{key}.angle", step["angle"])
            m3 = rotation_matrix(axis, angle) @ m3
    matrix = np.eye(4)
    matrix[:3, :3] = m3
    if "translate" in table:
        matrix[:3, 3] = _vector(ctx, where, "translate", table["translate"])
    return matrix


def _mesh_shape(ctx, where, scene_path: Path, table, materials, material_index, material_for):
    if "file" not in table:
        raise ctx.error(where, "missing 'file' (a mesh path relative to the scene file)")
    fname = table["file"]
    if not isinstance(fname, str) or not fname:
        raise ctx.error(where, f"'file' must be a path, got {_describe(fname)}")
    mesh_path = scene_path.parent / Path(fname).expanduser()
    if not mesh_path.exists():
        raise ctx.error(where, f"mesh file '{fname}' not found (looked for {mesh_path})")
    if mesh_path.is_dir():
        raise ctx.error(where, f"mesh file '{fname}' is a folder ({mesh_path})")
    use_file = _boolean(ctx, where, "use_file_materials", table.get("use_file_materials", False))
    suffix = mesh_path.suffix.lower()
    uvs = None
    if suffix in (".gltf", ".glb"):
        try:
            g = _read_gltf(mesh_path, f"{ctx.name}: {where}: {fname}")
        except UserError as exc:
            raise SceneError(_one_line(str(exc))) from None
        v, f, uvs = g.vertices, g.faces, g.uvs
    if use_file:
        if suffix not in (".obj", ".gltf", ".glb"):
            raise ctx.error(where, f"use_file_materials is only supported for OBJ and glTF files, not '{fname}'")
        fallback_index = material_for(where, table)
        overrides = {n: materials[i] for n, i in material_index.items()}
        if suffix == ".obj":
            try:
                v, f, local_mat, local_materials, uvs = _obj_with_materials(
                    mesh_path, f"{ctx.name}: {where}: {fname}", overrides, fallback=materials[fallback_index])
            except SceneError as exc:
                raise SceneError(_one_line(str(exc))) from None
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
        uvs = _trimesh_uvs(loaded, v, f)
        face_mat = None
    else:
        face_mat = None
    if len(f) == 0:
        raise ctx.error(where, f"mesh file '{fname}' contains no triangles")
    return np.asarray(v, np.float64), np.asarray(f, np.int64), face_mat, uvs


def _trimesh_uvs(loaded, v, f):
    """Per-corner UVs (v flipped to the top-down convention) of a single trimesh mesh that
    carries them (e.g. a PLY with s/t or texture_u/v), if flatten() kept its faces as they were."""
    uv = getattr(getattr(loaded, "visual", None), "uv", None)
    try:
        if uv is None or len(uv) != len(loaded.vertices) or len(loaded.faces) != len(f):
            return None
        out = np.asarray(uv, np.float32)[np.asarray(loaded.faces)][..., :2].copy()
    except (AttributeError, TypeError, ValueError, IndexError):
        return None
    out[..., 1] = 1.0 - out[..., 1]
    return out
