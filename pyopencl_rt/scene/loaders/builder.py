"""What the Mitsuba 3 XML and pbrt-v4 importers share: a :class:`SceneBuilder` that collects
triangles, analytic shapes, materials, lights, an environment map and the warnings of one import, and
turns them into the same :class:`~pyopencl_rt.scene.model.Scene` the TOML loader makes.

Conventions both importers rely on:

* **Front sides.** A triangle's front is the side of (p1 - p0) x (p2 - p0), in Mitsuba, pbrt and
  here alike; a transform that mirrors (negative determinant) keeps the front on the transformed
  normal's side (the corners are reversed), as both renderers do.
* **Image orientation.** Our camera puts ``cross(forward, up)`` on the image's right.  A camera
  whose file puts the opposite direction on the right (pbrt's left-handed ``LookAt`` without a
  ``Scale -1 1 1``, a Mitsuba ``to_world`` with a mirror) would see a mirrored image; the builder
  then mirrors the whole scene about the camera's vertical plane (:func:`camera_from_matrix`),
  which gives exactly the peer's image with our camera.
* **Environment maps** are resampled, once, to our equirectangular layout (docs/SCENE_FORMAT.md,
  ``[environment]``) from the direction each of our texels looks along: the importer supplies the
  map's own direction -> (u, v) function and its rotation (:class:`EnvMap`).
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...device import abi
from ...device.host_memory import aligned_empty
from ..lights import light_type
from ..shapes import REGISTRY as SHAPES, records as shape_records, transformed as shapes_moved
from ..model import Camera, Environment, Material, RenderSettings, Scene, vertical_fov  # noqa: F401 (vertical_fov: the loaders' import)
from .assembly import (PendingNormals, _finite_faces, angle_weighted_normals, frame_scene, stacked_per_face,
                       transform_normals, triangle_scene)
# the importers take the shared geometry and errors from here too
from .geometry import (cylinder_mesh, disk_mesh, grid_mesh, look_at_camera_to_world, quad_mesh,  # noqa: F401
                       rectangle_mesh, rotate, scale, sphere_mesh, transform_points, transform_vector, translate)
from .instancing import ShapeGroup, place, remap_instances
from .values import SceneFormatError, error_at, first_use_index, one_line  # noqa: F401


# --------------------------------------------------------------------------------------------
# camera


def camera_from_matrix(camera_to_world, fov: float, image_right_sign: float, *, aperture=0.0,
                       focus=None, projection="perspective", extent=2.0, fov_axis: str = "y") -> tuple:
    """(Camera, mirror) of a camera that looks along its local +z with local +y up and puts
    ``image_right_sign`` * local +x on the image's right (Mitsuba: -1, pbrt: +1).  ``mirror`` is
    None, or the 4x4 reflection to apply to the whole scene so that our camera sees the image
    the file's camera sees (see the module docstring).  An orthographic camera's film is centred
    on the matrix's origin, ``extent`` high (``fov`` is then unused); a perspective one's ``fov``
    spans ``fov_axis`` (Camera.fov_axis)."""
    m = np.asarray(camera_to_world, np.float64)
    eye = m[:3, 3]
    forward = m[:3, :3] @ np.array([0.0, 0.0, 1.0])
    up = m[:3, :3] @ np.array([0.0, 1.0, 0.0])
    right_image = image_right_sign * (m[:3, :3] @ np.array([1.0, 0.0, 0.0]))
    forward /= np.linalg.norm(forward)
    up = up - forward * np.dot(up, forward)
    up /= np.linalg.norm(up)
    ours_right = np.cross(forward, up)
    cam = Camera(eye=tuple(map(float, eye)), look_at=tuple(map(float, eye + forward)), up=tuple(map(float, up)),
                 fov=float(fov), fov_axis=fov_axis, aperture_radius=float(aperture),
                 focus_distance=None if focus is None else float(focus), projection=projection, extent=float(extent))
    if aperture > 0 and focus is None:
        cam.focus_distance = 1.0
    mirror = None
    if np.dot(right_image, ours_right) < 0:
        n = ours_right
        refl = np.eye(3) - 2 * np.outer(n, n)
        mirror = np.eye(4)
        mirror[:3, :3] = refl
        mirror[:3, 3] = eye - refl @ eye
    return cam, mirror


def mirror_texture_spaces(materials, mirror) -> None:
    """The textures of a scene mirrored by ``mirror`` (4 x 4, its own inverse) that look up by the
    hit point or mix by the normal: their frames take mirrored points (frame @ mirror), a direction
    mix's direction turns with the normals; each texture once."""
    from ..textures import DirectionMix, with_inputs

    for t in with_inputs(t for m in materials for t in m.textures()):
        if isinstance(t, DirectionMix):
            t.direction = tuple(float(x) for x in mirror[:3, :3] @ np.asarray(t.direction))
        elif t.mapping != "uv":
            t.frame = tuple(float(x) for x in (np.reshape(t.frame, (3, 4)) @ mirror).ravel())


# --------------------------------------------------------------------------------------------
# environment maps


def our_env_directions(height: int, width: int) -> np.ndarray:
    """(H*W, 3) directions of the texel centres of our equirectangular map (docs/SCENE_FORMAT.md)."""
    v, u = np.meshgrid((np.arange(height) + 0.5) / height, (np.arange(width) + 0.5) / width, indexing="ij")
    theta, phi = np.pi * v.ravel(), 2 * np.pi * u.ravel()
    return np.stack([-np.sin(theta) * np.sin(phi), np.cos(theta), np.sin(theta) * np.cos(phi)], 1)


def bilinear_wrap(image, u, v, v_scale: float | None = None, v_offset: float = -0.5) -> np.ndarray:
    """Bilinear lookup at (u, v) in [0, 1) (columns centred at (i + 0.5) / w; rows at y = v v_scale +
    v_offset, by default h and -0.5: centred too), wrapping in u and clamping in v."""
    h, w = image.shape[:2]
    fx = np.mod(u, 1.0) * w - 0.5
    fy = np.clip(v, 0.0, 1.0) * (h if v_scale is None else v_scale) + v_offset
    x0, y0 = np.floor(fx), np.floor(fy)
    ax, ay = (fx - x0)[:, None], (fy - y0)[:, None]
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    x1, y1 = (x0 + 1) % w, np.clip(y0 + 1, 0, h - 1)
    x0, y0 = x0 % w, np.clip(y0, 0, h - 1)
    img = np.asarray(image, np.float64)
    top = img[y0, x0] * (1 - ax) + img[y0, x1] * ax
    bottom = img[y1, x0] * (1 - ax) + img[y1, x1] * ax
    return top * (1 - ay) + bottom * ay


@dataclass
class EnvMap:
    """An environment image in its file's layout: ``lookup(dirs)`` maps unit directions in the
    map's own frame to its (u, v); ``to_world`` (3x3) rotates that frame into the scene."""

    image: np.ndarray
    lookup: Callable
    to_world: np.ndarray
    scale: tuple
    source: str
    out_shape: tuple  # (H, W) of our resampled map
    wrap_u: bool = True  # False: clamp u too (an octahedral map's edges do not wrap around)
    # the kernel's own layout of rows ("centred", "poles": Mitsuba's) when ``lookup`` is an
    # equirectangular map the kernel reads as it is (u = atan2(x, -z) / 2 pi, v = acos(y) / pi, in
    # the map's frame); None: resampled into our layout
    rows: str | None = None
    sampling_weight: float = 1.0  # Environment.sampling_weight

    def resample(self, mirror=None) -> Environment:
        rotation = self.kernel_rotation(mirror)
        if rotation is not None:
            return Environment(radiance=self.scale, image=np.asarray(self.image, np.float32)[:, :, :3],
                               source=self.source, rotation=rotation, rows=self.rows,
                               sampling_weight=self.sampling_weight)
        h, w = self.out_shape
        d = our_env_directions(h, w)
        if mirror is not None:
            d = d @ mirror[:3, :3].T
        local = d @ np.linalg.inv(self.to_world).T
        local /= np.linalg.norm(local, axis=1, keepdims=True)
        u, v = self.lookup(local)
        if not self.wrap_u:
            u = np.clip(u, 0.5 / self.image.shape[1], 1 - 0.5 / self.image.shape[1])
        texels = bilinear_wrap(np.nan_to_num(np.asarray(self.image, np.float64)), u, v)
        return Environment(radiance=self.scale, image=texels.reshape(h, w, 3).astype(np.float32), source=self.source,
                           sampling_weight=self.sampling_weight)

    def kernel_rotation(self, mirror=None) -> np.ndarray | None:
        """The world-to-map rotation of our layout that reads this map as it is: (-x, y, -z) of
        the file's frame (where u = atan2(x, -z) / 2 pi is our atan2(-x, z) / 2 pi), after
        ``to_world``'s inverse and the scene's ``mirror``; None where the map is resampled (no
        ``rows``, or a ``to_world`` that is not a rotation times a uniform scale)."""
        if self.rows is None:
            return None
        t = np.asarray(self.to_world, np.float64)
        scale = abs(np.linalg.det(t)) ** (1.0 / 3.0)
        if not scale > 0 or not np.allclose(t @ t.T, scale**2 * np.eye(3), rtol=0.0, atol=1e-6 * scale**2):
            return None
        m = np.eye(3) if mirror is None else np.asarray(mirror, np.float64)[:3, :3]
        return np.diag([-1.0, 1.0, -1.0]) @ (t.T / scale) @ m


# --------------------------------------------------------------------------------------------
# the scene under construction


def _per_face(parts) -> np.ndarray:
    """The int32 per-face array of ``parts``, (face count, value) per mesh in order."""
    counts = np.array([n for n, _ in parts], np.int64)
    return np.repeat(np.array([value for _, value in parts], np.int32), counts)


class SceneBuilder:
    """One import: geometry and lights in world space, materials by identity, warnings."""

    def __init__(self, name: str, fmt: str):
        self.name, self.format = name, fmt
        self.warnings: list[str] = []
        self.materials: list[Material] = []
        self._material_index: dict[int, int] = {}
        self._emissive: dict[tuple, Material] = {}
        self.vertices, self.faces, self.face_materials, self.uvs = [], [], [], []
        # per mesh: (F, 3, 3) or None where it has none (zeros, flat / ones, and uvs zeros, filled in
        # by build() only when some mesh has them: no placeholders for a mesh of millions of faces)
        self.normals, self.colors = [], []
        self.any_normals = self.any_colors = False
        self.n_vertices = 0
        # the analytic shapes (scene/shapes/): their abi.SHAPE records, per shape its material
        self.shapes, self.shape_materials = [], []
        self.lights: list = []
        self.environment: EnvMap | Environment | None = None
        self.camera: Camera | None = None
        self.camera_motion = None  # Scene.camera_motion (in the file's world: mirrored at build)
        self.mirror = None
        self.settings = RenderSettings()
        # participating media (pyopencl_rt/scene/media.py): the media, interfaces by value, per face and
        # shape the interface index (-1: none), and the camera's medium
        self.media: list = []
        self._medium_index: dict[int, int] = {}
        self.interfaces: list = []
        self._interface_index: dict = {}
        self.face_interfaces: list = []
        self.shape_interfaces: list = []
        self.camera_medium = -1
        # shape groups and instances (loaders/instancing.py): the group being recorded (None: shapes
        # go to the scene), the groups by name, the Instance records, and the faces added so far
        self.recording = None
        self.groups: dict = {}
        self.instances: list = []
        self.pending: dict = {}  # group name -> (group, its instances) that place() decides on
        self.motion_time = (0.0, 1.0)  # Scene.motion_time: the moving instances' time mapping
        self.n_faces = 0
        self.normals_as_given = False  # an unevenly scaled instance's normals (Scene.normals_as_given)
        # emitters of several primitives (Scene.face_emitters): per mesh and per shape its emitter
        # index (-1: none), and each emitter's sampling weight
        self.face_emitters: list = []
        self.shape_emitters: list = []
        self.emitter_weights: list = []

    def new_emitter(self, sampling_weight: float = 1.0) -> int:
        """The index of a new emitter (a shape's area emitter) to pass to add_mesh / add_shape."""
        self.emitter_weights.append(float(sampling_weight))
        return len(self.emitter_weights) - 1

    def begin_group(self, name: str):
        """Record the shapes added from now on in a new group ``name`` (until :meth:`end_group`)."""
        self.recording = self.groups[name] = ShapeGroup(name)
        return self.recording

    def end_group(self):
        group, self.recording = self.recording, None
        return group

    def warn(self, position: str, what: str) -> None:
        msg = one_line(f"{position}: {what}")
        self.warnings.append(msg)
        warnings.warn(msg, stacklevel=3)

    def material_index(self, material: Material) -> int:
        key = id(material)
        if key not in self._material_index:
            self._material_index[key] = len(self.materials)
            self.materials.append(material)
        return self._material_index[key]

    def emissive(self, material: Material, radiance, two_sided: bool = False, texture=None,
                 directional: bool = False) -> Material:
        """``material`` emitting ``radiance`` (one copy per combination); ``directional``: along
        the normal alone (Material.emission_directional)."""
        key = (id(material), tuple(float(x) for x in radiance), bool(two_sided), id(texture), bool(directional))
        if key not in self._emissive:
            self._emissive[key] = dataclasses.replace(
                material, name=f"{material.name}+emitter", emission=tuple(float(x) for x in radiance),
                two_sided=bool(two_sided), emission_texture=texture, emission_directional=bool(directional))
        return self._emissive[key]

    def medium_index(self, medium) -> int:
        """The index of ``medium`` (a scene.media.Medium) in the scene's media (added on first use)."""
        return first_use_index(self.media, self._medium_index, medium, key=id(medium))

    def interface_index(self, interface) -> int:
        """The index of a scene.media.MediumInterface (one entry per distinct value); None: -1."""
        return -1 if interface is None else first_use_index(self.interfaces, self._interface_index, interface)

    def add_mesh(self, vertices, faces, material: Material, uvs=None, matrix=None, flip=False, normals=None,
                 colors=None, compute_normals=None, interface=None, emitter: int = -1) -> None:
        """Triangles in object space, moved by the 4x4 ``matrix``; ``flip`` swaps their front (and
        turns their shading normals around, as Mitsuba's flip_normals and pbrt's
        ReverseOrientation do).  ``normals`` and ``colors``: per corner, (F, 3, 3) or None.
        ``compute_normals`` (without ``normals``): True or (F, 3) keys of the corners that are one
        vertex: the angle-weighted vertex normals Mitsuba computes for a mesh file without normals,
        in world space, on the front side.  ``interface``: the medium interface of every face (its
        sides stay with the faces' fronts: flipping them swaps what is inside).  ``emitter``: the
        index (new_emitter) of the emitter the faces make up, -1: none (each emissive face its own)."""
        # float32 vertices and int32 faces (a mesh file's) stay as they are: a float64 / int64 copy of
        # a mesh of millions of triangles costs a second and 300 MB (issue 35); the transform and
        # the normals compute in float64 either way, and float32 -> float64 is exact
        v = np.asarray(vertices)
        v = (v if v.dtype in (np.float32, np.float64) else v.astype(np.float64)).reshape(-1, 3)
        f = np.asarray(faces)
        f = (f if f.dtype in (np.int32, np.int64) else f.astype(np.int64)).reshape(-1, 3)
        uv = None if uvs is None else np.asarray(uvs, np.float32).reshape(-1, 3, 2)
        nrm = None if normals is None else np.asarray(normals, np.float32).reshape(-1, 3, 3)
        col = None if colors is None else np.asarray(colors, np.float32).reshape(-1, 3, 3)
        if nrm is not None and flip:
            nrm = -nrm
        if matrix is not None or nrm is not None:  # unit normals (as Mitsuba's meshes), also without a matrix
            v = transform_points(matrix, v) if matrix is not None else v
            nrm = transform_normals(np.eye(4) if matrix is None else matrix, nrm)
            if matrix is not None and np.linalg.det(matrix[:3, :3]) < 0:
                flip = not flip
        keys = None
        if compute_normals is not None and compute_normals is not False and nrm is None:
            keys = f if compute_normals is True else np.asarray(compute_normals, np.int64).reshape(-1, 3)
        if flip:
            f = f[:, ::-1]
            uv = uv[:, ::-1] if uv is not None else None
            nrm = nrm[:, ::-1] if nrm is not None else None
            col = col[:, ::-1] if col is not None else None
            keys = keys[:, ::-1] if keys is not None else None
        if len(f) == 0:
            return
        if keys is not None:  # a group's recorded meshes need them now; the scene's, when stacked
            nrm = angle_weighted_normals(v, f, keys) if self.recording is not None else PendingNormals(v, f, keys)
        if self.recording is not None:
            self.recording.meshes.append((v, f, uv, nrm, col, material, interface))
            return
        self.append_mesh(v, f, uv, nrm, col, material, interface, emitter)

    def append_mesh(self, v, f, uv, nrm, col, material: Material, interface, emitter: int = -1) -> None:
        """Triangles already in world space, their fronts set (what add_mesh leaves)."""
        self.vertices.append(v)
        self.faces.append(f + self.n_vertices if self.n_vertices else f)  # the first mesh's as they are
        self.uvs.append(uv)
        self.normals.append(nrm)
        self.colors.append(col)
        # one value for all the mesh's faces: the per-face arrays are made once, in build()
        self.face_materials.append((len(f), self.material_index(material)))
        self.face_interfaces.append((len(f), self.interface_index(interface)))
        self.face_emitters.append((len(f), int(emitter)))
        self.n_vertices += len(v)
        self.n_faces += len(f)
        self.any_normals |= nrm is not None
        self.any_colors |= col is not None

    def add_shape(self, shape, p, material: Material, interface=None, emitter: int = -1) -> None:
        """An analytic shape: its type (a ShapeType or its name) and its (1, 28) parameter row."""
        shape = SHAPES[shape] if isinstance(shape, str) else shape
        if self.recording is not None:
            self.recording.shapes.append((shape, np.asarray(p, np.float64).reshape(28), material, interface))
            return
        self.shapes.append(shape_records(shape, p))
        self.shape_materials.append(self.material_index(material))
        self.shape_interfaces.append(self.interface_index(interface))
        self.shape_emitters.append(int(emitter))

    def add_sphere(self, centre, radius: float, material: Material, interface=None, emitter: int = -1) -> None:
        """A sphere, its front outside (an interface given for an inward-facing one must be flipped)."""
        self.add_shape("sphere", SHAPES["sphere"].params(centre, radius), material, interface, emitter)

    def add_light(self, light) -> None:
        self.lights.append(light)

    def set_environment(self, env, position: str) -> None:
        if self.environment is not None:
            self.warn(position, "a second environment light: we render one; ignored")
            return
        self.environment = env

    def build(self) -> Scene:
        """The Scene (the framing camera when the file had none)."""
        mirror = self.mirror
        blas = place(self)  # two-level groups: their faces last, in their own space
        normals = colors = None
        if self.faces:
            # in float32 at once, no float64 copy of the whole, unless the mirror moves them first;
            # page-aligned, as check_triangles keeps them (a CPU device reads them in place)
            vertices = aligned_empty((sum(len(v) for v in self.vertices), 3),
                                     np.float32 if mirror is None else np.float64)
            with np.errstate(over="ignore", invalid="ignore"):  # beyond float32: check_triangles' warning
                np.concatenate(self.vertices, out=vertices)
            faces = np.concatenate(self.faces, out=aligned_empty((sum(len(f) for f in self.faces), 3),
                                                                  np.result_type(*self.faces)))
            uvs = stacked_per_face(self.uvs, self.faces, (3, 2), 0.0)
            face_materials = _per_face(self.face_materials)
            if self.any_normals:
                normals = stacked_per_face(self.normals, self.faces, (3, 3), 0.0)
            if self.any_colors:
                colors = stacked_per_face(self.colors, self.faces, (3, 3), 1.0)
            # the per-mesh parts are in the stacked arrays now: free them before the Scene is made
            for parts in (self.vertices, self.uvs, self.normals, self.colors, self.face_materials):
                parts[:] = [None] * len(parts)
            self.faces[:] = [np.zeros((len(f), 0), np.int8) for f in self.faces]  # their counts stay
        else:
            vertices, faces = np.zeros((0, 3)), np.zeros((0, 3), np.int64)
            uvs, face_materials = None, np.zeros(0, np.int32)
        face_interfaces = _per_face(self.face_interfaces)
        shapes = np.concatenate(self.shapes) if self.shapes else np.zeros(0, abi.SHAPE)
        media = list(self.media)
        lights = list(self.lights)
        if mirror is not None:
            vertices = transform_points(mirror, vertices)
            faces = faces[:, ::-1]
            uvs = uvs[:, ::-1] if uvs is not None else None
            normals = transform_normals(mirror, normals, unit=False)[:, ::-1] if normals is not None else None
            colors = colors[:, ::-1] if colors is not None else None
            if len(shapes):
                shapes = shapes_moved(shapes, mirror)
            lights = [light_type(lt).transformed(lt, mirror) for lt in lights]
            media = [m.transformed(mirror) for m in media]
            mirror_texture_spaces(self.materials, mirror)
        instances = self.instances
        if instances and mirror is not None:
            # a two-level group's own space was mirrored with the rest: its instances are
            # conjugated (mirror M mirror^-1 of the mirrored group is mirror M of the group)
            inverse = np.linalg.inv(mirror)

            def mirrored(i, m):
                return None if m is None else mirror @ m @ (inverse if i.blas >= 0 else np.eye(4))

            def pivot(p):
                return None if p is None else tuple(transform_points(mirror, p)[0])
            instances = [dataclasses.replace(i, to_world=mirrored(i, i.to_world),
                                             to_world_end=mirrored(i, i.to_world_end),
                                             motion_pivot=pivot(i.motion_pivot),
                                             motion_pivot_world=pivot(i.motion_pivot_world))
                         for i in instances]
        if not self.faces and not self.shapes:
            raise SceneFormatError(f"{self.name}: the scene has no shapes that we can render")
        scene = triangle_scene(vertices, faces, face_materials, self.materials, self.name, uvs=uvs, normals=normals,
                               colors=colors, own_normals=True,
                               shapes=shapes, shape_materials=np.asarray(self.shape_materials, np.int32),
                               settings=self.settings,
                               face_interfaces=face_interfaces if self.interfaces else None,
                               face_emitters=(_per_face(self.face_emitters)
                                              if self.emitter_weights and self.faces else None))
        scene.normals_as_given = bool(self.normals_as_given)
        scene.make_normals_unit()  # once, in place: the kernels read them as they are
        if self.interfaces or media:
            scene.media, scene.interfaces, scene.camera_medium = media, list(self.interfaces), int(self.camera_medium)
            scene.shape_interfaces = np.asarray(self.shape_interfaces, np.int32)
        scene.lights = lights
        if self.emitter_weights:
            scene.shape_emitters = np.asarray(self.shape_emitters, np.int32)
            scene.emitter_weights = list(self.emitter_weights)
        if instances:
            scene.instances, scene.blas_groups = remap_instances(instances, blas, _finite_faces(vertices, faces)
                                                                 if self.faces else None)
        scene.motion_time = self.motion_time
        if self.camera_motion is not None:  # the camera's frames move with the mirrored world: mirror M
            scene.camera_motion = tuple((mirror if mirror is not None else np.eye(4)) @ np.asarray(m, np.float64)
                                        for m in self.camera_motion)
        env = self.environment
        scene.environment = env.resample(mirror) if isinstance(env, EnvMap) else env
        if self.camera is None:
            frame_scene(scene)
        else:
            scene.camera = self.camera
        if hasattr(scene, "format"):
            scene.format = self.format
        if hasattr(scene, "warnings"):
            scene.warnings = list(self.warnings)
        return scene


# --------------------------------------------------------------------------------------------
# colours


def _cie_lobe(lam, mu, s1, s2):
    s = np.where(lam < mu, s1, s2)
    return np.exp(-0.5 * ((lam - mu) / s) ** 2)


XYZ_TO_LINEAR_SRGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                               [-0.9692660, 1.8760108, 0.0415560],
                               [0.0556434, -0.2040259, 1.0572252]])


def blackbody_rgb(kelvin: float) -> tuple:
    """Linear sRGB of a black body at ``kelvin``, scaled to luminance Y = 1 (what pbrt-v4 emits
    for a ``blackbody`` spectrum of scale 1), from the CIE 1931 observer in Wyman, Sloan and
    Shirley's analytic fit (JCGT 2013)."""
    lam = np.linspace(360.0, 830.0, 471)
    x = 1.056 * _cie_lobe(lam, 599.8, 37.9, 31.0) + 0.362 * _cie_lobe(lam, 442.0, 16.0, 26.7) \
        - 0.065 * _cie_lobe(lam, 501.1, 20.4, 26.2)
    y = 0.821 * _cie_lobe(lam, 568.8, 46.9, 40.5) + 0.286 * _cie_lobe(lam, 530.9, 16.3, 31.1)
    z = 1.217 * _cie_lobe(lam, 437.0, 11.8, 36.0) + 0.681 * _cie_lobe(lam, 459.0, 26.0, 13.8)
    lm = lam * 1e-9
    with np.errstate(over="ignore"):
        planck = 1.0 / (lm ** 5 * (np.exp(1.4387769e-2 / (lm * max(float(kelvin), 1.0))) - 1.0))
    xyz = np.array([np.sum(x * planck), np.sum(y * planck), np.sum(z * planck)])
    rgb = XYZ_TO_LINEAR_SRGB @ (xyz / xyz[1])
    return tuple(float(c) for c in np.maximum(rgb, 0.0))
