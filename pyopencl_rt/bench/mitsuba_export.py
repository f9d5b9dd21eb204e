"""The same scene for Mitsuba 3: the peer renderer of ``pyopencl-rt bench convergence --compare mitsuba``,
``bench render --mitsuba`` and ``bench set``.

Mitsuba usually lives in its own virtual environment, so the export has two halves:

* :func:`scene_arrays` (this process, numpy only) turns a :class:`~pyopencl_rt.scene.Scene` into
  plain arrays and numbers, saved with :func:`save_scene_npz`;
* :func:`dict_from_arrays` (in the Mitsuba process) turns them into a dict for
  ``mi.load_dict``; :func:`to_mitsuba_dict` does both in one go where Mitsuba imports here.

This module imports nothing but numpy at module level and nothing from the package, so that
``pyopencl_rt/bench/mitsuba_runner.py`` can load it by file path in an interpreter that has Mitsuba
and numpy but not pyopencl.

Correspondence (checked against our renderer by tests/bench/test_convergence.py and, for textures,
environments, participating media and the scenes of ``bench set``, tests/bench/test_mitsuba_export.py):

* triangles: one PLY mesh per material and medium interface (``face_normals = true``: flat shading
  on the geometric normal, as ours); a two-level instance (``Scene.blas_groups``) as its own moved
  copy of its group (pyopencl_rt/scene/instances.py:flattened), what our kernels draw; BSDF from
  the material type's ``to_mitsuba`` (pyopencl_rt/scene/materials/; a type without one is refused);
* emitters: ``area`` emitter with our radiance.  Ours is one-sided along the geometric normal
  (v1 - v0) x (v2 - v0); Mitsuba's area emitter emits on the side of the mesh normal, which for
  a PLY without normals is the same cross product (same winding): verified with a one-quad
  scene.  Mitsuba has no two-sided area emitter: a two-sided emissive material is refused;
* analytic shapes: Mitsuba's own (``sphere``, ``disk``: each type's ``to_mitsuba``);
* image textures (a diffuse albedo, a dielectric tint, an emission texture): ``bitmap`` textures of
  the texels times their factor, written as float OpenEXR and read ``raw`` (our texels are
  already linear), bilinear and repeating as ours; both renderers put texture coordinate (0, 0) at
  the top-left texel, and the PLY carries our per-corner (u, v) as they are (Mitsuba reads PLY
  coordinates without flipping them).  Spheres have no texture coordinates here and use the
  factors alone, so their BSDF and emitter are the untextured ones.  A type whose texture has no
  Mitsuba place (``gltf``, which has no ``to_mitsuba`` at all) is refused;
* environment: a constant one is Mitsuba's ``constant``; a map is ``envmap``.  Both interpolate
  bilinearly; Mitsuba's u = atan2(x, -z) / 2 pi looks along -z at u = 0, ours (cl/render/lights.h)
  along +z, so its frame is ours turned half a turn about +y; its column i is centred at
  u = (i + 1/2) / W, its row j at v = j / (H - 1) (the poles on the first and last rows: Mitsuba
  3.9's envmap.cpp).  A map of ours with rows on the poles (one read from Mitsuba's XML) is
  exported as it is with the ``to_world`` of its rotation; one with centred rows is resampled,
  each of Mitsuba's texels our interpolated map at its node, on a grid finer than ours
  (:data:`ENV_WIDTH`: 4 times for a map 256 texels wide).  Our RGB scale is multiplied in;
* point and directional lights: Mitsuba's ``point`` (``intensity``) and ``directional``
  (``irradiance``), the same quantities as ours; spot and projector lights (untextured, with
  Mitsuba's conventions: a textured one or pbrt-v4's is refused) its ``spot`` and ``projector``
  with our position and frame as ``to_world``;
* camera: ``perspective``, ``to_world = look_at(eye, look_at, up)``, ``fov_axis = 'y'`` (our
  fov is vertical), or ``orthographic`` with ``to_world = look_at(...) @ scale(s, s, 1)``, s our
  film's half width (Mitsuba's film is 2 wide and 2 / aspect high before the scale), the origin
  moved back by near_clip so that the rays start at our eye; ``hdrfilm`` with our pixel filter
  (:func:`mitsuba_rfilter`; a filter Mitsuba cannot express is refused) and
  ``pixel_format = 'rgb'``;
* integrator: ``path`` with our ``max_depth`` (both count path segments: 1 = emitters only) and
  ``rr_depth`` = our ``rr_depth`` (default 5, as Mitsuba's): both apply Russian roulette from
  the ``rr_depth``-th surface interaction on, keeping a path with probability
  min(max(throughput) eta^2, 0.95), eta^2 the product over the path's refractions.  Mitsuba's ``path`` is MIS of BSDF and emitter sampling, as our
  ``path`` integrator.
* participating media (pyopencl_rt/scene/media.py), scenes with media or index-matched shapes: the
  integrator is ``volpath``, or ``volpathmis`` where our estimator weighs chromatic distance samples
  by spectral MIS (``RenderSettings.spectral_mis`` and a chromatic medium: our ``SPECTRAL_MIS``
  define; with achromatic media the two estimators are the same and ``volpath`` is taken), with the
  same max_depth / rr_depth.  A homogeneous medium is Mitsuba's ``homogeneous`` (``sigma_t``,
  ``scale``, ``albedo``, ``sample_emitters``); a grid medium is ``heterogeneous`` whose ``sigma_t``
  is a ``gridvolume`` of our density times sigma_t * scale (baked in, ``scale`` 1; one channel while
  both are achromatic), built in memory (``mi.VolumeGrid`` of the (z, y, x, c) array: Mitsuba's
  order), with our grid's ``to_world`` and filter; both take the edge texels beyond the outer texel
  centres (``clamp``, Dr.Jit's texel centres at (i + 1/2) / n as ours) and are vacuum outside the
  grid's box.  Our ``outside = "zero"`` (pbrt-v4's) is the same with ``nearest`` filtering and is
  refused with ``trilinear`` (Mitsuba has no such wrap mode).  Mitsuba's heterogeneous majorant is
  one number (``scale`` times the grid's maximum, or our ``max_value`` times the largest sigma_t)
  where ours is per channel (an explicit ``majorant`` of ours is not exported): the same expectation,
  other noise.  An albedo grid is the ``albedo`` volume.  Phase: ``isotropic`` or ``hg`` with our g.
  A constant sigma_t is an ``srgb`` spectrum with ``unbounded`` (load_dict's ``rgb`` refuses values
  over 1).  Media are top-level objects referenced by id: a shape's medium interface gives its ``interior`` / ``exterior`` (the exterior on the side
  its normal faces, as ours; a side that is vacuum has none, and a shape that is no medium
  transition has neither, keeping the ray's medium in both renderers); an index-matched shape's
  BSDF is ``null``; the camera's medium is the sensor's ``medium``.  The meshes are written per
  (material, interface) pair.
"""
from __future__ import annotations

import json
import os
import tempfile
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from ..render.settings import ImageSettings


def scene_arrays(scene, settings: ImageSettings | None = None, spp=None) -> dict:
    """Plain arrays and numbers describing ``scene`` rendered with ``settings`` (default: the
    scene's own) and ``spp`` samples per pixel, for :func:`dict_from_arrays`."""
    from ..render.settings import ImageSettings  # here, not at the top: see the module docstring
    from ..scene.instances import flattened
    from ..scene.shapes import bounds as shape_bounds, shape_type

    settings = settings or ImageSettings.resolve(scene)
    scene = flattened(scene)  # two-level instances: the moved copies the kernels draw
    for m in scene.materials:
        if m.is_emissive and m.two_sided:
            raise ValueError(f"material {m.name!r}: Mitsuba 3 has no two-sided area emitter")
    for has, what in (("has_shading_normals", "shading normals"), ("has_normal_maps", "normal and bump maps"),
                      ("has_vertex_colors", "vertex colours")):
        if getattr(scene, has, lambda: False)():
            raise ValueError(f"{what} are not exported to Mitsuba yet (the meshes are written flat, face_normals)")
    cam = scene.camera
    if getattr(scene, "camera_motion", None) is not None or any(i.moves for i in getattr(scene, "instances", ())):
        raise ValueError("motion blur (a moving camera or instance) is not exported to Mitsuba")
    arrays, materials = {}, []
    for index, m in enumerate(scene.materials):
        materials.append(_material_record(m, index, arrays))
    record = {
        "width": settings.width, "height": settings.height,
        "spp": int(spp or scene.settings.spp),
        "max_depth": settings.max_depth,
        "rr_depth": settings.rr_depth,
        "eye": [float(x) for x in cam.eye], "look_at": [float(x) for x in cam.look_at],
        "up": [float(x) for x in cam.up], "fov": float(cam.vertical_fov(settings.width, settings.height)),
        "projection": getattr(cam, "projection", "perspective"), "extent": float(getattr(cam, "extent", 2.0)),
        "filter": settings.filter.as_dict(),
        "materials": materials, "lights": [_light_record(light) for light in scene.lights],
        "environment": _environment_record(scene.environment, arrays),
        "media": _media_record(scene, arrays),
    }
    if len(scene.shapes):  # each analytic shape as its type writes it for Mitsuba, and their box
        lo, hi = shape_bounds(scene.shapes)
        record["shapes"] = [shape_type(code).to_mitsuba(p) for p, code in zip(scene.shapes["params"],
                                                                             scene.shapes["type"])]
        record["shape_box"] = [lo.min(0).tolist(), hi.max(0).tolist()]
    if any(m.get("textured") for m in materials):  # per-corner (u, v); none given: all 0, as ours
        arrays["uvs"] = (np.zeros((len(scene.faces), 3, 2), np.float32) if scene.uvs is None
                         else np.asarray(scene.uvs, np.float32).reshape(-1, 3, 2))
    return {
        "vertices": np.asarray(scene.vertices, np.float32),
        "faces": np.asarray(scene.faces, np.int32),
        "face_materials": np.asarray(scene.face_materials, np.int32),
        "shape_materials": np.asarray(scene.shape_materials, np.int32),
        "settings": json.dumps(record),
        **arrays,
    }


def _media_record(scene, arrays: dict) -> dict | None:
    """The media (grids into ``arrays``), the interfaces, the camera's medium and the integrator;
    with each face's and analytic shape's interface index in ``arrays``.  None without media."""
    if not scene.has_media():
        return None
    media = [_medium_record(m, i, arrays) for i, m in enumerate(scene.media)]
    interfaces = []
    for k, itf in enumerate(scene.interfaces):
        sides = (int(itf.interior), int(itf.exterior)) if itf.transition else (-1, -1)
        if itf.transition and sides == (-1, -1):  # Mitsuba: a shape with no medium is no transition
            raise ValueError(f"medium interface {k}: a transition to vacuum on both sides has no Mitsuba form")
        interfaces.append({"interior": sides[0], "exterior": sides[1], "null": bool(itf.null)})
    arrays["face_interfaces"] = np.asarray(scene.face_interface_array(), np.int32)
    arrays["shape_interfaces"] = np.asarray(scene.shape_interface_array(), np.int32)
    spectral_mis = bool(getattr(scene.settings, "spectral_mis", True)) and any(m.chromatic() for m in scene.media)
    return {"media": media, "interfaces": interfaces, "camera_medium": int(scene.camera_medium),
            "integrator": "volpathmis" if spectral_mis else "volpath"}


def _grid_record(grid, key: str, values, arrays: dict, what: str) -> dict:
    """A gridvolume's record: ``values`` (z, y, x, c) into ``arrays[key]``, the grid's box and filter."""
    if grid.outside == "zero" and grid.filter != "nearest":
        raise ValueError(f"{what}: a trilinear grid that fades to 0 beyond its edge texels (outside = \"zero\") has "
                         "no Mitsuba wrap mode (gridvolume clamps)")
    arrays[key] = np.ascontiguousarray(values, np.float32)
    return {"grid": key, "to_world": np.asarray(grid.to_world, np.float64).tolist(), "filter": grid.filter}


def _medium_record(m, index: int, arrays: dict) -> dict:
    """A medium's export (see the module docstring)."""
    rec = {"name": m.name, "sample_emitters": bool(m.sample_emitters),
           "phase": {"type": "hg", "g": float(m.phase.g)} if m.phase.type == "hg" else {"type": "isotropic"},
           "albedo": [float(x) for x in m.albedo]}
    if m.density is None:
        rec.update(type="homogeneous", sigma_t=[float(x) for x in m.sigma_t], scale=float(m.scale))
    else:
        ext, data = m.extinction(), m.density.data.astype(np.float64)
        values = data * ext[0] if data.shape[3] == 1 and np.ptp(ext) == 0 else data * ext
        sigma_t = _grid_record(m.density, f"medium_density_{index}", values, arrays, f"medium {m.name!r}")
        if m.density.max_value is not None:  # the majorant's maximum as ours takes it
            sigma_t["max_value"] = float(m.density.max_value * ext.max())
        rec.update(type="heterogeneous", sigma_t=sigma_t, scale=1.0)
    if m.albedo_grid is not None:
        rec["albedo"] = _grid_record(m.albedo_grid, f"medium_albedo_{index}", m.albedo_grid.data, arrays,
                                     f"medium {m.name!r}'s albedo")
    return rec


# the exported environment map's grid is finer than ours (see the module docstring) by the factor
# that gives it ENV_WIDTH columns or more, at most ENV_MAX_UPSAMPLE (4 for a 256-column map)
ENV_WIDTH = 1024
ENV_MAX_UPSAMPLE = 16


def _texture_ref(key: str) -> dict:
    """A Mitsuba bitmap texture of the array ``key`` (a file once :func:`dict_from_arrays` writes it)."""
    return {"type": "bitmap", "texture": key, "raw": True, "filter_type": "bilinear", "wrap_mode": "repeat"}


def _baked(texture, factor) -> np.ndarray:
    """Texels (RGB, linear) times the RGB factor they multiply in our kernels."""
    return np.ascontiguousarray(np.asarray(texture.texels, np.float32)[..., :3] * np.asarray(factor, np.float32))


def _material_record(m, index: int, arrays: dict) -> dict:
    """A material's export: its BSDF (``bsdf``; with ``bsdf_plain`` beside it when a texture is
    put in, for spheres), its emission and, where textured, the emission texture; texel arrays go
    into ``arrays``."""
    bsdf = m.mitsuba_bsdf()
    record = {"name": m.name, "bsdf": bsdf, "emission": [float(x) for x in m.emission],
              "directional": bool(m.emission_directional)}
    if m.masked or m.one_sided:
        raise ValueError(f"material {m.name!r}: alpha cut-outs and one-sided materials are not exported to Mitsuba")
    for t in (m.base_texture, m.emission_texture):
        if t is not None and t.mapping != "uv":
            raise ValueError(f"material {m.name!r}: a {t.mapping} texture is not exported to Mitsuba")
        if t is not None and (t.wrap, t.filter, tuple(t.to_uv)) != ("repeat", "bilinear", (1, 0, 0, 0, 1, 0)):
            raise ValueError(f"material {m.name!r}: a texture looked up other than bilinearly, repeated and "
                             "untransformed is not exported to Mitsuba")
    if m.base_texture is not None and m.type != "conductor":  # a conductor's is inert in our kernels
        key = f"texture_base_{index}"
        if m.type == "diffuse":
            arrays[key] = _baked(m.base_texture, m.albedo)
            textured = {**bsdf, "material": {**bsdf["material"], "reflectance": _texture_ref(key)}}
        elif m.type == "dielectric":
            arrays[key] = _baked(m.base_texture, m.tint)
            textured = {**bsdf, "specular_reflectance": _texture_ref(key), "specular_transmittance": _texture_ref(key)}
        else:
            raise ValueError(f"material {m.name!r}: a {m.type} with a base texture is not exported to Mitsuba")
        record.update(bsdf=textured, bsdf_plain=bsdf, textured=True)
    if m.mr_texture is not None:
        raise ValueError(f"material {m.name!r}: a metallic-roughness texture is not exported to Mitsuba")
    if m.emission_texture is not None and m.is_emissive:
        key = f"texture_emission_{index}"
        arrays[key] = _baked(m.emission_texture, m.emission)
        record.update(emission_texture=key, textured=True)
    return record


def _light_record(light) -> dict:
    from ..scene.lights import light_type  # here: the Mitsuba runner loads this module without the package

    try:
        kind = light_type(light)
    except TypeError:
        raise ValueError(f"a {type(light).__name__} is not exported to Mitsuba") from None
    return kind.to_mitsuba(light)


def _environment_record(environment, arrays: dict) -> dict | None:
    if environment is None:
        return None
    if environment.image is None:
        return {"type": "constant", "radiance": [float(x) for x in environment.radiance]}
    arrays["envmap"], to_world = mitsuba_envmap(environment)
    return {"type": "envmap", "to_world": to_world.tolist()}


def mitsuba_envmap(environment, upsample=None) -> tuple[np.ndarray, np.ndarray]:
    """(image (H', W', 3) float32, to_world 3x3) of Mitsuba's ``envmap`` for our ``environment``
    (its RGB scale multiplied in).  A map whose rows lie on the poles is Mitsuba's own layout: its
    texels as they are, and the to_world that turns our frame into Mitsuba's (u turned by half a
    turn).  A map of centred rows is resampled: each of Mitsuba's texels is our interpolated map in
    the direction of its node, on a grid ``upsample`` times finer than ours (:data:`ENV_WIDTH`)."""
    from ..render.lights import environment_radiance

    img = np.maximum(np.nan_to_num(np.asarray(environment.image, np.float64)[:, :, :3], nan=0.0, posinf=0.0,
                                   neginf=0.0), 0.0)
    turn = np.diag([-1.0, 1.0, -1.0])  # Mitsuba's frame: ours turned half a turn about +y
    rotation = np.eye(3) if environment.rotation is None else np.asarray(environment.rotation, np.float64)
    if environment.rows == "poles":
        return (img * np.asarray(environment.radiance, np.float64)).astype(np.float32), rotation.T @ turn
    h, w = img.shape[:2]
    k = upsample or min(ENV_MAX_UPSAMPLE, max(1, -(-ENV_WIDTH // w)))
    out_w, out_h = k * w, max(3, k * h)
    # the nodes on the poles take our map's limit there along their own azimuth
    v = np.clip(np.arange(out_h) / (out_h - 1), 1e-6, 1 - 1e-6)
    v, u = np.meshgrid(v, (np.arange(out_w) + 0.5) / out_w, indexing="ij")
    theta, phi = np.pi * v.ravel(), 2 * np.pi * u.ravel()
    local = np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], 1)
    texels = environment_radiance(environment, local)  # Mitsuba's identity to_world: its frame is the world's
    return texels.reshape(out_h, out_w, 3).astype(np.float32), np.eye(3)


def save_scene_npz(path, arrays: dict) -> None:
    np.savez(path, **{k: (np.array(v) if isinstance(v, str) else v) for k, v in arrays.items()})


def load_scene_npz(path) -> dict:
    with np.load(path) as z:
        out = {k: z[k] for k in z.files}
    out["settings"] = str(out["settings"])
    return out


def write_ply(path, vertices: np.ndarray, faces: np.ndarray, uvs: np.ndarray | None = None) -> None:
    """A binary little-endian PLY with float vertices (and texture coordinates ``uvs``, one per
    vertex, when given) and int triangle indices."""
    v = np.ascontiguousarray(vertices, "<f4").reshape(-1, 3)
    if uvs is not None:
        v = np.ascontiguousarray(np.concatenate([v, np.asarray(uvs, "<f4").reshape(-1, 2)], 1))
    f = np.ascontiguousarray(faces, "<i4")
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(v)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              + ("property float u\nproperty float v\n" if uvs is not None else "")
              + f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n").encode("ascii")
    rec = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rec["n"] = 3
    rec["i"] = f
    with open(path, "wb") as fh:
        fh.write(header)
        fh.write(v.tobytes())
        fh.write(rec.tobytes())


def dict_from_arrays(arrays: dict, mi, tmpdir=None) -> dict:
    """The ``mi.load_dict`` dict of :func:`scene_arrays` output; meshes go to PLY files in tmpdir."""
    s = json.loads(arrays["settings"]) if isinstance(arrays["settings"], str) else arrays["settings"]
    tmpdir = tmpdir or tempfile.mkdtemp(prefix="pyopencl_rt_mi_")
    T = mi.ScalarTransform4f
    near = 1e-3 * _scene_scale(arrays)
    if s.get("projection", "perspective") == "orthographic":
        sensor = {"type": "orthographic", "to_world": T(_orthographic_to_world(s, near).tolist())}
    else:
        sensor = {"type": "perspective", "fov": float(s["fov"]), "fov_axis": "y",
                  "to_world": T.look_at(origin=s["eye"], target=s["look_at"], up=s["up"])}
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": int(s["max_depth"]), "rr_depth": int(s["rr_depth"])},
        "sensor": {
            **sensor, "near_clip": near, "far_clip": 1e3 * _scene_scale(arrays),
            "sampler": {"type": "independent", "sample_count": int(s["spp"])},
            "film": {"type": "hdrfilm", "width": int(s["width"]), "height": int(s["height"]),
                     "rfilter": mitsuba_rfilter(s.get("filter", {"type": "box"})), "pixel_format": "rgb"},
        },
    }
    media = s.get("media")
    if media:
        d["integrator"]["type"] = media["integrator"]
        for i, m in enumerate(media["media"]):
            d[f"medium_{i}"] = _mitsuba_medium(m, arrays, mi)
        if media["camera_medium"] >= 0:
            d["sensor"]["medium"] = {"type": "ref", "id": f"medium_{media['camera_medium']}"}
    interfaces = media["interfaces"] if media else []

    def with_interface(shape, k):
        """``shape`` bounding the media of interface ``k`` (-1: none): a null BSDF where index-matched."""
        if k < 0:
            return shape
        itf = interfaces[k]
        if itf["null"]:
            shape = {**shape, "bsdf": {"type": "null"}}
            shape.pop("emitter", None)
        for side in ("interior", "exterior"):
            if itf[side] >= 0:
                shape[side] = {"type": "ref", "id": f"medium_{itf[side]}"}
        return shape

    mats = s["materials"]
    files = {}

    def bitmap_file(key):
        """The array ``key`` written once as a float OpenEXR in tmpdir."""
        if key not in files:
            files[key] = os.path.join(tmpdir, f"{key}.exr")
            mi.Bitmap(np.ascontiguousarray(arrays[key], np.float32)).write(files[key])
        return files[key]

    def resolved(value):
        """``value`` with every texture reference of :func:`_texture_ref` made a file name."""
        if isinstance(value, dict):
            out = {k: resolved(v) for k, v in value.items() if k != "texture"}
            if "texture" in value:
                out["filename"] = bitmap_file(value["texture"])
            return out
        return value

    def emitter(m, textured=True):
        key = m.get("emission_texture") if textured else None
        radiance = resolved(_texture_ref(key)) if key else {"type": "rgb", "value": m["emission"]}
        return {"type": "directionalarea" if m.get("directional") else "area", "radiance": radiance}

    verts, faces, fmat = arrays["vertices"], arrays["faces"], arrays["face_materials"]
    fif = arrays.get("face_interfaces", np.full(len(fmat), -1, np.int32))
    uvs = arrays.get("uvs")
    for mi_index, k in np.unique(np.stack([fmat, fif], 1).reshape(-1, 2), axis=0):
        m = mats[int(mi_index)]
        in_material = (fmat == mi_index) & (fif == k)
        sel = faces[in_material]
        name = f"mesh_{int(mi_index)}" if k < 0 else f"mesh_{int(mi_index)}_interface_{int(k)}"
        path = os.path.join(tmpdir, f"{name}.ply")
        if m.get("textured") and uvs is not None:  # a vertex per corner, with the corner's (u, v)
            write_ply(path, verts[sel.ravel()], np.arange(3 * len(sel)).reshape(-1, 3), uvs[in_material].reshape(-1, 2))
        else:
            used, local = np.unique(sel.ravel(), return_inverse=True)
            write_ply(path, verts[used], local.reshape(-1, 3))
        shape = {"type": "ply", "filename": path, "face_normals": True, "bsdf": resolved(m["bsdf"])}
        if max(m["emission"]) > 0:
            shape["emitter"] = emitter(m)
        d[name] = with_interface(shape, int(k))
    sif = arrays.get("shape_interfaces", np.full(len(arrays["shape_materials"]), -1, np.int32))
    for i, (mitsuba_shape, mi_index) in enumerate(zip(s.get("shapes", []), arrays["shape_materials"])):
        m = mats[int(mi_index)]  # no texture coordinates on our analytic shapes: the factors alone
        shape = {**mitsuba_shape, "bsdf": m.get("bsdf_plain", m["bsdf"])}
        if "to_world" in shape:  # rows of a 4 x 4 matrix (a disk's)
            shape["to_world"] = T(shape["to_world"])
        if max(m["emission"]) > 0:
            shape["emitter"] = emitter(m, textured=False)
        d[f"shape_{i}"] = with_interface(shape, int(sif[i]))
    for i, light in enumerate(s.get("lights", [])):
        if light["type"] == "point":
            d[f"light_{i}"] = {"type": "point", "position": light["position"],
                               "intensity": {"type": "rgb", "value": light["intensity"]}}
        elif light["type"] == "spot":
            d[f"light_{i}"] = {"type": "spot", "to_world": T(light["to_world"]),
                               "intensity": {"type": "rgb", "value": light["intensity"]},
                               "cutoff_angle": light["cutoff_angle"], "beam_width": light["beam_width"]}
        elif light["type"] == "projector":
            d[f"light_{i}"] = {"type": "projector", "to_world": T(light["to_world"]), "fov": light["fov"],
                               "irradiance": {"type": "rgb", "value": light["irradiance"]}, "scale": light["scale"]}
        else:
            d[f"light_{i}"] = {"type": "directional", "direction": light["direction"],
                               "irradiance": {"type": "rgb", "value": light["irradiance"]}}
    environment = s.get("environment")
    if environment and environment["type"] == "constant":
        d["environment"] = {"type": "constant", "radiance": {"type": "rgb", "value": environment["radiance"]}}
    elif environment:
        to_world = np.eye(4)
        to_world[:3, :3] = environment.get("to_world", np.eye(3))
        d["environment"] = {"type": "envmap", "filename": bitmap_file("envmap"), "to_world": T(to_world.tolist())}
    return d


def _mitsuba_medium(m: dict, arrays: dict, mi) -> dict:
    """Mitsuba's medium dict of a record of :func:`_medium_record` (grids built in memory)."""
    T = mi.ScalarTransform4f

    def value(v, unbounded=False):
        if isinstance(v, dict):  # a grid
            vol = {"type": "gridvolume", "grid": mi.VolumeGrid(np.ascontiguousarray(arrays[v["grid"]], np.float32)),
                   "filter_type": v["filter"], "wrap_mode": "clamp", "to_world": T(v["to_world"])}
            if "max_value" in v:
                vol["max_value"] = float(v["max_value"])
            return vol
        if unbounded:  # the srgb plugin itself: load_dict's "rgb" has no "unbounded" (and refuses values over 1)
            return {"type": "srgb", "color": [float(x) for x in v], "unbounded": True}
        return {"type": "rgb", "value": [float(x) for x in v]}

    phase = {"type": "hg", "g": m["phase"]["g"]} if m["phase"]["type"] == "hg" else {"type": "isotropic"}
    return {"type": m["type"], "sigma_t": value(m["sigma_t"], unbounded=True), "albedo": value(m["albedo"]),
            "scale": float(m["scale"]), "sample_emitters": bool(m["sample_emitters"]), "phase": phase}


def mitsuba_rfilter(flt: dict) -> dict:
    """Mitsuba 3's rfilter for our pixel filter (PixelFilter.as_dict()); ValueError for one it has
    no equivalent of (its box is 1 pixel wide, its gaussian cut at 4 stddev, its mitchell 4 pixels
    wide, its lanczos as wide as its whole number of lobes; all the same along x and y)."""
    t = flt.get("type", "box")
    rx, ry = flt.get("radius", (0.5, 0.5))

    def close(a, b):
        return abs(a - b) <= 1e-6 * max(abs(a), abs(b), 1.0)

    if not close(rx, ry):
        raise ValueError(f"Mitsuba's filters have one radius: {t} of radii {rx:g}, {ry:g}")
    if t == "box" and close(rx, 0.5):
        return {"type": "box"}
    if t == "tent":
        return {"type": "tent", "radius": float(rx)}
    if t == "gaussian" and close(rx, 4 * flt["sigma"]):
        return {"type": "gaussian", "stddev": float(flt["sigma"])}
    if t == "mitchell" and close(rx, 2.0):
        return {"type": "mitchell", "B": float(flt["b"]), "C": float(flt["c"])}
    if t == "lanczos" and close(rx, flt["tau"]) and close(rx, round(rx)):
        return {"type": "lanczos", "lobes": int(round(rx))}
    raise ValueError(f"Mitsuba 3 has no {t} filter of radius {rx:g} (and these parameters): {flt}")


def _orthographic_to_world(s: dict, near: float) -> np.ndarray:
    """Mitsuba's look_at(origin, target, up) @ scale(h, h, 1) for our orthographic camera, h its half
    width, the origin near behind our eye (Mitsuba's rays start at near_clip along local z)."""
    eye, target, up = (np.asarray(s[k], np.float64) for k in ("eye", "look_at", "up"))
    forward = (target - eye) / np.linalg.norm(target - eye)
    left = np.cross(up, forward)
    left /= np.linalg.norm(left)
    half_width = s["extent"] / 2 * s["width"] / s["height"]
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = left * half_width, np.cross(forward, left) * half_width, forward
    m[:3, 3] = eye - near * forward
    return m


def _scene_scale(arrays) -> float:
    pts = [np.asarray(arrays["vertices"], np.float64).reshape(-1, 3)]
    box = json.loads(arrays["settings"]).get("shape_box")
    if box is not None:
        pts.append(np.asarray(box, np.float64))
    pts.append(np.asarray([json.loads(arrays["settings"])["eye"]], np.float64))
    allp = np.concatenate(pts)
    return float(max(np.ptp(allp, axis=0).max(), 1e-6))


def to_mitsuba_dict(scene, settings: ImageSettings | None = None, spp=None, tmpdir=None) -> dict:
    """``mi.load_dict`` input for ``scene`` (needs ``import mitsuba`` to work in this process,
    with a variant set)."""
    import mitsuba as mi

    return dict_from_arrays(scene_arrays(scene, settings, spp), mi, tmpdir)
