"""Test meshes and ray sets shared by the traversal tests (deterministic)."""
import numpy as np
import trimesh


def icosphere():
    m = trimesh.creation.icosphere(subdivisions=5)
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32)


def torus():
    m = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=160, minor_sections=64)
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32)


def soup(n=20_000, seed=3):
    rng = np.random.default_rng(seed)
    c = rng.uniform(-1, 1, (n, 1, 3))
    v = (c + rng.normal(scale=0.05, size=(n, 3, 3))).reshape(-1, 3)
    return v.astype(np.float32), np.arange(3 * n, dtype=np.int32).reshape(-1, 3)


def slivers():
    """A finely divided, very long cylinder: every triangle is a sliver of aspect ratio ~1e4,
    and many of them share each long edge and each end vertex (fans at the caps)."""
    m = trimesh.creation.cylinder(radius=0.01, height=100.0, sections=256)
    v = np.asarray(m.vertices, np.float64)
    v[:, 2] *= 0.1  # height 10, radius 0.01: still 1e3 : 1
    return v.astype(np.float32), np.asarray(m.faces, np.int32)


def grid(nx=200, ny=200):
    """A bumpy height field of 2*nx*ny triangles sharing every interior edge and vertex."""
    x, y = np.meshgrid(np.linspace(-1, 1, nx + 1), np.linspace(-1, 1, ny + 1))
    z = 0.1 * np.sin(3 * x) * np.cos(2 * y)
    v = np.stack([x, y, z], -1).reshape(-1, 3)
    i = np.arange(nx)[None, :] + (nx + 1) * np.arange(ny)[:, None]
    i = i.ravel()
    f = np.concatenate([np.stack([i, i + 1, i + nx + 2], 1), np.stack([i, i + nx + 2, i + nx + 1], 1)])
    return v.astype(np.float32), f.astype(np.int32)


MESHES = {"icosphere": icosphere, "torus": torus, "soup": soup, "slivers": slivers, "grid": grid}


def coherent_rays(vertices, n):
    from pyopencl_rt.bench.workloads import primary_rays

    bounds = np.stack([vertices.min(0), vertices.max(0)]).astype(np.float64)
    return primary_rays(bounds, n)


def incoherent_rays(vertices, faces, n, rng):
    """Half the rays start at random points of the scene box, half are aimed at random points of
    triangle edges and vertices (the cases watertightness is about); all directions random."""
    lo, hi = vertices.min(0).astype(np.float64), vertices.max(0).astype(np.float64)
    ext = hi - lo
    half = n // 2
    o1 = lo - 0.1 * ext + rng.random((half, 3)) * 1.2 * ext
    d1 = rng.normal(size=(half, 3))
    tri = vertices[faces[rng.integers(0, len(faces), n - half)]].astype(np.float64)
    k = rng.integers(0, 3, n - half)
    s = rng.random(n - half)
    s[: (n - half) // 4] = 0.0  # exactly at a vertex
    a = tri[np.arange(n - half), k]
    b = tri[np.arange(n - half), (k + 1) % 3]
    target = a + s[:, None] * (b - a)
    d2 = rng.normal(size=(n - half, 3))
    o2 = target - d2 * (np.linalg.norm(ext) * rng.uniform(0.2, 1.0, (n - half, 1)))
    o = np.concatenate([o1, o2]).astype(np.float32)
    d = np.concatenate([d1, d2]).astype(np.float32)
    return o, d


def ray_edge_distance(o, d, p):
    """float64: distance from each ray's line to the nearest edge segment of its triangle p
    (N x 3 x 3), relative to the magnitude of the coordinates involved: 1e-6 means "within a
    relative 1e-6 of an edge" (rounding a ray to float32 alone moves it by ~6e-8 of that)."""
    p = np.asarray(p, np.float64)
    oo = np.asarray(o, np.float64)
    dd = np.asarray(d, np.float64)
    dd = dd / np.linalg.norm(dd, axis=1, keepdims=True)
    best = np.full(len(p), np.inf)
    for k in range(3):
        a, e = p[:, k], p[:, (k + 1) % 3] - p[:, k]
        # closest points of the line o + t d and the segment a + s e, s in [0, 1]
        w = oo - a
        ee, de, dw, ew = np.sum(e * e, 1), np.sum(dd * e, 1), np.sum(dd * w, 1), np.sum(e * w, 1)
        denom = ee - de * de
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(denom > 1e-30 * ee, (ew - de * dw) / denom, 0.0)
        q = a + np.clip(s, 0.0, 1.0)[:, None] * e
        off = q - oo
        off -= np.sum(off * dd, 1)[:, None] * dd
        best = np.minimum(best, np.linalg.norm(off, axis=1))
    scale = np.abs(oo).max(1) + np.abs(p).max((1, 2)) + np.linalg.norm(p[:, 0] - oo, axis=1)
    return best / scale


def moller_trumbore(o, d, p):
    """float64 Möller–Trumbore of rays o + t d against triangles p (... x 3 x 3), broadcast
    (one ray against many triangles, or ray i against triangle i): (t, u, v, the smallest
    barycentric, i.e. how far inside the triangle the line passes).  Rays parallel to a
    triangle's plane give inf or NaN, without warnings."""
    o, d, p = (np.asarray(a, np.float64) for a in (o, d, p))
    e1, e2 = p[..., 1, :] - p[..., 0, :], p[..., 2, :] - p[..., 0, :]
    pvec = np.cross(d, e2)
    det = np.sum(e1 * pvec, -1)
    tvec = o - p[..., 0, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.sum(tvec * pvec, -1) / det
        qvec = np.cross(tvec, e1)
        v = np.sum(d * qvec, -1) / det
        t = np.sum(e2 * qvec, -1) / det
    return t, u, v, np.minimum(np.minimum(u, v), 1 - u - v)
