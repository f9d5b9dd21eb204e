"""Synthetic meshes and ray sets that the benchmarks run on (deterministic for a given seed)."""
from __future__ import annotations

import numpy as np

MESH_KINDS = ("sphere", "torus", "soup", "slivers")


def parse_sizes(text: str) -> list[int]:
    """'10k,100k,1M' (or plain integers) -> [10000, 100000, 1000000]; a UsageError (one line)
    for anything else, or a size outside 1 .. 1G."""
    from ..errors import UsageError

    sizes = []
    for raw in text.split(","):
        part = raw.strip().lower()
        if not part:
            continue
        multiplier = 1
        if part.endswith("k"):
            multiplier, part = 1_000, part[:-1]
        elif part.endswith("m"):
            multiplier, part = 1_000_000, part[:-1]
        try:
            value = float(part) * multiplier
        except ValueError:
            value = float("nan")
        if not (1 <= value <= 1e9):
            raise UsageError(f"--sizes {text}: {raw.strip()!r} is not a size (expected e.g. 10k,100k,1M: 1 .. 1000M)")
        sizes.append(int(value))
    if not sizes:
        raise UsageError(f"--sizes {text!r}: no size given (expected e.g. 10k,100k,1M)")
    return sizes


def bumpy_torus(n_triangles: int):
    """A torus with about ``n_triangles`` triangles (2 * major * minor), slightly bumpy so that
    its triangles are not all alike."""
    import trimesh

    minor = max(3, int(round(np.sqrt(n_triangles / 8.0))))
    major = max(3, int(round(n_triangles / (2 * minor))))
    mesh = trimesh.creation.torus(major_radius=1.0, minor_radius=0.35, major_sections=major, minor_sections=minor)
    vertices = np.asarray(mesh.vertices, np.float64)
    angle = np.arctan2(vertices[:, 1], vertices[:, 0])
    vertices *= (1.0 + 0.03 * np.sin(7 * angle))[:, None]
    return vertices.astype(np.float32), np.asarray(mesh.faces, np.int32)


def synthetic_mesh(kind: str, n: int, seed: int = 0):
    """(vertices, faces) of about n triangles (exactly n for the soups) of one of :data:`MESH_KINDS`:
    a subdivided icosphere, a torus, a soup of small random triangles, or a soup of long thin
    slivers in random directions (the hard case for SAH: their boxes overlap a lot)."""
    rng = np.random.default_rng(seed)
    if kind == "sphere":
        import trimesh

        subdivisions = max(0, int(round(np.log(max(n, 20) / 20) / np.log(4))))
        mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
        return np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.int32)
    if kind == "torus":
        import trimesh

        minor = max(3, int(np.sqrt(n / 2 / 4)))
        major = max(3, int(n / 2 / minor))
        mesh = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=major, minor_sections=minor)
        return np.asarray(mesh.vertices, np.float32), np.asarray(mesh.faces, np.int32)
    if kind == "soup":
        size = 2.0 / np.cbrt(n)
        centers = rng.random((n, 1, 3))
        corners = centers + (rng.random((n, 3, 3)) - 0.5) * size
    elif kind == "slivers":
        centers = rng.random((n, 1, 3))
        axis = rng.normal(size=(n, 1, 3))
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        along = np.array([-0.15, 0.15, 0.0])[None, :, None]
        corners = centers + axis * along + rng.normal(size=(n, 3, 3)) * 1e-3
    else:
        raise ValueError(f"unknown mesh kind {kind!r}: use one of {', '.join(MESH_KINDS)}")
    return corners.reshape(-1, 3).astype(np.float32), np.arange(3 * n, dtype=np.int32).reshape(n, 3)


def primary_rays(bounds, n: int):
    """Pinhole camera rays framing ``bounds`` (2 x 3), coherent: neighbouring rays are neighbouring
    pixels.  (origins, directions), float32, floor(sqrt(n))^2 rays."""
    side = int(np.sqrt(n))
    center = bounds.mean(axis=0)
    radius = float(np.linalg.norm(bounds[1] - bounds[0])) / 2
    view = np.array([0.3, -0.8, 0.6])
    eye = center + view * (2.2 * radius / np.linalg.norm(view))
    forward = center - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    screen = (np.arange(side) + 0.5) / side * 2 - 1
    x, y = np.meshgrid(screen * 0.5, -screen * 0.5)
    directions = forward + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    origins = np.broadcast_to(eye, directions.shape)
    return np.ascontiguousarray(origins, np.float32), np.ascontiguousarray(directions, np.float32)


def diffuse_rays(hits, origins, directions, rng):
    """Incoherent rays: from each hit point of (origins, directions), a cosine-distributed direction
    about the normal facing the incoming ray."""
    hit = hits["prim_id"] >= 0
    points = origins[hit] + hits["t"][hit, None] * directions[hit]
    normals = hits["normal"][hit]
    normals = np.where((np.sum(normals * directions[hit], axis=1) > 0)[:, None], -normals, normals)
    u1, u2 = rng.random(len(points)), rng.random(len(points))
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1)], axis=1)
    helper = np.where(np.abs(normals[:, :1]) > 0.9, [[0, 1.0, 0]], [[1.0, 0, 0]])
    tangent = np.cross(normals, helper)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    bitangent = np.cross(normals, tangent)
    new_directions = local[:, :1] * tangent + local[:, 1:2] * bitangent + local[:, 2:3] * normals
    # offset along the normal, scaled to the coordinates, so the ray does not re-hit its surface
    scale = np.abs(points).max(axis=1, keepdims=True) + 1.0
    new_origins = points + normals * (scale * 1e-4)
    return np.ascontiguousarray(new_origins, np.float32), np.ascontiguousarray(new_directions, np.float32)
