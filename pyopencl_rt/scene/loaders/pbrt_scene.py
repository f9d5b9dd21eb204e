"""pbrt-v4 scene files (``.pbrt``): the directives of :mod:`.pbrt` given their meaning — the
graphics state (transform, attributes, materials, area lights), shapes, lights, camera and
options — and mapped onto our scene (docs/SCENE_FORMAT.md, "pbrt-v4").

pbrt is spectral; an RGB reflectance is used as it is, and an RGB emission as radiance in our
linear sRGB (pbrt normalises an RGB illuminant to the luminance its RGB has, so this is what its
RGB film records for it).  Parameters this mapping does not read warn, one line each, with their
file position; directives we do not render warn and are skipped.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..media import MediumInterface
from ..model import Material, RenderSettings
from ..pixel_filter import PixelFilter
from .builder import EnvMap, SceneBuilder, camera_from_matrix, disk_mesh, error_at, sphere_mesh, transform_points
from ..shapes import REGISTRY as SHAPES
from .instancing import add_instance
from . import pbrt as _pbrt
from .pbrt import Directive, MissingFile, Parser
from .pbrt_film import film_settings, imaging_ratio
from .pbrt_lights import light_source
from .pbrt_materials import MaterialMapper
from .pbrt_spectra import spectrum_rgb
from .pbrt_transforms import Transforms, singular

SILENT = {("Film", "filename"), ("Sampler", "seed"), ("Film", "diagonal"),
          ("Film", "savefp16"), ("Integrator", "regularize"), ("Shape", "S"),
          ("Shape", "faceIndices"), ("Shape", "emissionfilename")}


# pbrt-v4's quadrics: intersected in object space, the ray moved by the shape's inverse transform
QUADRICS = {"sphere", "disk", "cylinder"}


def _flattened(geometry, m):
    """Triangles under a singular transform, as pbrt-v4 keeps them: their vertices moved by ``m``
    (they are intersected where they land); those left without area are dropped (no ray hits
    them), and the shading normals, which pbrt moves by the NaN inverse, are left out: every
    triangle that keeps an area lies in m's plane, flat shaded by its own normal.  None: nothing is
    left."""
    v, f, uv = geometry[:3]
    v = transform_points(m, np.asarray(v, np.float64))
    f = np.asarray(f, np.int64)
    corners = v[f]
    twice_area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    scale = max(float(np.abs(v).max()) if len(v) else 0.0, 1e-30)
    keep = twice_area > 1e-12 * scale * scale
    if not keep.any():
        return None
    return v, f[keep], None if uv is None else np.asarray(uv)[keep]


# read at the end (a Film may follow the Camera whose field of view depends on it)
DEFERRED = {"Camera", "Film", "Sampler", "Integrator", "PixelFilter"}


def load_pbrt(path, name: str | None = None):
    """The Scene of a pbrt-v4 scene file."""
    path = Path(path)
    name = name or str(path)
    builder = SceneBuilder(name, "pbrt-v4")
    _Importer(builder, path, name).run()
    return builder.build()


@dataclasses.dataclass
class _State:
    ctm: np.ndarray  # the transform at the start time (TransformTimes)
    reverse: bool = False
    # pbrt-v4's second transform, at the end time: the two differ where ActiveTransform made a
    # directive change one of them (motion blur); None: the same as ctm
    ctm_end: np.ndarray | None = None
    active: tuple = (True, True)  # ActiveTransform: which of (ctm, ctm_end) the transform directives change
    material: object = None  # a Material, or ("named", name, pos)
    area: object = None  # (radiance, two_sided) of the AreaLightSource in effect
    inside: str = ""  # MediumInterface: the media inside and outside shapes ("": vacuum)
    outside: str = ""


class _Importer(Transforms):
    def __init__(self, builder: SceneBuilder, path: Path, name: str):
        self.b, self.path, self.name = builder, path, name
        self.materials = MaterialMapper(self)
        self.state = _State(np.eye(4), material=self.materials.default())
        self.stack: list[_State] = []
        self.coords: dict[str, np.ndarray] = {}
        self.camera = None  # (directive, camera-from-world, the medium outside: the camera's)
        self.named_media: dict = {}  # MakeNamedMedium: name -> Medium, or None (a type we do not render)
        self.null_material = None  # the "interface" shapes' (they never scatter: cl/render/media.h)
        self.options: dict[str, Directive] = {}
        self.in_world = False
        self.transform_times = (0.0, 1.0)  # TransformTimes
        self.moving = None  # where the first moving shape or instance was (its position)
        self.shape_groups = 0  # the one-shape groups of moving shapes

    def warn(self, pos, what) -> None:
        self.b.warn(pos, what)

    def run(self) -> None:
        # pbrt-v4 creates the named materials once the whole file is read, so a shape may name one
        # that a MakeNamedMaterial further down defines: such shapes wait, with their graphics
        # state, until the end (outside ObjectBegin; inside, the name must be defined first)
        waiting = []
        for d in Parser(self.path, self.name).directives():
            handler = getattr(self, "d_" + d.name, None)
            if handler is None:
                self.warn(d.pos, f"{d.name}: not supported; ignored")
                continue
            if d.name == "Shape" and self._named_later() and self.b.recording is None:
                waiting.append((d, self._saved()))
                continue
            self._handle(handler, d)
        current = self.state
        for d, state in waiting:
            self.state = state
            if _pbrt.SKIP_MISSING_FILES and self._named_later():  # the bench's probe: defined in a missing file?
                _pbrt.skipped_missing(f"{d.pos}: NamedMaterial '{state.material[1]}' is never defined (in a missing "
                                      "file?); its shape is left out")
                continue
            self._handle(self.d_Shape, d)
        self.state = current
        if self.stack:
            self.warn(self.name, f"{len(self.stack)} AttributeBegin without AttributeEnd")
        self.finish_options()

    def _handle(self, handler, d) -> None:
        try:
            handler(d)
        except MissingFile as exc:
            if not _pbrt.SKIP_MISSING_FILES:
                raise
            _pbrt.skipped_missing(exc)
            return
        if d.name not in DEFERRED:
            self.unused(d)

    def _named_later(self) -> bool:
        """Whether the material in effect is a NamedMaterial not (yet) defined."""
        mat = self.state.material
        return isinstance(mat, tuple) and mat[1] not in self.materials.named

    def unused(self, d: Directive) -> None:
        for p in d.params.unused():
            if (d.name, p.name) not in SILENT:
                kind = f' "{d.args[0]}"' if d.args and isinstance(d.args[0], str) else ""
                self.warn(p.pos, f'"{p.type} {p.name}" of {d.name}{kind}: not supported; ignored')
                p.used = True

    # -- blocks ----------------------------------------------------------------------------------

    def d_AttributeBegin(self, d):
        self.stack.append(self._saved())

    def d_AttributeEnd(self, d):
        if not self.stack:
            raise error_at(d.pos, f"{d.name} without a matching {d.name.replace('End', 'Begin')}")
        self.state = self.stack.pop()

    def d_TransformBegin(self, d):  # deprecated in pbrt-v4: saves the transform only
        self.stack.append(self._saved())

    def d_TransformEnd(self, d):
        if not self.stack:
            raise error_at(d.pos, "TransformEnd without a matching TransformBegin")
        saved = self.stack.pop()
        self.state.ctm, self.state.ctm_end = saved.ctm, saved.ctm_end

    def d_WorldBegin(self, d):
        self.in_world = True
        self.state.ctm, self.state.ctm_end = np.eye(4), None
        self.coords["world"] = (np.eye(4), np.eye(4))

    def d_WorldEnd(self, d):  # pbrt-v3
        pass

    def d_ObjectBegin(self, d):
        """A shape group (loaders/instancing.py): its shapes are recorded with their CTM, not drawn."""
        if self.b.recording is not None:
            raise error_at(d.pos, "ObjectBegin inside another ObjectBegin")
        if d.args[0] in self.b.groups:
            raise error_at(d.pos, f"ObjectBegin: object '{d.args[0]}' is already defined")
        self.d_AttributeBegin(d)
        self.b.begin_group(d.args[0])

    def d_ObjectEnd(self, d):
        if self.b.recording is None:
            raise error_at(d.pos, "ObjectEnd without ObjectBegin")
        self.b.end_group()
        self.d_AttributeEnd(d)

    def d_ObjectInstance(self, d):
        """The object's shapes moved by the CTM (pbrt-v4: render-from-instance times each shape's
        own CTM at its definition)."""
        if self.b.recording is not None:
            raise error_at(d.pos, "ObjectInstance inside ObjectBegin")
        if d.args[0] not in self.b.groups:
            raise error_at(d.pos, f"ObjectInstance: no object named '{d.args[0]}' (ObjectBegin)")
        if singular(self.state.ctm) or singular(self.end_ctm()):  # pbrt-v4 moves rays into it by the inverse: NaN
            return
        moving = self.moves()
        if moving and self.moving is None:
            self.moving = d.pos
        # pbrt-v4 interpolates an instance's transform in its render space, the world moved so that
        # the camera is at the origin, and conjugated by that move: it turns about the camera
        # (accel/motion.py); without a camera yet, about the world's origin
        pivot = None if self.camera is None else np.linalg.inv(self.camera[1])[:3, 3]
        if self.b.camera_motion is not None:  # pbrt's render space: the camera at the middle time
            from ...accel.motion import Motion

            pivot = Motion(*self.b.camera_motion).at(0.5)[:3, 3]
        add_instance(self.b, self.b.groups[d.args[0]], self.state.ctm, d.pos,
                     matrix_end=self.end_ctm() if moving else None, what=f'ObjectInstance "{d.args[0]}"',
                     pivot=pivot)

    # -- options ---------------------------------------------------------------------------------

    def d_Camera(self, d):
        if singular(self.state.ctm):
            raise error_at(d.pos, "Camera: the transform is singular (the camera needs its inverse)")
        end = self.end_ctm()
        if self.moves():  # a moving camera (motion blur): its way from the start's frame to the end's
            if singular(end):
                raise error_at(d.pos, "Camera: the transform at the end time is singular")
            if self.moving is None:
                self.moving = d.pos
            self.b.camera_motion = (np.linalg.inv(self.state.ctm), np.linalg.inv(end))
        self.camera = (d, self.state.ctm.copy(), self.state.outside)
        self.coords["camera"] = (np.linalg.inv(self.state.ctm), np.linalg.inv(end))

    def _option(self, d):
        self.options[d.name] = d

    d_Sampler = d_Film = d_Integrator = d_PixelFilter = _option

    def d_Accelerator(self, d):
        for p in d.params.items.values():
            p.used = True

    def d_ColorSpace(self, d):
        if d.args[0] != "srgb":
            self.warn(d.pos, f"ColorSpace '{d.args[0]}': colours are read as linear sRGB")

    def d_Option(self, d):
        for p in d.params.items.values():
            self.warn(p.pos, f'Option "{p.type} {p.name}": not supported; ignored')
            p.used = True

    def finish_options(self) -> None:
        st = RenderSettings(width=1280, height=720, spp=16, max_depth=6, rr_depth=2)
        self.b.settings = st
        film = self.options.get("Film")
        ratio = imaging_ratio(self.camera[0] if self.camera is not None else None, film)
        if film is not None:
            film_settings(self, film, st)
        sampler = self.options.get("Sampler")
        if sampler is not None:
            st.spp = sampler.params.integer("pixelsamples", 16)
            if st.spp < 1:
                raise error_at(sampler.pos, "Sampler: pixelsamples must be at least 1")
            self.unused(sampler)
        integ = self.options.get("Integrator")
        if integ is not None:
            if integ.args[0] not in ("volpath", "path", "simplepath", "simplevolpath"):
                self.warn(integ.pos, f'Integrator "{integ.args[0]}": rendered with our path tracer (MIS)')
            st.spectral_mis = integ.args[0] != "simplevolpath"  # its media: the hero wavelength alone
            depth = integ.params.integer("maxdepth", 5)
            if depth < 0:
                raise error_at(integ.pos, f"Integrator: maxdepth must be >= 0, got {depth}")
            st.max_depth = depth + 1  # pbrt counts bounces, we count path segments
            # pbrt's default ("bvh") only where the file names it: otherwise our default (measured,
            # docs/BENCHMARKS.md)
            sampler_name = integ.params.string("lightsampler", st.light_sampler)
            # pbrt-v4's light samplers: "uniform" (each light alike: a triangle of a mesh is a light),
            # "power", and "bvh" (its default; by importance to the point: our light BVH);
            # "exhaustive" (every light, by power) is read as "power"
            if sampler_name not in ("bvh", "power", "uniform"):
                self.warn(integ.params.items["lightsampler"].pos,
                          f'Integrator "string lightsampler" "{sampler_name}": read as "power"')
            st.light_sampler = sampler_name if sampler_name in ("bvh", "uniform") else "power"
            if integ.params.boolean("regularize", False):
                self.warn(integ.params.items["regularize"].pos, "Integrator: regularize is not supported; ignored")
            self.unused(integ)
        st.filter = self.pixel_filter(self.options.get("PixelFilter"))
        self.expose(ratio)
        if self.camera is not None:
            self.finish_camera(*self.camera)
        self.motion_time()

    def expose(self, ratio: float) -> None:
        """Every emitter's radiance (area lights, lights, the environment) times ``ratio``: for our
        linear renderer, the image of pbrt's film scaled by its imaging ratio."""
        if ratio == 1.0:
            return
        seen = set()
        for mat in self.b.materials:
            if id(mat) not in seen and mat.is_emissive:
                seen.add(id(mat))
                mat.emission = tuple(float(c) * ratio for c in mat.emission)
        for light in self.b.lights:
            for key in ("intensity", "irradiance"):
                if hasattr(light, key) and not (key == "irradiance" and hasattr(light, "scale")):
                    setattr(light, key, tuple(float(c) * ratio for c in getattr(light, key)))
            if hasattr(light, "scale"):  # the projector: scale x the texel
                light.scale = float(light.scale) * ratio
        env = self.b.environment
        if isinstance(env, EnvMap):
            self.b.environment = dataclasses.replace(env, scale=tuple(float(c) * ratio for c in env.scale))
        elif env is not None:
            self.b.environment = dataclasses.replace(env, radiance=tuple(float(c) * ratio for c in env.radiance))

    def pixel_filter(self, pf: Directive | None) -> PixelFilter:
        """pbrt-v4's filters and defaults (a gaussian of radius 1.5 and sigma 0.5 without PixelFilter)."""
        if pf is None:
            return PixelFilter("gaussian", (1.5, 1.5), sigma=0.5)
        t, p = pf.args[0], pf.params
        default_radius = {"box": 0.5, "gaussian": 1.5, "mitchell": 2.0, "sinc": 4.0, "triangle": 2.0}.get(t)
        if default_radius is None:
            self.warn(pf.pos, f'PixelFilter "{t}": not supported; using pbrt\'s default, a gaussian (radius 1.5, sigma 0.5)')
            default_radius, t = 1.5, "gaussian"
        radius = (p.float("xradius", default_radius), p.float("yradius", default_radius))
        kind = {"sinc": "lanczos", "triangle": "tent"}.get(t, t)
        flt = PixelFilter(kind, radius)
        if kind == "gaussian":
            flt = dataclasses.replace(flt, sigma=p.float("sigma", 0.5))
        elif kind == "mitchell":
            flt = dataclasses.replace(flt, b=p.float("B", 1 / 3), c=p.float("C", 1 / 3))
        elif kind == "lanczos":
            flt = dataclasses.replace(flt, tau=p.float("tau", 3.0))
        self.unused(pf)
        try:
            return flt.checked()
        except ValueError as exc:
            raise error_at(pf.pos, f'PixelFilter "{pf.args[0]}": {exc}') from None

    def finish_camera(self, d: Directive, camera_from_world, medium: str = "") -> None:
        st, p = self.b.settings, d.params
        self.b.camera_medium = self.medium_index(medium, d.pos)
        if d.args[0] == "orthographic":
            return self.orthographic(d, camera_from_world)
        if d.args[0] != "perspective":
            self.warn(d.pos, f'Camera "{d.args[0]}": not supported; using a camera that frames the scene')
            return
        fov = p.float("fov", 90.0)
        if not 0 < fov < 180:
            raise error_at(d.pos, f"Camera: fov must be between 0 and 180 degrees, got {fov:g}")
        lens = p.float("lensradius", 0.0)
        focus = p.float("focaldistance", 1e6)
        for key in ("screenwindow", "frameaspectratio"):
            if key in p:
                self.warn(p.items[key].pos, f'Camera "{key}": not supported; ignored')
                p.items[key].used = True
        # pbrt's fov spans the shorter image side (of whatever size it is rendered at)
        self.b.camera, self.b.mirror = camera_from_matrix(np.linalg.inv(camera_from_world), fov, 1.0,
                                                          fov_axis="smaller", aperture=max(lens, 0.0),
                                                          focus=focus if lens > 0 else None)
        self.unused(d)

    def orthographic(self, d: Directive, camera_from_world) -> None:
        """pbrt-v4's orthographic camera: the screen window (default [-a, a] x [-1, 1] for a frame
        aspect ratio a > 1, else [-1, 1] x [-1 / a, 1 / a]) in camera space at z = 0, seen along +z."""
        st, p = self.b.settings, d.params
        frame = p.float("frameaspectratio", st.width / st.height)
        if not frame > 0:
            raise error_at(d.pos, f"Camera: frameaspectratio must be > 0, got {frame:g}")
        window = (-frame, frame, -1.0, 1.0) if frame > 1 else (-1.0, 1.0, -1.0 / frame, 1.0 / frame)
        window = p.numbers("screenwindow", n=4, default=window)
        x0, x1, y0, y1 = map(float, window)
        if not (x1 > x0 and y1 > y0):
            raise error_at(d.pos, f"Camera: the screen window {list(window)} is empty or flipped")
        m = np.linalg.inv(camera_from_world)
        half_width, half_height = np.linalg.norm(m[:3, 0]) * (x1 - x0) / 2, np.linalg.norm(m[:3, 1]) * (y1 - y0) / 2
        axes = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
        if not np.isclose(half_width / st.width, half_height / st.height, rtol=1e-5) or \
                not np.allclose(axes.T @ axes, np.eye(3), atol=1e-6):
            self.warn(d.pos, 'Camera "orthographic": the screen window or the transform make pixels that are not '
                             "square: the window's height is kept")
        centred = m.copy()
        centred[:3, 3] = m[:3, 3] + m[:3, 0] * (x0 + x1) / 2 + m[:3, 1] * (y0 + y1) / 2
        lens = p.float("lensradius", 0.0)
        focus = p.float("focaldistance", 1e6)
        self.b.camera, self.b.mirror = camera_from_matrix(centred, 40.0, 1.0, aperture=max(lens, 0.0),
                                                          focus=focus if lens > 0 else None,
                                                          projection="orthographic", extent=2 * half_height)
        self.unused(d)

    # -- materials, textures, lights ---------------------------------------------------------------

    def d_Material(self, d):
        self.state.material = self.materials.make(d.args[0], d.params, d.pos, f'Material "{d.args[0]}"')

    def d_MakeNamedMaterial(self, d):
        mtype = d.params.string("type")
        if mtype is None:
            raise error_at(d.pos, f'MakeNamedMaterial "{d.args[0]}" needs "string type"')
        self.materials.named[d.args[0]] = self.materials.make(mtype, d.params, d.pos, f'material "{d.args[0]}"',
                                                              name=d.args[0])

    def d_NamedMaterial(self, d):
        self.state.material = ("named", d.args[0], d.pos)

    def d_Texture(self, d):
        self.materials.texture(d)

    def d_AreaLightSource(self, d):
        if d.args[0] != "diffuse":
            self.warn(d.pos, f'AreaLightSource "{d.args[0]}": not supported; ignored')
            return
        radiance = spectrum_rgb(self, d.params, "L", (1.0, 1.0, 1.0))
        s = d.params.float("scale", 1.0)
        if "power" in d.params:
            self.warn(d.params.items["power"].pos, 'AreaLightSource "power": not supported; using "L"')
            d.params.items["power"].used = True
        self.state.area = (tuple(c * s for c in radiance), bool(d.params.boolean("twosided", False)))

    def d_LightSource(self, d):
        if self.moves():
            raise error_at(d.pos, f'LightSource "{d.args[0]}": a moving light (ActiveTransform) is not supported')
        light_source(self, d)

    def d_MakeNamedMedium(self, d):
        from .pbrt_media import make_medium

        if d.args[0] in self.named_media:
            raise error_at(d.pos, f'MakeNamedMedium: medium "{d.args[0]}" redefined')
        if self.moves():
            raise error_at(d.pos, f'MakeNamedMedium "{d.args[0]}": a moving medium (ActiveTransform) is not supported')
        self.named_media[d.args[0]] = make_medium(self, d, self.state.ctm.copy())

    def d_MediumInterface(self, d):
        inside = d.args[0]
        outside = d.args[1] if len(d.args) > 1 and d.args[1] is not None else inside
        self.state.inside, self.state.outside = inside, outside

    def medium_index(self, name: str, pos) -> int:
        """The scene's index of the named medium ("": vacuum, -1)."""
        if not name:
            return -1
        if name not in self.named_media:
            if _pbrt.SKIP_MISSING_FILES:  # the bench's probe: defined in a missing file? vacuum
                _pbrt.skipped_missing(f"{pos}: medium '{name}' is never defined (in a missing file?); vacuum")
                return -1
            raise error_at(pos, f'medium "{name}" is not defined (MakeNamedMedium before its use)')
        medium = self.named_media[name]
        return -1 if medium is None else self.b.medium_index(medium)

    def _interface(self, null: bool, pos):
        """The shapes' medium interface: a transition where the inside and outside media differ (as
        pbrt's IsMediumTransition), index-matched under an "interface" material."""
        inside, outside = self.state.inside, self.state.outside
        transition = inside != outside
        if not transition and not null:
            return None
        interior, exterior = (self.medium_index(inside, pos), self.medium_index(outside, pos)) if transition else (-1, -1)
        return MediumInterface(interior, exterior, transition=transition, null=null)

    def d_Attribute(self, d):
        self.warn(d.pos, f'Attribute "{d.args[0]}": default parameters are not supported; ignored')
        for p in d.params.items.values():
            p.used = True

    # -- shapes ----------------------------------------------------------------------------------

    def _material(self, pos) -> Material | None:
        mat = self.state.material
        if isinstance(mat, tuple):
            _, mname, mpos = mat
            if mname not in self.materials.named:
                raise error_at(mpos, f"NamedMaterial: no material named '{mname}' (MakeNamedMaterial)")
            mat = self.materials.named[mname]
        if mat is None:  # "interface"
            return None
        if self.state.area is not None and self.b.recording is not None:
            self.warn(pos, "AreaLightSource in ObjectBegin: area lights are not supported with object instancing "
                           "(as in pbrt-v4); the shape does not emit")
        elif self.state.area is not None:
            radiance, two_sided = self.state.area
            mat = self.b.emissive(mat, radiance, two_sided)
        return mat

    def _alpha(self, d, mat):
        """The shape's material as pbrt-v4's alpha cut-out ("float alpha" or "texture alpha", a float
        texture's first channel): Material.cutout, tested in the intersection (cl/scene/scene.h)."""
        import dataclasses

        q = d.params.items["alpha"]
        q.used = True
        tex = None
        if q.type == "texture":
            tname = d.params.string("alpha", types=("texture",))
            if tname not in self.materials.textures:
                raise error_at(q.pos, f'"texture alpha": no texture named "{tname}"')
            rgb, tex = self.materials.textures[tname]
            value = 1.0 if tex is not None else float(rgb[0])
        else:
            value = d.params.float("alpha", 1.0)
        if tex is None and value >= 1.0:
            return mat
        key = (id(mat), value, id(tex))
        cache = self.__dict__.setdefault("_alpha_materials", {})
        if key not in cache:
            cut = dataclasses.replace(mat, cutout=True, opacity=min(max(value, 0.0), 1.0), alpha_cutoff=0.0,
                                      scalar_textures=dict(mat.scalar_textures), params=dict(mat.params))
            if tex is not None:
                from ..textures import Texture

                if not isinstance(tex, Texture):
                    raise error_at(d.pos, f'Shape "{d.args[0]}": a directionmix "alpha" is not supported')
                first = np.repeat(tex.texels[..., :1], 4, axis=-1)  # pbrt's float textures read channel 0
                first[..., 3] = 1.0  # (its mapping kept: scene/validate.py refuses one of the hit point)
                cut.scalar_textures["opacity"] = dataclasses.replace(tex, texels=np.ascontiguousarray(first), channels=1)
            cache[key] = (cut, mat)  # keep mat alive: the key holds its id
        return cache[key][0]

    def d_Shape(self, d):
        from .pbrt_shapes import cylinder_triangles, shape_geometry

        mat = self._material(d.pos)
        interface = self._interface(mat is None, d.pos)
        if mat is None:  # "interface": a boundary of media only, which does not scatter
            if self.null_material is None:
                self.null_material = Material(name="pbrt-interface", albedo=(0.0, 0.0, 0.0))
            mat = self.null_material
        if "alpha" in d.params:
            mat = self._alpha(d, mat)
        if self.moves():
            return self._moving_shape(d, mat, interface)
        geometry = shape_geometry(self, d)
        if geometry is None:
            return
        m, flip = self.state.ctm, self.state.reverse
        if singular(m):
            if d.args[0] in QUADRICS:  # intersected in object space through the inverse: never hit
                return
            geometry = _flattened(geometry, m)  # moved by m as pbrt-v4 moves them
            if geometry is None:
                return
            m = None
        quadric = geometry[0] if isinstance(geometry[0], str) else None
        if quadric == "sphere":  # ("sphere", radius)
            _, radius = geometry
            self._sphere(transform_points(m, [0, 0, 0])[0], radius, m, mat, d.pos, flip, interface)
            return
        if quadric == "disk":  # ("disk", radius, height): analytic, its front as a mesh's would be
            to_world = m @ np.diag([geometry[1], geometry[1], 1.0, 1.0])
            to_world[:3, 3] += m[:3, 2] * geometry[2]
            if not mat.textures():  # ours have no uv: a textured one is pbrt's triangles (disk_mesh)
                self.b.add_shape("disk", SHAPES["disk"].params(to_world, flip), mat, interface=interface)
                return
            geometry = disk_mesh(geometry[1], 0.0, geometry[2], 360.0)
        if quadric == "cylinder":  # ("cylinder", radius, zmin, zmax): analytic under a similarity
            _, radius, zmin, zmax = geometry
            to_world = m @ np.diag([radius, radius, zmax - zmin, 1.0])
            to_world[:3, 3] += m[:3, 2] * zmin
            p = None if mat.textures() else SHAPES["cylinder"].params(to_world, flip)
            if p is not None:
                self.b.add_shape("cylinder", p, mat, interface=interface)
                return
            geometry = cylinder_triangles(radius, zmin, zmax)  # textured or elliptic: pbrt's triangles
        v, f, uv, *rest = geometry
        normals = rest[0] if rest else None
        self.b.add_mesh(v, f, mat, uvs=uv, matrix=m, flip=flip, normals=normals, interface=interface)

    def _sphere(self, centre, radius, m, mat, pos, flip, interface=None) -> None:
        s = np.linalg.svd(m[:3, :3], compute_uv=False)
        # scaled unevenly (an ellipsoid), or textured (our spheres take no textures): triangles, exact normals
        if s.max() - s.min() > 1e-6 * s.max() or mat.textures():
            v, f, uv = sphere_mesh(radius)
            self.b.add_mesh(v, f, mat, uvs=uv, matrix=m, flip=flip, normals=(v / radius)[f], interface=interface)
            return
        if flip and mat.is_emissive:
            self.warn(pos, 'Shape "sphere": ReverseOrientation: our spheres emit outwards only')
        if flip and interface is not None:  # its normal points inwards: inside and outside trade places
            interface = interface.flipped()
        self.b.add_sphere(centre, radius * float(s.mean()), mat, interface=interface)
