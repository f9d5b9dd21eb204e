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

from dataclasses import asdict, dataclass, fields

import numpy as np

from ..device import abi
from ..errors import UserError
from ..scene.model import INTEGRATORS  # MIS path tracing, BSDF sampling only, light sampling only

MAX_PIXELS = 1 << 26  # 8192 x 8192


@dataclass(frozen=True)
class ImageSettings:
    width: int
    height: int
    max_depth: int  # path segments at most: 1 shows emitters, 2 adds direct light; -1: no limit
    rr_depth: int  # Russian roulette starts after this many bounces
    integrator: str
    seed: int  # 32 bits: the kernels' RNG key

    @classmethod
    def resolve(cls, scene, *, width=None, height=None, max_depth=None, rr_depth=None, integrator=None,
                seed=None) -> "ImageSettings":
        """The scene's settings with every argument that is not None taking precedence; a
        UserError (one line) for values no render can use."""
        st = scene.settings
        settings = cls(
            width=int(st.width if width is None else width),
            height=int(st.height if height is None else height),
            max_depth=int(st.max_depth if max_depth is None else max_depth),
            rr_depth=int(st.rr_depth if rr_depth is None else rr_depth),
            integrator=str(st.integrator if integrator is None else integrator),
            seed=int(st.seed if seed is None else seed) & 0xFFFFFFFF,
        )
        settings.check()
        return settings

    def check(self) -> None:
        check_resolution(self.width, self.height)
        if self.max_depth == 0:
            raise UserError("--max-depth 0 renders nothing: use 1 for emitters only, -1 for no limit")
        if self.integrator not in INTEGRATORS:
            raise UserError(f"unknown integrator {self.integrator!r}: use one of {', '.join(INTEGRATORS)}")

    @property
    def n_pixels(self) -> int:
        return self.width * self.height

    def as_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> "ImageSettings":
        return cls(**{f.name: values[f.name] for f in fields(cls)})

    def differences(self, values: dict) -> str:
        """'name theirs -> mine' for each setting that ``values`` (e.g. a checkpoint's record) has otherwise."""
        mine = self.as_dict()
        return ", ".join(f"{k} {values[k]!r} -> {v!r}" for k, v in mine.items() if k in values and values[k] != v)


IMAGE_SETTINGS = tuple(f.name for f in fields(ImageSettings))


def check_resolution(width, height) -> None:
    if int(width) < 1 or int(height) < 1 or int(width) * int(height) > MAX_PIXELS:
        raise UserError(f"impossible resolution {width}x{height}: each side must be >= 1 and at most "
                        f"{MAX_PIXELS} pixels in all")


def check_run(spp=None, time_limit=None) -> None:
    """The arguments that say how long to render."""
    if spp is not None and int(spp) < 1:
        raise UserError(f"--spp must be at least 1 (got {spp})")
    if time_limit is not None and not (float(time_limit) > 0):
        raise UserError(f"--time-limit must be positive (got {time_limit})")


def kernel_features(scene, settings: ImageSettings, lights: np.ndarray, bvh_layout: str) -> dict:
    """Every preprocessor define of the wavefront program: only what the scene uses is compiled.

    ``lights`` is the light table of :func:`pyopencl_rt.render.lights.build_lights`,
    ``bvh_layout`` the node format the device traverses (:mod:`pyopencl_rt.accel.device_bvh`).
    """
    from ..accel.device_bvh import layout_defines

    defines = {"INTEGRATOR": INTEGRATORS.index(settings.integrator)}
    if len(scene.faces):
        defines["HAS_TRIANGLES"] = True
    if len(scene.spheres):
        defines["HAS_SPHERES"] = True
    defines.update(scene.material_defines())  # MATERIALS_SELECTED, HAS_MATERIAL_<TYPE>, HAS_TEXTURES
    kinds = lights["kind"] if len(lights) else np.zeros(0, np.int32)
    if len(kinds):
        defines["HAS_LIGHTS"] = True  # next-event estimation
    if np.isin(kinds, (abi.LIGHT_POINT, abi.LIGHT_DIRECTIONAL)).any():
        defines["HAS_DELTA_LIGHTS"] = True
    environment = np.flatnonzero(kinds == abi.LIGHT_ENVIRONMENT)
    if len(environment) > 1:
        raise ValueError("at most one environment light")
    if len(environment):
        defines["HAS_ENVIRONMENT"] = True
        defines["ENV_LIGHT"] = int(environment[0])  # its index in the light table
    if np.isin(kinds, (abi.LIGHT_DIRECTIONAL, abi.LIGHT_ENVIRONMENT)).any():
        defines["HAS_INFINITE_LIGHTS"] = True
    defines.update(layout_defines(bvh_layout))
    return defines


def feature_names(defines: dict) -> list[str]:
    """The defines as the sidecar lists them: NAME, or NAME=value."""
    return sorted(k if v is True else f"{k}={v}" for k, v in defines.items())
