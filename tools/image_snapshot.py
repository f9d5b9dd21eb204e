"""Bit-for-bit image snapshots, for changes that must not change any image (refactors, ABI moves).

    python tools/image_snapshot.py save DIR       # render every case below, save the film sums
    python tools/image_snapshot.py compare A B    # exit 1 unless every case in A is identical in B

Run ``save`` before the change (e.g. in a ``git worktree`` of the old commit) and after it, then
``compare``.  Each case renders a scene of ``scenes/`` at 48 x 40, 4 spp, seed 7 on the PoCL CPU
device, plus variants that exercise the other integrators, a small wave (slots reused across
passes) and the Embree intersector; the float64 film sums are compared with ``numpy.array_equal``.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
CORNELL = REPO / "scenes" / "cornell-box.toml"
VARIANTS = {
    "cbox-nee": {"integrator": "nee"},
    "cbox-bsdf": {"integrator": "bsdf", "max_depth": 3},
    "cbox-wave": {"wave_size": 5000},
    "cbox-embree": {"intersector": "embree"},
}


def cases():
    for path in sorted((REPO / "scenes").glob("*.toml")):
        yield path.stem, path, {}
    for name, options in VARIANTS.items():
        yield name, CORNELL, options


def save(folder: Path) -> None:
    import pyopencl_rt as rt

    folder.mkdir(parents=True, exist_ok=True)
    warnings.simplefilter("ignore")
    for name, path, options in cases():
        result = rt.render_full(rt.load_scene(path), spp=4, device="cpu", seed=7, width=48, height=40, **options)
        np.save(folder / f"{name}.npy", result.film.sum)
        print(f"{name}: {result.film.sum.sum():.6f}")


def compare(before: Path, after: Path) -> int:
    differ = 0
    for old in sorted(before.glob("*.npy")):
        new = after / old.name
        if not new.exists():
            print(f"{old.stem}: missing in {after}")
            differ += 1
            continue
        same = np.array_equal(np.load(old), np.load(new))
        differ += not same
        print(f"{old.stem}: {'identical' if same else 'DIFFERENT'}")
    print("all identical" if not differ else f"{differ} differ")
    return 1 if differ else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    sub.add_parser("save").add_argument("folder", type=Path)
    cmp = sub.add_parser("compare")
    cmp.add_argument("before", type=Path)
    cmp.add_argument("after", type=Path)
    args = parser.parse_args()
    if args.command == "save":
        save(args.folder)
        return 0
    return compare(args.before, args.after)


if __name__ == "__main__":
    sys.exit(main())
