#!/usr/bin/env python3
"""The pressure solve's relaxed Jacobi on the start lattice, per kernel
(support H = 2d, PHYSICS.md §1; the kernels of kernels/src/kernel.rs, Wendland
C2 with its lattice calibration). The evidence behind bench/RESULTS.md's
"Wendland C2 as the default: the failures' causes (issue 15)".

On the cubic lattice sum_j grad W_ij = 0, so the IISPH diagonal is
a_ii ~ sum_j |grad W_ij|^2 (times -dt^2 m^2 / rho^2) and the operator on a
Fourier mode p_j = e^{i k.x_j} has the symbol |G(k)|^2 with
G(k) = sum_j grad W_j (1 - e^{i k.x_j}) (same factor). The eigenvalues of
D^-1 A are |G(k)|^2 / sum_j |grad W_j|^2: the smallest (a smooth mode, here
k = pi / 30 d, the hydrostatic column's height) sets how fast Jacobi
converges at a given omega, the largest how large omega may be.

Also the own-side lattice sums d^3 sum_j W_ij of a particle at a flat face,
an edge and a corner of a lattice half-space, quarter-space and octant
(`Kernel::flat_wall_gamma` is the face's).

Measured 2026-12-05:
    cubic    smooth / diag 2.676e-02, largest 2.814; face 0.850, edge 0.720, corner 0.607
    wendland smooth / diag 2.216e-02, largest 2.605; face 0.876, edge 0.765, corner 0.666
(the largest over a 12-point grid per axis, at k = (pi/3, pi/3, pi/3) / d
for both; the first version took the largest of four k points, 2.449 and
2.028.)

    python3 scripts/jacobi_spectrum.py
"""
import cmath
import math

H = 2.0  # support in units of d
PTS = [(i, j, k) for i in range(-3, 4) for j in range(-3, 4) for k in range(-3, 4)]


def cubic(r):
    """(W, W') of the cubic spline, d = 1."""
    q, k, l = r / H, 8 / (math.pi * H**3), 48 / (math.pi * H**4)
    if q <= 0.5:
        return k * (6 * q**3 - 6 * q**2 + 1), l * q * (3 * q - 2)
    if q <= 1:
        return 2 * k * (1 - q) ** 3, -l * (1 - q) ** 2
    return 0.0, 0.0


def wendland_raw(r):
    q, c = r / H, 21 / (2 * math.pi * H**3)
    if q < 1:
        return c * (1 - q) ** 4 * (1 + 4 * q), -20 * c * q * (1 - q) ** 3 / H
    return 0.0, 0.0


def norm(p):
    return math.sqrt(p[0] ** 2 + p[1] ** 2 + p[2] ** 2)


# Wendland's calibration (kernels/src/kernel.rs): W by the lattice sum, the
# gradient by the first moment.
SUM = sum(wendland_raw(norm(p))[0] for p in PTS)
MOMENT = sum(-norm(p) * wendland_raw(norm(p))[1] / 3 for p in PTS)


def wendland(r):
    w, g = wendland_raw(r)
    return w / SUM, g / MOMENT


def symbol(f, kv):
    g = [0j, 0j, 0j]
    for p in PTS:
        r = norm(p)
        if r == 0:
            continue
        phase = 1 - cmath.exp(1j * sum(a * b for a, b in zip(kv, p)))
        for a in range(3):
            g[a] += f(r)[1] * p[a] / r * phase
    return sum(abs(z) ** 2 for z in g)


for name, f in [("cubic", cubic), ("wendland", wendland)]:
    diag = sum(f(norm(p))[1] ** 2 for p in PTS)
    smooth = symbol(f, (math.pi / 30, 0, 0))
    # The symbol is even in each component and symmetric under their
    # permutations: a grid over 0 <= k_z <= k_y <= k_x <= pi.
    n = 12
    ks = [
        tuple(math.pi * m / n for m in (i, j, l)) for i in range(n + 1) for j in range(i + 1) for l in range(j + 1)
    ]
    largest = max(symbol(f, k) for k in ks)
    side = [sum(f(norm(p))[0] for p in PTS if all(p[a] >= 0 for a in range(n))) for n in (1, 2, 3)]
    print(
        f"{name:8} smooth / diag {smooth / diag:.3e}, largest {largest / diag:.3f}; "
        f"face {side[0]:.3f}, edge {side[1]:.3f}, corner {side[2]:.3f}"
    )
