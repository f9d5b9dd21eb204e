"""pbrt-v4 shapes in object space: ``trianglemesh``, ``bilinearmesh`` (as triangles), ``plymesh``,
``loopsubdiv`` (Loop subdivision: subdivision.py), ``sphere`` (ours when whole and evenly scaled,
else triangles), ``disk`` and ``cylinder`` (ours, scene/shapes/, when whole, else triangles).

Texture coordinates become ours as (u, 1 - v): pbrt-v4's image textures look up (s, 1 - t) with
row 0 at the top of the image, ours (u, v) with row 0 at the top.

Shading normals: ``trianglemesh``'s ``normal N`` and a ``plymesh``'s vertex normals are
interpolated (cl/scene/shading.h); the triangles of a partial ``sphere`` and of a ``cylinder``
carry their surface's exact normal, as pbrt's analytic shapes shade; a ``disk`` is flat.
Geometry is (vertices, faces, per-corner uvs[, per-corner normals]).
"""
from __future__ import annotations

import numpy as np

from .builder import cylinder_mesh, disk_mesh, error_at, grid_mesh, sphere_mesh
from .pbrt import pbrt_file


def _flip_v(uv):
    if uv is None:
        return None
    uv = np.asarray(uv, np.float32).copy()
    uv[..., 1] = 1.0 - uv[..., 1]
    return uv


def _points(d, name="P", required=True):
    p = d.params
    values = p.numbers(name, ("point3", "point"))
    if values is None:
        if required:
            raise error_at(d.pos, f'Shape "{d.args[0]}" needs "point3 {name}"')
        return None
    if len(values) % 3:
        raise error_at(p.items[name].pos, f'"point3 {name}": {len(values)} numbers are not whole points')
    return np.asarray(values, np.float64).reshape(-1, 3)


def _indices(d, n_points, per, default_count):
    p = d.params
    values = p.numbers("indices", ("integer",))
    if values is None:
        if n_points != default_count:
            raise error_at(d.pos, f'Shape "{d.args[0]}" needs "integer indices" (it has {n_points} points)')
        return np.arange(per, dtype=np.int64).reshape(1, per)
    idx = np.asarray(values)
    if not np.all(idx == np.round(idx)):
        raise error_at(p.items["indices"].pos, '"integer indices" must be integers')
    idx = idx.astype(np.int64)
    if len(idx) % per:
        raise error_at(p.items["indices"].pos, f'"integer indices": {len(idx)} is not a multiple of {per}')
    if len(idx) and (idx.min() < 0 or idx.max() >= n_points):
        raise error_at(p.items["indices"].pos, f'"integer indices": an index outside [0, {n_points})')
    return idx.reshape(-1, per)


def _uvs(d, n_points):
    p = d.params
    values = p.numbers("uv", ("point2",))
    if values is None:
        return None
    uv = np.asarray(values, np.float64).reshape(-1, 2)
    if len(uv) != n_points:
        raise error_at(p.items["uv"].pos, f'"point2 uv": {len(uv)} coordinates for {n_points} points')
    return uv


def shape_geometry(imp, d):
    """('sphere', radius), (vertices, faces, per-corner uvs) or None (warned and skipped)."""
    t, p = d.args[0], d.params
    if t == "trianglemesh":
        v = _points(d)
        f = _indices(d, len(v), 3, 3)
        uv = _uvs(d, len(v))
        n = p.numbers("N", ("normal", "normal3"))
        normals = None
        if n is not None:
            if len(n) != 3 * len(v):
                raise error_at(p.items["N"].pos, f'"normal N": {len(n) // 3} normals for {len(v)} points')
            normals = _unit(np.asarray(n, np.float64).reshape(-1, 3))[f]
        return v, f, _flip_v(uv[f]) if uv is not None else None, normals
    if t == "bilinearmesh":
        return _bilinear(d)
    if t == "loopsubdiv":
        return _loopsubdiv(d)
    if t == "plymesh":
        return _plymesh(imp, d)
    if t == "sphere":
        radius = p.float("radius", 1.0)
        if not radius > 0:
            raise error_at(d.pos, f'Shape "sphere": radius must be > 0, got {radius:g}')
        zmin, zmax, phimax = p.float("zmin", -radius), p.float("zmax", radius), p.float("phimax", 360.0)
        if zmin > -radius or zmax < radius or phimax < 360:
            v, f, uv = sphere_mesh(radius, zmin, zmax, min(phimax, 360.0))
            return v, f, uv, _unit(np.asarray(v, np.float64))[f]
        return ("sphere", radius)
    if t == "disk":
        radius, inner, height = p.float("radius", 1.0), p.float("innerradius", 0.0), p.float("height", 0.0)
        phimax = min(p.float("phimax", 360.0), 360.0)
        if inner <= 0 and phimax >= 360 and radius > 0:
            return ("disk", radius, height)  # a full disk: our analytic one (scene/shapes/disk.py)
        return disk_mesh(radius, inner, height, phimax)
    if t == "cylinder":
        radius, zmin, zmax = p.float("radius", 1.0), p.float("zmin", -1.0), p.float("zmax", 1.0)
        phimax = min(p.float("phimax", 360.0), 360.0)
        if phimax >= 360 and radius > 0 and zmax > zmin:
            return ("cylinder", radius, zmin, zmax)  # a full tube: our analytic one (scene/shapes/cylinder.py)
        return cylinder_triangles(radius, zmin, zmax, phimax)
    raise error_at(d.pos, f'Shape "{t}": shape type "{t}" is not supported')


def cylinder_triangles(radius, zmin, zmax, phimax=360.0):
    """pbrt's cylinder as triangles with their exact radial normals (the geometry of shape_geometry)."""
    v, f, uv = cylinder_mesh(radius, zmin, zmax, phimax)
    return v, f, uv, _unit(np.asarray(v, np.float64) * [1.0, 1.0, 0.0])[f]


def _loopsubdiv(d):
    """``levels`` (default 3, as pbrt-v4) of Loop subdivision of the control mesh ``P`` /
    ``indices``, its vertices on the limit surface and its shading normals from the limit
    tangents, as pbrt-v4 computes both (subdivision.py)."""
    from .subdivision import SubdivisionError, limit_normals, loop_subdivide

    levels = d.params.integer("levels", 3)
    if levels < 0:
        raise error_at(d.params.items["levels"].pos, f'Shape "loopsubdiv": levels must be >= 0, got {levels}')
    if levels > 8:  # 4^levels triangles per control triangle
        raise error_at(d.params.items["levels"].pos, f'Shape "loopsubdiv": {levels} levels would make '
                       f'{4 ** levels} triangles of each control triangle (at most 8 levels)')
    v = _points(d)
    f = _indices(d, len(v), 3, 3)
    try:
        v, f = loop_subdivide(v, f, levels)
    except SubdivisionError as exc:
        raise error_at(d.pos, f'Shape "loopsubdiv": {exc}') from None
    return v, f, None, limit_normals(v, f).astype(np.float32)[f]


def _unit(n) -> np.ndarray:
    """Rows made unit length (0 where they have none)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        u = n / np.linalg.norm(n, axis=-1, keepdims=True)
    return np.nan_to_num(u, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32)


def _bilinear(d):
    """Each patch (p00, p10, p01, p11) as triangles (p00, p10, p11), (p00, p11, p01), whose front
    is pbrt's dp/du x dp/dv; a patch that is not flat is cut into an 8 x 8 grid first."""
    v = _points(d)
    patches = _indices(d, len(v), 4, 4)
    uv = _uvs(d, len(v))
    parts = []
    for patch in patches:
        p00, p10, p01, p11 = v[patch]
        uv4 = uv[patch] if uv is not None else np.array([[0, 0], [1, 0], [0, 1], [1, 1]], np.float64)
        normal = np.cross(p10 - p00, p01 - p00)
        size = max(np.linalg.norm(p10 - p00), np.linalg.norm(p01 - p00), 1e-300)
        flat = abs(np.dot(p11 - p00, normal)) <= 1e-6 * size * max(np.linalg.norm(normal), 1e-300)
        n = 1 if flat else 8

        def lerp(corners, s, t):
            c00, c10, c01, c11 = (np.asarray(c, np.float64) for c in corners)
            s, t = s[:, None], t[:, None]
            return (1 - s) * (1 - t) * c00 + s * (1 - t) * c10 + (1 - s) * t * c01 + s * t * c11

        pv, pf, puv = grid_mesh(lambda s, t: lerp((p00, p10, p01, p11), s, t), n, n)
        grid_uv = lerp(uv4, puv[..., 0].ravel(), puv[..., 1].ravel()).reshape(-1, 3, 2)
        parts.append((pv, pf, grid_uv))
    offsets = np.cumsum([0] + [len(x[0]) for x in parts[:-1]])
    vs = np.concatenate([x[0] for x in parts])
    fs = np.concatenate([x[1] + o for x, o in zip(parts, offsets)])
    uvs = np.concatenate([x[2] for x in parts]) if uv is not None else None
    return vs, fs, _flip_v(uvs)


def _plymesh(imp, d):
    from ..mesh import MeshError, flatten, load_trimesh
    from .meshfile import ply_extras, trimesh_uvs

    p = d.params
    fname, path = pbrt_file(d, imp.path.parent, 'Shape "plymesh"')
    if "edgelength" in p:
        p.items["edgelength"].used = True  # read with a displacement; pbrt ignores it without one
    try:
        if path.suffix.lower() == ".gz":  # pbrt-v4 reads .ply.gz through gzip
            loaded = _gzipped_mesh(path, d.pos)
        else:
            loaded = load_trimesh(path)
        v, f = flatten(loaded, name=str(path))
    except MeshError as exc:
        raise error_at(d.pos, f'Shape "plymesh": {exc}') from None
    if len(f) == 0:
        raise error_at(d.pos, f"Shape \"plymesh\": '{fname}' contains no triangles")
    v, f, uv, normals = np.asarray(v, np.float64), np.asarray(f, np.int64), trimesh_uvs(loaded, v, f), \
        ply_extras(loaded, f).normals
    if "displacement" in p:
        return _displaced(imp, d, v, f, uv, normals)
    return v, f, uv, normals


def _displaced(imp, d, v, f, uv, normals):
    """pbrt-v4's displaced plymesh (scene/displacement.py): refined to edges under "edgelength" (default
    1) in the world, each vertex moved along its normal by the float texture "displacement" at its uv
    (channels averaged, as pbrt's float image textures), normals recomputed.  -> (v, f, per-corner uv,
    per-corner normals)."""
    from ..displacement import displace
    from ..textures import Texture, lookup

    p = d.params
    q = p.items["displacement"]
    q.used = True
    if q.type != "texture":
        raise error_at(q.pos, 'Shape "plymesh": "displacement" must name a float texture ("texture displacement")')
    rgb, tex = imp.materials.color(p, "displacement", (0.0, 0.0, 0.0))
    if tex is not None and (not isinstance(tex, Texture) or tex.mapping != "uv"):
        kind = "directionmix" if not isinstance(tex, Texture) else f"{tex.mapping}-mapped"
        raise error_at(q.pos, f'Shape "plymesh": a {kind} displacement texture is not supported (uv only)')
    edge = p.float("edgelength", 1.0)
    if not edge > 0:
        raise error_at(p.items["edgelength"].pos, f'Shape "plymesh": edgelength must be > 0, got {edge:g}')
    if uv is None:
        raise error_at(d.pos, 'Shape "plymesh": a displacement needs the mesh\'s vertex uvs (as pbrt-v4)')
    scale = float(np.mean(rgb))
    corners = f.reshape(-1)
    uv_v = np.zeros((len(v), 2))
    uv_v[corners] = np.asarray(uv, np.float64).reshape(-1, 2)
    n_v = None
    if normals is not None:
        n_v = np.zeros((len(v), 3))
        n_v[corners] = np.asarray(normals, np.float64).reshape(-1, 3)
    if tex is None:
        def height(points):
            return np.full(len(points), scale)
    else:
        grey = tex.texels[..., :3].astype(np.float64).mean(axis=-1, keepdims=True)

        def height(points):
            return scale * lookup(grey, points, tex.wrap, tex.filter, tex.to_uv)[:, 0]
    try:
        v, f, uv_v, n_v = displace(v, f, uv_v, n_v, imp.state.ctm[:3, :3], edge, height)
    except ValueError as exc:
        raise error_at(d.pos, f'Shape "plymesh": displacement: {exc}') from None
    return v, f, uv_v[f].astype(np.float32), n_v[f].astype(np.float32)


def _gzipped_mesh(path, pos):
    """trimesh's reading of a gzip-compressed mesh (``x.ply.gz``), decompressed to a temporary
    ``x.ply`` first."""
    import tempfile
    from pathlib import Path

    from ..mesh import MeshError, load_trimesh
    from .pbrt import gunzip

    data = gunzip(path.read_bytes(), f'{pos}: Shape "plymesh": {path}')
    with tempfile.TemporaryDirectory() as folder:
        plain = Path(folder) / path.stem  # x.ply.gz -> x.ply
        plain.write_bytes(data)
        try:
            loaded = load_trimesh(plain)
        except MeshError as exc:  # named as the file the scene names
            raise MeshError(str(exc).replace(str(plain), str(path))) from None
    return loaded
