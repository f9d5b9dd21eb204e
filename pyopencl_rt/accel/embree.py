"""Intel Embree (through embreex) as the reference intersector: the scene of a BVH's triangles."""
from __future__ import annotations

import numpy as np

from .bvh import BVH


def embree_scene(bvh: BVH):
    """The embreex scene of a BVH's original triangles (cached on the BVH)."""
    scene = bvh.__dict__.get("_embree_scene")
    if scene is None:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        scene = rtcore_scene.EmbreeScene(robust=True)  # watertight mode: the fair reference
        if len(bvh.faces):
            TriangleMesh(scene, np.ascontiguousarray(bvh.vertices, np.float32), np.ascontiguousarray(bvh.faces, np.int32))
        bvh.__dict__["_embree_scene"] = scene
    return scene
