"""The record of a moving instance's or camera's way (motion blur), which abi registers among the
shared structs (``Motion``): accel/motion.py makes them (``Motion.record``), cl/accel/motion.h
(``motion_matrices``, for HAS_MOTION and HAS_CAMERA_MOTION) reads them.

A record (208 bytes): the transforms at the start and the end split as pbrt-v4 splits them, seen
from a pivot, M = Cw^-1 (T R S) Co with Cw and Co the moves of the pivot to the origin in the world
and in the moving thing's space (t0, t1: T; q0, q1: R as quaternions (x, y, z, w), q1 on q0's side
of the sphere; s0, s1: S's three rows, each a float4; pivot: the pivot in the thing's space,
world_pivot: in the world), and time = (a, b, theta, sin theta): at a ray's time sample u it is at
s = clamp(a + b u, 0, 1) of its way, T and S interpolated linearly, R by slerp over the angle theta
between q0 and q1 (b 0: a camera record that does not move)."""
import numpy as np

MOTION = np.dtype([("t0", np.float32, 4), ("t1", np.float32, 4), ("q0", np.float32, 4), ("q1", np.float32, 4),
                   ("s0", np.float32, 12), ("s1", np.float32, 12), ("time", np.float32, 4),
                   ("pivot", np.float32, 4), ("world_pivot", np.float32, 4)])
assert MOTION.itemsize == 208
