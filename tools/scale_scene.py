"""Write the height-field scene of issue 35 (a binary PLY of about N triangles and a Mitsuba XML
with an area light and a constant environment): see pyopencl_rt/bench/scale_scene.py.

    PYTHONPATH=. python tools/scale_scene.py OUTDIR --triangles 2e6
"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from pyopencl_rt.bench.scale_scene import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
