"""The values of a :class:`~pyopencl_rt.scene.model.Scene` checked against what the float32
kernels can hold, whatever made the scene (a loader or Python code).

Scene files are checked key by key by their loaders; this is the last check, on the finished
scene, that :func:`~pyopencl_rt.scene.loaders.load_scene` and ``render_full`` both run before
anything is built.  It refuses, with one line naming the scene:

* arrays of the wrong shape or kind (per-corner UVs, normals and colours too; colours negative or
  not finite), face and material indices out of range;
* geometry that is not finite, or beyond ``GEOMETRY_LIMIT`` from the origin: values finite in
  float64 can overflow in float32 (1e39), and the triangle test forms products of three
  coordinates (``n . a``, with n a cross product), which overflow float32 beyond ~7e12;
* an analytic shape its type's check refuses (a sphere whose radius float32 rounds to 0), a
  camera that sees nothing;
* radiance (emission, light intensity, irradiance, environment) that is negative, NaN, or finite
  but above ``RADIANCE_LIMIT``, where a path's products overflow float32.  An infinite emission
  is left to the kernels, which count such samples as non-finite and discard them.
"""
from __future__ import annotations

import math

import numpy as np

from ..device import abi
from ..errors import UserError, one_line
from . import shapes as SHAPES
from .model import FOV_AXES

GEOMETRY_LIMIT = float(2**40)  # ~1.1e12: a cube of it (n . a) stays below float32's 3.4e38
RADIANCE_LIMIT = 1e30
FLOAT32_MAX = float(np.finfo(np.float32).max)


class SceneValueError(UserError):
    """A scene value the kernels cannot use; the message is one line naming the scene."""


def _fail(scene, what: str):
    raise SceneValueError(one_line(f"{getattr(scene, 'source', '<memory>')}: {what}"))


def _array(scene, value, what, width, kinds):
    a = np.asarray(value)
    if a.size == 0:
        return a.reshape(0, width) if width else a.reshape(0)
    if a.dtype.kind not in kinds:
        _fail(scene, f"{what} must hold {'integers' if kinds == 'iu' else 'numbers'}, got dtype {a.dtype}")
    if (width and (a.ndim != 2 or a.shape[1] != width)) or (not width and a.ndim != 1):
        _fail(scene, f"{what} must have shape {'(N, %d)' % width if width else '(N,)'}, got {tuple(a.shape)}")
    return a


def _indices(scene, a, what, count):
    if a.size and (a.min() < 0 or a.max() >= count):
        _fail(scene, f"{what} must lie in 0 .. {count - 1}, got {a.min()} .. {a.max()}")


def _vector(scene, value, what, limit=None, n=3):
    try:
        v = np.asarray(value, np.float64)
    except (TypeError, ValueError):
        _fail(scene, f"{what} must be {n} numbers, got {value!r}")
    if v.shape != (n,):
        _fail(scene, f"{what} must be {n} numbers, got {value!r}")
    if not np.isfinite(v).all():
        _fail(scene, f"{what} must be finite, got {v.tolist()}")
    if limit is not None and np.abs(v).max() > limit:
        _fail(scene, f"{what} {v.tolist()} is beyond {limit:.3g} from the origin, more than the float32 kernels "
                     "can hold")
    return v


def _radiance(scene, value, what, allow_inf=False):
    v = np.asarray(value, np.float64).reshape(-1)
    if np.isnan(v).any() or (v < 0).any():
        _fail(scene, f"{what} must be >= 0, got {v.tolist()}")
    finite = v[np.isfinite(v)]
    if (not allow_inf and len(finite) < len(v)) or (finite > RADIANCE_LIMIT).any():
        _fail(scene, f"{what} {v.tolist()} is above {RADIANCE_LIMIT:g}, where float32 path contributions overflow")


def check_geometry(scene) -> None:
    """Triangles and analytic shapes: shapes, indices, finite and within GEOMETRY_LIMIT."""
    n_mat = len(scene.materials)
    v = _array(scene, scene.vertices, "vertices", 3, "fiu")
    f = _array(scene, scene.faces, "faces", 3, "iu")
    fm = _array(scene, scene.face_materials, "face_materials", 0, "iu")
    _indices(scene, f, "face vertex indices", len(v))
    if len(fm) != len(f):
        _fail(scene, f"face_materials has {len(fm)} entries for {len(f)} faces")
    _indices(scene, fm, "face material indices", n_mat)
    if len(f):
        from .meshops import used_vertex_reach, used_vertices

        finite, reach = used_vertex_reach(v, f)  # the vertices of np.unique(f), one parallel pass
        if not finite:  # how many: the used vertices themselves
            used = np.asarray(v)[used_vertices(f, len(v))]
            bad = ~np.isfinite(used.astype(np.float64)).all(axis=1)
            _fail(scene, f"{int(bad.sum())} vertices used by faces are not finite (NaN, Inf or beyond float32)")
        if reach > GEOMETRY_LIMIT:
            _fail(scene, f"triangle vertices reach {reach:.3g} from the origin, beyond {GEOMETRY_LIMIT:.3g}: the float32 "
                         "kernels cannot intersect them (scale the scene down)")
    for name in ("normals", "colors", "uvs"):
        a = getattr(scene, name, None)
        if a is None:
            continue
        a = np.asarray(a)
        width = 2 if name == "uvs" else 3
        if a.dtype.kind not in "fiu" or a.size != len(f) * 3 * width:
            _fail(scene, f"{name} must be {len(f)} faces x 3 corners x {width} numbers, got shape {tuple(a.shape)}")
        if name == "colors" and not (np.isfinite(a).all() and (a >= 0).all()):
            _fail(scene, "colors must be finite and >= 0")
    shapes = np.asarray(scene.shapes)
    if shapes.dtype != abi.SHAPE or shapes.ndim != 1:
        _fail(scene, f"shapes must be a 1-d array of abi.SHAPE records, got {shapes.dtype} of shape {shapes.shape}")
    sm = _array(scene, scene.shape_materials, "shape_materials", 0, "iu")
    if len(sm) != len(shapes):
        _fail(scene, f"shape_materials has {len(sm)} entries for {len(shapes)} shapes")
    _indices(scene, sm, "shape material indices", n_mat)
    if np.isin(shapes["type"], list(SHAPES.BY_CODE), invert=True).any():
        _fail(scene, f"shapes: unknown type {shapes['type'][~np.isin(shapes['type'], list(SHAPES.BY_CODE))][0]}")
    for t, idx, p in SHAPES.unit_rows(shapes):
        for row, what in t.check(p):
            _fail(scene, f"{t.name} #{idx[row] + 1}: {what}")
        reach = t.reach(p)
        far = np.flatnonzero(reach > GEOMETRY_LIMIT)
        if len(far):
            _fail(scene, f"{t.name} #{idx[far[0]] + 1} reaches {reach[far[0]]:.3g} from the origin, beyond "
                         f"{GEOMETRY_LIMIT:.3g}: the float32 kernels cannot intersect it (scale the scene down)")


def check_camera(scene) -> None:
    cam = scene.camera
    eye = _vector(scene, cam.eye, "camera eye", GEOMETRY_LIMIT)
    look_at = _vector(scene, cam.look_at, "camera look_at", GEOMETRY_LIMIT)
    up = _vector(scene, cam.up, "camera up")
    forward = look_at - eye
    if not np.linalg.norm(forward) > 0:
        _fail(scene, "camera eye and look_at are the same point")
    if not np.linalg.norm(np.cross(forward / np.linalg.norm(forward), up)) > 1e-9:
        _fail(scene, "camera up must not be zero or parallel to the viewing direction")
    if not (isinstance(cam.fov, (int, float, np.number)) and 0 < cam.fov < 180):
        _fail(scene, f"camera fov must be between 0 and 180 degrees, got {cam.fov!r}")
    if getattr(cam, "fov_axis", "y") not in FOV_AXES:
        _fail(scene, f"camera fov_axis must be one of {', '.join(FOV_AXES)}, got {cam.fov_axis!r}")
    aperture = float(cam.aperture_radius)
    if not (math.isfinite(aperture) and aperture >= 0):
        _fail(scene, f"camera aperture_radius must be finite and >= 0, got {aperture}")
    if cam.focus_distance is not None and not (math.isfinite(float(cam.focus_distance)) and cam.focus_distance > 0):
        _fail(scene, f"camera focus_distance must be finite and > 0, got {cam.focus_distance}")


def check_lights(scene) -> None:
    for i, m in enumerate(scene.materials):
        _radiance(scene, m.emission, f"material {m.name!r}: emission", allow_inf=True)
        rec = m.record({})
        for name in rec.dtype.names:
            if name != "emission" and rec.dtype[name].base.kind == "f" and not np.isfinite(rec[name]).all():
                _fail(scene, f"material {m.name!r}: {name} must be finite, got {np.asarray(rec[name]).tolist()}")
    for i, light in enumerate(scene.lights or [], 1):
        kind = type(light).__name__
        if hasattr(light, "position"):
            _vector(scene, light.position, f"light #{i} ({kind}): position", GEOMETRY_LIMIT)
            what = "irradiance" if hasattr(light, "irradiance") else "intensity"
            _radiance(scene, getattr(light, what), f"light #{i} ({kind}): {what}")
            if hasattr(light, "to_world"):
                try:
                    light.frame()
                except ValueError as exc:
                    _fail(scene, f"light #{i} ({kind}): {exc}")
        else:
            d = _vector(scene, light.direction, f"light #{i} ({kind}): direction")
            if not np.linalg.norm(d) > 0:
                _fail(scene, f"light #{i} ({kind}): direction must not be zero")
            _radiance(scene, light.irradiance, f"light #{i} ({kind}): irradiance")
    env = scene.environment
    if env is not None:
        _radiance(scene, env.radiance, "environment radiance")
        if env.image is not None:
            img = np.asarray(env.image)
            if img.ndim != 3 or img.shape[2] != 3 or img.dtype.kind not in "fiu" or 0 in img.shape:
                _fail(scene, f"environment image must be an H x W x 3 array of numbers, got shape {img.shape}")
    check_emitters(scene)


def check_emitters(scene) -> None:
    """Light picking (render/lights.py): the emitter indices of faces and shapes, the weights."""
    weights = list(getattr(scene, "emitter_weights", None) or [])
    lights = list(scene.lights or []) + ([scene.environment] if scene.environment is not None else [])
    for what, w in [*((f"emitter_weights[{i}]", w) for i, w in enumerate(weights)),
                    *((f"the sampling_weight of {type(lt).__name__}", getattr(lt, "sampling_weight", 1.0))
                      for lt in lights)]:
        if not isinstance(w, (int, float, np.number)) or not (math.isfinite(float(w)) and float(w) >= 0):
            _fail(scene, f"{what} must be a finite number >= 0, got {w!r}")
    _shape_indices(scene, "emitters", len(weights), " (indices of emitter_weights)")


def check_settings(scene) -> None:
    from ..validate import integer

    st = scene.settings
    for name, minimum in (("width", 1), ("height", 1), ("spp", 1), ("max_depth", -1), ("rr_depth", 0), ("seed", 0)):
        try:
            integer(getattr(st, name), name, minimum=minimum,
                    maximum={"seed": 2**32 - 1, "spp": abi.MAX_PASSES}.get(name))
        except UserError as exc:
            _fail(scene, f"settings: {exc}")
    from .model import LIGHT_SAMPLERS

    if getattr(st, "light_sampler", "power") not in LIGHT_SAMPLERS:
        _fail(scene, f"settings: light_sampler must be one of {', '.join(LIGHT_SAMPLERS)}, got {st.light_sampler!r}")


def check_media(scene) -> None:
    """Media (pyopencl_rt/scene/media.py): finite, non-negative extinction and grids, albedo in
    [0, 1], |g| < 1, invertible grid transforms; interface and medium indices in range."""
    media = list(getattr(scene, "media", None) or [])
    interfaces = list(getattr(scene, "interfaces", None) or [])
    for m in media:
        what = f"medium {m.name!r}"
        e = np.asarray(m.extinction(), np.float64)
        if e.shape != (3,) or not np.isfinite(e).all() or (e < 0).any() or e.max() > RADIANCE_LIMIT:
            _fail(scene, f"{what}: sigma_t * scale must be 3 finite numbers >= 0, got {np.ravel(e).tolist()}")
        a = np.asarray(m.albedo, np.float64)
        if a.shape != (3,) or not np.isfinite(a).all() or (a < 0).any() or (a > 1).any():
            _fail(scene, f"{what}: albedo must be 3 numbers in [0, 1], got {np.ravel(a).tolist()}")
        if m.phase.type not in ("isotropic", "hg") or not (-1 < float(m.phase.g) < 1):
            _fail(scene, f"{what}: the phase function must be isotropic or hg with -1 < g < 1, got "
                         f"{m.phase.type} g={m.phase.g}")
        maj = np.asarray(m.majorant_rgb(), np.float64)
        if not np.isfinite(maj).all() or (maj < 0).any() or maj.max() > RADIANCE_LIMIT:
            _fail(scene, f"{what}: its majorant {maj.tolist()} must be finite and >= 0")
        for name, grid in (("density", m.density), ("albedo grid", m.albedo_grid)):
            if grid is None:
                continue
            d = np.asarray(grid.data)
            if not np.isfinite(d).all() or (d < 0).any():
                _fail(scene, f"{what}: its {name} must be finite and >= 0")
            if name == "albedo grid" and d.max() > 1:
                _fail(scene, f"{what}: its albedo grid must lie in [0, 1], got values up to {d.max():g}")
            t = np.asarray(grid.to_world, np.float64)
            if t.shape != (4, 4) or not np.isfinite(t).all() or abs(np.linalg.det(t[:3, :3])) < 1e-300:
                _fail(scene, f"{what}: its {name}'s transform must be a finite, invertible 4x4 matrix")
    for i, mi in enumerate(interfaces):
        for side in ("interior", "exterior"):
            k = getattr(mi, side)
            if not -1 <= k < len(media):
                _fail(scene, f"medium interface #{i}: {side} {k} is not a medium index (-1 .. {len(media) - 1})")
    if not -1 <= int(getattr(scene, "camera_medium", -1)) < len(media):
        _fail(scene, f"camera_medium {scene.camera_medium} is not a medium index (-1 .. {len(media) - 1})")
    _shape_indices(scene, "interfaces", len(interfaces))


def check_textures(scene) -> None:
    """Textures looked up by the hit point or mixed by its normal (planar, spherical and
    cylindrical mappings, directionmix) where the kernels read them so: a material's base,
    metallic-roughness and scalar textures, not its emission, normal or bump map, cut-out
    opacity or a mix's weight (read by uv alone)."""
    for m in scene.materials:
        uv_only = [("emission", m.emission_texture), ("normal or bump map", m.normal_texture),
                   ("opacity", m.scalar_textures.get("opacity"))]
        if m.type == "mix":
            uv_only.append(("blend weight", m.scalar_textures.get("mix_weight")))
        for what, t in uv_only:
            if t is not None and getattr(t, "mapping", "uv") != "uv":
                _fail(scene, f"material {m.name!r}: a {t.mapping.replace('_', '')} texture ({t.name}) as its {what} "
                             "is not supported (there textures are looked up by the shape's uv)")


def check_directional_emitters(scene) -> None:
    """Material.emission_directional (Mitsuba's directionalarea) on flat faces alone: one-sided,
    untextured, not on an analytic shape (cl/render/lights.h projects onto a triangle)."""
    directional = [m for m in scene.materials if m.emission_directional and m.is_emissive]
    for m in directional:
        if m.two_sided or m.emission_texture is not None:
            _fail(scene, f"material {m.name!r}: a directional emission is one-sided and untextured")
    shapes = np.asarray(scene.shapes)
    for m in directional:
        on = [i for i, k in enumerate(np.asarray(scene.shape_materials, np.int64)) if scene.materials[k] is m]
        if on:
            name = SHAPES.shape_type(shapes["type"][on[0]]).name
            _fail(scene, f"material {m.name!r}: a directional emission on a {name} is not supported "
                         "(only on flat faces)")


def check_scene(scene) -> None:
    """Every check above; a SceneValueError (one line naming the scene) at the first problem."""
    from .model import Scene

    if not isinstance(scene, Scene):
        raise SceneValueError(f"not a Scene: {type(scene).__name__}")
    if not isinstance(scene.materials, (list, tuple)):
        _fail(scene, "materials must be a list of Material")
    with np.errstate(over="ignore", invalid="ignore"):
        check_geometry(scene)
        check_camera(scene)
        check_lights(scene)
        check_media(scene)
    check_textures(scene)
    check_directional_emitters(scene)
    check_settings(scene)


def _shape_indices(scene, kind: str, n: int, of: str = "") -> None:
    """face_<kind> and shape_<kind> (where the scene has them): one index per shape, -1 or an
    index below n."""
    for what, count in ((f"face_{kind}", len(scene.faces)), (f"shape_{kind}", len(scene.shapes))):
        arr = getattr(scene, what, None)
        if arr is None:
            continue
        a = _array(scene, arr, what, 0, "iu")
        if len(a) != count:
            _fail(scene, f"{what} has {len(a)} entries for {count} shapes")
        if a.size and (a.min() < -1 or a.max() >= n):
            _fail(scene, f"{what} must lie in -1 .. {n - 1}{of}, got {a.min()} .. {a.max()}")
