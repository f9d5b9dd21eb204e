"""Moving instances and cameras (motion blur): pbrt-v4's interpolation between two transforms, its
bounds, and the records the kernels read (abi.MOTION; cl/accel/motion.h interpolates the same way).

A transform M is split as pbrt-v4 splits it, M = T R S: T its translation, R the rotation of
M's 3x3 part's polar decomposition, S = R^-1 M (a stretch, symmetric up to rounding).  Between the
start (s = 0) and the end (s = 1), T and S are interpolated linearly and R by slerp along the
shorter arc; an instance is at s = clamp(a + b u, 0, 1) for a ray's time sample u in [0, 1)
(Scene.motion_time: the camera's shutter onto the transforms' times).
"""
from __future__ import annotations

import numpy as np

from ..device.motion_record import MOTION

POLAR_ITERATIONS = 100  # pbrt-v4's limit; the iteration converges in a few steps for any invertible M
POLAR_TOLERANCE = 1e-12  # on the largest change of an entry, relative to R's (unit) scale


def decompose(m) -> tuple:
    """(T (3,), q (4,) as (x, y, z, w), S (3, 3)) of the 4x4 affine ``m`` (float64): M = T R(q) S.
    A mirroring M (det < 0) keeps its mirror in S (R a rotation)."""
    m = np.asarray(m, np.float64)
    a = m[:3, :3]
    r = a.copy()
    for _ in range(POLAR_ITERATIONS):  # R <- (R + R^-T) / 2: the orthogonal factor of a
        nxt = 0.5 * (r + np.linalg.inv(r).T)
        done = np.abs(nxt - r).max() <= POLAR_TOLERANCE
        r = nxt
        if done:
            break
    if np.linalg.det(r) < 0:  # a mirror: R a rotation, the reflection left in S
        r = -r
    s = r.T @ a
    return m[:3, 3].copy(), quaternion(r), s


def quaternion(r) -> np.ndarray:
    """The unit quaternion (x, y, z, w) of the rotation matrix ``r``."""
    r = np.asarray(r, np.float64)
    tr = np.trace(r)
    if tr > 0:
        w = np.sqrt(tr + 1.0) * 2
        q = [(r[2, 1] - r[1, 2]) / w, (r[0, 2] - r[2, 0]) / w, (r[1, 0] - r[0, 1]) / w, 0.25 * w]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        t = np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k]) * 2
        q = [0.0, 0.0, 0.0, (r[k, j] - r[j, k]) / t]
        q[i], q[j], q[k] = 0.25 * t, (r[j, i] + r[i, j]) / t, (r[k, i] + r[i, k]) / t
    q = np.asarray(q, np.float64)
    return q / np.linalg.norm(q)


def rotation(q) -> np.ndarray:
    """The 3x3 rotation matrix of the unit quaternion ``q`` (x, y, z, w)."""
    x, y, z, w = np.asarray(q, np.float64)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


class Motion:
    """The way of one instance from ``start`` to ``end`` (4x4 affine transforms), interpolated
    about a pivot: the transforms are split as seen from it, M = Cw^-1 (T R S) Co, Cw and Co the
    moves of the pivot to the origin in the world (``world_pivot``, default ``pivot``) and in the
    instance's own space (``pivot``).  pbrt-v4 interpolates in its render space, whose origin is
    the camera's position: a shape's transform from render space to its own is C M, which moves
    the same way about any pivot, but an object instance's is C M C^-1 (its object space is in
    render space too), so that its rotation turns about the camera: its pivot (both sides at
    first; moving the world, as camera-relative rendering does, moves the world's alone)."""

    def __init__(self, start, end, pivot=(0.0, 0.0, 0.0), world_pivot=None):
        self.pivot = np.asarray(pivot, np.float64).reshape(3)
        self.world_pivot = self.pivot if world_pivot is None else np.asarray(world_pivot, np.float64).reshape(3)
        c = np.eye(4)
        c[:3, 3] = -self.world_pivot
        c_inv = np.eye(4)
        c_inv[:3, 3] = self.pivot
        self.t0, self.q0, self.s0 = decompose(c @ np.asarray(start, np.float64) @ c_inv)
        self.t1, q1, self.s1 = decompose(c @ np.asarray(end, np.float64) @ c_inv)
        self.q1 = -q1 if np.dot(self.q0, q1) < 0 else q1  # the shorter arc
        self.theta = float(np.arccos(np.clip(np.dot(self.q0, self.q1), -1.0, 1.0)))

    def quaternion_at(self, s: float) -> np.ndarray:
        if self.theta < 1e-9:
            q = (1 - s) * self.q0 + s * self.q1
        else:
            q = (np.sin((1 - s) * self.theta) * self.q0 + np.sin(s * self.theta) * self.q1) / np.sin(self.theta)
        return q / np.linalg.norm(q)

    def at(self, s: float) -> np.ndarray:
        """The 4x4 transform at s in [0, 1]."""
        m = np.eye(4)
        m[:3, :3] = rotation(self.quaternion_at(s)) @ ((1 - s) * self.s0 + s * self.s1)
        m[:3, 3] = (1 - s) * self.t0 + s * self.t1 + self.world_pivot - m[:3, :3] @ self.pivot
        return m

    def bounds(self, box, steps: int = 64) -> np.ndarray:
        """(2, 3) float64: a box around ``box`` (2, 3) moved over the whole way: its corners at
        ``steps`` + 1 even values of s, grown by the largest move of a corner between two of them
        (a point between two samples is within that of one of them: the way is smooth and each
        step turns less than 180 / steps degrees)."""
        box = np.asarray(box, np.float64)
        bits = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], bool)
        corners = np.where(bits, box[1], box[0])
        ms = [self.at(s) for s in np.linspace(0, 1, steps + 1)]
        at = np.array([corners @ m[:3, :3].T + m[:3, 3] for m in ms])
        step = np.linalg.norm(np.diff(at, axis=0), axis=2).max() if steps else 0.0
        return np.stack([at.min(axis=(0, 1)) - step, at.max(axis=(0, 1)) + step])

    def record(self, motion_time) -> np.ndarray:
        """The abi.MOTION record of this way, with Scene.motion_time (a, b)."""
        r = np.zeros(1, MOTION)[0]
        r["t0"][:3], r["t1"][:3], r["q0"], r["q1"] = self.t0, self.t1, self.q0, self.q1
        r["s0"].reshape(3, 4)[:, :3], r["s1"].reshape(3, 4)[:, :3] = self.s0, self.s1
        r["time"] = (*motion_time, self.theta, np.sin(self.theta))
        r["pivot"][:3], r["world_pivot"][:3] = self.pivot, self.world_pivot
        return r
