"""Write a TOML scene of many analytic shapes: an n x n field of spheres (and, with --disks, as
many disks tilted among them) on a floor under a quad light, seen from above at an angle.  The
benchmark of issue 36's shapes' BVH against the list every ray used to test
(docs/BENCHMARKS.md, "Analytic shapes as units"):

    python tools/shape_field.py 20 /tmp/field-400.toml            # 400 spheres
    python tools/shape_field.py 20 /tmp/field-800.toml --disks    # and 400 disks

A base commit from before the shapes' BVH reads the spheres (it has no disks)."""
from __future__ import annotations

import argparse

import numpy as np


def field(n: int, disks: bool, seed: int = 1) -> str:
    rng = np.random.default_rng(seed)
    lines = ['[camera]\neye = [0.0, 14.0, 16.0]\nlook_at = [0.0, 0.0, 0.0]\nfov = 45\n',
             '[render]\nspp = 16\nmax_depth = 6\n',
             '[materials.floor]\ntype = "diffuse"\nalbedo = [0.6, 0.6, 0.6]\n',
             '[materials.ball]\ntype = "diffuse"\nalbedo = [0.7, 0.4, 0.3]\n',
             '[materials.chip]\ntype = "diffuse"\nalbedo = [0.3, 0.5, 0.7]\n',
             '[materials.lamp]\nemission = [8.0, 8.0, 8.0]\nalbedo = [0.0, 0.0, 0.0]\n',
             '[[shape]]\ntype = "quad"\nmaterial = "floor"\npoints = [[-12, 0, -12], [-12, 0, 12], [12, 0, 12], [12, 0, -12]]\n',
             '[[shape]]\ntype = "quad"\nmaterial = "lamp"\npoints = [[-3, 10, -3], [3, 10, -3], [3, 10, 3], [-3, 10, 3]]\n']
    step = 20.0 / n
    for i in range(n):
        for j in range(n):
            x, z = -10 + (i + 0.5) * step, -10 + (j + 0.5) * step
            r = step * rng.uniform(0.15, 0.35)
            lines.append(f'[[shape]]\ntype = "sphere"\nmaterial = "ball"\ncenter = [{x:.4f}, {r:.4f}, {z:.4f}]\n'
                         f'radius = {r:.4f}\n')
            if disks:
                nrm = rng.normal(size=3) + [0, 2, 0]
                lines.append(f'[[shape]]\ntype = "disk"\nmaterial = "chip"\ncenter = [{x + step / 3:.4f}, '
                             f'{step * 0.6:.4f}, {z + step / 3:.4f}]\nnormal = [{nrm[0]:.4f}, {nrm[1]:.4f}, '
                             f'{nrm[2]:.4f}]\nradius = {step * 0.25:.4f}\n')
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("n", type=int, help="spheres per side")
    ap.add_argument("out")
    ap.add_argument("--disks", action="store_true", help="a tilted disk beside each sphere")
    a = ap.parse_args()
    with open(a.out, "w") as f:
        f.write(field(a.n, a.disks))


if __name__ == "__main__":
    main()
