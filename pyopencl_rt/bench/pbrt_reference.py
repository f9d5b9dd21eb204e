"""pbrt-v4 itself as the reference for pbrt scenes, as Mitsuba is for XML: ``bench pbrt-scenes
PATH --pbrt BINARY`` (and ``python -m pyopencl_rt.bench.pbrt_reference --pbrt BINARY SCENE``).

Nothing of pbrt-v4 is part of this repository: BINARY is a ``pbrt`` the user built (CPU is
enough); this module only runs it.  A scene is rendered small by both renderers:

* pbrt: a copy of the scene file with the Film's ``xresolution`` / ``yresolution`` set to the
  size asked for (written beside the scene, so that its relative file names resolve, and removed
  afterwards), rendered ``seeds`` times (``pbrt --spp N --seed S --outfile X.exr``, seeds 0 ..
  seeds - 1): the reference is the mean of those renders, and the variance of that mean is the
  variance over the renders divided by their number (pbrt writes no per-pixel variance of its
  RGB film; its gbuffer film's is of camera samples that hit a surface only, in sensor space);
* ours: ``pyopencl-rt render`` at ``spp`` with the ``variance`` AOV (the variance of the pixel's
  mean, docs/OUTPUT.md).

The verdict is the mitsuba-suite's rule (:mod:`.mitsuba_suite`): per pixel and channel, in CIE XYZ,
z = |ours - pbrt| / sqrt(var_ours + var_pbrt) (each variance floored at 1e-4 / spp of its side),
accepted while |z| is within the Sidak-corrected bound for a 1% level over the pixel count, and a
pass when at least 99.75% of the channels are accepted.  With the reference's variance estimated
from ``seeds`` renders its z is heavier-tailed than a normal one (a t with seeds - 1 degrees of
freedom); so many seeds (16 by default) of enough samples that ours dominates the sum keep that
within the 0.25% the rule allows.  Beside the verdict: the ratio of mean luminance, ours over
pbrt's, which tells an energy error from noise.
"""
from __future__ import annotations

import argparse
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import UserError, one_line
from .mitsuba_suite import ACCEPT_FRACTION, VARIANCE_FLOOR, critical_z, rgb_to_xyz

RESOLUTION = re.compile(r'"integer\s+([xy])resolution"\s*(?:\[\s*[-+0-9.eE]+\s*\]|[-+0-9.eE]+)')
FILM = re.compile(r'(\bFilm\s+"[^"]*")')


def _code(line: str) -> tuple[str, str]:
    """(the part of a pbrt line before its comment, the comment): '#' outside quotes."""
    quoted = False
    for i, ch in enumerate(line):
        if ch == '"':
            quoted = not quoted
        elif ch == "#" and not quoted:
            return line[:i], line[i:]
    return line, ""


def resized_text(text: str, width: int, height: int) -> str:
    """The scene text with its Film's resolution ``width`` x ``height``: the resolution
    parameters dropped wherever they are (outside comments) and given again after ``Film "..."``
    (which the top-level file must hold)."""
    lines = [list(_code(line)) for line in text.split("\n")]
    for parts in lines:
        parts[0] = RESOLUTION.sub("", parts[0])
    for parts in lines:
        if FILM.search(parts[0]):
            parts[0] = FILM.sub(rf'\1 "integer xresolution" [ {width} ] "integer yresolution" [ {height} ]',
                                parts[0], count=1)
            return "\n".join(code + comment for code, comment in lines)
    raise UserError("the scene file has no Film directive of its own to set the resolution of")


@dataclass
class Render:
    image: np.ndarray  # H x W x 3 linear RGB, the mean
    variance: np.ndarray  # H x W x 3, the variance of that mean
    spp: int  # samples per pixel in all
    seconds: float


def render_pbrt(pbrt, scene: Path, width: int, height: int, spp: int, seeds: int = 16,
                timeout: float = 600.0, threads: int | None = None) -> Render:
    """pbrt's renders of ``scene`` at ``width`` x ``height``, ``spp`` each, seeds 0 .. seeds - 1."""
    from ..imageio import read_exr

    scene = Path(scene)
    if seeds < 2:
        raise UserError("the pbrt reference needs at least 2 seeds (its variance comes from them)")
    text = scene.read_bytes()
    if text[:2] == b"\x1f\x8b":
        import gzip

        text = gzip.decompress(text)
    copy = scene.with_name(f".{scene.name}.pbrt-reference-{os.getpid()}.pbrt")
    copy.write_text(resized_text(text.decode("utf-8", "replace"), width, height))
    images = []
    start = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory(prefix="pbrt-reference-") as folder:
            for seed in range(seeds):
                out = Path(folder) / f"seed{seed}.exr"
                args = [str(pbrt), "--quiet", "--spp", str(spp), "--seed", str(seed), "--outfile", str(out)]
                if threads:
                    args += ["--nthreads", str(threads)]
                try:
                    done = subprocess.run(args + [str(copy)], capture_output=True, text=True, timeout=timeout)
                except OSError as exc:
                    raise UserError(f"{pbrt}: cannot run ({exc.strerror or exc})") from None
                except subprocess.TimeoutExpired:
                    raise UserError(f"pbrt ran past {timeout:g} s on {scene}") from None
                if done.returncode != 0 or not out.is_file():
                    tail = (done.stderr or done.stdout).strip().splitlines()
                    raise UserError(f"pbrt failed on {scene.name} (exit status {done.returncode})"
                                    + (f": {one_line(tail[-1])}" if tail else ""))
                images.append(read_exr(out)[..., :3].astype(np.float64))
    finally:
        copy.unlink(missing_ok=True)
    stack = np.stack(images)
    return Render(stack.mean(0), stack.var(0, ddof=1) / seeds, spp * seeds, time.perf_counter() - start)


def render_ours(scene: Path, width: int, height: int, spp: int, seed: int = 0, timeout: float = 600.0) -> Render:
    """Our render (``pyopencl-rt render`` in a subprocess) with the variance of each pixel's mean."""
    from ..imageio import read_exr_channels

    with tempfile.TemporaryDirectory(prefix="ours-reference-") as folder:
        out = Path(folder) / "ours.exr"
        args = [sys.executable, "-m", "pyopencl_rt.cli", "render", str(scene), "-o", str(out), "--width", str(width),
                "--height", str(height), "--spp", str(spp), "--seed", str(seed), "--aov", "variance", "--quiet"]
        start = time.perf_counter()
        done = subprocess.run(args, capture_output=True, text=True, timeout=timeout)
        if done.returncode != 0:
            tail = done.stderr.strip().splitlines()
            raise UserError(f"our render failed on {scene.name}" + (f": {one_line(tail[-1])}" if tail else ""))
        channels = read_exr_channels(out)
    image = np.stack([channels[c] for c in ("R", "G", "B")], -1).astype(np.float64)
    variance = np.stack([channels[f"variance.{c}"] for c in ("R", "G", "B")], -1).astype(np.float64)
    return Render(image, variance, spp, time.perf_counter() - start)


@dataclass
class Judgement:
    passed: bool
    accepted_fraction: float  # of the pixel channels
    bound: float  # the |z| bound of each channel
    mean_ratio: float | None  # mean luminance Y, ours / pbrt's
    mean_ratio_rgb: list


def judge(ours: Render, reference: Render) -> Judgement:
    """The suite's rule on two renders with their variances of the mean (see the module's text)."""
    if ours.image.shape != reference.image.shape:
        raise UserError(f"the renders differ in size: {ours.image.shape[:2]} and {reference.image.shape[:2]}")
    a, b = rgb_to_xyz(ours.image).astype(np.float64), rgb_to_xyz(reference.image).astype(np.float64)
    # variances of a linear map of RGB: the diagonal of M diag(v) M^T (channels independent)
    m2 = np.asarray(rgb_to_xyz(np.eye(3)).T, np.float64) ** 2
    va, vb = ours.variance @ m2.T, reference.variance @ m2.T
    va = np.maximum(np.nan_to_num(va, nan=np.inf, posinf=np.inf), VARIANCE_FLOOR / ours.spp)
    vb = np.maximum(np.nan_to_num(vb, nan=np.inf, posinf=np.inf), VARIANCE_FLOOR / reference.spp)
    z = np.abs(a - b) / np.sqrt(va + vb)
    pixels = a.shape[0] * a.shape[1]
    bound = critical_z(pixels)
    accepted = int(np.count_nonzero(z <= bound))
    ya, yb = float(a[..., 1].mean()), float(b[..., 1].mean())
    ratio = (lambda x, y: float(x / y) if y != 0 and math.isfinite(x) and math.isfinite(y) else None)
    rgb_a, rgb_b = ours.image.reshape(-1, 3).mean(0), reference.image.reshape(-1, 3).mean(0)
    return Judgement(accepted / z.size >= ACCEPT_FRACTION, accepted / z.size, bound, ratio(ya, yb),
                     [ratio(x, y) for x, y in zip(rgb_a, rgb_b)])


def compare_scene(pbrt, scene, width=160, height=120, spp=64, ref_spp=64, seeds=16, seed=0,
                  timeout=600.0) -> dict:
    """Our render of ``scene`` judged against pbrt's: a dict for the bench's row."""
    reference = render_pbrt(pbrt, Path(scene), width, height, ref_spp, seeds, timeout)
    ours = render_ours(Path(scene), width, height, spp, seed, timeout)
    j = judge(ours, reference)
    return {"verdict": "pass" if j.passed else "fail", "accepted": j.accepted_fraction, "bound_z": j.bound,
            "mean_ratio": j.mean_ratio, "mean_ratio_rgb": j.mean_ratio_rgb, "spp": spp,
            "pbrt_spp": reference.spp, "pbrt_seconds": reference.seconds, "our_seconds": ours.seconds}


def format_judgement(row: dict) -> str:
    ratio = "-" if row["mean_ratio"] is None else f"{row['mean_ratio']:.3f}"
    rgb = "/".join("-" if r is None else f"{r:.3f}" for r in row["mean_ratio_rgb"])
    return (f"{row['verdict']} {100 * row['accepted']:.2f}% of channels within |z| {row['bound_z']:.2f}, "
            f"mean Y ours/pbrt {ratio} (RGB {rgb}), {row['spp']} spp vs pbrt's {row['pbrt_spp']}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m pyopencl_rt.bench.pbrt_reference",
                                     description="Judge our render of pbrt scenes against pbrt-v4's.")
    parser.add_argument("scenes", nargs="+", type=Path)
    parser.add_argument("--pbrt", required=True, help="a pbrt-v4 binary")
    parser.add_argument("--width", type=int, default=160)
    parser.add_argument("--height", type=int, default=120)
    parser.add_argument("--spp", type=int, default=64, help="our samples per pixel")
    parser.add_argument("--ref-spp", type=int, default=64, help="pbrt's samples per pixel per seed")
    parser.add_argument("--seeds", type=int, default=16, help="pbrt renders (seeds 0 .. N-1)")
    args = parser.parse_args(argv)
    failed = 0
    for scene in args.scenes:
        try:
            row = compare_scene(args.pbrt, scene, args.width, args.height, args.spp, args.ref_spp, args.seeds)
        except UserError as exc:
            print(f"{scene}: error: {exc}")
            failed += 1
            continue
        print(f"{scene}: {format_judgement(row)} ({row['pbrt_seconds']:.1f} s pbrt, {row['our_seconds']:.1f} s ours)",
              flush=True)
        failed += row["verdict"] != "pass"
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
