"""Mitsuba's binary volume grids (``.vol``, Mitsuba 0.6 and 3; src/render/volumegrid.cpp), little endian:

| bytes | content |
|---|---|
| 1-3 | ``V``, ``O``, ``L`` |
| 4 | version: 3 |
| 5-8 | encoding (int32): 1, float32 (the only one Mitsuba 3 reads) |
| 9-20 | cells along x, y, z (int32 each) |
| 21-24 | channels (int32): 1, 3 or 6 |
| 25-48 | the data's bounding box (6 float32: xmin, ymin, zmin, xmax, ymax, zmax) |
| 49- | the values, ``data[((z * ny + y) * nx + x) * channels + c]`` |

Mitsuba 3 places a grid in the unit cube of its volume's local space and ignores the box unless
the volume asks for it (``use_grid_bbox``).
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

from .builder import error_at

HEADER = struct.Struct("<3sBi3ii6f")  # 48 bytes


# the first bytes of OpenVDB files (the int32 0x56444220, little endian) and NanoVDB ones ("NanoVDB0",
# "NanoVDB1", "NanoVDB2" by version)
OPENVDB_MAGIC = b" BDV"
NANOVDB_MAGIC = b"NanoVDB"


def read_vol(path, where: str = "") -> tuple[np.ndarray, np.ndarray]:
    """(values (nz, ny, nx, channels) float32, box (2, 3) float64) of a .vol file; a
    SceneFormatError naming ``where`` (or the file) if it is not one we can read."""
    path = Path(path)
    where = where or str(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise error_at(where, f"cannot read '{path}' ({exc.strerror or exc})") from None
    if raw[:4] == OPENVDB_MAGIC or raw[:7] == NANOVDB_MAGIC or path.suffix.lower() in (".vdb", ".nvdb"):
        raise error_at(where, f"'{path.name}' is an OpenVDB / NanoVDB grid, which we do not read (no maintained reader "
                              "installs from pip); convert it to Mitsuba's .vol (docs/SCENE_FORMAT.md, media)")
    if len(raw) < HEADER.size:
        raise error_at(where, f"'{path.name}' is not a volume grid (.vol): {len(raw)} bytes, shorter than its header")
    magic, version, encoding, nx, ny, nz, channels, *box = HEADER.unpack_from(raw)
    if magic != b"VOL":
        raise error_at(where, f"'{path.name}' is not a volume grid (.vol): it does not start with 'VOL'")
    if version != 3:
        raise error_at(where, f"'{path.name}': .vol version {version}; only version 3 is supported (as in Mitsuba 3)")
    if encoding != 1:
        raise error_at(where, f"'{path.name}': .vol encoding {encoding}; only 1 (float32) is supported (as in Mitsuba 3)")
    if min(nx, ny, nz) < 1 or channels not in (1, 3, 6):
        raise error_at(where, f"'{path.name}': impossible grid {nx} x {ny} x {nz} with {channels} channels")
    count = nx * ny * nz * channels
    if len(raw) < HEADER.size + 4 * count:
        raise error_at(where, f"'{path.name}': truncated: {nx} x {ny} x {nz} x {channels} values need "
                              f"{HEADER.size + 4 * count} bytes, the file has {len(raw)}")
    data = np.frombuffer(raw, "<f4", count, HEADER.size).astype(np.float32).reshape(nz, ny, nx, channels)
    return data, np.asarray(box, np.float64).reshape(2, 3)


def write_vol(path, data, box=((0.0, 0.0, 0.0), (1.0, 1.0, 1.0))) -> None:
    """Write values (nz, ny, nx[, channels]) as a version-3 float32 .vol file."""
    d = np.asarray(data, np.float32)
    if d.ndim == 3:
        d = d[..., None]
    nz, ny, nx, channels = d.shape
    header = HEADER.pack(b"VOL", 3, 1, nx, ny, nz, channels, *np.asarray(box, np.float64).reshape(6))
    Path(path).write_bytes(header + d.astype("<f4").tobytes())
