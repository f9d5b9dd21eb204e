"""``pyopencl-rt bench mitsuba-suite PATH``: Mitsuba 3's render-regression scenes, rendered by us
and judged by Mitsuba's own statistical test.

PATH is a checkout of mitsuba-data (github.com/mitsuba-renderer/mitsuba-data) or its
``tests/scenes`` folder.  Nothing of mitsuba-data is part of this repository (it carries no
licence): the scenes, the meshes and textures they name (``../../../common``) and the reference
images are all read from PATH.

The rule is that of Mitsuba 3's ``src/render/tests/test_renders.py`` (read at mitsuba3 commit
b45b0a9, August 2026), here for its ``rgb`` variants and without its JIT-only integrator
substitutions:

* The scenes are ``tests/scenes/<folder>/<name>_<integrator>.xml``.  A scene's references are
  ``<folder>/refs/<name>_ref_rgb.exr`` and the per-sample variance ``<name>_ref_rgb_var.exr``
  beside it (made by that file's own ``__main__``, 32000 spp by default, with the moment
  integrator's per-sample variance); a scene without both is skipped, as Mitsuba's test skips it.
* It is rendered with a budget of 2e6 samples in all: spp = 2000000 // (the reference's pixel
  count), given to the scene as its ``$spp`` parameter (Mitsuba's ``mi.load_file(..., spp=spp,
  integrator=...)``; ours: ``load_scene(..., defines={"spp": ..., "integrator": ...})``, which is
  ``render -D``), with the integrator named by the file's suffix, seed 0.
* Image, reference and variance are compared in CIE XYZ: each RGB image goes through the linear
  Rec. 709 matrix of Mitsuba's ``Bitmap::convert`` (:data:`RGB_TO_XYZ`).  Mitsuba's image is
  the XYZ output of its ``moment`` integrator, which is the same linear map of the RGB mean.
* Per pixel channel, a two-sided z-test: z = |image - reference| * sqrt(spp / variance), the
  variance clamped below at 1e-4, p = 2 (1 - Phi(z)), computed in single precision as Mitsuba
  does (its p-values are float32, and so in steps of about 1.2e-7 near 0).
* A channel is accepted when p > alpha, alpha the Sidak correction of a 1% significance level
  for as many tests as the image has *pixels*: alpha = 1 - 0.99^(1 / pixel count) (Mitsuba
  counts pixels here, not the 3x as many channels it tests).  The bound on |z| is the normal
  quantile 1 - alpha/2 (:func:`critical_z`: 4.59 at 48 x 48, 5.25 at 256 x 256) up to about
  2^17 pixels; above, alpha is below the float32 steps of p and the bound stays at |z| = 5.35.
* The scene passes when the accepted channels, divided by 3, are at least 99.75% of the pixel
  count: at least 99.75% of the channels are accepted.

:func:`judge` is that test alone (numpy and scipy's erf).  Beside the verdict each row reports
the accepted fraction and the ratio of the image means of luminance (Y), ours over the
reference's, which tells an energy error from noise.  A scene that fails to load or render is a
fail row with the reason in one line; the suite goes on.  The command exits with 1 when a scene
fails, as pytest does, and 0 when all pass.
"""
from __future__ import annotations

import fnmatch
import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import UserError, one_line

SAMPLE_BUDGET = 2_000_000  # samples per scene: spp = SAMPLE_BUDGET // pixel count
SIGNIFICANCE = 0.01  # before the Sidak correction
ACCEPT_FRACTION = 0.9975  # of the pixel channels
VARIANCE_FLOOR = 1e-4
COLOR_MODE = "rgb"  # which variant's references
# linear Rec. 709 RGB -> CIE XYZ, the coefficients of Mitsuba's Bitmap::convert (src/core/bitmap.cpp)
RGB_TO_XYZ = np.array([[0.412453, 0.357580, 0.180423],
                       [0.212671, 0.715160, 0.072169],
                       [0.019334, 0.119193, 0.950227]])


@dataclass
class Verdict:
    passed: bool
    accepted_fraction: float  # of the pixel channels
    alpha: float  # the Sidak-corrected significance level of each channel's test
    min_p: float
    mean_ratio: float | None  # mean luminance (Y), ours / the reference's; None on a black reference
    mean_ratio_rgb: list  # per RGB channel


def rgb_to_xyz(image) -> np.ndarray:
    """H x W x 3 linear RGB -> XYZ, float32 (as Mitsuba's bitmaps)."""
    return (np.asarray(image, np.float64) @ RGB_TO_XYZ.T).astype(np.float32)


def sidak_alpha(pixel_count: int, significance: float = SIGNIFICANCE) -> float:
    """Each test's level so that ``pixel_count`` independent tests reject none with probability
    1 - ``significance``."""
    return 1.0 - (1.0 - significance) ** (1.0 / pixel_count)


def critical_z(pixel_count: int, significance: float = SIGNIFICANCE) -> float:
    """The |z| at which a channel's two-sided p-value equals :func:`sidak_alpha` (in exact
    arithmetic; Mitsuba's float32 p-values move the effective bound by a few hundredths)."""
    from statistics import NormalDist

    return NormalDist().inv_cdf(1.0 - sidak_alpha(pixel_count, significance) / 2.0)


def p_values(image_xyz, spp, reference_xyz, variance_xyz) -> np.ndarray:
    """Mitsuba's ``z_test``: two-sided p-values of |image - reference| * sqrt(spp / variance),
    in float32 (its numpy arrays and Dr.Jit's single-precision erf)."""
    from scipy.special import erf

    var = np.maximum(np.asarray(variance_xyz, np.float32), np.float32(VARIANCE_FLOOR))
    diff = np.abs(np.asarray(image_xyz, np.float32) - np.asarray(reference_xyz, np.float32))
    z = diff * np.sqrt(np.float32(spp) / var)
    cdf = (np.float32(1.0) - erf(-z / np.float32(math.sqrt(2.0)))) * np.float32(0.5)
    return np.float32(2.0) * (np.float32(1.0) - cdf.astype(np.float32))


def judge(image, spp, reference, variance) -> Verdict:
    """Mitsuba's verdict on ``image`` (H x W x 3 linear RGB, the mean of ``spp`` samples per
    pixel) against ``reference`` and its per-sample ``variance`` (both RGB, as mitsuba-data
    stores them)."""
    image, reference, variance = (np.asarray(a, np.float32) for a in (image, reference, variance))
    if image.shape != reference.shape or variance.shape != reference.shape:
        raise UserError(f"image {image.shape[:2]}, reference {reference.shape[:2]} and variance "
                        f"{variance.shape[:2]} differ in size")
    pixel_count = reference.shape[0] * reference.shape[1]
    ours, ref = rgb_to_xyz(image), rgb_to_xyz(reference)
    p = p_values(ours, spp, ref, rgb_to_xyz(variance))
    alpha = sidak_alpha(pixel_count)
    accepted = int(np.count_nonzero(p > alpha))
    ref_means = reference.astype(np.float64).mean((0, 1))
    our_means = image.astype(np.float64).mean((0, 1))
    ref_y, our_y = float(ref.astype(np.float64)[..., 1].mean()), float(ours.astype(np.float64)[..., 1].mean())
    return Verdict(passed=accepted / 3 >= ACCEPT_FRACTION * pixel_count, accepted_fraction=accepted / p.size,
                   alpha=alpha, min_p=float(np.nanmin(p)) if np.isfinite(p).any() else float("nan"),
                   mean_ratio=_ratio(our_y, ref_y),
                   mean_ratio_rgb=[_ratio(a, b) for a, b in zip(our_means, ref_means)])


def _ratio(a, b):
    return float(a / b) if b != 0 and math.isfinite(a) and math.isfinite(b) else None


# -- the scenes --------------------------------------------------------------------------------------

@dataclass
class SuiteScene:
    name: str  # "<folder>/<file stem>", e.g. "bsdf_spheres/test_arealight_path"
    xml: Path
    integrator: str  # the file name's suffix
    reference: Path
    variance: Path

    @property
    def has_references(self) -> bool:
        return self.reference.is_file() and self.variance.is_file()


def scenes_dir(path) -> Path:
    """The ``tests/scenes`` folder of a mitsuba-data checkout given as PATH, or PATH itself."""
    p = Path(path)
    for candidate in (p / "tests" / "scenes", p):
        if candidate.is_dir() and any(candidate.glob("*/*.xml")):
            return candidate
    raise UserError(f"{path}: no mitsuba-data scenes here (expected tests/scenes/<folder>/<name>_<integrator>.xml "
                    "in a checkout of github.com/mitsuba-renderer/mitsuba-data, or that tests/scenes folder)")


def list_scenes(path) -> list[SuiteScene]:
    """Every ``<folder>/<name>_<integrator>.xml`` under the scenes folder, sorted by name, with
    its ``refs/`` paths (as Mitsuba's ``get_ref_fname`` makes them)."""
    root = scenes_dir(path)
    out = []
    for xml in sorted(root.glob("*/*.xml")):
        base, _, integrator = xml.stem.rpartition("_")
        refs = xml.parent / "refs"
        reference = refs / f"{base or integrator}_ref_{COLOR_MODE}.exr"
        out.append(SuiteScene(f"{xml.parent.name}/{xml.stem}", xml, integrator, reference,
                              reference.with_name(reference.stem + "_var.exr")))
    return out


def select(scenes, only=(), skip=()) -> list:
    """The scenes whose name contains, or matches as a glob, one of ``only`` (all without it)
    and none of ``skip``."""
    def matches(scene, pattern):
        return pattern in scene.name or fnmatch.fnmatchcase(scene.name, pattern)

    return [s for s in scenes if (not only or any(matches(s, p) for p in only))
            and not any(matches(s, p) for p in skip)]


# -- one scene ---------------------------------------------------------------------------------------

def run_scene(scene: SuiteScene, device, seed: int = 0, timeout: float | None = None) -> dict:
    """One row: the scene rendered as the rule says and judged; a failure to read, load or render
    is a fail row whose ``reason`` is one line."""
    row = {"scene": scene.name, "integrator": scene.integrator, "passed": False, "reason": None,
           "accepted_fraction": None, "mean_ratio": None, "mean_ratio_rgb": None, "spp": None,
           "spp_rendered": None, "warnings": [], "seconds": None}
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:  # the scene's and the render's, kept in the row
        warnings.simplefilter("always")
        _render_and_judge(scene, row, device, seed, timeout)
    row["warnings"] = [one_line(w.message) for w in caught]
    row["seconds"] = time.perf_counter() - start
    return row


def _render_and_judge(scene: SuiteScene, row: dict, device, seed, timeout) -> None:
    from ..imageio import read_exr
    from ..render.api import render_full
    from ..scene.loaders import load_scene

    stage = "reference"
    try:
        reference, variance = read_exr(scene.reference), read_exr(scene.variance)
        height, width = reference.shape[:2]
        spp = max(1, SAMPLE_BUDGET // (width * height))
        row.update(width=width, height=height, spp=spp)
        stage = "load"
        loaded = load_scene(scene.xml, defines={"spp": str(spp), "integrator": scene.integrator})
        if (loaded.settings.width, loaded.settings.height) != (width, height):
            raise UserError(f"the scene's film is {loaded.settings.width}x{loaded.settings.height}, the reference "
                            f"{width}x{height}")
        stage = "render"
        result = render_full(loaded, spp=spp, device=device, seed=seed, time_limit=timeout)
        row.update(spp_rendered=result.film.passes, render_seconds=result.info["render_seconds"],
                   kernel_build_seconds=result.info.get("kernel_build_seconds"),
                   nonfinite_samples=result.info.get("nonfinite_samples"))
        if result.film.passes == 0:
            raise UserError(f"no pass completed within --timeout {timeout} s")
        verdict = judge(result.image, result.film.passes, reference, variance)
        row.update(passed=verdict.passed, accepted_fraction=verdict.accepted_fraction, alpha=verdict.alpha,
                   min_p=verdict.min_p, mean_ratio=verdict.mean_ratio, mean_ratio_rgb=verdict.mean_ratio_rgb)
        if result.film.passes < spp:
            row["reason"] = f"--timeout: {result.film.passes} of {spp} spp"
    except UserError as exc:
        row["reason"] = f"{stage}: {one_line(exc)}"
    except Exception as exc:  # a bug or a device failure: this scene's row, never the suite's end
        row["reason"] = f"{stage}: {type(exc).__name__}: {one_line(exc)}"


# -- the suite ---------------------------------------------------------------------------------------

def header(width: int) -> str:
    return f"{'scene':<{width}} {'result':<6} {'accepted':>9} {'mean Y':>7} {'spp':>5} {'seconds':>7}  note"


def format_row(row, width: int) -> str:
    """The table's line of a row; ``width``: the scene column's."""
    accepted = "" if row["accepted_fraction"] is None else f"{100 * row['accepted_fraction']:8.2f}%"
    ratio = "" if row["mean_ratio"] is None else f"{row['mean_ratio']:7.3f}"
    spp = "" if row["spp_rendered"] is None else str(row["spp_rendered"])
    note = row["reason"] or ""
    return (f"{row['scene']:<{width}} {'pass' if row['passed'] else 'FAIL':<6} {accepted:>9} {ratio:>7} "
            f"{spp:>5} {row['seconds']:7.1f}  {note[:160]}").rstrip()


def run_suite(path, device=None, only=(), skip=(), seed=0, timeout=None, json_path=None, echo=print) -> int:
    """Run the suite and print a row per scene as it is done, then "K of N pass".  Returns the
    number of scenes that failed (the command's exit code is 1 when it is not 0)."""
    from .. import validate
    from ..device.devices import device_label, resolve
    from .timing import machine_info, write_results

    if json_path is not None:  # before minutes of rendering
        validate.writable_file(json_path, "JSON file")
    chosen = resolve(device)  # a wrong --device is one line before anything renders
    everything = list_scenes(path)
    picked = select(everything, only, skip)
    runnable = [s for s in picked if s.has_references]
    missing = [s.name for s in picked if not s.has_references]
    if not runnable:
        raise UserError(f"{path}: no scene with {COLOR_MODE} references selected "
                        f"({len(everything)} scenes, {len(picked)} selected, {len(missing)} without references)")
    echo(f"{len(runnable)} scenes of {scenes_dir(path)} on {'; '.join(device_label(d) for d in chosen)}, seed {seed}"
         + (f"; without {COLOR_MODE} references, skipped: {', '.join(missing)}" if missing else ""))
    width = max(len(s.name) for s in runnable)
    echo(header(width))
    rows = []
    for scene in runnable:
        rows.append(run_scene(scene, chosen[0] if len(chosen) == 1 else chosen, seed=seed, timeout=timeout))
        echo(format_row(rows[-1], width))
    passed = sum(r["passed"] for r in rows)
    echo(f"{passed} of {len(rows)} pass")
    if json_path:
        results = {"path": str(path), "scenes_dir": str(scenes_dir(path)), "device": [device_label(d) for d in chosen],
                   "seed": seed, "timeout": timeout, "only": list(only), "skip": list(skip),
                   "rule": {"sample_budget": SAMPLE_BUDGET, "significance": SIGNIFICANCE, "correction": "sidak",
                            "accept_fraction": ACCEPT_FRACTION, "variance_floor": VARIANCE_FLOOR,
                            "references": COLOR_MODE, "space": "XYZ"},
                   "machine": machine_info(), "date": time.strftime("%Y-%m-%d"), "passed": passed,
                   "total": len(rows), "skipped_without_references": missing, "scenes": rows}
        write_results(json_path, results, echo)
    return len(rows) - passed
