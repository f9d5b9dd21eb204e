"""Spectra in Mitsuba 3 XML as Mitsuba 3's RGB variants (``scalar_rgb``, ``llvm_ad_rgb``, ...) see
them (docs/SCENE_FORMAT.md, "Mitsuba 3 XML").

A ``<spectrum>`` property is a constant (``value="0.5"``) or a sampled spectrum: ``wavelength:value``
pairs in increasing wavelength, or a ``.spd`` file of ``wavelength value`` lines.  Mitsuba's RGB
variants turn it into an RGB colour when a plugin asks for the property as a texture, and how
depends on what the plugin asks for (``Properties::get_texture``, ``get_unbounded_texture``,
``get_emissive_texture`` in Mitsuba 3.7+):

=============  ================================================  ================================
context        a sampled spectrum                                a constant c
=============  ================================================  ================================
reflectance    ∫ s D65 x̄ȳz̄ → linear sRGB, clamped to [0, 1]        (c, c, c)
unbounded      the same, clamped at 0 only (conductor ``eta``,    (c, c, c)
               ``k``; roughness ``alpha``)
emission       ∫ s x̄ȳz̄ → linear sRGB (no D65), clamped at 0        c · M (1, 1, 1) ≈ c (1.205, 0.948, 0.909)
=============  ================================================  ================================

M is the XYZ → linear sRGB (Rec. 709, D65 white) matrix.  The emission row is Mitsuba's own
choice: an equal-energy emitter (``<spectrum name="radiance" value="c"/>``) looks as it does in
the spectral variants, a little purple next to D65 white; an ``<rgb>`` or ``<float>`` is used as
it is.  The integral is Mitsuba's: 1000 wavelengths evenly spaced over [360, 830] nm (both ends
included), the spectrum linearly interpolated between its samples and zero outside them, the
tables below interpolated linearly between their 5 nm samples, and the sum scaled by
(830 − 360) / 1000 / 106.7502594 (Mitsuba's normalisation of ȳ: 106.75 is ∫ȳ as that sum gives
it, so that a unit spectrum has luminance 1); D65 is scaled by 1 / 98.99741751876255, Mitsuba's
constant.  Out-of-range colours are clamped, and the caller warns, as Mitsuba logs a warning.

The tables are the CIE's published data: the CIE 1931 2° standard observer x̄, ȳ, z̄ (CIE 015,
CIE S 014-1 / ISO 11664-1) and the relative spectral power of CIE standard illuminant D65 (CIE
S 014-2 / ISO 11664-2), at 5 nm from 360 to 830 nm, held in single precision as Mitsuba holds
them.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

CIE_MIN, CIE_MAX = 360.0, 830.0
STEPS = 1000
Y_NORMALIZATION = 1.0 / 106.7502593994140625
D65_NORMALIZATION = 1.0 / 98.99741751876255

# wavelength [nm], x̄, ȳ, z̄ (CIE 1931 2°), D65 (relative spectral power, 100 at 560 nm)
_CIE_TABLE = """
    360  0.0001299       0.000003917    0.0006061      46.6383
    365  0.0002321       0.000006965    0.001086       49.3637
    370  0.0004149       0.00001239     0.001946       52.0891
    375  0.0007416       0.00002202     0.003486       51.0323
    380  0.001368        0.000039       0.006450001    49.9755
    385  0.002236        0.000064       0.01054999     52.3118
    390  0.004243        0.00012        0.02005001     54.6482
    395  0.00765         0.000217       0.03621        68.7015
    400  0.01431         0.000396       0.06785001     82.7549
    405  0.02319         0.00064        0.1102         87.1204
    410  0.04351         0.00121        0.2074         91.486
    415  0.07763         0.00218        0.3713         92.4589
    420  0.13438         0.004          0.6456         93.4318
    425  0.21477         0.0073         1.0390501      90.057
    430  0.2839          0.0116         1.3856         86.6823
    435  0.3285          0.01684        1.62296        95.7736
    440  0.34828         0.023          1.74706        104.865
    445  0.34806         0.0298         1.7826         110.936
    450  0.3362          0.038          1.77211        117.008
    455  0.3187          0.048          1.7441         117.41
    460  0.2908          0.06           1.6692         117.812
    465  0.2511          0.0739         1.5281         116.336
    470  0.19536         0.09098        1.28764        114.861
    475  0.1421          0.1126         1.0419         115.392
    480  0.09564         0.13902        0.8129501      115.923
    485  0.05795001      0.1693         0.6162         112.367
    490  0.03201         0.20802        0.46518        108.811
    495  0.0147          0.2586         0.3533         109.082
    500  0.0049          0.323          0.272          109.354
    505  0.0024          0.4073         0.2123         108.578
    510  0.0093          0.503          0.1582         107.802
    515  0.0291          0.6082         0.1117         106.296
    520  0.06327         0.71           0.07824999     104.79
    525  0.1096          0.7932         0.05725001     106.239
    530  0.1655          0.862          0.04216        107.689
    535  0.2257499       0.9148501      0.02984        106.047
    540  0.2904          0.954          0.0203         104.405
    545  0.3597          0.9803         0.0134         104.225
    550  0.4334499       0.9949501      0.008749999    104.046
    555  0.5120501       1              0.005749999    102.023
    560  0.5945          0.995          0.0039         100
    565  0.6784          0.9786         0.002749999    98.1671
    570  0.7621          0.952          0.0021         96.3342
    575  0.8425          0.9154         0.0018         96.0611
    580  0.9163          0.87           0.001650001    95.788
    585  0.9786          0.8163         0.0014         92.2368
    590  1.0263          0.757          0.0011         88.6856
    595  1.0567          0.6949         0.001          89.3459
    600  1.0622          0.631          0.0008         90.0062
    605  1.0456          0.5668         0.0006         89.8026
    610  1.0026          0.503          0.00034        89.5991
    615  0.9384          0.4412         0.00024        88.6489
    620  0.8544499       0.381          0.00019        87.6987
    625  0.7514          0.321          0.0001         85.4936
    630  0.6424          0.265          0.00004999999  83.2886
    635  0.5419          0.217          0.00003        83.4939
    640  0.4479          0.175          0.00002        83.6992
    645  0.3608          0.1382         0.00001        81.863
    650  0.2835          0.107          0              80.0268
    655  0.2187          0.0816         0              80.1207
    660  0.1649          0.061          0              80.2146
    665  0.1212          0.04458        0              81.2462
    670  0.0874          0.032          0              82.2778
    675  0.0636          0.0232         0              80.281
    680  0.04677         0.017          0              78.2842
    685  0.0329          0.01192        0              74.0027
    690  0.0227          0.00821        0              69.7213
    695  0.01584         0.005723       0              70.6652
    700  0.01135916      0.004102       0              71.6091
    705  0.008110916     0.002929       0              72.979
    710  0.005790346     0.002091       0              74.349
    715  0.004109457     0.001484       0              67.9765
    720  0.002899327     0.001047       0              61.604
    725  0.00204919      0.00074        0              65.7448
    730  0.001439971     0.00052        0              69.8856
    735  0.0009999493    0.0003611      0              72.4863
    740  0.0006900786    0.0002492      0              75.087
    745  0.0004760213    0.0001719      0              69.3398
    750  0.0003323011    0.00012        0              63.5927
    755  0.0002348261    0.0000848      0              55.0054
    760  0.0001661505    0.00006        0              46.4182
    765  0.000117413     0.0000424      0              56.6118
    770  0.00008307527   0.00003        0              66.8054
    775  0.00005870652   0.0000212      0              65.0941
    780  0.00004150994   0.00001499     0              63.3828
    785  0.00002935326   0.0000106      0              63.8434
    790  0.00002067383   0.0000074657   0              64.304
    795  0.00001455977   0.0000052578   0              61.8779
    800  0.00001025398   0.0000037029   0              59.4519
    805  0.000007221456  0.0000026078   0              55.7054
    810  0.000005085868  0.0000018366   0              51.959
    815  0.000003581652  0.0000012934   0              54.6998
    820  0.000002522525  0.00000091093  0              57.4406
    825  0.000001776509  0.00000064153  0              58.8765
    830  0.000001251141  0.00000045181  0              60.3125
"""

_rows = np.array([[float(x) for x in line.split()] for line in _CIE_TABLE.strip().splitlines()])
CIE_WAVELENGTHS = _rows[:, 0]
CIE_XYZ = _rows[:, 1:4].astype(np.float32).astype(np.float64)
CIE_D65 = _rows[:, 4].astype(np.float32).astype(np.float64)
SAMPLES = len(_rows)

# XYZ -> linear sRGB (ITU-R BT.709 primaries, D65 white), in single precision as Mitsuba has it
XYZ_TO_SRGB = np.array([[3.240479, -1.537150, -0.498535],
                        [-0.969256, 1.875991, 0.041556],
                        [0.055648, -0.204043, 1.057311]], np.float32).astype(np.float64)

CONTEXTS = ("reflectance", "unbounded", "emission")


@dataclass(frozen=True)
class Spectrum:
    """A ``<spectrum>`` value: ``wavelengths`` None for the constant ``values[0]``."""

    wavelengths: tuple | None
    values: tuple

    @property
    def constant(self) -> bool:
        return self.wavelengths is None


def _table(column: np.ndarray, w: np.ndarray) -> np.ndarray:
    """A 5 nm table at wavelengths ``w``: linear between samples, 0 outside [360, 830] nm."""
    t = (w - CIE_MIN) * ((SAMPLES - 1) / (CIE_MAX - CIE_MIN))
    i0 = np.clip(np.floor(t).astype(np.int64), 0, SAMPLES - 2)
    f = (t - i0).reshape((-1,) + (1,) * (column.ndim - 1))
    v = (1.0 - f) * column[i0] + f * column[i0 + 1]
    inside = ((w >= CIE_MIN) & (w <= CIE_MAX)).reshape(f.shape)
    return np.where(inside, v, 0.0)


def cie_xyz(w) -> np.ndarray:
    """x̄, ȳ, z̄ at wavelengths ``w`` [nm] (N, 3)."""
    return _table(CIE_XYZ, np.atleast_1d(np.asarray(w, np.float64)))


def d65(w) -> np.ndarray:
    """D65 at wavelengths ``w`` [nm], scaled as Mitsuba's ``cie_d65``."""
    return _table(CIE_D65, np.atleast_1d(np.asarray(w, np.float64))) * D65_NORMALIZATION


def sampled_to_xyz(wavelengths, values, *, with_d65: bool) -> np.ndarray:
    """XYZ of a sampled spectrum (Mitsuba's ``spectrum_list_to_srgb`` before the matrix)."""
    wl = np.asarray(wavelengths, np.float64)
    v = np.asarray(values, np.float64)
    w = CIE_MIN + (np.arange(STEPS) / (STEPS - 1)) * (CIE_MAX - CIE_MIN)
    w = w[(w >= wl[0]) & (w <= wl[-1])]
    i = np.clip(np.searchsorted(wl, w, side="right") - 1, 0, len(wl) - 2)
    w0, w1, v0, v1 = wl[i], wl[i + 1], v[i], v[i + 1]
    s = ((w - w1) * v0 + (w0 - w) * v1) / (w0 - w1)
    if with_d65:
        s = s * d65(w)
    return (cie_xyz(w) * s[:, None]).sum(0) * ((CIE_MAX - CIE_MIN) * Y_NORMALIZATION / STEPS)


def spectrum_rgb(spec: Spectrum, context: str) -> tuple[tuple, tuple | None]:
    """(linear sRGB, the unclamped RGB where it was clamped, else None) of ``spec`` where a
    plugin asks for it as ``context`` ('reflectance', 'unbounded' or 'emission')."""
    if context not in CONTEXTS:
        raise ValueError(f"unknown context {context!r} (one of {', '.join(CONTEXTS)})")
    if spec.constant:
        c = float(spec.values[0])
        rgb = c * XYZ_TO_SRGB.sum(1) if context == "emission" else np.full(3, c)
        return tuple(float(x) for x in rgb), None
    rgb = XYZ_TO_SRGB @ sampled_to_xyz(spec.wavelengths, spec.values, with_d65=context != "emission")
    clamped = np.clip(rgb, 0.0, 1.0) if context == "reflectance" else np.maximum(rgb, 0.0)
    raw = tuple(float(x) for x in rgb)
    return tuple(float(x) for x in clamped), (raw if (clamped != rgb).any() else None)


def _checked(wavelengths: list, values: list) -> Spectrum:
    if len(wavelengths) < 2:
        raise ValueError("a sampled spectrum needs at least two wavelengths")
    if any(b <= a for a, b in zip(wavelengths, wavelengths[1:])):
        raise ValueError("the wavelengths must increase")
    if not all(np.isfinite(wavelengths)) or not all(np.isfinite(values)):
        raise ValueError("wavelengths and values must be finite")
    return Spectrum(tuple(wavelengths), tuple(values))


def parse_pairs(text: str) -> Spectrum:
    """``"400:0.1, 500:0.5 ..."`` (comma- or space-separated); ValueError with the reason."""
    wavelengths, values = [], []
    for token in (t for t in re.split(r"[,\s]+", text.strip()) if t):
        parts = token.split(":")
        try:
            if len(parts) != 2:
                raise ValueError
            wavelengths.append(float(parts[0]))
            values.append(float(parts[1]))
        except ValueError:
            raise ValueError(f"'{token}' is not a wavelength:value pair") from None
    return _checked(wavelengths, values)


def read_spd(path) -> Spectrum:
    """A ``.spd`` file: one ``wavelength value`` pair a line (more numbers on a line are
    ignored, as Mitsuba does), ``#`` comment lines and blank lines skipped; ValueError with the
    line at fault."""
    wavelengths, values = [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for n, line in enumerate(f, 1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            parts = re.split(r"[,\s]+", text)
            try:
                wl, v = float(parts[0]), float(parts[1])
            except (ValueError, IndexError):
                raise ValueError(f"line {n}: expected 'wavelength value', got '{text}'") from None
            wavelengths.append(wl)
            values.append(v)
    return _checked(wavelengths, values)
