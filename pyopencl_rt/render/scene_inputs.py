"""What the kernels receive of a scene, per kernel parameter, in a form that does not depend on the
device: the resume key of a checkpoint (:func:`pyopencl_rt.render.checkpoint.scene_hash`) hashes it.

Every kernel parameter of :data:`pyopencl_rt.device.abi.WAVE_PARAMS` says where its value comes
from (``Param.source``): the scene, the settings (hashed by the render key as they are) or the run.
:data:`SCENE_INPUTS` gives, for each parameter sourced from the scene, a function of the scene that
returns the arrays that buffer is made of, before the device's layout applies: the BVH nodes and
triangle records come from the vertices and faces (their layout and order are the device's choice,
so a checkpoint resumes on a CPU's 8-wide BVH and a GPU's binary one alike), per-triangle buffers
are in the scene's face order, the light table is built in that order too.  Parameters that share a
function (the light table, the emitter of each triangle and shape, the light count) name the same
one, which is called once.  ``tests/render/test_scene_inputs.py`` checks that this table and the
ABI's agree, so a new scene buffer is in the key as soon as it is in the ABI.
"""
from __future__ import annotations

from types import SimpleNamespace
from typing import Callable

import numpy as np

from ..device import abi
from .settings import max_component_value


def _geometry(scene) -> dict:
    """nodes, tris, vertices, faces, prim_ids: the triangles the BVH is built over."""
    return {"vertices": scene.vertices, "faces": scene.faces}


def _instances(scene) -> dict:
    """tlas, instances, blas_nodes: each two-level instance's transform (and, where it moves, its
    transform at the end of the motion and the time mapping) and group, and the groups' ranges of
    faces (none without two-level instances)."""
    if not getattr(scene, "blas_groups", None):
        return {}
    from ..scene.instances import two_level

    insts = two_level(scene)
    return {"instance_to_world": np.asarray([i.to_world for i in insts], np.float64).reshape(-1, 4, 4),
            "instance_blas": np.asarray([i.blas for i in insts], np.int64),
            "blas_groups": np.asarray([(g.first_face, g.n_faces) for g in scene.blas_groups], np.int64),
            "instance_to_world_end": np.asarray([i.to_world_end if i.moves else i.to_world for i in insts],
                                                np.float64).reshape(-1, 4, 4),
            "instance_motion_pivot": np.asarray([i.pivots() or ((0.0, 0.0, 0.0),) * 2 for i in insts],
                                                np.float64).reshape(-1, 2, 3),
            "motion_time": np.asarray(getattr(scene, "motion_time", (0.0, 1.0)), np.float64)}


class _FaceCorners:
    """``bvh.triangles`` as build_lights reads it (``triangles["v0"][rows, :3]``), in the scene's face
    order, without the 48-byte records of every face."""

    def __init__(self, scene):
        self.vertices, self.faces = np.asarray(scene.vertices), np.asarray(scene.faces)

    def __getitem__(self, corner: str):
        k = ("v0", "v1", "v2").index(corner)
        index = self.faces[:, k] if len(self.faces) else np.zeros(0, np.int64)
        return _CornerRows(self.vertices, index)


class _CornerRows:
    """One corner of some faces: ``[rows, columns]`` -> those faces' corner positions."""

    def __init__(self, vertices, index):
        self.vertices, self.index = vertices, index

    def __getitem__(self, key):
        rows, columns = key
        return self.vertices[self.index[rows]][:, columns]


def _lights(scene) -> dict:
    """lights, tri_light, shape_light, n_lights, env_light, light_nodes: the light table (and the
    light BVH) as render/lights.py builds it, over the faces in the scene's order."""
    from .lights import build_lights
    from .settings import environment_row, has_light_tree

    identity = SimpleNamespace(prim_ids=np.arange(len(scene.faces)), triangles=_FaceCorners(scene))
    lights, tri_light, shape_light, light_nodes = build_lights(scene, identity)
    return {"lights": lights, "tri_light": tri_light, "shape_light": shape_light,
            "env_light": np.int64(environment_row(lights)), "light_nodes": light_nodes,
            "light_tree": np.int64(has_light_tree(lights))}


def _shapes(scene) -> dict:
    """shapes, shape_material, shape_nodes (the BVH comes from the records)."""
    return {"shapes": np.asarray(scene.shapes), "shape_material": scene.shape_materials}


def _face_materials(scene) -> dict:
    return {"face_materials": scene.face_materials}


def _materials(scene) -> dict:
    return {"materials": scene.material_records()}


def _camera(scene) -> dict:
    """camera, camera_motion (the aspect ratio is a setting: width, height)."""
    moving = getattr(scene, "camera_motion", None)
    return {"camera": scene.camera.record(1, 1),
            "camera_motion": np.zeros((0, 4, 4)) if moving is None else np.asarray(moving, np.float64),
            "motion_time": np.asarray(getattr(scene, "motion_time", (0.0, 1.0)), np.float64)}


def _film_clamp(scene) -> dict:
    return {"max_component": np.float32(max_component_value(scene))}


def _textures(scene) -> dict:
    """tri_uv, textures, tex_data: every face's UVs (the kernels read them for textures and for the
    tangent of anisotropic materials) and the packed texture table and texels."""
    from ..scene.textures import pack_textures

    out = {}
    if len(scene.faces) and (scene.has_textures() or scene.has_anisotropy()):
        out["face_uvs"] = scene.face_uvs()
    if scene.has_textures():
        out["textures"], out["tex_data"] = pack_textures(scene.textures(), scene.world_origin)
    return out


def _shading_normals(scene) -> dict:
    """face_normal: the corners' shading normals (none without per-vertex normals)."""
    return {} if getattr(scene, "normals", None) is None else {"face_normals": scene.face_normals()}


def _vertex_colors(scene) -> dict:
    """tri_color: the corners' colours (none without vertex colours)."""
    return {} if getattr(scene, "colors", None) is None else {"face_colors": scene.face_colors()}


def _environment(scene) -> dict:
    """env_map, env_cdf (the complete density: whether MIS compensates it is the integrator's, a setting)."""
    from .lights import environment_buffers

    env_map, env_cdf = environment_buffers(scene)
    return {"env_map": env_map, "env_cdf": env_cdf}


def _media(scene) -> dict:
    """abi.MEDIA_PARAMS' scene buffers: media, their grids, the medium interfaces, each face's and
    shape's interface and the camera's medium."""
    from ..scene.media import pack_media

    return {k: np.asarray(v) for k, v in pack_media(scene).items()}


SCENE_INPUTS: dict[str, Callable] = {
    "nodes": _geometry, "tris": _geometry, "vertices": _geometry, "faces": _geometry,
    "prim_ids": _geometry,
    "tlas": _instances, "instances": _instances, "blas_nodes": _instances, "instance_motion": _instances,
    "tri_material": _face_materials,
    "tri_light": _lights, "shape_light": _lights, "lights": _lights, "n_lights": _lights, "env_light": _lights,
    "light_tree": _lights,
    "light_nodes": _lights,
    "shapes": _shapes, "shape_material": _shapes, "shape_nodes": _shapes,
    "materials": _materials,
    "camera": _camera, "camera_motion": _camera, "max_component": _film_clamp,
    "tri_uv": _textures, "textures": _textures, "tex_data": _textures,
    "face_normal": _shading_normals,
    "tri_color": _vertex_colors,
    "env_map": _environment, "env_cdf": _environment,
    **{p.name: _media for p in abi.MEDIA_PARAMS if p.source == "scene"},
}


def scene_inputs(scene) -> dict[str, np.ndarray]:
    """Every array the kernels' scene parameters are made of, named ``<function>.<array>`` (each
    function of :data:`SCENE_INPUTS` called once), in the order of abi.WAVE_PARAMS."""
    out: dict[str, np.ndarray] = {}
    done = set()
    for param in abi.WAVE_PARAMS:
        if param.source != "scene":
            continue
        produce = SCENE_INPUTS[param.name]
        if produce in done:
            continue
        done.add(produce)
        for name, array in produce(scene).items():
            out[f"{produce.__name__.lstrip('_')}.{name}"] = np.asarray(array)
    return out
