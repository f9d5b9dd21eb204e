"""Write the scene of issue 35: one height-field grid mesh of about N triangles as a binary
little-endian PLY (float32 x y z, uchar-counted int32 vertex_indices, no normals: both renderers
compute the angle-weighted vertex normals) and a Mitsuba 3 XML that references it, with a
rectangular area light above it and a constant environment.

    python tools/scale_scene.py OUTDIR --triangles 2e6 [--width 256 --height 256 --spp 16]
    python -m pyopencl_rt.bench.scale_scene OUTDIR ...      (the same)

writes OUTDIR/heightfield_<N>.ply and OUTDIR/heightfield_<N>.xml and prints the XML's path.
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


def write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Binary little-endian PLY: float x, y, z; list uchar int vertex_indices."""
    header = (f"ply\nformat binary_little_endian 1.0\ncomment pyopencl_rt tools/scale_scene.py\n"
              f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n").encode("ascii")
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
        <string name="filename" value="{ply}"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.6, 0.55, 0.5"/></bsdf>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="0.4"/><rotate x="1" angle="180"/><translate value="0.3, -0.2, 1.5"/></transform>
        <emitter type="area"><rgb name="radiance" value="12, 11, 10"/></emitter>
    </shape>
    <emitter type="constant"><rgb name="radiance" value="0.3, 0.35, 0.4"/></emitter>
</scene>
"""


def write_scene(outdir, triangles: float, width: int = 256, height: int = 256, spp: int = 16) -> Path:
    """Writes the PLY and the XML of about ``triangles`` triangles into ``outdir`` (reusing a PLY
    already there); returns the XML's path."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    k = grid_size(triangles)
    stem = f"heightfield_{2 * k * k}"
    ply = outdir / f"{stem}.ply"
    if not ply.exists():
        vertices, faces = heightfield(k)
        tmp = ply.with_suffix(".ply.part")
        write_ply(tmp, vertices, faces)
        tmp.replace(ply)
    xml = outdir / f"{stem}.xml"
    xml.write_text(XML.format(ply=ply.name, width=int(width), height=int(height), spp=int(spp)))
    return xml


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("outdir")
    ap.add_argument("--triangles", type=float, default=2e6, help="about this many triangles (default 2e6)")
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--height", type=int, default=256)
    ap.add_argument("--spp", type=int, default=16)
    a = ap.parse_args(argv)
    print(write_scene(a.outdir, a.triangles, a.width, a.height, a.spp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
