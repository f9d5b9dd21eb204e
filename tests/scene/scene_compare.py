"""Helpers of the scene importer tests (test_mitsuba_xml.py, test_pbrt.py): scenes compared
triangle by triangle, and rendered side by side with a tile z-test."""
from __future__ import annotations

import numpy as np

import pyopencl_rt as rt


def triangle_records(scene, skip_emissive=False, decimals=3):
    """Sorted (corners..., albedo, emission, material type) of every triangle: the scene up to
    the order of its triangles and materials."""
    out = []
    v = scene.vertices.astype(np.float64)
    for f, m in zip(scene.faces, scene.face_materials):
        mat = scene.materials[m]
        if skip_emissive and mat.is_emissive:
            continue
        corners = v[f]
        k = int(np.lexsort(corners.T[::-1])[0])  # the same triangle, whichever corner comes first
        corners = np.roll(corners, -k, axis=0)
        out.append(tuple(np.round(corners.ravel(), decimals)) + tuple(np.round(mat.albedo, 6)) +
                   tuple(np.round(mat.emission, 6)) + (mat.type,))
    return sorted(out)


def triangles_equal(a, b) -> bool:
    return len(a) == len(b) and all(x == y for x, y in zip(a, b))


def tile_z(a, b, tile=8):
    """z-scores of the tile means of two render results (independent noise)."""
    h, w = a.image.shape[:2]

    def tiles(x):
        return np.asarray(x, np.float64).reshape(h // tile, tile, w // tile, tile, 3).sum(axis=(1, 3)) / tile ** 2

    var = (tiles(a.film.variance_of_mean()) + tiles(b.film.variance_of_mean())) / tile ** 2
    return (tiles(a.image) - tiles(b.image)) / np.sqrt(var)


def render_pair_z(scene_a, scene_b, size=32, spp=256, flip_b=False):
    """Tile z-scores of ``scene_a`` against ``scene_b`` (seeds 1 and 2); with ``flip_b`` the
    second image is mirrored left to right first."""
    a = rt.render_full(scene_a, spp=spp, width=size, height=size, device="cpu", seed=1)
    b = rt.render_full(scene_b, spp=spp, width=size, height=size, device="cpu", seed=2)
    if flip_b:
        b.image = b.image[:, ::-1]
        b.film = mirrored_x(b.film)
    return tile_z(a, b)


class mirrored_x:
    """A film's variance_of_mean mirrored left to right."""

    def __init__(self, film):
        self.film = film

    def variance_of_mean(self):
        return self.film.variance_of_mean()[:, ::-1]


def write_exr_image(path, image):
    from pyopencl_rt.imageio import write_exr

    write_exr(path, np.asarray(image, np.float32))


def write_png_image(path, rgb8):
    from PIL import Image

    Image.fromarray(np.asarray(rgb8, np.uint8), "RGB").save(path)
