"""pbrt-v4's Film directive (:func:`film_settings`: resolution, maxcomponentvalue, whitebalance,
sensor) and its imaging ratio (:func:`imaging_ratio`).

Film "whitebalance" is the colour matrix by which pbrt's film turns what its sensor
recorded into the output colour space, as a 3 x 3 matrix on our linear sRGB image.

pbrt-v4's default sensor (``cie1931``) records CIE XYZ.  With ``whitebalance`` T > 0 its film maps
that XYZ through a von Kries adaptation in the Bradford LMS space (``WhiteBalance`` in pbrt's
color.cpp) from the chromaticity of the CIE daylight illuminant of temperature T (pbrt's
``Spectra::D(T)``) to the output colour space's white (sRGB: D65), then to RGB.  Our renderer's
image is linear sRGB, that is RGB = RGB_from_XYZ . XYZ, so pbrt's output is
M . RGB with M = RGB_from_XYZ . WB . XYZ_from_RGB (:func:`white_balance_matrix`).

The source white: pbrt's ``D(T)`` converts the temperature to a correlated colour temperature
cct = T x 1.4388 / 1.4380 (the change of the second radiation constant), takes the daylight
locus's chromaticity at cct (CIE 15: x by a cubic in 1000 / cct, y = -3x^2 + 2.87x - 0.275)
and builds the spectrum from it; below cct = 4000 K, where the D series is not defined, a black
body of temperature cct.  We take the locus chromaticity itself (the spectrum pbrt builds has it
to within about 1e-3 in x and y: the S0, S1, S2 reconstruction's error) and the black body's
chromaticity by integrating Planck's law against the CIE 1931 observer; the target white is the
chromaticity of the CIE D65 table (mitsuba_spectrum.py), as pbrt takes its colour space's white
from its D65 spectrum.
"""
from __future__ import annotations

import math

import numpy as np

from .builder import error_at

# linear sRGB (Rec. 709 primaries, D65) -> CIE XYZ, and back
XYZ_FROM_RGB = np.array([[0.412453, 0.357580, 0.180423],
                         [0.212671, 0.715160, 0.072169],
                         [0.019334, 0.119193, 0.950227]])
RGB_FROM_XYZ = np.linalg.inv(XYZ_FROM_RGB)
# the Bradford cone response (pbrt-v4's LMSFromXYZ)
LMS_FROM_XYZ = np.array([[0.8951, 0.2664, -0.1614],
                         [-0.7502, 1.7135, 0.0367],
                         [0.0389, -0.0685, 1.0296]])


def _xyz_of_xy(xy) -> np.ndarray:
    x, y = xy
    return np.array([x / y, 1.0, (1.0 - x - y) / y])


def daylight_xy(temperature: float) -> tuple[float, float]:
    """The chromaticity of pbrt-v4's ``Spectra::D(temperature)``: the CIE daylight locus at the
    correlated colour temperature, or a black body's below 4000 K."""
    cct = temperature * 1.4388 / 1.4380
    if cct < 4000.0:
        return blackbody_xy(cct)
    t = 1000.0 / cct
    if cct <= 7000.0:
        x = -4.6070 * t ** 3 + 2.9678 * t ** 2 + 0.09911 * t + 0.244063
    else:
        x = -2.0064 * t ** 3 + 1.9018 * t ** 2 + 0.24748 * t + 0.237040
    return x, -3.0 * x * x + 2.870 * x - 0.275


def blackbody_xy(kelvin: float) -> tuple[float, float]:
    """The chromaticity of a black body (Planck's law against the CIE 1931 observer)."""
    from .mitsuba_spectrum import CIE_WAVELENGTHS, CIE_XYZ

    lam = CIE_WAVELENGTHS * 1e-9
    with np.errstate(over="ignore"):
        planck = 1.0 / (lam ** 5 * (np.exp(1.4387769e-2 / (lam * kelvin)) - 1.0))
    xyz = CIE_XYZ.T @ planck
    return float(xyz[0] / xyz.sum()), float(xyz[1] / xyz.sum())


def d65_xy() -> tuple[float, float]:
    from .mitsuba_spectrum import CIE_D65, CIE_XYZ

    xyz = CIE_XYZ.T @ CIE_D65
    return float(xyz[0] / xyz.sum()), float(xyz[1] / xyz.sum())


def white_balance_xyz(source_xy, target_xy) -> np.ndarray:
    """pbrt-v4's ``WhiteBalance``: von Kries scaling in Bradford LMS taking the white of
    chromaticity ``source_xy`` (Y = 1) to that of ``target_xy``."""
    src = LMS_FROM_XYZ @ _xyz_of_xy(source_xy)
    dst = LMS_FROM_XYZ @ _xyz_of_xy(target_xy)
    return np.linalg.inv(LMS_FROM_XYZ) @ np.diag(dst / src) @ LMS_FROM_XYZ


def white_balance_matrix(temperature: float) -> np.ndarray:
    """The 3 x 3 matrix M with which pbrt-v4's image is M . (our linear sRGB image) for Film
    "whitebalance" ``temperature`` and the cie1931 sensor."""
    return RGB_FROM_XYZ @ white_balance_xyz(daylight_xy(temperature), d65_xy()) @ XYZ_FROM_RGB


def film_settings(imp, film, st) -> None:
    """The Film directive's resolution, white balance (st.color_matrix), maxcomponentvalue
    (st.max_component_value) and sensor into the RenderSettings ``st``; ``imp``: the importer
    (warnings, unused parameters)."""
    if film.args[0] not in ("rgb", "gbuffer"):  # a gbuffer film's image is the rgb film's (its other
        imp.warn(film.pos, f'Film "{film.args[0]}": read as an "rgb" film')  # layers: our --aov)
    st.width = film.params.integer("xresolution", 1280)
    st.height = film.params.integer("yresolution", 720)
    if st.width < 1 or st.height < 1:
        raise error_at(film.pos, f"Film: impossible resolution {st.width}x{st.height}")
    whitebalance = film.params.float("whitebalance", 0.0)
    if whitebalance < 0.0 or not math.isfinite(whitebalance):
        raise error_at(film.params.items["whitebalance"].pos,
                       f'Film "float whitebalance" must be 0 (none) or a temperature > 0, got {whitebalance:g}')
    if whitebalance > 0.0:  # pbrt-v4: the cie1931 sensor's white balance (pbrt_film.py)
        st.color_matrix = tuple(float(v) for v in white_balance_matrix(whitebalance).ravel())
    if "maxcomponentvalue" in film.params:
        limit = film.params.float("maxcomponentvalue")
        if not limit > 0:
            raise error_at(film.params.items["maxcomponentvalue"].pos,
                           f'Film "float maxcomponentvalue" must be > 0, got {limit:g}')
        if math.isfinite(limit):  # pbrt's default is infinity: no clamp
            st.max_component_value = limit
    sensor = film.params.string("sensor", "cie1931")
    if sensor != "cie1931":
        imp.warn(film.params.items["sensor"].pos, f"Film sensor '{sensor}': rendered as cie1931")
    imp.unused(film)


def shutter(cam) -> tuple:
    """(open, close) of the Camera directive ``cam`` (None: pbrt-v4's defaults, 0 and 1); a shutter
    that does not open is an error, as in pbrt-v4."""
    if cam is None:
        return 0.0, 1.0
    opened, closed = cam.params.float("shutteropen", 0.0), cam.params.float("shutterclose", 1.0)
    if not closed - opened > 0:
        raise error_at(cam.pos, f"Camera: shutteropen {opened:g} and shutterclose {closed:g}: the shutter "
                                "does not open (as pbrt-v4, an error)")
    return opened, closed


def imaging_ratio(cam, film) -> float:
    """pbrt-v4's PixelSensor imaging ratio, exposure time x ISO / 100 (film.cpp), by which its RGB
    film scales what it records: the exposure time is the camera's shutterclose - shutteropen
    (defaults 1 and 0; scene.cpp).  pbrt-v4's film has no "exposuretime" (pbrt 5f7a606 stops at it:
    "unused parameter"), and neither has ours.  ``cam``: the Camera directive (or None), ``film``:
    the Film directive (or None)."""
    opened, closed = shutter(cam)
    exposure = closed - opened
    if film is None:
        return exposure
    if "exposuretime" in film.params:
        raise error_at(film.params.items["exposuretime"].pos, 'Film "float exposuretime": not a parameter of '
                       "pbrt-v4's film, which refuses it (the exposure time is the Camera's shutterclose - shutteropen)")
    iso = film.params.float("iso", 100.0)
    if "iso" in film.params and not iso > 0:
        raise error_at(film.params.items["iso"].pos, f'Film "float iso" must be > 0, got {iso:g}')
    return exposure * iso / 100.0
