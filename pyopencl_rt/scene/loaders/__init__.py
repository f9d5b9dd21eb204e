"""Scene files in, :class:`~pyopencl_rt.scene.model.Scene` out: :func:`load_scene` reads

* a **TOML scene file** (``.toml``, :mod:`.toml`; the format is docs/SCENE_FORMAT.md);
* an **OBJ file** (``.obj``, :mod:`.obj`) with its MTL materials, a camera framing the scene and
  default settings;
* a **glTF 2.0 file** (``.gltf`` / ``.glb``, :mod:`.gltf`) with its PBR materials, textures, UVs
  and camera (or the framing camera);
* a **Mitsuba 3 XML** (``.xml``, :mod:`.mitsuba_scene`) or **pbrt-v4** (``.pbrt`` or ``.pbrt.gz``, :mod:`.pbrt_scene`)
  scene file, the subsets docs/SCENE_FORMAT.md describes (unsupported elements warn);
* **any other mesh file** trimesh reads (PLY, STL, OFF, ...; :mod:`.meshfile`) with one default
  diffuse material (albedo 0.8) and the framing camera.

Every problem with the input raises a :class:`SceneError` (a :class:`~pyopencl_rt.errors.UserError`)
whose message is one line and starts with the scene file's name.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import UserError
from ..model import Scene
from .assembly import framing_camera
from .gltf import load_gltf_scene
from .meshfile import load_mesh_scene
from .obj import load_obj_scene, parse_mtl, parse_obj
from .toml import load_toml_scene
from .values import SceneError, one_line

__all__ = ["load_scene", "SceneError", "framing_camera", "parse_obj", "parse_mtl"]


def load_scene(path, defines: dict | None = None) -> Scene:
    """Load a scene file of any of the formats above, chosen by the file's suffix; ``defines``
    ({name: value}) set a Mitsuba XML file's ``$name`` parameters (the CLI's ``--define``)."""
    p = Path(path)
    name = str(path)
    if not p.exists():
        raise SceneError(f"{name}: no such file")
    if p.is_dir():
        raise SceneError(f"{name}: is a folder, not a scene file")
    suffix = p.suffix.lower()
    if defines and suffix != ".xml":
        raise SceneError(f"{name}: --define sets parameters of Mitsuba XML (.xml) scenes only")
    scene = _load(p, name, suffix, defines)
    import gc

    gc.collect()  # the loader's own arrays (a parser and its builder refer to each other): freed now, not later
    from ..validate import check_scene

    from ...host_stages import host_stage

    with host_stage("validation"):
        check_scene(scene)  # the kernels' float32 limits, whichever format the values came from
    return scene


def _load(p: Path, name: str, suffix: str, defines):
    try:
        # casts to float32 that overflow or underflow are found by check_scene (one line), not
        # reported by numpy on the way
        with np.errstate(over="ignore", under="ignore"):
            return _load_format(p, name, suffix, defines)
    except SceneError:
        raise
    except UserError as exc:  # MeshError / GltfError: they name the file; make sure it is one line
        raise type(exc)(one_line(str(exc))) from None


def _load_format(p: Path, name: str, suffix: str, defines):
    if suffix == ".xml":  # Mitsuba 3 XML
        from .mitsuba_scene import load_mitsuba_xml

        return load_mitsuba_xml(p, name, defines)
    if suffix == ".pbrt" or p.name.lower().endswith(".pbrt.gz"):  # pbrt-v4 (gzip-compressed: .pbrt.gz)
        from .pbrt_scene import load_pbrt

        return load_pbrt(p, name)
    if suffix == ".toml":
        return load_toml_scene(p, name)
    if suffix == ".obj":
        return load_obj_scene(p, name)
    if suffix in (".gltf", ".glb"):
        return load_gltf_scene(p, name)
    return load_mesh_scene(p, name)
