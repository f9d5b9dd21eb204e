"""The display transform of the PNG: exposure, a tone curve, then the sRGB encoding.  The EXR
always holds the linear radiance; only the PNG (and the preview) goes through this.

``exposure`` (EV) scales the linear values by 2^EV first.  The tone curves map scene-linear
Rec.709/sRGB values to display-linear values in [0, 1]:

* ``clamp``: min(max(x, 0), 1) per channel: the identity on [0, 1].
* ``filmic``: Narkowicz's 2015 fit of the ACES reference rendering and output transforms,
  x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14) per channel on 0.6 x (his pre-scale, which
  keeps a mid grey close to the ACES one), clamped to [0, 1]; monotonic (its derivative's
  numerator 1.408 x^2 + 0.7028 x + 0.0042 is positive).
* ``agx``: Troy Sobotka's AgX base look in the common "minimal" form (Wrensch 2023): the
  AgX inset matrix, log2 exposure mapped from [-12.47393, 4.026069] EV to [0, 1], the sixth-order
  polynomial fit of the AgX sigmoid, the outset matrix and the 2.2 power of the display EOTF.
  Highlights desaturate toward white instead of clipping per channel.

Then the sRGB transfer function (IEC 61966-2-1) and 8 bits.
"""
from __future__ import annotations

import numpy as np

TONEMAPS = ("clamp", "filmic", "agx")

# AgX: rows map a linear Rec.709 colour into / out of the AgX working space
_AGX_INSET = np.array([[0.842479062253094, 0.0784335999999992, 0.0792237451477643],
                       [0.0423282422610123, 0.878468636469772, 0.0791661274605434],
                       [0.0423756549057051, 0.0784336, 0.879142973793104]])
# rows scaled to sum to 1 (they are within 1.4e-4 of it): a grey stays grey in the AgX space, so its
# channels saturate together and a grey ramp maps monotonically
_AGX_INSET /= _AGX_INSET.sum(1, keepdims=True)
_AGX_OUTSET = np.array([[1.19687900512017, -0.0980208811401368, -0.0990297440797205],
                        [-0.0528968517574562, 1.15190312990417, -0.0989611768448433],
                        [-0.0529716355144438, -0.0980434501171241, 1.15107367264116]])
_AGX_MIN_EV, _AGX_MAX_EV = -12.47393, 4.026069
# the sigmoid's polynomial, highest power first
_AGX_CURVE = (15.5, -40.14, 31.96, -6.868, 0.4298, 0.1191, -0.00232)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1) on values clamped to [0, 1]."""
    x = np.clip(np.nan_to_num(x, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _finite(x: np.ndarray) -> np.ndarray:
    return np.nan_to_num(np.asarray(x, np.float64), nan=0.0, posinf=1e30, neginf=0.0)


def tonemap(x: np.ndarray, curve: str = "clamp") -> np.ndarray:
    """Scene-linear RGB (... x 3) to display-linear values in [0, 1] with ``curve``."""
    x = np.maximum(_finite(x), 0.0)
    if curve == "clamp":
        return np.minimum(x, 1.0)
    if curve == "filmic":
        x = 0.6 * x
        return np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    if curve == "agx":
        v = x @ _AGX_INSET.T
        v = np.log2(np.maximum(v, 2.0**_AGX_MIN_EV))
        v = (np.clip(v, _AGX_MIN_EV, _AGX_MAX_EV) - _AGX_MIN_EV) / (_AGX_MAX_EV - _AGX_MIN_EV)
        v = np.polyval(_AGX_CURVE, v)
        v = np.clip(v, 0.0, 1.0) @ _AGX_OUTSET.T
        return np.clip(v, 0.0, 1.0) ** 2.2
    raise ValueError(f"unknown tone curve {curve!r}: use one of {', '.join(TONEMAPS)}")


def display(image: np.ndarray, exposure: float = 0.0, curve: str = "clamp") -> np.ndarray:
    """Linear radiance to sRGB-encoded values in [0, 1] (float64)."""
    return linear_to_srgb(tonemap(_finite(image) * (2.0 ** float(exposure)), curve))


def to_8bit(image: np.ndarray, exposure: float = 0.0, curve: str = "clamp") -> np.ndarray:
    return (display(image, exposure, curve) * 255.0 + 0.5).astype(np.uint8)
