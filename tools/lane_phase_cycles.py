"""Cycles per sample of the lane megakernel's phases (starting samples, extend packets, the
environment of escaped rays, shading, shadow packets), for one source tree or several in turn:
where a scene's time goes.

    python tools/lane_phase_cycles.py . /tmp/base --pairs 3 --scene scenes/textured-sky.toml

Each tree's cl/ and pyopencl_rt/ are copied to a scratch folder and cl/megakernel/path.cl is
patched there (never in the tree) to read the cycle counter (__builtin_readcyclecounter) around
the phases of its loop and add the sums, in units of 256 cycles, into the counters the megakernel
leaves unused (0, 1, 2, 6, 7); the scene is then rendered at 256x256 (4 passes a round) and the
sums divided by the samples.  $PYOPENCL_RT_LANES applies (0: the one-path megakernel).

Why cycles and ratios: on a shared 2-vCPU machine the wall-clock speed of one tree moves by 10-20%
between runs, and so do these absolute counts (a descheduled thread's wait is counted too), but
the phases of one run move together: compare the ratios of a phase to the others (or to shading,
which a traversal change leaves alone) between trees run in turn.
"""
from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

# (anchor in path.cl, text inserted after it); each anchor must occur exactly once
PATCHES = [
    ('#include "megakernel/ray_counts.h"\n', "#define CYC ((ulong)__builtin_readcyclecounter())\n"),
    ("    pint out = PINT(0);\n", "    ulong cy[5] = {0, 0, 0, 0, 0}, c0 = CYC;\n"),
    ("ring_size, seed, camera_medium, &s, &key, &out, &weight); /* bit k: lane k holds a path */\n",
     "    cy[0] += CYC - c0;\n"),
    ("    while (live) {\n", "        c0 = CYC;\n"),
    ("        n_extend += popcount(live);\n", "        cy[1] += CYC - c0; c0 = CYC;\n"),
    ("        pint goes_on, with_shadow;\n", "        cy[2] += CYC - c0; c0 = CYC;\n"),
    ("INSTANCE_SHADE_ARGS(inst));\n", "        cy[3] += CYC - c0; c0 = CYC;\n"),
    ("            s.L = pv3_sel(s.L, pv3_add(s.L, shadow.contribution), with_shadow & pnot(occluded));\n#endif\n        }\n",
     "        cy[4] += CYC - c0; c0 = CYC;\n"),
    ("                                ring_size, seed, camera_medium, &s, &key, &out, &weight);\n",
     "        cy[0] += CYC - c0;\n"),
    ("    add_group_ray_counts(group_rays, LANE_GROUP, n_extend, n_shadow, counters);\n",
     "    atomic_add(&counters[0], (int)(cy[0] >> 8)); atomic_add(&counters[1], (int)(cy[1] >> 8));\n"
     "    atomic_add(&counters[2], (int)(cy[2] >> 8)); atomic_add(&counters[6], (int)(cy[3] >> 8));\n"
     "    atomic_add(&counters[7], (int)(cy[4] >> 8));\n"),
]

RUNNER = r'''
import sys
import numpy as np
import pyopencl as cl
sys.path.insert(0, sys.argv[1])
from pyopencl_rt.device.devices import select_device
from pyopencl_rt.render.film import Film
from pyopencl_rt.render.wavefront import Wavefront
from pyopencl_rt.scene.loaders import load_scene
wf = Wavefront(load_scene(sys.argv[2]), select_device("cpu"), width=256, height=256, kernel_mode="megakernel")
wf.run(Film(256, 256), passes=1)
total, samples = np.zeros(5), 0
for _ in range(int(sys.argv[3])):
    zero = np.zeros_like(wf.counters_host)
    cl.enqueue_copy(wf.rt.queue, wf.buffer("counters"), zero)
    stats = wf.run(Film(256, 256), passes=4)
    c = np.zeros_like(wf.counters_host)
    cl.enqueue_copy(wf.rt.queue, c, wf.buffer("counters"))
    wf.rt.queue.finish()
    total += np.array([c[0], c[1], c[2], c[6], c[7]], float) * 256
    samples += stats.samples
per = total / samples
print("%.1f %.1f %.1f %.1f %.1f" % tuple(per))
'''


def patched_copy(tree: Path, into: Path) -> Path:
    dest = into / tree.resolve().name
    for part in ("cl", "pyopencl_rt"):
        shutil.copytree(tree / part, dest / part)
    lanes = dest / "cl" / "megakernel" / "path.cl"
    text = lanes.read_text()
    for anchor, insert in PATCHES:
        if text.count(anchor) != 1:
            raise SystemExit(f"{tree}: path.cl no longer has this line once: {anchor.strip()!r}")
        text = text.replace(anchor, anchor + insert)
    lanes.write_text(text)
    return dest


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("trees", nargs="+", type=Path, help="source trees (a checkout or a git worktree)")
    parser.add_argument("--pairs", type=int, default=3, help="rounds: every tree once per round, in turn")
    parser.add_argument("--rounds", type=int, default=6, help="4-pass renders per measurement")
    parser.add_argument("--scene", type=Path, default=Path(__file__).resolve().parents[1] / "scenes" / "mitsuba-cbox.toml")
    args = parser.parse_args(argv)
    scene = args.scene.resolve()
    names = ("start", "extend", "escape", "shade", "shadow")
    with tempfile.TemporaryDirectory() as scratch:
        copies = [patched_copy(tree, Path(scratch) / str(i)) for i, tree in enumerate(args.trees)]
        for round_ in range(args.pairs):
            for tree, copy in zip(args.trees, copies):
                out = subprocess.run([sys.executable, "-c", RUNNER, str(copy), str(scene), str(args.rounds)],
                                     capture_output=True, text=True)
                if out.returncode:
                    raise SystemExit(out.stderr.strip().splitlines()[-1])
                per = [float(x) for x in out.stdout.split()]
                shares = " ".join(f"{n} {v:.0f} ({v / sum(per):.2f})" for n, v in zip(names, per))
                print(f"round {round_ + 1} {str(tree):24s} cycles/sample: {shares}  total {sum(per):.0f}", flush=True)


if __name__ == "__main__":
    main()
