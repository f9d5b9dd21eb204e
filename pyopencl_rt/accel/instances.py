"""The two-level BVH of a scene with two-level instances (cl/accel/instances.h).

One bottom-level BVH (BLAS) per shape group, built once over the group's faces in its own space;
a top-level BVH (TLAS, binary nodes) over the instances' world boxes; the instance records
(abi.INSTANCE: both 3x4 transforms, where the group's BVH and triangles start).  The world's own
faces keep their BVH (``world``).  ``triangles`` and ``prim_ids`` are those of every BVH one after
another (the world's first), so the per-triangle buffers the renderer makes by ``prim_ids`` (materials,
UVs, normals) serve the groups' triangles as they serve the world's.  Device memory grows with the
instances (112 bytes a record, about 32 bytes of TLAS nodes), not with their triangles.
"""
from __future__ import annotations

import time

import numpy as np

from ..device import abi
from ..device.host_memory import aligned_empty
from .motion import Motion
from .bvh import build_bvh

BLAS_ALIGN = 64  # bytes: every group's node buffer starts on a cache line (a float8 node's alignment)
TLAS_PAD_RELATIVE = 2.0**-16  # an instance's world box is grown by this share of its extent and position


class TwoLevelBVH:
    """The scene's BVHs: ``world`` (its world faces), ``blas`` (one per Scene.blas_groups entry),
    ``tlas`` over the instances, ``records`` (abi.INSTANCE, in the TLAS's leaf order) and
    ``order`` (the Scene.instances index of each record)."""

    def __init__(self, vertices, faces, n_world: int, groups: list, instances: list, threads=None,
                 ends=None, motion_time=(0.0, 1.0), pivots=None):
        """``faces[:n_world]`` in world space; ``groups`` (first_face, n_faces) ranges of ``faces``
        in their groups' spaces; ``instances`` (4x4 to_world, group index) pairs; ``ends``: per
        instance its to_world at the end of its motion (None: it does not move), ``motion_time`` Scene.motion_time, ``pivots`` each one's (pivot, world pivot) or None
        (Instance.motion_pivot, motion_pivot_world)."""
        t0 = time.perf_counter()
        faces = np.asarray(faces)
        self.world = build_bvh(vertices, faces[:n_world], threads=threads)
        self.blas = []
        first_tri = [len(self.world.prim_ids)]
        prim_ids = [self.world.prim_ids]
        for first, n in groups:
            b = build_bvh(vertices, faces[first:first + n], threads=threads)
            self.blas.append(b)
            prim_ids.append(b.prim_ids + np.int32(first))
            first_tri.append(first_tri[-1] + len(b.prim_ids))
        # page-aligned: a CPU device reads it in place (device/host_memory.py)
        self.prim_ids = np.concatenate(prim_ids, out=aligned_empty(first_tri[-1], np.int32))
        self.triangles = np.concatenate([self.world.triangles] + [b.triangles for b in self.blas])
        self.tri_offsets = first_tri[:-1]
        self.to_world = np.asarray([m for m, _ in instances], np.float64).reshape(-1, 4, 4)
        self.group = np.asarray([g for _, g in instances], np.int64)
        ends = [None] * len(instances) if ends is None else list(ends)
        pivots = [None] * len(instances) if pivots is None else list(pivots)
        # each moving instance's way (accel/motion.py), None where it stays
        self.motion = [None if e is None else Motion(m, e, *(c or ()))
                       for e, c, (m, _) in zip(ends, pivots, instances)]
        self.motion_time = tuple(float(x) for x in motion_time)
        # a group without faces gets a zero box (its instances get no record below)
        group_boxes = np.array([b.bounds if len(b.prim_ids) else np.zeros((2, 3)) for b in self.blas],
                               np.float64).reshape(-1, 2, 3)
        # an instance of a group without faces draws nothing: no record (no TLAS, even, without any)
        drawn = np.flatnonzero([len(self.blas[g].prim_ids) > 0 for g in self.group])
        boxes = world_boxes(group_boxes[self.group[drawn]], self.to_world[drawn])
        for k, i in enumerate(drawn):  # a moving instance's box holds its whole way
            if self.motion[i] is not None:
                boxes[k] = padded_boxes(self.motion[i].bounds(group_boxes[self.group[i]])[None])[0]
        # the TLAS: a BVH over one degenerate triangle per instance (lo, hi, centre): its box is the
        # instance's box, its centroid the box's centre
        corners = np.stack([boxes[:, 0], boxes[:, 1], boxes.mean(axis=1)], axis=1).reshape(-1, 3)
        self.tlas = build_bvh(corners, np.arange(len(corners)).reshape(-1, 3), threads=threads)
        self.order = drawn[self.tlas.prim_ids]  # the instance of each record
        self.build_seconds = time.perf_counter() - t0

    @property
    def nodes(self):
        return self.world.nodes

    def records(self, blas_offsets) -> np.ndarray:
        """The instance records, each pointing at byte ``blas_offsets[group]`` of the groups' node buffer."""
        recs = np.zeros(len(self.order), abi.INSTANCE)
        if not len(recs):
            return recs
        m, g = self.to_world[self.order], self.group[self.order]
        recs["object_to_world"] = m[:, :3, :].reshape(-1, 12)
        recs["world_to_object"] = np.linalg.inv(m)[:, :3, :].reshape(-1, 12)
        recs["motion"] = -1
        moving = [k for k, i in enumerate(self.order) if self.motion[i] is not None]
        recs["motion"][moving] = np.arange(len(moving))
        recs["blas_offset"] = np.asarray(blas_offsets, np.int64)[g]
        recs["tri_offset"] = np.asarray(self.tri_offsets, np.int64)[g]
        return recs

    def buffers(self, layout: str) -> dict:
        """tlas, instances and blas_nodes as the kernels read them on a device of ``layout``."""
        from .device_bvh import node_buffer, padded_nodes

        blobs, offsets, at = [], [], 0
        for b in self.blas:
            blob = np.ascontiguousarray(node_buffer(b, layout)).view(np.uint8).reshape(-1)
            offsets.append(at)
            pad = -len(blob) % BLAS_ALIGN
            blobs += [blob, np.zeros(pad, np.uint8)]
            at += len(blob) + pad
        if at >= 2**31:
            from ..errors import UserError

            raise UserError(f"the instanced groups' BVHs take {at / 2**30:.1f} GiB: at most 2 GiB in all")
        blas_nodes = np.concatenate(blobs) if blobs else np.zeros(0, np.uint8)
        return {"tlas": padded_nodes(self.tlas), "instances": self.records(offsets), "blas_nodes": blas_nodes,
                "instance_motion": self.motion_records()}

    def motion_records(self) -> np.ndarray:
        """abi.MOTION of the moving instances, in the order of their records (a 16-byte dummy
        without any: the kernels read it only with HAS_MOTION)."""
        ways = [self.motion[i] for i in self.order if self.motion[i] is not None]
        if not ways:
            return np.zeros(16, np.uint8)
        return np.array([w.record(self.motion_time) for w in ways], abi.MOTION)


def world_boxes(boxes, m) -> np.ndarray:
    """(N, 2, 3) float32 boxes of the (N, 2, 3) ``boxes``' corners moved by the (N, 4, 4) ``m``,
    grown outward so that the float32 test of the ray moved into an instance cannot find a hit
    outside its box."""
    bits = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)])
    c = np.where(bits[None].astype(bool), boxes[:, 1:2, :], boxes[:, 0:1, :])  # (N, 8, 3)
    w = np.einsum("nij,nkj->nki", m[:, :3, :3], c) + m[:, None, :3, 3]
    return padded_boxes(np.stack([w.min(axis=1), w.max(axis=1)], axis=1))


def padded_boxes(boxes) -> np.ndarray:
    """(N, 2, 3) float64 world boxes grown by TLAS_PAD_RELATIVE of their size and position and
    rounded outward to float32 (the float32 test of a ray moved into the group)."""
    lo, hi = boxes[:, 0], boxes[:, 1]
    pad = TLAS_PAD_RELATIVE * (np.maximum(np.abs(lo), np.abs(hi)).max(axis=1) + (hi - lo).max(axis=1))[:, None]
    lo = np.nextafter((lo - pad).astype(np.float32), np.float32(-np.inf))
    hi = np.nextafter((hi + pad).astype(np.float32), np.float32(np.inf))
    return np.stack([lo, hi], axis=1)
