"""Writes the files of scenes/textured-sky.toml (made for this project; licence: the project's).

* ``sky.exr``: an equirectangular environment map (256 x 128, half-float RGB, our layout: row 0 up,
  u = 0.5 looking along -z, docs/SCENE_FORMAT.md) of a sky gradient, zenith blue to a pale horizon,
  a darker ground below the horizon, and a sun-like bright spot 40 degrees up behind the camera's
  right shoulder (a Gaussian of 2 degrees, peak radiance 900: about as much irradiance as the sky);
* ``checker.png``, ``bricks.png``, ``globe.png``: 8-bit sRGB textures (a floor checker, bricks, a
  globe of coloured meridian sectors and latitude bands, none of them symmetric under a flip);
* ``box.obj``, ``globe.obj``: a unit cube with a planar map per face and a UV sphere (32 x 16), with
  texture coordinates (OBJ's v upwards).

Every value is computed here; nothing is copied.  Run: python scenes/textured-sky/make_assets.py
"""
from pathlib import Path

import numpy as np
from PIL import Image

HERE = Path(__file__).resolve().parent
SUN_ELEVATION, SUN_AZIMUTH = 40.0, 35.0  # degrees; azimuth from +z (towards the camera) to +x
SUN_SIGMA, SUN_PEAK = 2.0, 900.0  # degrees; radiance at the centre


def our_directions(height, width):
    """Directions of the texel centres of our equirectangular layout (cl/render/lights.h)."""
    v, u = np.meshgrid((np.arange(height) + 0.5) / height, (np.arange(width) + 0.5) / width, indexing="ij")
    theta, phi = np.pi * v, 2 * np.pi * u
    return np.stack([-np.sin(theta) * np.sin(phi), np.cos(theta), np.sin(theta) * np.cos(phi)], -1)


def sky(height=128, width=256):
    d = our_directions(height, width)
    y = d[..., 1:2]
    zenith, horizon, ground = np.array([0.18, 0.36, 0.85]), np.array([0.95, 0.95, 1.0]), np.array([0.22, 0.19, 0.16])
    up = np.clip(y, 0.0, 1.0) ** 0.5
    rgb = np.where(y >= 0, horizon * (1 - up) + zenith * up, ground * (0.6 + 0.4 * np.exp(8 * np.minimum(y, 0))))
    el, az = np.radians(SUN_ELEVATION), np.radians(SUN_AZIMUTH)
    sun = np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
    angle = np.degrees(np.arccos(np.clip(d @ sun, -1.0, 1.0)))
    rgb = rgb + SUN_PEAK * np.exp(-0.5 * (angle / SUN_SIGMA) ** 2)[..., None] * np.array([1.0, 0.93, 0.82])
    return rgb.astype(np.float32)


def write_exr(path, rgb):
    import OpenEXR

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": np.ascontiguousarray(rgb, np.float16)}) as f:
        f.write(str(path))


def checker(n=256, tiles=32):
    i, j = np.indices((n, n)) * tiles // n
    a = np.where(((i + j) % 2 == 0)[..., None], [205, 200, 190], [70, 75, 85])
    return a.astype(np.uint8)


def bricks(n=128):
    y, x = np.indices((n, n))
    row = y // 16
    xs = (x + (row % 2) * 16) % 32
    mortar = (y % 16 < 2) | (xs < 2)
    shade = 0.85 + 0.15 * ((x // 32 + row * 3) % 4) / 3  # bricks of a few shades
    rgb = np.where(mortar[..., None], [200, 195, 185], np.array([160, 62, 40]) * shade[..., None])
    return rgb.astype(np.uint8)


def globe(h=128, w=256):
    y, x = np.indices((h, w))
    sectors = np.array([[200, 60, 50], [230, 190, 60], [60, 150, 80], [50, 90, 190]])[(x * 4) // w]
    band = (y // 16) % 2 == 0
    rgb = np.where(band[..., None], sectors, sectors * 0.45 + 90)
    rgb[: h // 8] = [235, 235, 240]  # a white cap on top only
    return rgb.astype(np.uint8)


def write_obj(path, vertices, uvs, faces):
    """OBJ with 'v' and 'vt' per vertex and faces 'f a/a b/b c/c' (1-based)."""
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in vertices]
    lines += [f"vt {u:.6f} {v:.6f}" for u, v in uvs]
    lines += [f"f {a}/{a} {b}/{b} {c}/{c}" for a, b, c in np.asarray(faces) + 1]
    Path(path).write_text("\n".join(lines) + "\n")


def cube():
    """A unit cube centred at the origin, 4 vertices per face, faces outwards, uv over each face."""
    vertices, uvs, faces = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            a, b = (axis + 1) % 3, (axis + 2) % 3  # e_a x e_b = e_axis
            if sign < 0:
                a, b = b, a  # keep the winding counter-clockwise seen from outside
            for s, t in ((0, 0), (1, 0), (1, 1), (0, 1)):
                p = np.zeros(3)
                p[axis], p[a], p[b] = 0.5 * sign, s - 0.5, t - 0.5
                vertices.append(p)
                uvs.append((s, t))
            n = len(vertices) - 4
            faces += [(n, n + 1, n + 2), (n, n + 2, n + 3)]
    return np.array(vertices), np.array(uvs, float), np.array(faces)


def uv_sphere(stacks=16, slices=32):
    """A unit sphere, v = 1 at the top (OBJ's convention), u around the y axis; faces outwards."""
    vertices, uvs = [], []
    for i in range(stacks + 1):
        theta = np.pi * i / stacks
        for j in range(slices + 1):
            phi = 2 * np.pi * j / slices
            vertices.append((np.sin(theta) * np.sin(phi), np.cos(theta), np.sin(theta) * np.cos(phi)))
            uvs.append((j / slices, 1.0 - i / stacks))
    faces = []
    for i in range(stacks):
        for j in range(slices):
            a, b = i * (slices + 1) + j, (i + 1) * (slices + 1) + j
            if i > 0:
                faces.append((a, b, a + 1))
            if i < stacks - 1:
                faces.append((a + 1, b, b + 1))
    return np.array(vertices), np.array(uvs), np.array(faces)


def main():
    write_exr(HERE / "sky.exr", sky())
    Image.fromarray(checker()).save(HERE / "checker.png")
    Image.fromarray(bricks()).save(HERE / "bricks.png")
    Image.fromarray(globe()).save(HERE / "globe.png")
    write_obj(HERE / "box.obj", *cube())
    write_obj(HERE / "globe.obj", *uv_sphere())
    for name in ("sky.exr", "checker.png", "bricks.png", "globe.png", "box.obj", "globe.obj"):
        print(f"{HERE / name}: {(HERE / name).stat().st_size} bytes")


if __name__ == "__main__":
    main()
