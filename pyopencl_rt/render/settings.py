"""The settings of one render, resolved once, and the kernel features they imply.

:class:`ImageSettings` holds what determines the image: the same scene with equal settings gives
the same image, bit for bit, on the same device.  It is made once, by :meth:`ImageSettings.resolve`
from the scene's ``[film]``/``[render]`` tables and the caller's overrides (CLI options or API
arguments), and that one object is what the wavefront, the checkpoint key, the JSON sidecar, the
Dask workers and the Mitsuba export read.  Settings that do not change the image (device, wave
size, intersector) are arguments of the render, not part of it.

:func:`kernel_features` is the one place that decides every ``-D`` the wavefront program is built
with, so that a scene compiles only the code it uses.
"""
from __future__ import annotations

import math

from dataclasses import MISSING, asdict, dataclass, fields

import numpy as np

from ..device import abi
from .. import validate
from ..errors import UsageError, UserError
from ..scene.media import uses_spectral_mis
from ..scene.model import INTEGRATORS, SAMPLERS  # MIS path, BSDF only, light only; cl/render/sampler.h
from ..scene.pixel_filter import PixelFilter
from ..scene.shapes import shape_type
from .lights import INFINITE_LIGHTS

MAX_PIXELS = 1 << 26  # 8192 x 8192


@dataclass(frozen=True)
class ImageSettings:
    width: int
    height: int
    max_depth: int  # path segments at most: 1 shows emitters, 2 adds direct light; -1: no limit
    rr_depth: int  # Russian roulette starts after this many bounces
    integrator: str
    seed: int  # 32 bits: the kernels' RNG key
    # the kernels also record the per-sample AOVs (albedo, normal, depth, position) and the film
    # sums them (render/aovs.py): the beauty is the same, but the film is not
    film_aovs: bool = False
    sampler: str = "sobol"  # where the random numbers come from (cl/render/sampler.h)
    # adaptive sampling (render/adaptive.py): a pixel stops once its estimated relative error is at
    # most target_error, the spp then being each pixel's maximum (None: no target, the spp a mean)
    adaptive: bool = False
    target_error: float | None = None
    # the pixel reconstruction filter (render/filters.py): the camera samples' pixel offsets
    filter: PixelFilter = PixelFilter()

    @classmethod
    def resolve(cls, scene, *, width=None, height=None, max_depth=None, rr_depth=None, integrator=None,
                seed=None, aovs=None, sampler=None, adaptive=None, target_error=None,
                filter=None) -> "ImageSettings":
        """The scene's settings with every argument that is not None taking precedence; a
        UserError (one line) for values no render can use.  ``aovs``: the AOV layers wanted
        (names of render/aovs.py; default the scene's ``[film] aovs``)."""
        from .aovs import needs_kernel_aovs, parse_aovs

        st = scene.settings
        adaptive = validate.flag(getattr(st, "adaptive", False) if adaptive is None else adaptive, "--adaptive")
        if target_error is None and adaptive:  # the scene's target counts only when sampling is adaptive
            target_error = getattr(st, "target_error", None)
        settings = cls(
            width=validate.integer(st.width if width is None else width, "--width"),
            height=validate.integer(st.height if height is None else height, "--height"),
            max_depth=validate.integer(st.max_depth if max_depth is None else max_depth, "--max-depth", minimum=-1),
            rr_depth=validate.integer(st.rr_depth if rr_depth is None else rr_depth, "--rr-depth", minimum=0),
            integrator=validate.choice(st.integrator if integrator is None else integrator, "integrator",
                                       INTEGRATORS),
            seed=validate.seed(st.seed if seed is None else seed),  # 32 bits, never wrapped
            film_aovs=needs_kernel_aovs(parse_aovs(getattr(st, "aovs", ()) if aovs is None else aovs)),
            sampler=validate.choice(getattr(st, "sampler", "sobol") if sampler is None else sampler, "sampler",
                                    SAMPLERS),
            adaptive=adaptive,
            target_error=check_target_error(target_error),
            filter=check_filter(getattr(st, "filter", PixelFilter()) if filter is None else filter),
        )
        settings.check()
        return settings

    def check(self) -> None:
        check_resolution(self.width, self.height)
        if self.max_depth == 0:
            raise UsageError("--max-depth 0 renders nothing: use 1 for emitters only, -1 for no limit")
        if self.integrator not in INTEGRATORS:
            raise UsageError(f"unknown integrator {self.integrator!r}: use one of {', '.join(INTEGRATORS)}")
        if self.sampler not in SAMPLERS:
            raise UsageError(f"unknown sampler {self.sampler!r}: use one of {', '.join(SAMPLERS)}")
        check_filter(self.filter)
        if self.target_error is not None and not self.adaptive:
            raise UsageError("--target-error needs --adaptive (or adaptive = true in the scene's [render])")

    @property
    def n_pixels(self) -> int:
        return self.width * self.height

    def as_dict(self) -> dict:
        """JSON values (the filter as its dict)."""
        return {**asdict(self), "filter": self.filter.as_dict()}

    @classmethod
    def from_dict(cls, values: dict) -> "ImageSettings":
        """Settings from :meth:`as_dict`'s values (TypeError/ValueError for a filter that is none)."""
        settings = {f.name: values[f.name] if f.name in values or f.default is MISSING else f.default
                    for f in fields(cls)}
        settings["filter"] = PixelFilter.from_value(settings["filter"])
        return cls(**settings)

    def differences(self, values: dict) -> str:
        """'name theirs -> mine' for each setting that ``values`` (e.g. a checkpoint's record) has otherwise."""
        mine = self.as_dict()
        return ", ".join(f"{k} {values[k]!r} -> {v!r}" for k, v in mine.items() if k in values and values[k] != v)


IMAGE_SETTINGS = tuple(f.name for f in fields(ImageSettings))


def check_resolution(width, height) -> None:
    width, height = validate.integer(width, "--width"), validate.integer(height, "--height")
    if width < 1 or height < 1 or width * height > MAX_PIXELS:
        raise UsageError(f"impossible resolution {width}x{height}: each side must be >= 1 and at most "
                        f"{MAX_PIXELS} pixels in all")


def check_filter(value) -> PixelFilter:
    """A pixel filter (a PixelFilter or its dict), checked: UsageError (one line) if it is none."""
    from . import filters

    try:
        flt = PixelFilter.from_value(value)
    except (TypeError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    filters.check(flt)
    return flt


def check_target_error(value) -> float | None:
    """--target-error: a relative error > 0 (None: not given)."""
    return None if value is None else validate.number(value, "--target-error", positive=True)


def check_run(spp=None, time_limit=None) -> None:
    """The arguments that say how long to render."""
    if spp is not None:
        validate.integer(spp, "--spp", minimum=1)
    if time_limit is not None:
        validate.number(time_limit, "--time-limit", positive=True)


# $PYOPENCL_RT_KERNEL_FEATURES=all: one program for every scene of a schedule, width, sampler and
# integrator (EVERY_FEATURE below compiled in, whether the scene uses it or not): no new build
# when a scene gains a texture or a light type, at the price of a longer first build.  The image
# is the same bit for bit (tests/render/test_features.py); the test suite runs so.
FEATURES_ENV = "PYOPENCL_RT_KERNEL_FEATURES"
# The defines that only gate code the scene's data selects at run time (a material's type and
# flags, a light's kind, a shape's type, n_lights, env_light, light_tree, the camera's motion
# record; the BVH of a scene without triangles, and the shapes' BVH without shapes, is one empty root).  HAS_MEDIA (the volumetric integrator),
# HAS_INSTANCES (the two-level BVH, and with it HAS_MOTION: an instance record's motion) and
# HAS_AOVS (a setting) stay the scene's.
EVERY_FEATURE = ("HAS_SHAPES", *(f"HAS_SHAPE_{name.upper()}" for name in abi.SHAPE_TYPES), "HAS_TEXTURES",
                 "HAS_SHADING_NORMALS", "HAS_NORMAL_MAPS", "HAS_VERTEX_COLORS", "HAS_CUTOUTS", "HAS_ANISOTROPY", "HAS_DELTA_LIGHTS", "HAS_ENVIRONMENT", "HAS_INFINITE_LIGHTS",
                 "HAS_TRIANGLES", "HAS_LIGHTS", "LIGHT_TREE", "HAS_CAMERA_MOTION")

# The defines that "all" replaces by a run-time choice: every material type compiled in, and the
# kernels' `sampler`, `max_component`, `light_tree` and `spectral_mis` arguments (cl/render/sampler.h,
# cl/common.h clamp_sample, cl/render/path.h nee_light_sample, cl/render/volpath.h), read where the
# *_RUNTIME defines say.
RUN_TIME_CHOICES = ("MATERIALS_SELECTED", "SAMPLER", "MAX_COMPONENT_VALUE", "SPECTRAL_MIS")
RUN_TIME_DEFINES = ("MAX_COMPONENT_RUNTIME", "LIGHT_TREE_RUNTIME")

# Material types (besides diffuse) from which a program calls its BSDF dispatch out of line
# (RT_BSDF_NOINLINE): the build of a program of every type takes half the time, and scenes of one
# or two types, whose renders lose 3-6% of their speed so, keep it inline (docs/BENCHMARKS.md).
BSDF_OUT_OF_LINE_TYPES = 3


def max_component_value(scene) -> float:
    """Film maxcomponentvalue (pbrt-v4): the largest XYZ component of a camera sample, +inf: none."""
    value = getattr(scene.settings, "max_component_value", None)
    return math.inf if value is None or not math.isfinite(value) else float(value)


def every_feature() -> bool:
    """Whether $PYOPENCL_RT_KERNEL_FEATURES asks for every feature ("all"; "scene", the default:
    only what the scene uses)."""
    import os

    value = os.environ.get(FEATURES_ENV, "scene").strip().lower() or "scene"
    if value not in ("all", "scene"):
        raise UsageError(f"${FEATURES_ENV} must be 'scene' or 'all', not {value!r}")
    return value == "all"


def has_light_tree(lights: np.ndarray) -> bool:
    """Whether the light table has rows in the light BVH (light_sampler "bvh"; the kernels' light_tree)."""
    return bool(len(lights) and (lights["trail"] >= 0).any())


def environment_row(lights: np.ndarray) -> int:
    """The environment light's row in the light table (the kernels' env_light), -1 if none."""
    rows = np.flatnonzero(lights["kind"] == abi.LIGHT_ENVIRONMENT) if len(lights) else ()
    if len(rows) > 1:
        raise ValueError("at most one environment light")
    return int(rows[0]) if len(rows) else -1


def kernel_features(scene, settings: ImageSettings, lights: np.ndarray, bvh_layout: str) -> dict:
    """Every preprocessor define of the wavefront program: only what the scene uses is compiled
    (or, with $PYOPENCL_RT_KERNEL_FEATURES=all, :data:`EVERY_FEATURE` too).

    ``lights`` is the light table of :func:`pyopencl_rt.render.lights.build_lights`,
    ``bvh_layout`` the node format the device traverses (:mod:`pyopencl_rt.accel.device_bvh`).
    """
    from ..accel.device_bvh import layout_defines

    defines = {"SAMPLER": abi.SAMPLERS[settings.sampler]}  # the integrator: a kernel argument
    if len(scene.faces):
        defines["HAS_TRIANGLES"] = True
    if len(scene.shapes):
        defines["HAS_SHAPES"] = True  # cl/scene/shapes.h, and each type's unit (cl/shapes/)
        for code in np.unique(scene.shapes["type"]):
            defines[f"HAS_SHAPE_{shape_type(code).name.upper()}"] = True
    if getattr(scene, "blas_groups", None):
        defines["HAS_INSTANCES"] = True  # the two-level BVH (cl/accel/instances.h): never in "all"
        if any(i.moves for i in scene.instances):
            defines["HAS_MOTION"] = True  # moving instances (motion blur; "all" adds it with HAS_INSTANCES)
    if getattr(scene, "camera_motion", None) is not None:
        defines["HAS_CAMERA_MOTION"] = True  # a moving camera (cl/render/path.h camera_moved)
    defines.update(scene.material_defines())  # MATERIALS_SELECTED, HAS_MATERIAL_<TYPE>, HAS_TEXTURES
    kinds = lights["kind"] if len(lights) else np.zeros(0, np.int32)
    if len(kinds):
        defines["HAS_LIGHTS"] = True  # next-event estimation
    if np.isin(kinds, abi.DELTA_LIGHTS).any():
        defines["HAS_DELTA_LIGHTS"] = True
    if environment_row(lights) >= 0:
        defines["HAS_ENVIRONMENT"] = True
    if np.isin(kinds, INFINITE_LIGHTS).any():
        defines["HAS_INFINITE_LIGHTS"] = True
    if has_light_tree(lights):
        defines["LIGHT_TREE"] = True  # light_sampler "bvh" (cl/render/light_tree.h)
    defines.update(layout_defines(bvh_layout))
    if settings.film_aovs:
        defines["HAS_AOVS"] = True  # cl/render/aov.h
    max_component = max_component_value(scene)
    if math.isfinite(max_component):
        defines["MAX_COMPONENT_VALUE"] = f"{max_component!r}f"  # cl/common.h clamp_sample
    if scene.has_media():
        defines["HAS_MEDIA"] = True  # the volumetric integrator (cl/render/volpath.h)
        if uses_spectral_mis(scene):
            defines["SPECTRAL_MIS"] = True  # chromatic sigma_t: the balance heuristic over the channels
    if sum(k.startswith("HAS_MATERIAL_") for k in defines) >= BSDF_OUT_OF_LINE_TYPES or every_feature():
        defines["RT_BSDF_NOINLINE"] = True  # cl/materials/dispatch.h: one copy of the BSDF dispatch
    if every_feature():
        defines = {k: v for k, v in defines.items() if not k.startswith("HAS_MATERIAL_") and k not in RUN_TIME_CHOICES}
        defines.update(dict.fromkeys(EVERY_FEATURE, True))  # and every material type (no MATERIALS_SELECTED)
        defines.update(dict.fromkeys(RUN_TIME_DEFINES, True))
        defines["RT_NEE_NOINLINE"] = True  # cl/render/path.h: a shorter build of the biggest programs
        if "HAS_MEDIA" in defines:
            defines.update(SPECTRAL_MIS=True, SPECTRAL_MIS_RUNTIME=True)  # the kernels' spectral_mis
        if "HAS_INSTANCES" in defines:
            defines["HAS_MOTION"] = True  # an instance record's motion -1: it stays (cl/accel/instances.h)
    return defines


def feature_names(defines: dict) -> list[str]:
    """The defines as the sidecar lists them: NAME, or NAME=value."""
    return sorted(k if v is True else f"{k}={v}" for k, v in defines.items())
