"""Writes lamps-*.obj for scenes/many-lights.toml: 3072 small square lamps (a 64 x 48 grid over a
24 m x 18 m hall, jittered, at heights 0.4 to 6 m, sides 4 to 16 cm), facing down, in four colour
groups (one OBJ each), from a fixed seed.  Run from this folder: python make_lamps.py"""
import numpy as np

COLUMNS, ROWS = 64, 48
GROUPS = 4


def lamps(seed=34):
    rng = np.random.default_rng(seed)
    x = (np.arange(COLUMNS) + 0.5) / COLUMNS * 24.0 - 12.0
    z = (np.arange(ROWS) + 0.5) / ROWS * 18.0 - 9.0
    cx, cz = (a.ravel() for a in np.meshgrid(x, z))
    cx = cx + rng.uniform(-0.12, 0.12, cx.size)
    cz = cz + rng.uniform(-0.12, 0.12, cz.size)
    cy = rng.uniform(0.4, 6.0, cx.size)
    half = 0.5 * rng.uniform(0.04, 0.16, cx.size)
    group = rng.integers(0, GROUPS, cx.size)
    return cx, cy, cz, half, group


def write(folder="."):
    cx, cy, cz, half, group = lamps()
    for g in range(GROUPS):
        lines = [f"# {int((group == g).sum())} lamps of group {g}, written by make_lamps.py"]
        faces = []
        k = 0
        for i in np.flatnonzero(group == g):
            h = half[i]
            # corners counter-clockwise seen from below: the normal (p1 - p0) x (p2 - p0) is -y
            for dx, dz in ((-h, -h), (h, -h), (h, h), (-h, h)):
                lines.append(f"v {cx[i] + dx:.5f} {cy[i]:.5f} {cz[i] + dz:.5f}")
            faces.append(f"f {k + 1} {k + 2} {k + 3} {k + 4}")
            k += 4
        with open(f"{folder}/lamps-{g}.obj", "w") as f:
            f.write("\n".join(lines + faces) + "\n")


if __name__ == "__main__":
    write()
