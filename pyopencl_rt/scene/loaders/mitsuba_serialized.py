"""Mitsuba's ``serialized`` mesh files: a sequence of zlib-compressed meshes and, at the end of the
file, the offset of each (Mitsuba 3 documentation, "Serialized mesh loader").

Each mesh: uint16 0x041C, uint16 version (3 or 4), then a zlib stream of uint32 flags (0x1 vertex
normals, 0x2 texture coordinates, 0x8 vertex colours, 0x1000 single precision, 0x2000 double
precision), the mesh's name (version 4: a NUL-terminated string), uint64 vertex and triangle
counts, positions, [normals], [uvs], [colours], and the triangles' indices (uint32, or uint64 for
more than 2^32 vertices).  The file ends with the meshes' offsets (version 4: uint64 each,
version 3: uint32) and their number (uint32).  Everything is little-endian.
"""
from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from .builder import error_at

MAGIC = 0x041C
HAS_NORMALS, HAS_UVS, HAS_COLORS, SINGLE, DOUBLE = 0x1, 0x2, 0x8, 0x1000, 0x2000


def read_serialized(path, index: int, where: str):
    """(vertices (V, 3) float64, faces (F, 3) int64, per-corner uvs (F, 3, 2) or None, per-corner
    unit normals (F, 3, 3) or None) of mesh ``index`` of the file.  Vertex colours are skipped,
    as Mitsuba 3 skips them."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise error_at(where, f"cannot read ({exc.strerror or exc})") from None
    try:
        return _read(data, index)
    except (ValueError, struct.error, zlib.error) as exc:
        raise error_at(where, f"not a valid serialized mesh file ({exc})") from None


def _read(data: bytes, index: int):
    if len(data) < 8:
        raise ValueError("too short")
    magic, version = struct.unpack_from("<HH", data, 0)
    if magic != MAGIC or version not in (3, 4):
        raise ValueError(f"bad header {magic:#06x}, version {version}")
    count = struct.unpack_from("<I", data, len(data) - 4)[0]
    width = 8 if version == 4 else 4
    table = len(data) - 4 - width * count
    if count < 1 or table < 0:
        raise ValueError(f"bad mesh count {count}")
    if index >= count:
        raise ValueError(f"shape_index {index}, but the file holds {count} meshes")
    offset = struct.unpack_from("<Q" if version == 4 else "<I", data, table + width * index)[0]
    magic, version = struct.unpack_from("<HH", data, offset)
    if magic != MAGIC:
        raise ValueError(f"mesh {index}: bad header at offset {offset}")
    stream = zlib.decompressobj().decompress(data[offset + 4:])
    pos = 0
    flags = struct.unpack_from("<I", stream, pos)[0]
    pos += 4
    if version == 4:
        end = stream.index(b"\0", pos)
        pos = end + 1
    nv, nf = struct.unpack_from("<QQ", stream, pos)
    pos += 16
    real = np.dtype("<f8") if flags & DOUBLE else np.dtype("<f4")

    def take(n, dtype):
        nonlocal pos
        a = np.frombuffer(stream, dtype, count=n, offset=pos)
        pos += n * np.dtype(dtype).itemsize
        return a

    vertices = take(3 * nv, real).reshape(-1, 3).astype(np.float64)
    normals = take(3 * nv, real).reshape(-1, 3).astype(np.float64) if flags & HAS_NORMALS else None
    uv = take(2 * nv, real).reshape(-1, 2).astype(np.float32) if flags & HAS_UVS else None
    if flags & HAS_COLORS:
        take(3 * nv, real)
    faces = take(3 * nf, "<u8" if nv > 0xFFFFFFFF else "<u4").reshape(-1, 3).astype(np.int64)
    if len(faces) and faces.max() >= nv:
        raise ValueError(f"a face index {int(faces.max())} >= the {nv} vertices")
    if normals is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            normals = np.nan_to_num(normals / np.linalg.norm(normals, axis=1, keepdims=True), nan=0.0, posinf=0.0,
                                    neginf=0.0)[faces].astype(np.float32)
    return vertices, faces, (uv[faces] if uv is not None else None), normals


def write_serialized(path, meshes) -> None:
    """Write (vertices, faces[, uvs per vertex[, normals per vertex]]) meshes as a version-4
    serialized file (single precision): what the tests use, and a way to make such files without
    Mitsuba."""
    out, offsets = bytearray(), []
    for mesh in meshes:
        v, f = np.asarray(mesh[0], "<f4"), np.asarray(mesh[1], "<u4")
        uv = np.asarray(mesh[2], "<f4") if len(mesh) > 2 and mesh[2] is not None else None
        n = np.asarray(mesh[3], "<f4") if len(mesh) > 3 and mesh[3] is not None else None
        flags = SINGLE | (HAS_UVS if uv is not None else 0) | (HAS_NORMALS if n is not None else 0)
        body = struct.pack("<I", flags) + b"mesh\0" + struct.pack("<QQ", len(v), len(f)) + v.tobytes()
        if n is not None:
            body += n.tobytes()
        if uv is not None:
            body += uv.tobytes()
        body += f.tobytes()
        offsets.append(len(out))
        out += struct.pack("<HH", MAGIC, 4) + zlib.compress(body)
    out += b"".join(struct.pack("<Q", o) for o in offsets) + struct.pack("<I", len(offsets))
    Path(path).write_bytes(bytes(out))
