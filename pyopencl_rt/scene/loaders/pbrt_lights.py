"""pbrt-v4's ``LightSource`` directive (:mod:`.pbrt_scene`): point, distant, spot, projection and
infinite lights mapped onto our lights (docs/SCENE_FORMAT.md, "pbrt-v4")."""
from __future__ import annotations

import numpy as np

from ..model import DirectionalLight, Environment, PointLight, ProjectorLight, SpotLight, look_at_frame
from .builder import EnvMap, error_at, transform_points, transform_vector
from .pbrt import pbrt_file, pbrt_path
from .pbrt_spectra import spectrum_rgb


def light_source(imp, d):
    """LightSource: point, distant, spot, projection and infinite lights."""
    t, p, m = d.args[0], d.params, imp.state.ctm
    s = p.float("scale", 1.0)
    if "power" in p or "illuminance" in p:
        key = "power" if "power" in p else "illuminance"
        imp.warn(p.items[key].pos, f'LightSource "{t}": "{key}" is not supported; using the radiance given')
        p.items[key].used = True
    if t == "point":
        pos = transform_points(m, p.numbers("from", ("point3", "point"), 3, [0.0, 0.0, 0.0]))[0]
        intensity = spectrum_rgb(imp, p, "I", (1.0, 1.0, 1.0))
        imp.b.add_light(PointLight(position=tuple(map(float, pos)), intensity=tuple(c * s for c in intensity)))
    elif t == "distant":
        src = np.asarray(p.numbers("from", ("point3", "point"), 3, [0.0, 0.0, 0.0]), np.float64)
        dst = np.asarray(p.numbers("to", ("point3", "point"), 3, [0.0, 0.0, 1.0]), np.float64)
        direction = transform_vector(m, dst - src)
        if not np.linalg.norm(direction) > 0:
            raise error_at(d.pos, 'LightSource "distant": "from" and "to" are the same point' if not
                           np.linalg.norm(dst - src) > 0 else
                           'LightSource "distant": the transform is singular (it takes the direction to zero)')
        radiance = spectrum_rgb(imp, p, "L", (1.0, 1.0, 1.0))
        imp.b.add_light(DirectionalLight(direction=tuple(map(float, direction / np.linalg.norm(direction))),
                                          irradiance=tuple(c * s for c in radiance)))
    elif t == "spot":
        src = np.asarray(p.numbers("from", ("point3", "point"), 3, [0.0, 0.0, 0.0]), np.float64)
        dst = np.asarray(p.numbers("to", ("point3", "point"), 3, [0.0, 0.0, 1.0]), np.float64)
        axis = dst - src
        if not np.linalg.norm(axis) > 0:
            raise error_at(d.pos, 'LightSource "spot": "from" and "to" are the same point')
        cone = p.float("coneangle", 30.0)
        delta = p.float("conedeltaangle", 5.0)
        if not 0 < cone <= 180 or not 0 <= delta <= cone:
            raise error_at(d.pos, f'LightSource "spot": needs 0 < coneangle <= 180 and 0 <= conedeltaangle '
                                  f"<= coneangle, got {cone:g} and {delta:g}")
        # a frame whose +z is the axis (its x and y do not matter: no texture), then the CTM
        up = np.array([0.0, 1.0, 0.0]) if abs(axis[1]) < 0.9 * np.linalg.norm(axis) else np.array([1.0, 0.0, 0.0])
        frame = m[:3, :3] @ look_at_frame(src, dst, up)
        if abs(np.linalg.det(frame)) < 1e-300:
            raise error_at(d.pos, 'LightSource "spot": the transform is singular')
        intensity = spectrum_rgb(imp, p, "I", (1.0, 1.0, 1.0))
        imp.b.add_light(SpotLight(position=tuple(map(float, transform_points(m, src)[0])),
                                   intensity=tuple(c * s for c in intensity), cutoff_angle=cone,
                                   beam_width=cone - delta, falloff="smoothstep", to_world=frame))
    elif t == "projection":
        projection(imp, d, s, m)
    elif t == "infinite":
        infinite(imp, d, s)
    else:
        imp.warn(d.pos, f'LightSource "{t}": not supported; ignored')

def projection(imp, d, s, m) -> None:
    """pbrt-v4's projection light: the image `filename` projected from the CTM's origin along its
    +z, `fov` (default 90) across the image's shorter side, intensity `scale` x the texel."""
    from ..textures import texture_from_array, texture_from_image

    p = d.params
    fname, path = pbrt_file(d, imp.path.parent, 'LightSource "projection"')
    where = f'{d.pos}: LightSource "projection"'
    if path.suffix.lower() in (".exr", ".pfm"):
        from .images import read_hdr_image

        texture = texture_from_array(read_hdr_image(path, where), name=fname)
    else:
        try:
            texture = texture_from_image(path, srgb=True)
        except Exception as exc:
            raise error_at(where, f"cannot read '{fname}' ({type(exc).__name__}: {exc})") from None
    fov = p.float("fov", 90.0)
    if not 0 < fov < 180:
        raise error_at(d.pos, f'LightSource "projection": fov must be between 0 and 180 degrees, got {fov:g}')
    aspect = texture.width / texture.height
    fov_x = fov if aspect <= 1 else float(np.degrees(2 * np.arctan(np.tan(np.radians(fov) / 2) * aspect)))
    if abs(np.linalg.det(m[:3, :3])) < 1e-300:
        raise error_at(d.pos, 'LightSource "projection": the transform is singular')
    imp.warn(d.pos, 'LightSource "projection": the image is interpolated bilinearly (pbrt-v4 takes the '
                     "nearest texel)")
    imp.b.add_light(ProjectorLight(position=tuple(map(float, m[:3, 3])), texture=texture, scale=s, fov=fov_x,
                                    convention="pbrt", to_world=m[:3, :3].copy()))

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

