"""``pyopencl-rt bench mitsuba-suite`` (pyopencl_rt/bench/mitsuba_suite.py): Mitsuba 3's render-test
rule as a pure function, checked on closed forms, and the command on a tiny suite that the test
writes itself.  Nothing of mitsuba-data (it has no licence) is in the repository: the suite here
is a few scenes of our own with references computed in closed form or, when Mitsuba 3 imports,
rendered by its scalar_rgb variant the way its test suite renders its references."""
import json
import math
from statistics import NormalDist

import numpy as np
import pytest
from scipy import stats

from pyopencl_rt.bench import mitsuba_suite as ms
from pyopencl_rt.cli import main
from pyopencl_rt.errors import UserError
from pyopencl_rt.imageio import write_exr

XYZ_TO_RGB = np.linalg.inv(ms.RGB_TO_XYZ)


def from_xyz(xyz) -> np.ndarray:
    """An RGB image whose XYZ (through the judge's matrix) is ``xyz``."""
    return (np.asarray(xyz, np.float64) @ XYZ_TO_RGB.T).astype(np.float32)


def constant(h, w, value) -> np.ndarray:
    return np.full((h, w, 3), value, np.float64)


# -- the rule ----------------------------------------------------------------------------------------

def test_sidak_threshold_is_the_normal_quantile():
    """alpha = 1 - 0.99^(1/pixels); the |z| where a two-sided p-value equals it is the normal
    quantile 1 - alpha/2, as scipy and the statistics module compute it; alpha is close to
    0.01 / pixels (the Bonferroni bound)."""
    for pixels in (48 * 48, 256 * 256, 640 * 480):
        alpha = ms.sidak_alpha(pixels)
        assert alpha == pytest.approx(1 - 0.99 ** (1 / pixels), rel=1e-12)
        assert alpha == pytest.approx(0.01 / pixels, rel=0.01) and alpha > 0.01 / pixels
        assert ms.critical_z(pixels) == pytest.approx(stats.norm.isf(alpha / 2), rel=1e-9)
        assert ms.critical_z(pixels) == pytest.approx(NormalDist().inv_cdf(1 - alpha / 2), rel=1e-12)
    assert ms.critical_z(48 * 48) == pytest.approx(4.593, abs=1e-3)  # 48 x 48: the bsdf_spheres scenes


def test_p_values_are_two_sided_normal_tails():
    z = np.array([0.0, 0.5, 1.0, 2.0, 3.0, 4.0], np.float32)
    p = ms.p_values(z, 100, np.zeros_like(z), np.full_like(z, 100.0))  # sigma = sqrt(var / spp) = 1
    assert p.dtype == np.float32
    assert np.allclose(p, 2 * stats.norm.sf(z), rtol=1e-4, atol=1e-6)
    # the variance is clamped at 1e-4: a zero variance is read as 1e-4
    assert ms.p_values(np.float32(0.01), 1, np.float32(0), np.float32(0)) == pytest.approx(2 * stats.norm.sf(1), rel=1e-4)


def test_p_values_agree_with_mitsubas_z_test():
    """Single precision as in Mitsuba's z_test (float32 numpy arrays, Dr.Jit's float32 erf): the
    same p-values, up to a unit in the last place of the erf, also far in the tail where the
    float32 steps decide."""
    dr = pytest.importorskip("drjit")
    from drjit.scalar import ArrayXf as Float

    z = np.concatenate([np.linspace(0, 7, 701), np.random.default_rng(1).uniform(4, 6, 300)]).astype(np.float32)
    cdf = np.array((1.0 - dr.erf(-Float(z) / dr.sqrt(2.0))) * 0.5)  # Mitsuba's stdnormal_cdf
    theirs = 2.0 * (1.0 - cdf)
    ours = ms.p_values(z, 1, np.zeros_like(z), np.ones_like(z))
    assert np.allclose(ours, theirs, rtol=1e-5, atol=2.5e-7), np.abs(ours - theirs).max()
    for pixels in (48 * 48, 256 * 256, 512 * 512):  # the same verdicts (above 2^17 pixels alpha is below
        alpha = ms.sidak_alpha(pixels)            # the float32 steps: the bound stays at |z| 5.35)
        assert np.array_equal(ours > alpha, theirs > alpha)


def test_an_image_equal_to_the_reference_passes():
    rng = np.random.default_rng(2)
    reference = rng.uniform(0.05, 3.0, (24, 40, 3)).astype(np.float32)
    variance = rng.uniform(0.0, 2.0, (24, 40, 3)).astype(np.float32)
    v = ms.judge(reference, 868, reference, variance)
    assert v.passed and v.accepted_fraction == 1.0
    assert v.mean_ratio == pytest.approx(1.0, rel=1e-6) and v.mean_ratio_rgb == pytest.approx([1, 1, 1], rel=1e-6)
    assert v.alpha == ms.sidak_alpha(24 * 40)


H, W, SPP, VAR = 64, 64, 400, 0.04  # sigma of the mean = sqrt(VAR / SPP) = 0.01 in every XYZ channel


@pytest.mark.parametrize("bad", [0, 1, 10, 11, 40])
def test_far_off_pixels_fail_beyond_a_quarter_percent(bad):
    """``bad`` pixels 12 sigma off in each channel: rejected, the rest exact; the scene passes while
    the accepted channels are at least 99.75% (4096 pixels: 10 off pass, 11 fail)."""
    ref = constant(H, W, 0.5)
    image = ref.copy()
    image.reshape(-1, 3)[:bad] += 12 * math.sqrt(VAR / SPP)
    v = ms.judge(from_xyz(image), SPP, from_xyz(ref), from_xyz(constant(H, W, VAR)))
    assert v.accepted_fraction == pytest.approx(1 - bad / (H * W), abs=1e-12)
    assert v.passed == (bad <= 0.0025 * H * W) == (bad <= 10)


@pytest.mark.parametrize("margin", [-0.1, 0.1])
def test_every_pixel_near_the_sidak_bound(margin):
    """Every channel k = critical_z + margin sigma off: all accepted just inside the bound, all
    rejected just outside it (the judge's float32 p-values move the bound by less than 0.02 here)."""
    k = ms.critical_z(H * W) + margin
    image = constant(H, W, 0.5 + k * math.sqrt(VAR / SPP))
    v = ms.judge(from_xyz(image), SPP, from_xyz(constant(H, W, 0.5)), from_xyz(constant(H, W, VAR)))
    assert v.accepted_fraction == (1.0 if margin < 0 else 0.0)
    assert v.passed == (margin < 0)
    assert v.mean_ratio == pytest.approx(1 + k * 0.02, rel=1e-5)  # Y: 0.5 + k * 0.01 over 0.5


def test_more_samples_make_the_same_error_significant():
    """The z statistic grows with sqrt(spp): an error of 0.04 is 4 sigma at 100 spp (accepted) and
    8 sigma at 400 spp (rejected), against the same per-sample variance."""
    ref, var = constant(H, W, 0.5), constant(H, W, 0.01)
    assert 4 < ms.critical_z(H * W) < 8
    image = from_xyz(ref + 0.04)
    assert ms.judge(image, 100, from_xyz(ref), from_xyz(var)).passed
    assert not ms.judge(image, 400, from_xyz(ref), from_xyz(var)).passed


def test_nan_pixels_are_rejected_and_sizes_must_match():
    ref = np.full((8, 8, 3), 0.5, np.float32)
    image = ref.copy()
    image[0, 0] = np.nan
    v = ms.judge(image, 10, ref, ref)
    assert v.accepted_fraction == pytest.approx(1 - 3 / 192) and not v.passed
    with pytest.raises(UserError, match="differ in size"):
        ms.judge(ref[:4], 10, ref, ref)


# -- a tiny suite ------------------------------------------------------------------------------------

SKY = (0.2, 0.4, 0.6)  # the constant emitter's radiance: every camera ray sees it, exactly
FILM_W, FILM_H = 12, 8


def scene_xml(body, sampler="independent"):
    """A scene in the form of mitsuba-data's tests/scenes: $spp and $integrator, a moment integrator."""
    return f"""<scene version="3.0.0">
    <default name="spp" value="16"/>
    <default name="integrator" value="path"/>
    <default name="sampler" value="{sampler}"/>
    <integrator type="moment">
        <integrator type="$integrator"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="30"/>
        <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm">
            <integer name="width" value="{FILM_W}"/>
            <integer name="height" value="{FILM_H}"/>
            <rfilter type="box"/>
            <string name="pixel_format" value="rgb"/>
        </film>
        <sampler type="$sampler"><integer name="sample_count" value="$spp"/></sampler>
    </sensor>
    <emitter type="constant"><rgb name="radiance" value="{', '.join(map(str, SKY))}"/></emitter>
    {body}
</scene>
"""


# a sphere behind the camera, out of its view (we render no scene without shapes)
BEHIND = '<shape type="sphere"><point name="center" value="0, 0, 20"/><float name="radius" value="0.5"/></shape>'
SPHERE = """<shape type="sphere"><float name="radius" value="0.9"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.5, 0.5"/></bsdf></shape>"""


def add_scene(scenes, folder, stem, xml, reference=None, variance=None):
    (scenes / folder / "refs").mkdir(parents=True, exist_ok=True)
    (scenes / folder / f"{stem}.xml").write_text(xml)
    name = stem.rsplit("_", 1)[0]
    if reference is not None:
        write_exr(scenes / folder / "refs" / f"{name}_ref_rgb.exr", reference)
        write_exr(scenes / folder / "refs" / f"{name}_ref_rgb_var.exr", variance)


def mitsuba_reference(path, spp):
    """The reference and per-sample variance of a scene as Mitsuba's test suite makes them
    (render_ref_images: the moment integrator's XYZ mean and second moment, written as RGB), with
    a stratified sampler so that a few thousand samples are enough for a test."""
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    scene = mi.load_file(str(path), spp=spp, sampler="multijitter")
    scene.integrator().render(scene, seed=0, develop=False)
    layers = scene.sensors()[0].film().bitmap(raw=False).split()
    mean, m2 = np.array(layers[1][1], copy=True), np.array(layers[2][1], copy=True)

    def rgb(xyz):
        return np.array(mi.Bitmap(xyz, mi.Bitmap.PixelFormat.XYZ).convert(
            mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False))

    return rgb(mean), rgb(m2 - mean * mean)


@pytest.fixture
def checkout(tmp_path):
    """A mitsuba-data-like checkout: sky (exact reference: passes), sky_wrong (its reference 1.25x
    too bright: fails), broken (a mesh that is not there: fails to load), lonely (no references:
    skipped); the Mitsuba-rendered diffuse sphere is added by the test that wants it."""
    root = tmp_path / "mitsuba-data"
    scenes = root / "tests" / "scenes"
    sky, zero = constant(FILM_H, FILM_W, SKY), constant(FILM_H, FILM_W, 0.0)
    add_scene(scenes, "sky", "sky_path", scene_xml(BEHIND), sky, zero)
    add_scene(scenes, "wrong", "sky_wrong_direct", scene_xml(BEHIND), 1.25 * sky, zero)
    add_scene(scenes, "broken", "broken_path",
              scene_xml('<shape type="obj"><string name="filename" value="missing.obj"/></shape>'), sky, zero)
    add_scene(scenes, "lonely", "lonely_path", scene_xml(BEHIND))
    return root


def test_scenes_are_listed_as_mitsubas_test_lists_them(checkout):
    scenes = ms.list_scenes(checkout)
    assert [s.name for s in scenes] == ["broken/broken_path", "lonely/lonely_path", "sky/sky_path",
                                        "wrong/sky_wrong_direct"]
    wrong = scenes[-1]
    assert wrong.integrator == "direct" and wrong.reference.name == "sky_wrong_ref_rgb.exr"
    assert wrong.variance.name == "sky_wrong_ref_rgb_var.exr" and wrong.has_references
    assert not scenes[1].has_references
    assert ms.list_scenes(checkout / "tests" / "scenes") == scenes  # PATH may be the scenes folder
    pick = [s.name for s in ms.select(scenes, only=["sky"], skip=["*direct"])]
    assert pick == ["sky/sky_path"]
    assert [s.name for s in ms.select(scenes, only=["b*/*"])] == ["broken/broken_path"]
    with pytest.raises(UserError, match="no mitsuba-data scenes here"):
        ms.list_scenes(checkout / "tests")


def test_the_command_on_a_tiny_suite(checkout, tmp_path, capsys):
    """A pass row, a fail row for a wrong reference (mean ratio 0.8), a fail row with the loader's
    one-line reason, the scene without references skipped, and exit code 1 as pytest's."""
    out = tmp_path / "suite.json"
    with pytest.raises(SystemExit) as exc:
        main(["bench", "mitsuba-suite", str(checkout), "--device", "cpu", "--json", str(out)])
    assert exc.value.code == 1
    printed = capsys.readouterr()
    assert "Traceback" not in printed.out + printed.err
    data = json.loads(out.read_text())
    rows = {row["scene"]: row for row in data["scenes"]}
    assert list(rows) == ["broken/broken_path", "sky/sky_path", "wrong/sky_wrong_direct"]
    assert data["skipped_without_references"] == ["lonely/lonely_path"]
    assert (data["passed"], data["total"]) == (1, 3)
    spp = 2_000_000 // (FILM_W * FILM_H)
    sky = rows["sky/sky_path"]
    assert sky["passed"] and sky["accepted_fraction"] == 1.0 and sky["reason"] is None
    assert sky["spp"] == sky["spp_rendered"] == spp and sky["mean_ratio"] == pytest.approx(1.0, rel=1e-5)
    wrong = rows["wrong/sky_wrong_direct"]
    assert not wrong["passed"] and wrong["accepted_fraction"] == 0.0
    assert wrong["mean_ratio"] == pytest.approx(0.8, rel=1e-5) and wrong["mean_ratio_rgb"] == pytest.approx([0.8] * 3)
    broken = rows["broken/broken_path"]
    assert not broken["passed"] and broken["reason"].startswith("load: ") and "missing.obj" in broken["reason"]
    assert "\n" not in broken["reason"] and broken["accepted_fraction"] is None
    lines = printed.out.splitlines()
    assert lines[-2] == "1 of 3 pass" and lines[-1] == f"wrote {out}"
    table = {line.split()[0]: line for line in lines if line.split()[0] in rows}
    assert table["sky/sky_path"].split()[1:3] == ["pass", "100.00%"]
    assert table["wrong/sky_wrong_direct"].split()[1:4] == ["FAIL", "0.00%", "0.800"]
    assert table["broken/broken_path"].split()[1] == "FAIL" and "load: " in table["broken/broken_path"]
    assert "lonely/lonely_path" in lines[0]  # named as skipped


def test_a_suite_that_passes_exits_0_and_nothing_selected_is_an_error(checkout, capsys):
    main(["bench", "mitsuba-suite", str(checkout / "tests" / "scenes"), "--device", "cpu", "--only", "sky",
          "--skip", "wrong", "--seed", "3"])
    assert capsys.readouterr().out.splitlines()[-1] == "1 of 1 pass"
    with pytest.raises(SystemExit) as exc:
        main(["bench", "mitsuba-suite", str(checkout), "--only", "nothing-like-this"])
    assert exc.value.code == 1
    assert "no scene with rgb references selected" in capsys.readouterr().err


def test_a_diffuse_sphere_against_mitsubas_reference(tmp_path):
    """A diffuse sphere under the constant sky, its reference rendered by Mitsuba 3 (scalar_rgb,
    the moment integrator): the rule accepts our render, and rejects it against a reference whose
    sphere is 10% brighter."""
    scenes = tmp_path / "tests" / "scenes"
    add_scene(scenes, "sphere", "diffuse_path", scene_xml(SPHERE))
    reference, variance = mitsuba_reference(scenes / "sphere" / "diffuse_path.xml", 4096)
    add_scene(scenes, "sphere", "diffuse_path", scene_xml(SPHERE), reference, variance)
    (scene,) = ms.list_scenes(tmp_path)
    row = ms.run_scene(scene, "cpu")
    assert row["passed"], row
    assert row["accepted_fraction"] >= 0.9975 and row["mean_ratio"] == pytest.approx(1.0, abs=0.01)
    assert row["warnings"] == []  # nothing of this scene is approximated (the moment wrapper renders its path)
    darker = reference.copy()
    darker[np.abs(reference - np.asarray(SKY, np.float32)).max(-1) > 0.05] *= 1.1
    add_scene(scenes, "sphere", "diffuse_path", scene_xml(SPHERE), darker, variance)
    row = ms.run_scene(scene, "cpu")
    assert not row["passed"] and row["mean_ratio"] < 0.99
