"""OBJ files with their MTL materials: ``usemtl`` gives one material per face, ``vt`` the UVs;
a camera framing the scene and default settings."""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..materials import MTL_TYPES
from ..model import Material, Scene
from ..textures import texture_from_image
from .assembly import frame_scene, triangle_scene
from .values import SceneError


@dataclass
class MtlStatements:
    """What the statements of one ``newmtl`` say beyond its colours: the material types read
    these in their ``from_mtl`` (docs/SCENE_FORMAT.md, "OBJ and MTL", has the table)."""

    specular: tuple  # Ks (clamped to [0, 1]); 0 without it
    illum: int | None
    opacity: float  # d, or 1 - Tr; 1 without either
    ior: float  # Ni; 1.5 without it (or when it is not > 0)
    alpha: float | None  # GGX alpha from Pr (alpha = Pr^2) or the Phong exponent Ns; None without either
    metallic: float | None  # Pm (the PBR extension) clamped to [0, 1]; None without it

    @classmethod
    def from_values(cls, statements: dict) -> "MtlStatements":
        """From {statement: value} (``Ks`` a 3-tuple, the others numbers)."""
        ior = statements.get("Ni", 1.5)
        if "Pr" in statements:
            alpha = min(max(statements["Pr"], 0.0), 1.0) ** 2
        elif "Ns" in statements:  # Walter et al. (2007)'s Phong-Beckmann correspondence
            alpha = min(1.0, math.sqrt(2.0 / (max(statements["Ns"], 0.0) + 2.0)))
        else:
            alpha = None
        return cls(
            specular=statements.get("Ks", (0.0, 0.0, 0.0)),
            illum=int(statements["illum"]) if "illum" in statements else None,
            opacity=statements.get("d", 1.0 - statements.get("Tr", 0.0)),
            ior=ior if ior > 0 else 1.5,
            alpha=alpha,
            metallic=min(max(statements["Pm"], 0.0), 1.0) if "Pm" in statements else None,
        )


def choose_mtl_type(material: Material, mtl: MtlStatements) -> None:
    """The first material type, in MTL precedence, that claims the material sets its type and
    parameters (every MTL material that no other type claims stays diffuse)."""
    for material_type in MTL_TYPES:
        if material_type.from_mtl(material, mtl):
            material.type = material_type.name
            return


def parse_mtl(path, name: str | None = None) -> dict:
    """{material name: Material} from an MTL file: ``Kd`` -> albedo (clamped to [0, 1]), ``Ke`` ->
    emission, ``map_Kd`` / ``map_Ke`` -> their textures; the other statements choose the type
    (see :func:`choose_mtl_type`).
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
                tex = texture_from_image(tex_path, srgb=True)
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
        choose_mtl_type(mat, MtlStatements.from_values(props[mname]))
    return materials



def parse_obj(path, name: str | None = None, *, with_uvs: bool = False, with_normals: bool = False):
    """(vertices (V,3) float64, faces (F,3) int64, face material names list[str|None], mtllib paths),
    and with ``with_uvs`` a fifth item: per-corner texture coordinates (F, 3, 2) float32 from
    ``vt`` (v flipped to the top-down image convention of pyopencl_rt.scene.textures), or None when
    the file has none (corners without a ``vt`` index get (0, 0)); with ``with_normals`` (and
    ``with_uvs``) a sixth: per-corner normals (F, 3, 3) float32 from ``vn`` (unit length), or None
    when no face names one (a face with a corner that names none gets 0: shaded flat).

    Polygons are fan-triangulated (as trimesh does); negative (relative) indices and
    ``v/vt/vn`` forms are accepted; only ``v``, ``vt``, ``vn``, ``f``, ``usemtl`` and ``mtllib``
    matter.
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
    normal_text: list[str] = []
    normal_corners: list[int] = []  # 3 resolved vn indices per triangle (-1: none)
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
        elif key == "vn" and with_normals:
            fields = rest.split()
            normal_text.append(" ".join((fields + ["0", "0", "0"])[:3]))
        elif key == "f":
            toks = rest.split()
            if "/" in rest:
                if with_uvs:
                    for slot, table, out in ((1, uv_text, uv_corners), (2, normal_text, normal_corners)):
                        if slot == 2 and not with_normals:
                            continue
                        tidx = []
                        for t in toks:
                            parts = t.split("/")
                            try:
                                k = int(parts[slot]) if len(parts) > slot and parts[slot] else 0
                            except ValueError:
                                raise SceneError(f"{name}:{lineno}: bad face '{raw.strip()}'") from None
                            k = len(table) + k if k < 0 else k - 1
                            tidx.append(k if 0 <= k < len(table) else -1)
                        for k in range(1, len(tidx) - 1):
                            out.extend((tidx[0], tidx[k], tidx[k + 1]))
                toks = [t.split("/", 1)[0] for t in toks]
            elif with_uvs:
                uv_corners.extend([-1] * (3 * max(len(toks) - 2, 0)))
                normal_corners.extend([-1] * (3 * max(len(toks) - 2, 0)))
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
    if not with_normals:
        return v, f, names, mtllibs, uvs
    normals = None
    corners = np.asarray(normal_corners, np.int64).reshape(-1, 3)
    if normal_text and len(corners) == len(f) and (corners >= 0).any():
        try:
            table = np.array(" ".join(normal_text).split(), dtype=np.float64).reshape(-1, 3)
        except ValueError:
            raise SceneError(f"{name}: bad vertex normal (vn)") from None
        with np.errstate(invalid="ignore", divide="ignore"):
            table = table / np.linalg.norm(table, axis=1, keepdims=True)
        table = np.vstack([np.nan_to_num(table, nan=0.0, posinf=0.0, neginf=0.0), [[0.0, 0.0, 0.0]]])
        normals = table[corners].astype(np.float32)  # index -1: 0
        normals[(corners < 0).any(axis=1)] = 0.0
    return v, f, names, mtllibs, uvs, normals


def obj_with_materials(path: Path, name: str, overrides: dict | None = None, fallback: Material | None = None):
    """vertices, faces, face material indices (into the returned list), materials list, uvs
    ((F, 3, 2) or None), normals ((F, 3, 3) or None)."""
    vertices, faces, face_names, mtllibs, uvs, normals = parse_obj(path, name, with_uvs=True, with_normals=True)
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
    return vertices, faces, face_mat, materials, uvs, normals


def load_obj_scene(path: Path, name: str) -> Scene:
    vertices, faces, face_mat, materials, uvs, normals = obj_with_materials(path, name)
    if len(faces) == 0:
        raise SceneError(f"{name}: contains no faces")
    return frame_scene(triangle_scene(vertices, faces, face_mat, materials, name, uvs, normals=normals))
