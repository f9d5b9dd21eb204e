"""pbrt-v4's ``LightSource`` directive (:mod:`.pbrt_scene`): point, distant, spot and projection lights
read by their light types (scene/lights/, ``from_pbrt``), and the infinite light (docs/SCENE_FORMAT.md,
"pbrt-v4")."""
from __future__ import annotations

import numpy as np

from ..lights import PBRT_TYPES as PBRT_LIGHTS
from ..model import Environment
from .builder import EnvMap, error_at
from .pbrt import pbrt_file, pbrt_path
from .pbrt_spectra import spectrum_rgb


class LightReading:
    """What a light type's ``from_pbrt`` reads of a ``LightSource`` besides its own numbers
    (scene/lights/__init__.py): the CTM, ``scale``, spectra, an image file, and warnings and
    errors at its place in the file."""

    def __init__(self, imp, d, scale: float):
        self.imp, self.d, self.ctm, self.scale = imp, d, imp.state.ctm, scale
        self.label = f'LightSource "{d.args[0]}"'

    def spectrum(self, name, default) -> tuple:
        return spectrum_rgb(self.imp, self.d.params, name, default)

    def image(self, finite: bool = False):
        """The Texture of the ``filename`` image (an EXR / PFM as it is, others as sRGB); ``finite``:
        an HDR image with an infinite or NaN texel is refused (else those become 0)."""
        from ..textures import texture_from_array, texture_from_image

        fname, path = pbrt_file(self.d, self.imp.path.parent, self.label)
        where = f"{self.d.pos}: {self.label}"
        if path.suffix.lower() in (".exr", ".pfm"):
            from .images import read_hdr_image

            texels = read_hdr_image(path, where)
            if finite and not np.isfinite(texels).all():
                raise self.error(f"'{fname}' has infinite or NaN texels (pbrt-v4 refuses them)")
            return texture_from_array(texels, name=fname)
        try:
            return texture_from_image(path, srgb=True)
        except Exception as exc:
            raise error_at(where, f"cannot read '{fname}' ({type(exc).__name__}: {exc})") from None

    def warn(self, what: str) -> None:
        self.imp.warn(self.d.pos, f"{self.label}: {what}")

    def error(self, what: str):
        return error_at(self.d.pos, f"{self.label}: {what}")


def light_source(imp, d):
    """LightSource: the registered light types' (scene/lights/: point, distant, spot, projection) and
    the infinite light."""
    t, p = d.args[0], d.params
    s = p.float("scale", 1.0)
    if "power" in p or "illuminance" in p:
        key = "power" if "power" in p else "illuminance"
        imp.warn(p.items[key].pos, f'LightSource "{t}": "{key}" is not supported; using the radiance given')
        p.items[key].used = True
    if t in PBRT_LIGHTS:
        imp.b.add_light(PBRT_LIGHTS[t].from_pbrt(p, LightReading(imp, d, s)))
    elif t == "infinite":
        infinite(imp, d, s)
    else:
        imp.warn(d.pos, f'LightSource "{t}": not supported; ignored')


def infinite(imp, d, s) -> None:
    p = d.params
    fname = p.string("filename")
    if "portal" in p:
        imp.warn(p.items["portal"].pos, 'LightSource "infinite": portals are not supported; ignored')
        p.items["portal"].used = True
    if fname is None:
        radiance = spectrum_rgb(imp, p, "L", (1.0, 1.0, 1.0))
        imp.b.set_environment(Environment(radiance=tuple(c * s for c in radiance)), d.pos)
        return
    from .images import read_hdr_image
    from .pbrt_materials import equal_area_sphere_to_square

    path = pbrt_path(d.pos, imp.path.parent, fname, 'LightSource "infinite"')
    image = read_hdr_image(path, f'{d.pos}: LightSource "infinite"')
    h, w = image.shape[:2]
    wrap = h != w
    if h == w:
        lookup, out = equal_area_sphere_to_square, (h, 2 * h)
    else:
        imp.warn(d.pos, f"LightSource \"infinite\": '{fname}' is not square (pbrt-v4 wants an equal-area "
                         "octahedral map); read as pbrt-v3's latitude-longitude map")
        lookup, out = _latlong_uv, (h, w)
    rot = imp.state.ctm[:3, :3]
    if not abs(np.linalg.det(rot)) > 1e-300:
        raise error_at(d.pos, 'LightSource "infinite": the transform is singular (the map needs its inverse)')
    imp.b.set_environment(EnvMap(image=image, lookup=lookup, to_world=rot, scale=(s, s, s), source=fname,
                                  out_shape=out, wrap_u=wrap), d.pos)


def _latlong_uv(d):
    """pbrt-v3's infinite light: z up, u = phi / 2 pi with phi = atan2(y, x), v = theta / pi."""
    phi = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2 * np.pi)
    return phi / (2 * np.pi), np.arccos(np.clip(d[:, 2], -1.0, 1.0)) / np.pi

