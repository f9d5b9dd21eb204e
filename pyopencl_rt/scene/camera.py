"""The camera of a scene (:mod:`.model` re-exports it): where it is, its projection, its field of
view and the axis that field spans, its thin lens, and the CAMERA record the kernels read."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..device import abi

PROJECTIONS = ("perspective", "orthographic")
assert set(PROJECTIONS) == set(abi.PROJECTIONS)


FOV_AXES = ("x", "y", "diagonal", "smaller", "larger")


def vertical_fov(fov_degrees: float, axis: str, width: int, height: int) -> float:
    """The vertical field of view from a field of view along ``axis`` (FOV_AXES) of a width x
    height image."""
    if axis == "smaller":
        axis = "x" if width <= height else "y"
    elif axis == "larger":
        axis = "x" if width > height else "y"
    t = math.tan(math.radians(fov_degrees) / 2)
    if axis == "x":
        t *= height / width
    elif axis == "diagonal":
        t *= height / math.hypot(width, height)
    elif axis != "y":
        raise ValueError(f"unknown fov axis {axis!r}: use one of {', '.join(FOV_AXES)}")
    return math.degrees(2 * math.atan(t))


@dataclass
class Camera:
    eye: tuple = (0.0, 0.0, 5.0)
    look_at: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    fov: float = 40.0  # degrees (perspective), along fov_axis
    # the image axis fov spans: "y" (vertical), "x", "diagonal", "smaller" or "larger" (the
    # shorter or longer side: pbrt-v4's fov spans the shorter), resolved at the rendered size, so
    # that a file rendered at another size keeps its renderer's rule (FOV_AXES)
    fov_axis: str = "y"
    # thin lens (depth of field) when aperture_radius > 0: the lens radius, and the distance
    # along the viewing direction of the plane in focus (None: |look_at - eye|)
    aperture_radius: float = 0.0
    focus_distance: float | None = None
    # "perspective", or "orthographic": rays parallel to look_at - eye from the points of a
    # rectangle centred on eye, `extent` high (scene units) and extent * width / height wide
    projection: str = "perspective"
    extent: float = 2.0

    def vertical_fov(self, width: int, height: int) -> float:
        """The vertical field of view (degrees) of an image of width x height."""
        return vertical_fov(self.fov, self.fov_axis, width, height)

    def record(self, width: int, height: int) -> np.ndarray:
        """The CAMERA struct for an image of width x height (its filter fields a box of radius 0.5:
        pyopencl_rt/render/filters.py sets those)."""
        eye = np.asarray(self.eye, np.float64)
        forward = np.asarray(self.look_at, np.float64) - eye
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(self.up, np.float64))
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        rec = np.zeros((), abi.CAMERA)
        if self.projection == "orthographic":
            half = float(self.extent) / 2
            rec["projection"] = abi.PROJECTION_ORTHOGRAPHIC
        elif self.projection == "perspective":
            half = np.tan(np.radians(self.vertical_fov(width, height)) / 2)
        else:
            raise ValueError(f"unknown projection {self.projection!r}: use one of {', '.join(PROJECTIONS)}")
        rec["origin"] = eye
        rec["forward"] = forward
        rec["right"] = right * half * width / height
        rec["up"] = up * half
        rec["width"] = width
        rec["height"] = height
        rec["lens_radius"] = max(float(self.aperture_radius), 0.0)
        focus = self.focus_distance if self.focus_distance is not None else np.linalg.norm(
            np.asarray(self.look_at, np.float64) - eye)
        rec["focus_distance"] = focus
        rec["filter"] = abi.FILTER_BOX
        rec["filter_radius"] = 0.5
        rec["filter_weight"] = 1.0
        return rec
