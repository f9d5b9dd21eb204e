"""pbrt-v4's graphics state's transforms, as pbrt_scene's importer reads them: the current
transform at the start and end times (``TransformTimes``; ``ActiveTransform`` picks which of them
the transform directives change), named coordinate systems, and what moves between the two times
(motion blur: a moving shape becomes a moving two-level instance, loaders/instancing.py; the
interpolation is accel/motion.py's).  A mixin of ``pbrt_scene._Importer``: ``self.state`` holds
``ctm``, ``ctm_end`` and ``active`` (its _State), ``self.b`` the SceneBuilder."""
from __future__ import annotations

import dataclasses

import numpy as np

from .builder import disk_mesh, error_at, rotate, scale, translate
from .instancing import add_instance
from .pbrt_film import shutter


def singular(m) -> bool:
    """Whether the 4x4 transform ``m`` has no inverse (pbrt-v4 keeps it, its inverse NaN)."""
    return not abs(np.linalg.det(np.asarray(m, np.float64)[:3, :3])) > 1e-300 or not np.isfinite(m).all()


class Transforms:
    """The transform directives (d_Translate, ..., d_ActiveTransform) and the moving shapes."""

    def _saved(self) -> _State:
        st = self.state
        return dataclasses.replace(st, ctm=st.ctm.copy(), ctm_end=None if st.ctm_end is None else st.ctm_end.copy())

    def end_ctm(self) -> np.ndarray:
        """The transform at the end time (the start's where no ActiveTransform made them differ)."""
        return self.state.ctm if self.state.ctm_end is None else self.state.ctm_end

    def moves(self) -> bool:
        """Whether the current transform changes between the start and end times."""
        return self.state.ctm_end is not None and not np.array_equal(self.state.ctm, self.state.ctm_end)

    def _set(self, start, end) -> None:
        """The transforms after a directive: each active one becomes its new value."""
        st = self.state
        old_end = self.end_ctm()
        st.ctm, new_end = (start if st.active[0] else st.ctm), (end if st.active[1] else old_end)
        st.ctm_end = None if new_end is st.ctm else new_end

    def _apply(self, m) -> None:
        self._set(self.state.ctm @ m, self.end_ctm() @ m)

    def d_Identity(self, d):
        self._set(np.eye(4), np.eye(4))

    def d_Translate(self, d):
        self._apply(translate(d.args[0]))

    def d_Scale(self, d):
        self._apply(scale(d.args[0]))

    def d_Rotate(self, d):
        angle, *axis = d.args[0]
        if not np.linalg.norm(axis) > 0:
            raise error_at(d.pos, "Rotate needs a non-zero axis")
        self._apply(rotate(axis, angle))

    def d_LookAt(self, d):
        v = np.asarray(d.args[0], np.float64)
        eye, look, up = v[:3], v[3:6], v[6:]
        fwd = look - eye
        if not np.linalg.norm(fwd) > 0:
            raise error_at(d.pos, "LookAt: the eye and the point looked at are the same")
        fwd /= np.linalg.norm(fwd)
        right = np.cross(up / max(np.linalg.norm(up), 1e-300), fwd)
        if not np.linalg.norm(right) > 1e-9:
            raise error_at(d.pos, "LookAt: 'up' is zero or parallel to the viewing direction")
        right /= np.linalg.norm(right)
        world_from_camera = np.eye(4)
        world_from_camera[:3, 0], world_from_camera[:3, 1] = right, np.cross(fwd, right)
        world_from_camera[:3, 2], world_from_camera[:3, 3] = fwd, eye
        self._apply(np.linalg.inv(world_from_camera))

    def _matrix(self, d):
        # pbrt's Transform lists the matrix column by column (the transpose of its rows); a singular
        # one is kept, as pbrt-v4 keeps it (its inverse NaN): see singular() for what it draws
        return np.asarray(d.args[0], np.float64).reshape(4, 4).T

    def d_Transform(self, d):
        m = self._matrix(d)
        self._set(m, m.copy())

    def d_ConcatTransform(self, d):
        self._apply(self._matrix(d))

    def d_CoordinateSystem(self, d):
        self.coords[d.args[0]] = (self.state.ctm.copy(), self.end_ctm().copy())

    def d_CoordSysTransform(self, d):
        if d.args[0] not in self.coords:
            self.warn(d.pos, f"CoordSysTransform: no coordinate system named '{d.args[0]}'; ignored")
            return
        start, end = self.coords[d.args[0]]
        self.state.ctm, self.state.ctm_end = start.copy(), end.copy()  # both, as pbrt-v4

    def d_ReverseOrientation(self, d):
        self.state.reverse = not self.state.reverse

    def d_TransformTimes(self, d):
        start, end = (float(x) for x in d.args[0])
        if not end >= start:
            raise error_at(d.pos, f"TransformTimes: the end time {end:g} is before the start time {start:g}")
        self.transform_times = (start, end)

    def d_ActiveTransform(self, d):
        which = {"StartTime": (True, False), "EndTime": (False, True), "All": (True, True)}.get(d.args[0])
        if which is None:
            raise error_at(d.pos, f'ActiveTransform "{d.args[0]}": expected StartTime, EndTime or All')
        self.state.active = which

    def motion_time(self) -> None:
        """The moving instances' time mapping (Scene.motion_time): a ray's time is open + u (close -
        open) over the Camera's shutter (pbrt-v4's default [0, 1]), and an instance is at (time -
        start) / (end - start) of its way (TransformTimes, default 0 and 1), held at its ends
        outside them."""
        if self.moving is None:
            return
        opened, closed = shutter(self.camera[0] if self.camera is not None else None)
        start, end = self.transform_times
        if not end > start:
            raise error_at(self.moving, f"a moving shape needs TransformTimes with the end after the start (they are "
                                        f"{start:g} and {end:g})")
        self.b.motion_time = ((opened - start) / (end - start), (closed - opened) / (end - start))

    def _moving_shape(self, d, mat, interface) -> None:
        """A shape whose transform differs between the start and end times (pbrt-v4 intersects it
        in its own space through the interpolated transform): a group of this one shape, in its own
        space, drawn by one moving instance (loaders/instancing.py refuses what it cannot move)."""
        from .pbrt_shapes import cylinder_triangles, shape_geometry

        what = f'Shape "{d.args[0]}"'
        if self.b.recording is not None:
            raise error_at(d.pos, f"{what}: a moving shape inside ObjectBegin is not supported "
                                  "(move the ObjectInstance)")
        start, end = self.state.ctm, self.end_ctm()
        if singular(start) or singular(end):
            raise error_at(d.pos, f"{what}: a moving shape with a singular transform is not supported")
        if mat.is_emissive:
            raise error_at(d.pos, f"{what}: a moving area light (ActiveTransform) is not supported")
        geometry = shape_geometry(self, d)
        if geometry is None:
            return
        if isinstance(geometry[0], str) and geometry[0] == "disk":  # moved as its triangles (a moving instance draws triangles)
            geometry = disk_mesh(geometry[1], 0.0, geometry[2], 360.0)
        if isinstance(geometry[0], str) and geometry[0] == "cylinder":
            geometry = cylinder_triangles(*geometry[1:])
        if isinstance(geometry[0], str):
            raise error_at(d.pos, f"{what}: motion blur of an analytic sphere is not supported")
        v, f, uv, *rest = geometry
        self.shape_groups += 1
        group = self.b.begin_group(f"(moving {what} #{self.shape_groups})")
        try:
            self.b.add_mesh(v, f, mat, uvs=uv, matrix=None, flip=self.state.reverse,
                            normals=rest[0] if rest else None, interface=interface)
        finally:
            self.b.end_group()
        if self.moving is None:
            self.moving = d.pos
        add_instance(self.b, group, start, d.pos, matrix_end=end, what=what)
