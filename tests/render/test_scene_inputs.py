"""The checkpoint's scene key covers every scene buffer the kernels receive (issue 36): the table of
pyopencl_rt/render/scene_inputs.py and the kernel ABI agree, a change of any array the key is made
of changes the key (a key that dropped one would not), and the changes that the old hand-kept list
missed (texels, UVs, media, medium interfaces, emitter indices) are refused on resume."""
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.render import checkpoint as ckp
from pyopencl_rt.render import scene_inputs as si
from pyopencl_rt.render.film import Film
from pyopencl_rt.render.settings import ImageSettings
from pyopencl_rt.scene.loaders import load_scene

from test_checkpoint import two_level_scene  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SETTINGS = ImageSettings(width=4, height=4, max_depth=3, rr_depth=3, integrator="path", seed=1)


def test_every_parameter_says_where_it_comes_from_and_scene_ones_have_an_input():
    """Each kernel parameter is sourced from the scene, the settings or the run; the scene's are
    exactly the table's keys; the settings' are fields the render key hashes."""
    scene_params = {p.name for p in abi.WAVE_PARAMS if p.source == "scene"}
    assert scene_params == set(si.SCENE_INPUTS)
    settings_fields = set(SETTINGS.as_dict())
    derived = {"n_pixels": {"width", "height"}, "filter_cdf": {"filter"}}
    for p in abi.WAVE_PARAMS:
        if p.source == "settings":
            assert derived.get(p.name, {p.name}) <= settings_fields, p.name
        if p.source == "run":
            assert p.per_slot or p.launch or p.kind == "global" or p.name in ("pixel_list", "ring_size"), p.name


def _rich_scenes():
    """Scenes that between them make every input function return arrays: media and a grid, textures
    and UVs, an environment map, spheres, lights, two-level instances, shading normals and colours."""
    fog = load_scene(REPO / "scenes/cornell-fog.toml")
    textured = load_scene(REPO / "scenes/textured.toml")
    sky = load_scene(REPO / "scenes/textured-sky.toml")
    corners = load_scene(REPO / "scenes/cornell-box.toml")
    n = len(corners.faces)
    rng = np.random.default_rng(1)
    corners.normals = rng.normal(size=(n * 3, 3)).astype(np.float32)
    corners.colors = rng.uniform(size=(n * 3, 3)).astype(np.float32)
    return [fog, textured, sky, corners, two_level_scene([0.0, 2.0])]


def _flipped(a: np.ndarray) -> np.ndarray:
    """``a`` with one byte changed (its first)."""
    b = np.array(a, copy=True)
    raw = b.reshape(-1).view(np.uint8) if b.ndim else b.reshape(1).view(np.uint8)
    raw[0] ^= 0x01
    return b


@pytest.mark.parametrize("function", sorted({f.__name__ for f in si.SCENE_INPUTS.values()}))
def test_changing_any_input_array_changes_the_key(monkeypatch, function):
    """Mutation test of the key: for every input function and every array it returns (on some scene),
    the key with that array changed by one byte differs, and the unchanged key is reproducible."""
    produce = next(f for f in si.SCENE_INPUTS.values() if f.__name__ == function)
    checked = 0
    for scene in _rich_scenes():
        arrays = produce(scene)
        base = ckp.scene_hash(scene)
        assert ckp.scene_hash(scene) == base
        for name, array in arrays.items():
            if np.asarray(array).nbytes == 0:
                continue

            def changed(s, _name=name):
                out = dict(produce(s))
                out[_name] = _flipped(np.asarray(out[_name]))
                return out

            changed.__name__ = produce.__name__
            with monkeypatch.context() as m:
                for param, f in si.SCENE_INPUTS.items():
                    if f is produce:
                        m.setitem(si.SCENE_INPUTS, param, changed)
                assert ckp.scene_hash(scene) != base, f"{function}: {name}"
            checked += 1
    assert checked, f"no scene gives {function} an array to change"


def _refused(before, after):
    """A checkpoint of ``before`` is refused for ``after`` (and accepted for ``before`` itself)."""
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = ckp.save(Path(tmp) / "r.ckpt.npz", Film.new(4, 4), before, SETTINGS)
        assert ckp.load(path, before, SETTINGS)[0].passes == 0
        with pytest.raises(ckp.CheckpointError, match="another scene"):
            ckp.load(path, after, SETTINGS)


def test_resume_refused_after_a_texel_or_uv_changes():
    scene = load_scene(REPO / "scenes/textured.toml")
    before = ckp.scene_hash(scene)
    texture = scene.textures()[0]
    texels = np.array(texture.texels, copy=True)
    texels.reshape(-1)[0] += 0.25
    other = load_scene(REPO / "scenes/textured.toml")
    other_texture = other.textures()[0]
    other_texture.texels = texels
    assert ckp.scene_hash(other) != before
    _refused(scene, other)
    moved = load_scene(REPO / "scenes/textured.toml")
    moved.uvs = np.asarray(moved.face_uvs(), np.float32) + np.float32(0.125)
    assert ckp.scene_hash(moved) != before


def test_resume_refused_after_a_medium_or_interface_changes():
    scene = load_scene(REPO / "scenes/cornell-fog.toml")
    denser = load_scene(REPO / "scenes/cornell-fog.toml")
    medium = next(m for m in denser.media if m.density is not None)
    medium.density.data = medium.density.data * np.float32(1.5)
    _refused(scene, denser)
    thicker = load_scene(REPO / "scenes/cornell-fog.toml")
    thicker.media[0] = replace(thicker.media[0], sigma_t=tuple(2 * x for x in thicker.media[0].sigma_t))
    _refused(scene, thicker)
    swapped = load_scene(REPO / "scenes/cornell-fog.toml")
    iface = swapped.interfaces[0]
    swapped.interfaces[0] = replace(iface, interior=iface.exterior, exterior=iface.interior)
    _refused(scene, swapped)


def test_resume_refused_after_emitter_indices_change_under_the_uniform_sampler():
    """Mitsuba's uniform light picking weights an emitter by its sampling_weight, shared by its
    triangles: which emitter a triangle belongs to changes the light table the kernels sample."""
    scene = load_scene(REPO / "scenes/cornell-box.toml")
    scene.settings = replace(scene.settings, light_sampler="uniform")
    lights = np.nonzero([scene.materials[m].is_emissive for m in scene.face_materials])[0]
    assert len(lights) >= 2
    scene.face_emitters = np.full(len(scene.faces), -1, np.int64)
    scene.face_emitters[lights] = 0
    scene.emitter_weights = [1.0, 3.0]
    split = load_scene(REPO / "scenes/cornell-box.toml")
    split.settings = scene.settings
    split.face_emitters = scene.face_emitters.copy()
    split.face_emitters[lights[0]] = 1  # one triangle now an emitter of its own, weight 3
    split.emitter_weights = scene.emitter_weights
    _refused(scene, split)
