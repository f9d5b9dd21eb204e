"""glTF 2.0 (``.gltf`` + buffers, or binary ``.glb``) in, triangles + materials + camera out, and
the scene of a glTF file (:func:`load_gltf_scene`: the file's camera, or the framing camera).

A small reader of its own (numpy + Pillow) rather than ``trimesh.load``: trimesh 5.2 drops the
material extensions this renderer needs (KHR_materials_emissive_strength, _transmission, _ior),
reads only a camera whose node hangs from the root, and does not say which glTF material each
primitive had.  (trimesh still *writes* the GLB files of the tests.)

What is read:

* the default scene's node tree with every node's ``matrix`` or translation/rotation/scale;
  mesh primitives of mode TRIANGLES, TRIANGLE_STRIP and TRIANGLE_FAN (points and lines are
  skipped), indexed or not; a node whose world matrix mirrors keeps its faces' front side;
* ``TEXCOORD_n`` (the set the material's base colour texture names; 0 by default); ``NORMAL``
  (shading normals; a primitive without them is shaded flat, as glTF asks); ``COLOR_0`` (linear
  RGB, multiplying baseColor: Material.vertex_colors);
* materials, metallic-roughness: ``baseColorFactor`` (rgb) x ``baseColorTexture`` (sRGB),
  ``metallicFactor`` / ``roughnessFactor`` x ``metallicRoughnessTexture`` (B = metallic,
  G = roughness; linear), ``emissiveFactor`` x ``emissiveTexture`` (sRGB) x
  ``KHR_materials_emissive_strength.emissiveStrength``; ``doubleSided`` makes emission two-sided;
  ``KHR_materials_ior`` (default 1.5); ``KHR_materials_transmission`` with
  ``transmissionFactor`` > 0 makes a ``dielectric`` (that IOR, alpha = roughness^2, tint =
  baseColor and its texture); ``normalTexture`` (linear, x and y times its ``scale``) as a normal
  map in the frame of the triangle's dp/du (cl/scene/shading.h; ``TANGENT`` and MikkTSpace are
  not used: the per-triangle tangent approximates them).  A primitive without a material gets
  glTF's default (white, metallic 1, roughness 1).  Samplers' wrapS (both axes) and magFilter
  (nearest or bilinear) and KHR_texture_transform (the lookup's affine map) are kept (Texture).
  ``alphaMode`` MASK (``alphaCutoff``) and BLEND (stochastic: pbrt-v4's alpha) are cut-outs in the
  intersection (baseColorFactor's alpha times the base texture's; Material.cutout).  Occlusion maps
  are ignored;
* images embedded in the GLB / a buffer view, as data: URIs or as files next to the .gltf;
* the first perspective camera in the node tree (``yfov``; the node's world transform, looking
  down its local -z with +y up).  Orthographic cameras are ignored.
"""
from __future__ import annotations

import base64
import io
import json
import math
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import UserError
from ..model import Camera, Material, Scene
from ..textures import Texture, texture_from_image
from .assembly import frame_scene, transform_normals, triangle_scene
from .values import SceneError

GLB_MAGIC = 0x46546C67  # b"glTF"
CHUNK_JSON = 0x4E4F534A
CHUNK_BIN = 0x004E4942

_COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


class GltfError(UserError):
    pass


@dataclass
class GltfScene:
    vertices: np.ndarray  # (V, 3) float64, world space
    faces: np.ndarray  # (F, 3) int64
    uvs: np.ndarray  # (F, 3, 2) float32
    face_materials: np.ndarray  # (F,) int32 into materials
    materials: list  # list[Material]
    camera: Camera | None
    aspect_ratio: float | None = None
    normals: np.ndarray | None = None  # (F, 3, 3) float32 per corner (0: flat), or None
    colors: np.ndarray | None = None  # (F, 3, 3) float32 linear RGB per corner, or None


def read_gltf_json(path) -> tuple[dict, bytes | None]:
    """(the JSON document, the GLB binary chunk or None) of a .gltf or .glb file."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError as exc:
        raise GltfError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if len(data) >= 12 and struct.unpack_from("<I", data, 0)[0] == GLB_MAGIC:
        _, version, length = struct.unpack_from("<III", data, 0)
        if version != 2:
            raise GltfError(f"{path}: GLB version {version} is not supported (only 2)")
        pos, doc, binary = 12, None, None
        while pos + 8 <= min(length, len(data)):
            clen, ctype = struct.unpack_from("<II", data, pos)
            chunk = data[pos + 8: pos + 8 + clen]
            if ctype == CHUNK_JSON and doc is None:
                doc = chunk
            elif ctype == CHUNK_BIN and binary is None:
                binary = chunk
            pos += 8 + clen + (-clen % 4)
        if doc is None:
            raise GltfError(f"{path}: GLB without a JSON chunk")
    else:
        doc, binary = data, None
    try:
        tree = json.loads(doc.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise GltfError(f"{path}: not a glTF file (bad JSON: {exc})") from None
    if not isinstance(tree, dict) or not str(tree.get("asset", {}).get("version", "2")).startswith("2"):
        raise GltfError(f"{path}: only glTF 2.0 is supported")
    return tree, binary


def _quat_matrix(q) -> np.ndarray:
    x, y, z, w = (float(c) for c in q)
    n = math.sqrt(x * x + y * y + z * z + w * w) or 1.0
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def node_matrix(node: dict) -> np.ndarray:
    """The node's local 4x4 matrix (column vectors)."""
    if "matrix" in node:
        return np.asarray(node["matrix"], np.float64).reshape(4, 4).T  # glTF stores column-major
    m = np.eye(4)
    m[:3, :3] = _quat_matrix(node.get("rotation", (0, 0, 0, 1))) * np.asarray(node.get("scale", (1, 1, 1)), np.float64)
    m[:3, 3] = node.get("translation", (0, 0, 0))
    return m


class _Reader:
    def __init__(self, path: Path, tree: dict, binary: bytes | None, name: str):
        self.path, self.tree, self.binary, self.name = path, tree, binary, name
        self._buffers: dict[int, bytes] = {}
        self._textures: dict[tuple, Texture] = {}

    def error(self, what: str) -> GltfError:
        return GltfError(f"{self.name}: {what}")

    def _uri(self, uri: str) -> bytes:
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            return base64.b64decode(payload) if head.endswith(";base64") else payload.encode()
        from urllib.parse import unquote

        f = self.path.parent / unquote(uri)
        try:
            return f.read_bytes()
        except OSError as exc:
            raise self.error(f"cannot read '{uri}' ({exc.strerror or exc})") from None

    def buffer(self, i: int) -> bytes:
        if i not in self._buffers:
            b = self.tree["buffers"][i]
            if "uri" in b:
                self._buffers[i] = self._uri(b["uri"])
            elif self.binary is not None:
                self._buffers[i] = self.binary
            else:
                raise self.error(f"buffer {i} has no data")
        return self._buffers[i]

    def view(self, i: int) -> tuple[bytes, int, int, int | None]:
        v = self.tree["bufferViews"][i]
        return self.buffer(v["buffer"]), v.get("byteOffset", 0), v["byteLength"], v.get("byteStride")

    def accessor(self, i: int) -> np.ndarray:
        a = self.tree["accessors"][i]
        if "sparse" in a:
            raise self.error(f"accessor {i}: sparse accessors are not supported")
        dtype = np.dtype(_COMPONENT[a["componentType"]]).newbyteorder("<")
        ncomp = _NCOMP[a["type"]]
        count = a["count"]
        if "bufferView" not in a:
            return np.zeros((count, ncomp), np.float64)
        buf, off, length, stride = self.view(a["bufferView"])
        off += a.get("byteOffset", 0)
        esize = dtype.itemsize * ncomp
        stride = stride or esize
        if count and off + stride * (count - 1) + esize > len(buf):
            raise self.error(f"accessor {i} runs past the end of its buffer")
        raw = np.ndarray((count, ncomp), dtype, buffer=buf, offset=off, strides=(stride, dtype.itemsize))
        out = raw.astype(np.float64)
        if a.get("normalized") and dtype.kind in "iu":
            out = np.maximum(out / np.iinfo(dtype).max, -1.0)
        return out

    def texture(self, info: dict | None, srgb: bool) -> Texture | None:
        if not info or "index" not in info:
            return None
        tex = self.tree["textures"][info["index"]]
        lookup = self._lookup(tex, info)
        src = tex.get("source")
        if src is None:  # e.g. EXT_texture_webp only
            for ext in tex.get("extensions", {}).values():
                if isinstance(ext, dict) and "source" in ext:
                    src = ext["source"]
        if src is None:
            return None
        key = (src, srgb)
        if key not in self._textures:
            img = self.tree["images"][src]
            if "bufferView" in img:
                buf, off, length, _ = self.view(img["bufferView"])
                blob = buf[off: off + length]
            else:
                blob = self._uri(img["uri"])
            from PIL import Image

            try:
                im = Image.open(io.BytesIO(blob))
                im.load()
            except Exception as exc:
                raise self.error(f"image {src}: cannot decode ({type(exc).__name__}: {exc})") from None
            self._textures[key] = texture_from_image(im, srgb=srgb, name=f"{self.name}#image{src}")
        return self._textures[key].with_lookup(**lookup)

    def _lookup(self, tex: dict, info: dict) -> dict:
        """The Texture lookup settings of a texture reference: its sampler's wrap (one mode for
        both axes) and magnification filter, and KHR_texture_transform as the affine to_uv
        (translation x rotation x scale, the extension's order; its rotation turns uv clockwise)."""
        out = {}
        if "sampler" in tex:
            smp = self.tree.get("samplers", [])[tex["sampler"]]
            wraps = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
            ws, wt = (wraps.get(int(smp.get(k, 10497)), "repeat") for k in ("wrapS", "wrapT"))
            if ws != wt:
                warnings.warn(f"{self.name}: sampler {tex['sampler']}: wrapS {ws} and wrapT {wt} differ; "
                              f"using {ws} for both", stacklevel=5)
            out["wrap"] = ws
            out["filter"] = "nearest" if int(smp.get("magFilter", 9729)) == 9728 else "bilinear"
        xf = info.get("extensions", {}).get("KHR_texture_transform")
        if xf is not None:
            ox, oy = (float(x) for x in xf.get("offset", (0.0, 0.0)))
            r = float(xf.get("rotation", 0.0))
            sx, sy = (float(x) for x in xf.get("scale", (1.0, 1.0)))
            c, s = math.cos(r), math.sin(r)
            out["to_uv"] = (c * sx, s * sy, ox, -s * sx, c * sy, oy)
            if "texCoord" in xf and xf["texCoord"] != info.get("texCoord", 0):
                warnings.warn(f"{self.name}: KHR_texture_transform's texCoord {xf['texCoord']} is ignored", stacklevel=5)
        return out

    def material(self, i: int | None) -> tuple[Material, int]:
        """(Material, texCoord set) of glTF material i (None: the default material)."""
        if i is None:
            return Material(name="gltf-default", type="gltf", albedo=(1.0, 1.0, 1.0), metallic=1.0, alpha=1.0), 0
        m = self.tree["materials"][i]
        pbr = m.get("pbrMetallicRoughness", {})
        ext = m.get("extensions", {})
        base = np.asarray(pbr.get("baseColorFactor", (1, 1, 1, 1)), np.float64)[:3]
        metallic = float(pbr.get("metallicFactor", 1.0))
        rough = float(pbr.get("roughnessFactor", 1.0))
        strength = float(ext.get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0))
        emission = np.asarray(m.get("emissiveFactor", (0, 0, 0)), np.float64) * strength
        ior = float(ext.get("KHR_materials_ior", {}).get("ior", 1.5))
        transmission = float(ext.get("KHR_materials_transmission", {}).get("transmissionFactor", 0.0))
        infos = [pbr.get("baseColorTexture"), pbr.get("metallicRoughnessTexture"), m.get("emissiveTexture"),
                 m.get("normalTexture")]
        sets = {inf.get("texCoord", 0) for inf in infos if inf}
        if len(sets) > 1:
            warnings.warn(f"{self.name}: material {i}: textures use different UV sets; using set {min(sets)}", stacklevel=3)
        mat = Material(
            name=str(m.get("name", f"material{i}")),
            albedo=tuple(float(x) for x in np.clip(base, 0, 1)),
            emission=tuple(float(x) for x in np.maximum(emission, 0)),
            two_sided=bool(m.get("doubleSided", False)),
            metallic=min(max(metallic, 0.0), 1.0),
            alpha=min(max(rough, 0.0), 1.0) ** 2,
            ior=ior if ior > 0 else 1.5,
        )
        mat.base_texture = self.texture(infos[0], srgb=True)
        mat.emission_texture = self.texture(infos[2], srgb=True) if mat.is_emissive else None
        mat.normal_texture = self.texture(infos[3], srgb=False)
        mat.normal_scale = float(infos[3].get("scale", 1.0)) if infos[3] else 1.0
        mode = m.get("alphaMode", "OPAQUE")
        if mode in ("MASK", "BLEND"):  # alpha cut-outs in the intersection (Material.cutout)
            mat.cutout = True
            mat.opacity = min(max(float(np.asarray(pbr.get("baseColorFactor", (1, 1, 1, 1)), np.float64)[3]), 0.0), 1.0)
            mat.alpha_cutoff = max(float(m.get("alphaCutoff", 0.5)), 1e-6) if mode == "MASK" else 0.0
            t = mat.base_texture
            if t is not None and t.channels in (2, 4):  # the base colour's alpha
                a = np.repeat(t.texels[..., 3:4], 4, axis=-1)
                a[..., 3] = 1.0
                mat.scalar_textures["opacity"] = Texture(np.ascontiguousarray(a), channels=1, name=t.name,
                                                         wrap=t.wrap, filter=t.filter, to_uv=t.to_uv)
            if mode == "MASK" and mat.opacity >= mat.alpha_cutoff and "opacity" not in mat.scalar_textures:
                mat.cutout = False  # every texel passes
        if transmission > 0:
            mat.type, mat.tint, mat.albedo = "dielectric", mat.albedo, (0.8, 0.8, 0.8)
            mat.ior = ior if ior > 1.0 else 1.5  # KHR_materials_ior's 0 (= 1) would be invisible
        else:
            mat.type = "gltf"
            mat.mr_texture = self.texture(infos[1], srgb=False)
        return mat, (min(sets) if sets else 0)


def _triangles(mode: int, idx: np.ndarray) -> np.ndarray:
    if mode == 4:
        return idx[: len(idx) // 3 * 3].reshape(-1, 3)
    if mode == 5:  # strip: alternate the winding
        n = len(idx) - 2
        if n <= 0:
            return np.zeros((0, 3), np.int64)
        k = np.arange(n)
        even = k % 2 == 0
        return np.stack([idx[k], np.where(even, idx[k + 1], idx[k + 2]), np.where(even, idx[k + 2], idx[k + 1])], axis=1)
    if mode == 6:  # fan
        n = len(idx) - 2
        if n <= 0:
            return np.zeros((0, 3), np.int64)
        k = np.arange(n)
        return np.stack([np.full(n, idx[0]), idx[k + 1], idx[k + 2]], axis=1)
    return np.zeros((0, 3), np.int64)  # points, lines


def load_gltf(path, name: str | None = None) -> GltfScene:
    """Read a .gltf / .glb file (see the module docstring)."""
    p = Path(path)
    name = name or str(path)
    tree, binary = read_gltf_json(p)
    if "KHR_draco_mesh_compression" in tree.get("extensionsRequired", []):
        raise GltfError(f"{name}: Draco-compressed meshes are not supported")
    r = _Reader(p, tree, binary, name)
    try:
        return _load(r, tree)
    except GltfError:
        raise
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise GltfError(f"{name}: malformed glTF ({type(exc).__name__}: {exc})") from None


def _load(r: _Reader, tree: dict) -> GltfScene:
    nodes = tree.get("nodes", [])
    scenes = tree.get("scenes", [])
    if scenes:
        roots = scenes[tree.get("scene", 0)].get("nodes", [])
    else:  # no scene: every node that is nobody's child
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    mat_cache: dict = {}
    materials: list[Material] = []
    verts, faces, uvs, fmats, normals, colors = [], [], [], [], [], []
    nv = 0
    camera = None
    aspect = None
    stack = [(i, np.eye(4), 0) for i in reversed(roots)]
    while stack:
        i, parent, depth = stack.pop()
        if depth > 256:
            raise r.error("node hierarchy too deep (a cycle?)")
        node = nodes[i]
        world = parent @ node_matrix(node)
        if "camera" in node and camera is None:
            cam = tree["cameras"][node["camera"]]
            if cam.get("type") == "perspective":
                persp = cam["perspective"]
                lin = world[:3, :3]
                eye = world[:3, 3]
                fwd = lin @ np.array([0.0, 0.0, -1.0])
                up = lin @ np.array([0.0, 1.0, 0.0])
                if np.linalg.norm(fwd) > 0 and np.linalg.norm(np.cross(fwd, up)) > 0:
                    fwd /= np.linalg.norm(fwd)
                    camera = Camera(eye=tuple(map(float, eye)), look_at=tuple(map(float, eye + fwd)),
                                    up=tuple(map(float, up / np.linalg.norm(up))),
                                    fov=math.degrees(float(persp["yfov"])))
                    aspect = persp.get("aspectRatio")
            else:
                warnings.warn(f"{r.name}: {cam.get('type')} camera ignored (only perspective)", stacklevel=3)
        if "mesh" in node:
            flip = np.linalg.det(world[:3, :3]) < 0
            for prim in tree["meshes"][node["mesh"]].get("primitives", []):
                if "extensions" in prim and "KHR_draco_mesh_compression" in prim["extensions"]:
                    raise r.error("Draco-compressed meshes are not supported")
                attrs = prim.get("attributes", {})
                if "POSITION" not in attrs:
                    continue
                pos = r.accessor(attrs["POSITION"])[:, :3]
                idx = r.accessor(prim["indices"])[:, 0].astype(np.int64) if "indices" in prim else np.arange(len(pos))
                tri = _triangles(prim.get("mode", 4), idx)
                if len(tri) == 0:
                    continue
                if (tri < 0).any() or (tri >= len(pos)).any():
                    raise r.error(f"mesh {node['mesh']}: index out of range")
                mi = prim.get("material")
                if mi not in mat_cache:
                    mat, uvset = r.material(mi)
                    mat_cache[mi] = (len(materials), uvset)
                    materials.append(mat)
                m_index, uvset = mat_cache[mi]
                key = f"TEXCOORD_{uvset}"
                uv = r.accessor(attrs[key])[:, :2] if key in attrs else np.zeros((len(pos), 2))
                world_pos = pos @ world[:3, :3].T + world[:3, 3]
                if flip:
                    tri = tri[:, ::-1]
                verts.append(world_pos)
                faces.append(tri + nv)
                uvs.append(uv[tri].astype(np.float32))
                normals.append(None if "NORMAL" not in attrs else
                               transform_normals(world, r.accessor(attrs["NORMAL"])[:, :3][tri]))
                colors.append(None if "COLOR_0" not in attrs else
                              np.clip(r.accessor(attrs["COLOR_0"])[:, :3], 0.0, None)[tri].astype(np.float32))
                fmats.append(np.full(len(tri), m_index, np.int32))
                nv += len(pos)
        for c in reversed(node.get("children", [])):
            stack.append((c, world, depth + 1))
    if not faces:
        return GltfScene(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3, 2), np.float32),
                         np.zeros(0, np.int32), materials, camera, aspect)
    def corners(parts, fill):
        if all(p is None for p in parts):
            return None
        return np.concatenate([np.full((len(f), 3, 3), fill, np.float32) if p is None else p
                               for p, f in zip(parts, faces)])

    if any(c is not None for c in colors):  # COLOR_0 multiplies the base colour of its primitives
        for m in materials:
            m.vertex_colors = True
    return GltfScene(np.concatenate(verts), np.concatenate(faces), np.concatenate(uvs), np.concatenate(fmats),
                     materials, camera, aspect, corners(normals, 0.0), corners(colors, 1.0))


def read_gltf(path: Path, name: str) -> GltfScene:
    """load_gltf, its warnings raised again here (for a caller that names the scene file)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        g = load_gltf(path, name)
    for w in caught:
        warnings.warn(w.message, stacklevel=4)
    return g


def load_gltf_scene(path: Path, name: str) -> Scene:
    g = read_gltf(path, name)
    if len(g.faces) == 0:
        raise SceneError(f"{name}: contains no triangles")
    scene = triangle_scene(g.vertices, g.faces, g.face_materials, g.materials, name, g.uvs, normals=g.normals,
                           colors=g.colors)
    if g.aspect_ratio and g.aspect_ratio > 0:
        scene.settings.width = max(1, int(round(scene.settings.height * float(g.aspect_ratio))))
    if g.camera is None:
        return frame_scene(scene)
    scene.camera = g.camera
    return scene
