"""pbrt-v4's spectra as RGB: ``rgb``, ``blackbody``, named and sampled spectra and ``.spd`` files
(docs/SCENE_FORMAT.md, "pbrt-v4"), by what the parameter is (an emission, a reflectance, a
conductor's eta or k)."""
from __future__ import annotations

import numpy as np

from .builder import blackbody_rgb, error_at
from .pbrt import MissingFile, one_line_at


# how a sampled spectrum (a .spd file or wavelength-value pairs) becomes RGB, by parameter
EMISSION_PARAMS = {"L", "I"}
REFLECTANCE_PARAMS = {"reflectance", "tex1", "tex2", "value", "albedo", "transmittance"}
CONDUCTOR_PARAMS = {"eta", "k", "conductor.eta", "conductor.k"}


def _context(name: str, conductor: bool) -> str:
    if conductor and name in CONDUCTOR_PARAMS:
        return "conductor"
    if name in EMISSION_PARAMS:
        return "emission"
    return "reflectance" if name in REFLECTANCE_PARAMS else "unbounded"


def sampled_rgb(wavelengths, values, context: str) -> tuple:
    """Linear sRGB of a sampled spectrum, with the conversions of mitsuba_spectrum.py (the CIE 1931
    observer, Mitsuba's integration): ``conductor`` (eta, k) as Mitsuba's named conductors
    (mitsuba_metals.py: no illuminant, clamped at 0; Mitsuba's own Au.eta.spd gives its "Au"),
    ``reflectance`` under D65, clamped to [0, 1], ``unbounded`` under D65, clamped at 0 (a
    constant spectrum stays that constant), ``emission`` the spectrum's colour at luminance 1
    (pbrt-v4 divides a light's scale by the spectrum's photometric value)."""
    from .mitsuba_spectrum import XYZ_TO_SRGB, Spectrum, sampled_to_xyz
    from .mitsuba_spectrum import spectrum_rgb as mitsuba_rgb

    if context == "conductor":
        rgb = XYZ_TO_SRGB @ sampled_to_xyz(wavelengths, values, with_d65=False)
        return tuple(float(x) for x in np.maximum(rgb, 0.0))
    if context == "emission":
        xyz = sampled_to_xyz(wavelengths, values, with_d65=False)
        if not xyz[1] > 0:
            return (0.0, 0.0, 0.0)
        return tuple(float(x) for x in np.maximum(XYZ_TO_SRGB @ (xyz / xyz[1]), 0.0))
    return mitsuba_rgb(Spectrum(tuple(wavelengths), tuple(values)), context)[0]


def read_spectrum_file(path, pos: str, what: str) -> tuple:
    """(wavelengths, values) of a pbrt spectrum file: numbers separated by blanks (``#`` starts a
    comment), taken in wavelength-value pairs, as pbrt-v4's ReadFloatFile and
    PiecewiseLinearSpectrum::FromInterleaved read it."""
    numbers = []
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise error_at(pos, f"{what}: cannot read '{path.name}' ({exc.strerror or exc})") from None
    for n, line in enumerate(text.splitlines(), 1):
        for token in line.split("#", 1)[0].split():
            try:
                numbers.append(float(token))
            except ValueError:
                raise error_at(pos, f"{what}: '{path.name}' line {n}: '{token}' is not a number") from None
    return _pairs(numbers, pos, f"{what}: '{path.name}'")


def _pairs(numbers, pos: str, what: str) -> tuple:
    if len(numbers) % 2 or len(numbers) < 4:
        raise error_at(pos, f"{what}: needs wavelength-value pairs, at least two (got {len(numbers)} numbers)")
    wl, v = [float(x) for x in numbers[0::2]], [float(x) for x in numbers[1::2]]
    if any(b <= a for a, b in zip(wl, wl[1:])):
        raise error_at(pos, f"{what}: the wavelengths must increase")
    if not all(np.isfinite(wl + v)):
        raise error_at(pos, f"{what}: wavelengths and values must be finite")
    return wl, v


def spectrum_file(imp, p):
    """The path of a "spectrum" parameter's string value if it names a file (pbrt-v4 looks for a
    file when the name is not one of its named spectra), else None."""
    fname = p.values[0]
    path = imp.path.parent / fname
    if path.is_file():
        return path
    if "/" in fname or "\\" in fname or fname.lower().endswith((".spd", ".txt", ".csv")):
        raise MissingFile(one_line_at(p.pos, f'"spectrum {p.name}": spectrum file \'{fname}\' not found '
                                      f'(looked for {path})'))
    return None


def spectrum_rgb(imp, params, name, default, conductor: bool = False):
    """Linear RGB of a spectrum-valued parameter: ``rgb``, a constant ``float`` or ``spectrum``,
    ``blackbody`` (at luminance 1, as pbrt normalises it), a named spectrum, or a sampled one
    (wavelength-value pairs, or a file of them: :func:`sampled_rgb`, by the parameter's role;
    ``conductor``: a conductor's ``eta`` and ``k``)."""
    p = params.get(name)
    if p is None:
        return tuple(float(x) for x in default)
    if p.type in ("rgb", "color"):
        v = params.numbers(name, (p.type,), 3)
        return tuple(float(x) for x in v)
    if p.type == "float":
        v = params.float(name)
        return (v, v, v)
    if p.type == "blackbody":
        v = params.numbers(name, ("blackbody",), 1)
        return blackbody_rgb(v[0])
    if p.type == "spectrum":
        context = _context(name, conductor)
        if len(p.values) == 1 and isinstance(p.values[0], str):
            path = spectrum_file(imp, p)
            if path is not None:
                return sampled_rgb(*read_spectrum_file(path, p.pos, f'"spectrum {name}"'), context)
            named = p.values[0]
            if named != "stdillum-D65":
                imp.warn(p.pos, f'"spectrum {name}" "{named}": named spectra are rendered as white')
            return (1.0, 1.0, 1.0)
        values = params.numbers(name, ("spectrum",))
        if len(values) == 1:
            return (float(values[0]),) * 3
        return sampled_rgb(*_pairs(values, p.pos, f'"spectrum {name}"'), context)
    raise error_at(p.pos, f'"{p.type} {name}": expected an rgb, spectrum, blackbody or float value')
