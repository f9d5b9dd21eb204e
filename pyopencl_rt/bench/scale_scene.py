"""Write the scene of issue 35: one height-field grid mesh of about N triangles as a binary
little-endian PLY (float32 x y z, uchar-counted int32 vertex_indices, no normals: both renderers
compute the angle-weighted vertex normals) and a Mitsuba 3 XML that references it, with a
rectangular area light above it and a constant environment.

    python tools/scale_scene.py OUTDIR --triangles 2e6 [--width 256 --height 256 --spp 16]
    python -m pyopencl_rt.bench.scale_scene OUTDIR ...      (the same)

writes OUTDIR/heightfield_<N>.ply and OUTDIR/heightfield_<N>.xml and prints the XML's path.
With ``--textured``, the textured variant of issue 34's benchmark set: the PLY also holds texture
coordinates (u, v over the grid), is flat-shaded and two-sided, and the ground's reflectance is a 1024 x 1024 image
(OUTDIR/heightfield_texture.png: bands and a checker, deterministic), in
OUTDIR/heightfield_textured_<N>.{ply,xml}.
The grid has k x k quads (k = round(sqrt(N / 2))), so 2 k^2 triangles; the heights are a sum of
sines (deterministic: the same file on every machine).  ``pyopencl-rt bench scale``
(:mod:`.scale`) writes its scenes with :func:`write_scene`."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def grid_size(triangles: float) -> int:
    """Quads along each side of the grid of about ``triangles`` triangles."""
    return max(1, int(round(np.sqrt(float(triangles) / 2.0))))


def heightfield(k: int) -> tuple[np.ndarray, np.ndarray]:
    """((k+1)^2, 3) float32 vertices over [-1, 1]^2 (z up, heights in about [-0.15, 0.15]) and
    (2 k^2, 3) int32 faces, counter-clockwise seen from +z."""
    t = np.linspace(-1.0, 1.0, k + 1, dtype=np.float64)
    x, y = np.meshgrid(t, t, indexing="xy")
    z = 0.08 * np.sin(7.0 * x) * np.cos(5.0 * y) + 0.04 * np.sin(23.0 * x + 17.0 * y) + 0.03 * np.cos(41.0 * np.hypot(x, y))
    vertices = np.stack([x, y, z], -1).reshape(-1, 3).astype(np.float32)
    i = np.arange(k, dtype=np.int64)
    a = (i[:, None] * (k + 1) + i[None, :]).reshape(-1)  # lower-left corner of each quad (row-major)
    b, c, d = a + 1, a + k + 2, a + k + 1
    faces = np.empty((2 * len(a), 3), np.int32)
    faces[0::2] = np.stack([a, b, c], 1)
    faces[1::2] = np.stack([a, c, d], 1)
    return vertices, faces


def write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray | None = None) -> None:
    """Binary little-endian PLY: float x, y, z (and u, v); list uchar int vertex_indices."""
    texcoords = "property float u\nproperty float v\n" if uv is not None else ""
    header = (f"ply\nformat binary_little_endian 1.0\ncomment pyopencl_rt tools/scale_scene.py\n"
              f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n{texcoords}"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n").encode("ascii")
    if uv is not None:
        vertices = np.concatenate([vertices, uv], 1)
    rec = np.empty(len(faces), np.dtype([("n", "u1"), ("i", "<i4", (3,))]))
    rec["n"] = 3
    rec["i"] = faces
    with open(path, "wb") as fh:
        fh.write(header)
        fh.write(np.ascontiguousarray(vertices, "<f4").tobytes())
        fh.write(rec.tobytes())


XML = """<scene version="3.0.0">
    <integrator type="path"><integer name="max_depth" value="8"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, -2.6, 2.2" target="0, 0, 0" up="0, 0, 1"/></transform>
        <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
        <film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/>
            <rfilter type="box"/></film>
    </sensor>
    <shape type="ply">
        <string name="filename" value="{ply}"/>{ply_options}
        {bsdf}
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="0.4"/><rotate x="1" angle="180"/><translate value="0.3, -0.2, 1.5"/></transform>
        <emitter type="area"><rgb name="radiance" value="12, 11, 10"/></emitter>
    </shape>
    <emitter type="constant"><rgb name="radiance" value="0.3, 0.35, 0.4"/></emitter>
</scene>
"""


TEXTURE = "heightfield_texture.png"


def texture_image(n: int = 1024) -> np.ndarray:
    """(n, n, 3) uint8: earthy bands along v crossed by a fine checker, so that a texel's colour
    changes within a few pixels of a 256 x 256 image (texture lookups and their variance matter)."""
    t = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(t, t, indexing="xy")
    band = 0.5 + 0.5 * np.sin(2 * np.pi * (9 * v + 0.3 * np.sin(2 * np.pi * 3 * u)))
    checker = ((np.floor(64 * u) + np.floor(64 * v)) % 2)[..., None]
    rgb = np.stack([0.45 + 0.4 * band, 0.35 + 0.3 * band, 0.2 + 0.15 * (1 - band)], -1) * (0.75 + 0.25 * checker)
    return np.clip(np.round(255 * rgb), 0, 255).astype(np.uint8)


def write_scene(outdir, triangles: float, width: int = 256, height: int = 256, spp: int = 16,
                textured: bool = False) -> Path:
    """Writes the PLY and the XML of about ``triangles`` triangles into ``outdir`` (reusing a PLY
    and a texture already there); returns the XML's path."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    k = grid_size(triangles)
    stem = f"heightfield_{'textured_' if textured else ''}{2 * k * k}"
    ply = outdir / f"{stem}.ply"
    if not ply.exists():
        vertices, faces = heightfield(k)
        uv = (vertices[:, :2] + 1.0) / 2.0 if textured else None
        tmp = ply.with_suffix(".ply.part")
        write_ply(tmp, vertices, faces, uv)
        tmp.replace(ply)
    bsdf = '<bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.55, 0.5"/></bsdf>'
    ply_options = ""
    if textured:
        if not (outdir / TEXTURE).exists():
            from PIL import Image

            Image.fromarray(texture_image()).save(outdir / TEXTURE)
        # flat-shaded (face normals) and two-sided: the benchmark set's export to Mitsuba writes
        # triangles without vertex normals and two-sided BSDFs (a million triangles hide the
        # facets, and the camera sees the top side only)
        bsdf = (f'<bsdf type="twosided"><bsdf type="diffuse"><texture type="bitmap" name="reflectance">'
                f'<string name="filename" value="{TEXTURE}"/></texture></bsdf></bsdf>')
        ply_options = '\n        <boolean name="face_normals" value="true"/>'
    xml = outdir / f"{stem}.xml"
    xml.write_text(XML.format(ply=ply.name, width=int(width), height=int(height), spp=int(spp),
                              bsdf=bsdf, ply_options=ply_options))
    return xml


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("outdir")
    ap.add_argument("--triangles", type=float, default=2e6, help="about this many triangles (default 2e6)")
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--height", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--textured", action="store_true", help="texture coordinates and an image as the reflectance")
    a = ap.parse_args(argv)
    print(write_scene(a.outdir, a.triangles, a.width, a.height, a.spp, a.textured))
    return 0


if __name__ == "__main__":
    sys.exit(main())
