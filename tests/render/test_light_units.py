"""The light types as units (pyopencl_rt/scene/lights/, cl/lights/): the kernel's light enum, the
headers that sample each type and the host modules agree; the generated "lights/units.h" lists
every unit; each registered type reads its TOML table, packs its record (the kind the kernels
dispatch on) and survives a mirror and the Mitsuba export as a light of its type.  The images these
units make are checked elsewhere (test_lights.py: closed forms and every lane width alike;
test_features.py: bit for bit against each scene's own kernel).  Host-only."""
import importlib
import pkgutil
import re
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.device.cl_header import SURFACE_LIGHTS, light_units
from pyopencl_rt.device.kernels import assemble
from pyopencl_rt.render.lights import INFINITE_LIGHTS, other_lights
from pyopencl_rt.scene import lights
from pyopencl_rt.scene.lights import REGISTRY, UNREGISTERED, light_type
from pyopencl_rt.scene.loaders.values import ErrorContext, TableReader
from pyopencl_rt.scene.model import Material, Scene

REPO = Path(__file__).resolve().parents[2]
CL_LIGHTS = REPO / "cl" / "lights"

# one TOML table per registered type (the required keys and one more)
TABLES = {
    "point": {"position": [1.0, 2.0, 3.0], "intensity": [4.0, 5.0, 6.0]},
    "directional": {"direction": [0.0, -2.0, 0.0], "irradiance": 2.0},
    "spot": {"position": [0.0, 1.0, 0.0], "look_at": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0], "cutoff_angle": 30.0},
    "projector": {"position": [0.0, 1.0, 0.0], "look_at": [0.0, 0.0, 1.0], "fov": 40.0},
    "goniometric": {"position": [0.0, 1.0, 0.0], "look_at": [0.0, 0.0, 1.0], "intensity": 2.0},
}


def unit_headers() -> set:
    """Headers of cl/lights/ that define a type's sampling, ``light_sample_<name>(``, and its case."""
    return {h.stem for h in CL_LIGHTS.glob("*.h")
            if re.search(rf"\blight_sample_{h.stem}\s*\(", h.read_text())
            and f"#define LIGHT_CASE_{h.stem.upper()}(X) X({h.stem}, {h.stem.upper()})" in h.read_text()
            and "ls->delta" not in h.read_text()}  # the dispatch's, from abi.DELTA_LIGHTS


def host_modules() -> set:
    return {info.name for info in pkgutil.iter_modules(lights.__path__)
            if hasattr(importlib.import_module(f"{lights.__name__}.{info.name}"), "pack")}


def one_triangle(lights_) -> Scene:
    return Scene(vertices=np.array([[-1.0, 0, -1], [1, 0, -1], [0, 0, 1]], np.float32),
                 faces=np.array([[0, 1, 2]], np.int32), face_materials=np.zeros(1, np.int32),
                 materials=[Material(name="white")], lights=lights_)


def test_enum_kernel_units_and_host_modules_agree():
    kernel_units = set(abi.LIGHT_TYPES) - set(SURFACE_LIGHTS)
    assert unit_headers() == kernel_units
    assert host_modules() == set(REGISTRY) == set(abi.LIGHT_TYPES) - set(UNREGISTERED)
    assert {name: t.kind for name, t in REGISTRY.items()} == {n: abi.LIGHT_TYPES[n] for n in REGISTRY}
    assert set(TABLES) == set(REGISTRY), "a new type needs its table here"


def test_the_generated_header_lists_every_unit_in_the_enums_order():
    text = light_units(abi.LIGHT_TYPES, abi.DELTA_LIGHTS)
    units = [n for n in abi.LIGHT_TYPES if n not in SURFACE_LIGHTS]
    assert re.findall(r'#include "lights/(\w+)\.h"', text) == units
    assert re.findall(r"LIGHT_CASES\(X\) (.*)", text)[0].split() == [f"LIGHT_CASE_{n.upper()}(X)" for n in units]
    delta = dict(re.findall(r"#define LIGHT_DELTA_(\w+) (\d)", text))
    assert delta == {n.upper(): str(int(abi.LIGHT_TYPES[n] in abi.DELTA_LIGHTS)) for n in units}
    source = assemble("megakernel/path.cl")  # the dispatch reaches each unit through the cases
    assert "LIGHT_CASES(LIGHT_SAMPLE_CASE)" in source
    for name in units:
        assert f"light_sample_{name}(LIGHT_UNIT_PARAMS)" in source


def test_infinitely_far_kinds_come_from_the_types():
    assert set(INFINITE_LIGHTS) == {abi.LIGHT_ENVIRONMENT} | {t.kind for t in REGISTRY.values() if t.infinite}
    assert abi.LIGHT_DIRECTIONAL in INFINITE_LIGHTS and abi.LIGHT_POINT not in INFINITE_LIGHTS


@pytest.mark.parametrize("name", sorted(TABLES))
def test_each_type_reads_packs_mirrors_and_exports(name):
    t = REGISTRY[name]
    light = t.read_toml(TableReader(ErrorContext("test.toml"), f"[[light]] ({name})", TABLES[name]))
    assert isinstance(light, t.light) and light_type(light) is t
    scene = one_triangle([light])
    recs, power = other_lights(scene)
    assert recs["kind"].tolist() == [t.kind] and np.isfinite(power).all() and power[0] > 0
    flip = np.diag([-1.0, 1.0, 1.0, 1.0])  # a mirror in x
    mirrored = t.transformed(light, flip)
    assert type(mirrored) is t.light
    twice = t.transformed(mirrored, flip)
    for field in ("position", "direction"):
        if hasattr(light, field):
            assert np.allclose(getattr(twice, field), getattr(light, field))
            assert np.allclose(getattr(mirrored, field), np.asarray(getattr(light, field)) * [-1, 1, 1])
    if t.mitsuba_plugins:
        assert t.to_mitsuba(light)["type"] in t.mitsuba_plugins
    else:  # no such emitter in Mitsuba 3: the export refuses it in one line
        with pytest.raises(ValueError, match="not exported to Mitsuba"):
            t.to_mitsuba(light)


def test_an_object_of_no_registered_type_is_refused():
    with pytest.raises(TypeError, match="unknown light"):
        light_type(object())
    with pytest.raises(TypeError, match="unknown light"):
        other_lights(one_triangle([object()]))


MITSUBA = {"point": '<emitter type="point"><point name="position" value="1, 2, 3"/></emitter>',
           "directional": '<emitter type="directional"><vector name="direction" value="0, -1, 0"/></emitter>',
           "spot": '<emitter type="spot"><float name="cutoff_angle" value="30"/></emitter>',
           "projector": '<emitter type="projector"><float name="fov" value="40"/></emitter>'}
PBRT = {"point": 'LightSource "point" "point3 from" [1 2 3]',
        "distant": 'LightSource "distant" "point3 from" [0 1 0] "point3 to" [0 0 0]',
        "spot": 'LightSource "spot" "point3 from" [0 1 0] "point3 to" [0 0 0] "float coneangle" 25',
        "projection": 'LightSource "projection" "string filename" "square.png"',
        "goniometric": 'LightSource "goniometric" "string filename" "square.png"'}


@pytest.mark.filterwarnings("ignore:.*interpolated bilinearly")  # the projection's one line
def test_the_file_formats_reach_each_type_through_the_registry(tmp_path):
    """Each Mitsuba emitter plugin and pbrt-v4 LightSource type a registered type claims is read by
    that type (its dataclass in Scene.lights), and the Mitsuba parameters it honours are the
    plugin table's."""
    from PIL import Image
    from pyopencl_rt import load_scene
    from pyopencl_rt.scene.lights import MITSUBA_TYPES, PBRT_TYPES
    from pyopencl_rt.scene.loaders.mitsuba_plugins import HONOURED

    assert set(MITSUBA_TYPES) == set(MITSUBA) and set(PBRT_TYPES) == set(PBRT)
    Image.fromarray(np.full((4, 4, 3), 200, np.uint8)).save(tmp_path / "square.png")
    for plugin, t in MITSUBA_TYPES.items():
        assert HONOURED["emitter"][plugin] == t.mitsuba_plugins[plugin]
        path = tmp_path / f"{plugin}.xml"
        path.write_text(f'<scene version="3.0.0"><shape type="rectangle"/>{MITSUBA[plugin]}</scene>')
        (light,) = load_scene(path).lights
        assert light_type(light) is t, plugin
    for name, t in PBRT_TYPES.items():
        path = tmp_path / f"{name}.pbrt"
        path.write_text('LookAt 0 0 5  0 0 0  0 1 0\nCamera "perspective"\nWorldBegin\n'
                        f'{PBRT[name]}\nShape "sphere" "float radius" 1\n')
        (light,) = load_scene(path).lights
        assert light_type(light) is t, name


def test_a_goniometric_profile_must_be_square_and_finite(tmp_path):
    """pbrt-v4 refuses a profile that is not square (not an equal-area map) or not finite: so do we,
    in one line naming the file's place, from TOML and from pbrt-v4."""
    from PIL import Image

    from pyopencl_rt import load_scene
    from pyopencl_rt.imageio import write_exr
    from pyopencl_rt.scene.loaders.values import SceneError

    Image.fromarray(np.full((4, 8, 3), 200, np.uint8)).save(tmp_path / "wide.png")
    bad = np.ones((4, 4, 3), np.float32)
    bad[1, 2] = np.inf
    write_exr(tmp_path / "inf.exr", bad)
    toml = tmp_path / "g.toml"
    toml.write_text('[[shape]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1\n\n[[light]]\ntype = "goniometric"\n'
                    'position = [0, 3, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, 1]\ntexture = "wide.png"\n')
    with pytest.raises(SceneError, match=r"g\.toml: \[\[light\]\] #1 \(goniometric\): the profile image is 8 x 4, not square"):
        load_scene(toml)
    for image, what in (("wide.png", "not square"), ("inf.exr", "infinite or NaN")):
        path = tmp_path / "g.pbrt"
        path.write_text('LookAt 0 0 5  0 0 0  0 1 0\nCamera "perspective"\nWorldBegin\n'
                        f'LightSource "goniometric" "string filename" "{image}"\nShape "sphere" "float radius" 1\n')
        with pytest.raises(SceneError, match=rf'g\.pbrt:4: LightSource "goniometric": .*{what}'):
            load_scene(path)
