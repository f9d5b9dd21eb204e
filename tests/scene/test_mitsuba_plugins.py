"""The Mitsuba 3 plugins and parameters the XML loader takes (mitsuba_plugins.py) are the ones
docs/SCENE_FORMAT.md lists, row for row, and the loader refuses the others with one line."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from pyopencl_rt.scene.loaders import SceneError, load_scene
from pyopencl_rt.scene.loaders.mitsuba_plugins import HONOURED, NEUTRAL

DOC = Path(__file__).resolve().parents[2] / "docs" / "SCENE_FORMAT.md"
ROW = re.compile(r"^\| `(\w+)` `(\w+)` \| ([^|]*) \| ([^|]*) \|")


def documented() -> dict:
    """{(tag, type): (rendered, neutral)} from the table of "Mitsuba 3 plugin parameters"."""
    text = DOC.read_text()
    section = text[text.index("### Mitsuba 3 plugin parameters"):text.index("## pbrt-v4")]
    rows = {}
    for line in section.splitlines():
        m = ROW.match(line)
        if m:
            assert (m.group(1), m.group(2)) not in rows, line
            rows[m.group(1), m.group(2)] = tuple(frozenset(re.findall(r"`(\w+)`", m.group(k))) for k in (3, 4))
    return rows


def test_the_table_lists_every_plugin_and_parameter_the_loader_takes_and_no_other():
    rows = documented()
    registry = {(tag, t): (frozenset(params), frozenset(NEUTRAL.get(tag, {}).get(t, ())))
                for tag, types in HONOURED.items() for t, params in types.items()}
    assert set(rows) == set(registry), set(rows) ^ set(registry)
    for key, (rendered, neutral) in registry.items():
        assert rows[key] == (rendered, neutral), (key, rows[key], (rendered, neutral))
        assert not rendered & neutral, key


def _scene(tmp_path, body) -> Path:
    path = tmp_path / "s.xml"
    path.write_text(f'<scene version="3.0.0">\n{body}\n<shape type="sphere"/></scene>\n')
    return path


@pytest.mark.parametrize("body, message", [
    ('<sensor type="perspective"><float name="principal_point_offset_x" value="0.1"/></sensor>',
     r'<float name="principal_point_offset_x"> of <sensor type="perspective">: parameter not supported$'),
    ('<sensor type="perspective"><film type="hdrfilm"><integer name="crop_offset_x" value="2"/></film></sensor>',
     r'<integer name="crop_offset_x"> of <film type="hdrfilm">: parameter not supported$'),
    ('<bsdf type="diffuse" id="d"><rgb name="reflectance" value="0.5"/><float name="alpha" value="0.1"/></bsdf>'
     '<shape type="sphere"><ref id="d"/></shape>',
     r'<float name="alpha"> of <bsdf type="diffuse" id="d">: parameter not supported$'),
    ('<shape type="rectangle"><bsdf type="conductor"><string name="material" value="Au"/>'
     '<rgb name="specular_reflectance" value="0.5"/></bsdf></shape>',
     r'<bsdf type="conductor">: specular_reflectance with eta/k or a named material is not supported$'),
    ('<emitter type="sunsky"/>', r'<emitter type="sunsky">: emitter type "sunsky" is not supported \(we render: area, '),
    ('<emitter type="area"/>', r'<emitter type="area">: an area emitter must be attached to a shape$'),
    ('<shape type="sphere"><bsdf type="measured"/></shape>', r'<bsdf type="measured">: bsdf type "measured" is not'),
    ('<shape type="sphere"><bsdf type="diffuse"><spectrum type="irregular" name="reflectance">'
     '<string name="wavelengths" value="400, 500"/><string name="values" value="0.1, 0.2"/></spectrum></bsdf></shape>',
     r'<spectrum type="irregular">: spectrum type "irregular" is not supported'),
])
def test_what_the_table_does_not_list_is_refused_in_one_line(tmp_path, body, message):
    with pytest.raises(SceneError) as exc:
        load_scene(_scene(tmp_path, body))
    text = str(exc.value)
    assert "\n" not in text and re.search(rf"s\.xml:\d+: {message}", text), text


def test_neutral_parameters_are_read_without_a_word(tmp_path):
    """The output-format and noise-only parameters change nothing in Mitsuba's image: taken silently."""
    import warnings

    body = ('<integrator type="direct"><integer name="emitter_samples" value="4"/></integrator>'
            '<sensor type="perspective"><float name="near_clip" value="0.1"/><float name="far_clip" value="100"/>'
            '<sampler type="stratified"><boolean name="jitter" value="false"/></sampler>'
            '<film type="hdrfilm"><string name="pixel_format" value="rgba"/><boolean name="banner" value="false"/>'
            '</film></sensor>'
            '<shape type="rectangle"><bsdf type="roughconductor"><boolean name="sample_visible" value="false"/></bsdf>'
            '</shape>')
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = load_scene(_scene(tmp_path, body))
    assert scene.settings.max_depth == 2 and scene.warnings == []
