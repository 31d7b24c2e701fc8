#!/usr/bin/env python3
"""Initial grains of Lethe's dense pneumatic conveying example, for plugflow.

Lethe (examples/unresolved-cfd-dem/dense-pneumatic-conveying) loads 32 194 grains of
5 mm into a periodic pipe (D = 84 mm, L = 1 m) shaped as a slug: a core 0.5 m long at
the top of the pipe, its rear and front faces inclined at 45 degrees (the slug is longer
at the bottom by D at each end), over a resting layer 0.021 m high along the whole pipe
(20 % of the cross-section). That fill is dense (solid fraction ~0.6): random placement
jams near 0.38, so the grains go on a face-centred cubic lattice whose spacing is chosen
so that the shape holds a few per cent more sites than grains; a seeded random subset of
the sites is kept and each grain is moved at random within the gap the spacing leaves
(no two overlap). The scene then settles them under gravity (`dem.settle`) before the gas
starts, as Lethe settles its loaded slug without the shape's walls.

Writes `initial.csv` (x,y,z,radius; SI) beside this script. Stdlib only, deterministic.
Frame: the pipe's axis along x from the origin, gravity along -z.
"""
import math
import os
import random

D, L, D_GRAIN, COUNT = 0.084, 1.0, 0.005, 32194
CORE, LAYER = 0.5, 0.021
R, r = D / 2, D_GRAIN / 2
CORE_FROM = 0.5 * (L - CORE)  # the core centred in the section
SEED = 2024


def inside(x, y, z):
    """The centre keeps the whole grain in the pipe and in the slug or the layer."""
    if math.hypot(y, z) > R - r or x - r < 0.0 or x + r > L:
        return False
    h = z + R  # height above the pipe's lowest line
    if h + r <= LAYER:
        return True
    # At height H the slug spans [CORE_FROM - (D - H), CORE_FROM + CORE + (D - H)]; the
    # grain is held to the span at its top (h + r), the narrowest it reaches.
    lean = D - (h + r)
    return x - r >= CORE_FROM - lean and x + r <= CORE_FROM + CORE + lean


def sites(spacing):
    """FCC sites (nearest neighbours `spacing` apart) inside the shape."""
    a = spacing * math.sqrt(2.0)  # cubic cell
    basis = [(0, 0, 0), (0.5, 0.5, 0), (0.5, 0, 0.5), (0, 0.5, 0.5)]
    out = []
    nx, ny = int(L / a) + 2, int(D / a) + 2
    for i in range(nx):
        for j in range(-ny, ny):
            for k in range(-ny, ny):
                for b in basis:
                    x = (i + b[0]) * a + r
                    y = (j + b[1]) * a
                    z = (k + b[2]) * a - R + r  # the lowest row on the pipe's bottom
                    if inside(x, y, z):
                        out.append((x, y, z))
    return out


def main():
    # The largest spacing whose sites outnumber the grains by 2 % (bisection).
    lo, hi = D_GRAIN * 1.0001, D_GRAIN * 1.5
    if len(sites(lo)) < COUNT:
        raise SystemExit(f"the shape holds only {len(sites(lo))} grains on a lattice")
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if len(sites(mid)) >= 1.02 * COUNT:
            lo = mid
        else:
            hi = mid
    spacing = lo
    rng = random.Random(SEED)
    chosen = rng.sample(sites(spacing), COUNT)
    gap = 0.5 * (spacing - D_GRAIN) * 0.999
    rows = []
    for (x, y, z) in chosen:
        for _ in range(100):
            # A uniform point in the ball of radius `gap`.
            dx, dy, dz = (rng.uniform(-gap, gap) for _ in range(3))
            if dx * dx + dy * dy + dz * dz <= gap * gap and inside(x + dx, y + dy, z + dz):
                x, y, z = x + dx, y + dy, z + dz
                break
        rows.append((x, y, z))
    rows.sort()
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "initial.csv")
    with open(path, "w") as f:
        f.write("x,y,z,radius\n")
        for (x, y, z) in rows:
            f.write(f"{x:.9e},{y:.9e},{z:.9e},{r:.9e}\n")
    solid = COUNT * 4.0 / 3.0 * math.pi * r**3
    print(f"{COUNT} grains, lattice spacing {spacing * 1e3:.4f} mm "
          f"({spacing / D_GRAIN:.4f} d), solid volume {solid:.4e} m3 -> {path}")


if __name__ == "__main__":
    main()
