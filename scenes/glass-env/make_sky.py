"""Writes scenes/glass-env/sun-sky.exr (made for this project; licence: the project's): the sky of
scenes/textured-sky/make_assets.py at 1024 x 512 texels with a small, bright sun (a Gaussian of
0.5 degrees, peak radiance 12000: about 3x the sky's irradiance), as in a captured HDR sky, where
the sun covers few texels.  Run: python scenes/glass-env/make_sky.py"""
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "textured-sky"))
import make_assets  # noqa: E402

make_assets.SUN_SIGMA, make_assets.SUN_PEAK = 0.5, 12000.0

if __name__ == "__main__":
    make_assets.write_exr(HERE / "sun-sky.exr", make_assets.sky(512, 1024))
