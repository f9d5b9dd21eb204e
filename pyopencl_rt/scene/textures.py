"""Image textures: loaded once, decoded to linear float RGBA, packed into one texel buffer.

A :class:`Texture` holds an (H, W, 4) float32 array of linear values, row 0 at the top of the
image: texture coordinate (u, v) = (0, 0) is the top-left corner, as in glTF (OBJ's ``vt``, whose
v runs upwards, is flipped to this convention when an OBJ is read).  Colour textures (base colour,
emission) are stored in sRGB and decoded to linear here, once, with the exact piecewise sRGB
transfer function (IEC 61966-2-1); data textures (glTF metallic-roughness) are used as they are.
8-bit values map to [0, 1] by /255, 16-bit by /65535; grey images are replicated into RGB and a
missing alpha is 1.

The device looks textures up as each Texture's ``to_uv``, ``wrap`` and ``filter`` say (bilinear
and repeat by default; ``cl/scene/textures.h``, abi.TEXTURE); :func:`lookup` is the same lookup in
numpy float64 (the reference the tests hold the kernel to), :func:`bilinear` its default case.
"""
from __future__ import annotations

import dataclasses
import weakref
from dataclasses import dataclass

import numpy as np

from ..device import abi


def srgb_to_linear(c):
    """sRGB-encoded values in [0, 1] to linear (float64)."""
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


WRAPS = tuple(abi.TEXTURE_WRAPS)      # "repeat", "mirror", "clamp"
FILTERS = tuple(abi.TEXTURE_FILTERS)  # "bilinear", "nearest"
POINT_MAPPINGS = ("planar", "spherical", "cylindrical")  # of the hit point (pbrt-v4's), besides "uv"
IDENTITY_UV = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0)


def affine_uv(matrix) -> tuple:
    """The 2-D affine map (a, b, c, d, e, f): u' = a u + b v + c, v' = d u + e v + f, of a 3 x 3
    matrix acting on (u, v, 1), or of a 4 x 4 one whose rows 0, 1 and columns 0, 1, 3 act on
    (u, v) (Mitsuba's to_uv given as a 4 x 4 transform, as its Properties read it)."""
    m = np.asarray(matrix, np.float64)
    if m.shape == (4, 4):
        m = m[np.ix_([0, 1, 3], [0, 1, 3])]
    if m.shape != (3, 3):
        raise ValueError(f"a texture coordinate transform must be 3 x 3 or 4 x 4, got {m.shape}")
    return tuple(float(x) for x in (m[0, 0], m[0, 1], m[0, 2], m[1, 0], m[1, 1], m[1, 2]))


def compose_uv(outer, inner) -> tuple:
    """The affine map ``outer`` after ``inner`` (both (a, b, c, d, e, f))."""
    a = np.array([[*outer[:3]], [*outer[3:]], [0, 0, 1]], np.float64)
    b = np.array([[*inner[:3]], [*inner[3:]], [0, 0, 1]], np.float64)
    return affine_uv(a @ b)


@dataclass(eq=False)
class Texture:
    """Linear RGBA texels (H, W, 4) float32; ``srgb`` records that they were decoded from sRGB.

    How it is looked up: ``to_uv``, the affine map (a, b, c, d, e, f) applied to the hit's uv
    (u' = a u + b v + c, v' = d u + e v + f), ``wrap`` (one of WRAPS) and ``filter`` (one of
    FILTERS); :meth:`with_lookup` gives the same texels with other settings (they share one copy
    on the device).  ``mapping`` "uv" (the shape's uv) or one of POINT_MAPPINGS: to_uv then
    applies to the (s, t) of the hit point that :func:`map_points` gives (pbrt-v4's planar,
    spherical and cylindrical mappings), ``frame`` their 3 x 4 matrix (12 numbers, rows)."""

    texels: np.ndarray
    srgb: bool = False
    channels: int = 4
    name: str = "texture"
    wrap: str = "repeat"
    filter: str = "bilinear"
    to_uv: tuple = IDENTITY_UV
    mapping: str = "uv"
    frame: tuple = ()

    def __post_init__(self):
        if self.wrap not in WRAPS:
            raise ValueError(f"{self.name}: wrap must be one of {', '.join(WRAPS)}, got {self.wrap!r}")
        if self.filter not in FILTERS:
            raise ValueError(f"{self.name}: filter must be one of {', '.join(FILTERS)}, got {self.filter!r}")
        self.to_uv = tuple(float(x) for x in self.to_uv)
        if len(self.to_uv) != 6 or not all(np.isfinite(self.to_uv)):
            raise ValueError(f"{self.name}: to_uv must be 6 finite numbers (a b c d e f), got {self.to_uv}")
        if self.mapping not in ("uv", *POINT_MAPPINGS):
            raise ValueError(f"{self.name}: mapping must be uv or one of {', '.join(POINT_MAPPINGS)}")
        self.frame = tuple(float(x) for x in self.frame) if self.mapping != "uv" else ()
        if self.mapping != "uv" and (len(self.frame) != 12 or not all(np.isfinite(self.frame))):
            raise ValueError(f"{self.name}: a {self.mapping} mapping needs 12 finite numbers (its 3 x 4 frame)")

    def with_lookup(self, wrap=None, filter=None, to_uv=None, mapping=None, frame=None) -> "Texture":
        """These texels with other lookup settings (None keeps one); ``self`` when nothing changes."""
        wrap = self.wrap if wrap is None else wrap
        filter = self.filter if filter is None else filter
        to_uv = self.to_uv if to_uv is None else tuple(float(x) for x in to_uv)
        mapping = self.mapping if mapping is None else mapping
        frame = self.frame if frame is None else tuple(float(x) for x in frame)
        if (wrap, filter, to_uv, mapping, frame) == (self.wrap, self.filter, self.to_uv, self.mapping, self.frame):
            return self
        return dataclasses.replace(self, wrap=wrap, filter=filter, to_uv=to_uv, mapping=mapping, frame=frame)

    def lookup_key(self) -> tuple:
        """What besides the texels decides a lookup (textures that share it read the same texel)."""
        return self.texels.shape, self.wrap, self.filter, self.to_uv, self.mapping, self.frame

    @property
    def width(self) -> int:
        return int(self.texels.shape[1])

    @property
    def height(self) -> int:
        return int(self.texels.shape[0])

    def mean_rgb(self) -> np.ndarray:
        """Mean linear RGB over the image (the average a uniformly sampled uv sees)."""
        return self.texels[..., :3].astype(np.float64).mean(axis=(0, 1))


@dataclass(eq=False)
class DirectionMix:
    """pbrt-v4's directionmix texture: ``first`` weighted by |ng . direction| (ng the hit's geometric
    normal, ``direction`` a unit vector in the world), ``second`` by the rest; both image Textures
    (each with its own mapping).  No texels of its own (abi.TEXTURE_MAP_DIRECTION_MIX)."""

    first: Texture
    second: Texture
    direction: tuple = (0.0, 1.0, 0.0)
    name: str = "directionmix"
    mapping = "direction_mix"

    def __post_init__(self):
        d = np.asarray(self.direction, np.float64)
        if d.shape != (3,) or not np.all(np.isfinite(d)) or not np.linalg.norm(d) > 0:
            raise ValueError(f"{self.name}: the direction must be a finite, non-zero 3-vector")
        self.direction = tuple(float(x) for x in d / np.linalg.norm(d))
        if not (isinstance(self.first, Texture) and isinstance(self.second, Texture)):
            raise ValueError(f"{self.name}: a directionmix mixes two image textures")

    @property
    def channels(self) -> int:
        return max(self.first.channels, self.second.channels)

    @property
    def srgb(self) -> bool:
        return self.first.srgb and self.second.srgb

    def children(self) -> tuple:
        return self.first, self.second

    def mean_rgb(self) -> np.ndarray:
        """An estimate of the mean over the surfaces (the two textures' means averaged)."""
        return 0.5 * (self.first.mean_rgb() + self.second.mean_rgb())


def with_inputs(textures) -> list:
    """``textures`` and, after each DirectionMix among them, its two inputs: each once, in order of
    first use (what the texture table holds, and what a change of the scene's frame moves)."""
    seen = {}
    for t in textures:
        for x in (t, *getattr(t, "children", tuple)()):
            seen.setdefault(id(x), x)
    return list(seen.values())


# Mitsuba's luminance of linear sRGB (include/mitsuba/core/spectrum.h)
LUMINANCE = (0.212671, 0.715160, 0.072169)


_SCALAR_TEXTURES: "weakref.WeakKeyDictionary[Texture, Texture]" = weakref.WeakKeyDictionary()


def scalar_texture(texture: Texture) -> Texture:
    """The texture of a scalar parameter: its luminance in R, G and B (Mitsuba's eval_1 of a
    colour texture; a grey one keeps its value); one per source texture."""
    cached = _SCALAR_TEXTURES.get(texture)
    if cached is None and isinstance(texture, DirectionMix):
        cached = dataclasses.replace(texture, first=scalar_texture(texture.first), second=scalar_texture(texture.second))
        _SCALAR_TEXTURES[texture] = cached
    elif cached is None:
        t = texture.texels.astype(np.float64)
        lum = t[..., :3] @ np.array(LUMINANCE) if texture.channels >= 3 else t[..., 0]
        out = np.ones_like(t)
        out[..., :3] = lum[..., None]
        cached = dataclasses.replace(texture, texels=np.ascontiguousarray(out, np.float32), channels=1)
        _SCALAR_TEXTURES[texture] = cached
    return cached


def texture_from_array(values, *, srgb: bool = False, name: str = "texture") -> Texture:
    """A texture from an (H, W), (H, W, C) array: integers are scaled to [0, 1] by their type's
    maximum, floats used as they are; ``srgb`` decodes the colour channels (not alpha)."""
    a = np.asarray(values)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in (1, 2, 3, 4) or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"{name}: texture must be (H, W) or (H, W, 1..4), got shape {a.shape}")
    channels = a.shape[2]
    if np.issubdtype(a.dtype, np.integer):
        f = a.astype(np.float64) / float(np.iinfo(a.dtype).max)
    else:
        f = np.nan_to_num(a.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    h, w = f.shape[:2]
    out = np.ones((h, w, 4), np.float64)
    if channels in (1, 2):  # grey (+ alpha)
        out[..., :3] = f[..., :1]
        if channels == 2:
            out[..., 3] = f[..., 1]
    else:
        out[..., :channels] = f
    if srgb:
        out[..., :3] = srgb_to_linear(np.clip(out[..., :3], 0.0, 1.0))
    return Texture(np.ascontiguousarray(out, np.float32), srgb=srgb, channels=channels, name=name)


def texture_from_image(image, *, srgb: bool = False, name: str | None = None) -> Texture:
    """A texture from a Pillow image or an image file path (any format Pillow reads)."""
    from PIL import Image

    if not isinstance(image, Image.Image):
        name = name or str(image)
        with Image.open(image) as im:
            im.load()
            image = im.copy()
    name = name or getattr(image, "filename", None) or "image"
    mode = image.mode
    if mode in ("I;16", "I;16B", "I;16L", "I"):
        a = np.asarray(image).astype(np.uint16 if mode.startswith("I;16") else np.int32)
        if a.dtype == np.int32:
            a = np.clip(a, 0, 65535).astype(np.uint16)
    elif mode == "F":
        a = np.asarray(image, np.float32)
    else:
        if mode not in ("L", "LA", "RGB", "RGBA"):
            image = image.convert("RGBA" if "A" in mode or "transparency" in image.info else "RGB")
        a = np.asarray(image)
    return texture_from_array(a, srgb=srgb, name=str(name))


def pack_textures(textures, origin=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """(TEXTURE table, float32 texel buffer of 4 floats per texel) for a list of textures; textures
    that share their texels array (Texture.with_lookup) share its copy in the buffer.  ``origin``:
    the world position of the kernels' origin (Scene.world_origin), which the frames of point
    mappings add to the points the kernels give them."""
    table = np.zeros(max(1, len(textures)), abi.TEXTURE)
    table["to_uv"] = IDENTITY_UV
    table["children"] = -1
    chunks = []
    offset = 0
    placed: dict[int, int] = {}  # id(texels) -> offset
    index = {id(t): i for i, t in enumerate(textures)}
    for i, t in enumerate(textures):
        if isinstance(t, DirectionMix):  # its two textures are in the table too (Scene.textures)
            table["mapping"][i] = abi.TEXTURE_MAP_DIRECTION_MIX
            table["children"][i] = index[id(t.first)], index[id(t.second)]
            table["frame"][i, :3] = t.direction
            table["channels"][i] = t.channels
            continue
        if id(t.texels) not in placed:
            placed[id(t.texels)] = offset
            chunks.append(t.texels.reshape(-1))
            offset += t.width * t.height
        table[i]["offset"] = placed[id(t.texels)]
        table[i]["width"] = t.width
        table[i]["height"] = t.height
        table[i]["channels"] = t.channels
        table[i]["flags"] = abi.TEXTURE_FLAG_SRGB if t.srgb else 0
        table[i]["wrap"] = abi.TEXTURE_WRAPS[t.wrap]
        table[i]["filter"] = abi.TEXTURE_FILTERS[t.filter]
        table[i]["to_uv"] = t.to_uv
        table[i]["mapping"] = abi.TEXTURE_MAPS[t.mapping]
        if t.frame:
            frame = np.reshape(np.asarray(t.frame, np.float64), (3, 4)).copy()
            frame[:, 3] += frame[:, :3] @ np.asarray(origin, np.float64)
            table[i]["frame"] = frame.ravel()
    if offset >= 2**31:
        raise ValueError("textures too large (more than 2^31 texels in all)")
    data = np.concatenate(chunks).astype(np.float32) if chunks else np.zeros(4, np.float32)
    return table, data


def _wrap_index(i, n, wrap):
    if wrap == "clamp":
        return np.clip(i, 0, n - 1)
    if wrap == "mirror":
        m = np.mod(i, 2 * n)
        return np.where(m >= n, 2 * n - 1 - m, m)
    return np.mod(i, n)


def lookup(texels, uv, wrap="repeat", filter="bilinear", to_uv=IDENTITY_UV) -> np.ndarray:
    """A lookup as cl/scene/textures.h does it (float64), from Dr.Jit's definitions: uv through
    to_uv; bilinear: texel x's centre at (x + 0.5) / W, the four centres around uv weighted;
    nearest: texel floor(u W); indices outside the image wrapped (repeat: modulo W; mirror:
    modulo 2 W, the second copy reversed; clamp: to [0, W - 1])."""
    t = np.asarray(texels, np.float64)
    h, w = t.shape[:2]
    uv = np.asarray(uv, np.float64).reshape(-1, 2)
    uv = np.where(np.isfinite(uv), uv, 0.0)
    a, b, c, d, e, f = to_uv
    u = a * uv[:, 0] + b * uv[:, 1] + c
    v = d * uv[:, 0] + e * uv[:, 1] + f
    if filter == "nearest":
        x = _wrap_index(np.floor(u * w).astype(np.int64), w, wrap)
        y = _wrap_index(np.floor(v * h).astype(np.int64), h, wrap)
        return t[y, x]
    fx = u * w - 0.5
    fy = v * h - 0.5
    x0 = np.floor(fx)
    y0 = np.floor(fy)
    ax = (fx - x0)[:, None]
    ay = (fy - y0)[:, None]
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    x1, y1 = _wrap_index(x0 + 1, w, wrap), _wrap_index(y0 + 1, h, wrap)
    x0, y0 = _wrap_index(x0, w, wrap), _wrap_index(y0, h, wrap)
    top = t[y0, x0] * (1 - ax) + t[y0, x1] * ax
    bot = t[y1, x0] * (1 - ax) + t[y1, x1] * ax
    return top * (1 - ay) + bot * ay


def map_points(mapping, frame, points) -> np.ndarray:
    """(s, t) of world points (N x 3) under pbrt-v4's mapping (float64; cl/scene/textures.h
    tex_map_lanes): x = frame (p, 1) with frame 3 x 4; planar (x0, x1) (pbrt's ds + vs . p, folded
    into the frame); spherical (theta / pi, phi / 2 pi) of x / |x|, theta from +z, phi from +x
    toward +y in [0, 2 pi); cylindrical ((pi + atan2(x1, x0)) / 2 pi, x2)."""
    m = np.asarray(frame, np.float64).reshape(3, 4)
    p = np.asarray(points, np.float64).reshape(-1, 3)
    x = p @ m[:, :3].T + m[:, 3]
    if mapping == "planar":
        return x[:, :2]
    if mapping == "cylindrical":
        return np.stack([(np.pi + np.arctan2(x[:, 1], x[:, 0])) / (2 * np.pi), x[:, 2]], 1)
    d = x / np.linalg.norm(x, axis=1, keepdims=True)
    return np.stack([np.arccos(np.clip(d[:, 2], -1, 1)) / np.pi,
                     np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi) / (2 * np.pi)], 1)


def bilinear(texels, uv) -> np.ndarray:
    """Bilinear lookup with wrap (repeat) addressing (float64), as cl/scene/textures.h does it by
    default: texel (x, y) covers [x, x+1) / W x [y, y+1) / H, its centre at ((x + 0.5) / W, (y + 0.5) / H)."""
    return lookup(texels, uv)
