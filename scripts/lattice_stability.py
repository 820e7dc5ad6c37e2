#!/usr/bin/env python3
"""Linear stability of particle lattices under the symmetric SPH pressure
force at positive pressure, for the cubic spline of scripts/kernel_sums.py
(support H = 2d, PHYSICS.md §1). The evidence behind tests/hydrostatic.rs's
`tank_at_rest_per_particle` doc.

Model: at uniform pressure p the symmetric pressure force is the gradient
of (p m^2 / rho^2) times the total kernel sum S = sum_i sum_j W_ij; the
pressure solve keeps every particle's density, so the lattice is stable
when the second variation of S is non-negative on the density-preserving
displacements. For a Bravais lattice and a Bloch mode u e^{i k.R}, the
second variation is u^T D(k) u with D(k) = sum_r Hess W(r) (2 - 2 cos k.r)
and the density constraint is u . sum_r grad W(r) sin(k.r) = 0. The script
samples k at random and prints the least eigenvalue of D restricted to the
constraint's null space (negative: unstable).

Measured 2026-12-02: cubic -2.7e-1, BCC -2.1e-1, FCC -2.4e-2 (all unstable).
With `--kernel wendland` (Wendland C2 at the same H = 2d, kernels/src/kernel.rs;
its lattice calibration is a positive factor and leaves the signs alone),
2026-12-03: cubic +1.0e-3 (no unstable mode found in 4000 samples), BCC
-8.3e-2, FCC -1.9e-1; at H = 1.9d and 2.2d its cubic lattice is unstable
too (-3.1e-2, -1.4e-1).

    python3 scripts/lattice_stability.py [--kernel wendland] [--support H/d]   # needs numpy
"""
import argparse

import numpy as np

from kernel_sums import H, K, pieces


def dw(r):
    q, d, a, b = pieces(r)
    d[a] = K * (18 * q[a] ** 2 - 12 * q[a]) / H
    d[b] = -6 * K * (1 - q[b]) ** 2 / H
    return d


def d2w(r):
    q, d, a, b = pieces(r)
    d[a] = K * (36 * q[a] - 12) / H**2
    d[b] = 12 * K * (1 - q[b]) / H**2
    return d


def neighbours(primitive, a):
    m = int(np.ceil(H / a)) + 3
    cells = np.stack(np.meshgrid(*[np.arange(-m, m + 1)] * 3, indexing="ij"), -1).reshape(-1, 3)
    pts = (cells @ np.array(primitive)) * a
    r = np.linalg.norm(pts, axis=1)
    return pts[(r > 1e-9) & (r < H)]


def wendland(support):
    """Replaces dw, d2w (and the support) by Wendland C2's, C = 21 / (2 pi H^3)."""
    global H, dw, d2w
    H = support
    c = 21 / (2 * np.pi * H**3)

    def wdw(r):
        q = np.minimum(r / H, 1.0)
        return -20 * c * q * (1 - q) ** 3 / H

    def wd2w(r):
        q = np.minimum(r / H, 1.0)
        return 20 * c * (1 - q) ** 2 * (4 * q - 1) / H**2

    dw, d2w = wdw, wd2w


def least_curvature(pts, samples=3000, seed=0):
    r = np.linalg.norm(pts, axis=1)
    e = pts / r[:, None]
    grad = dw(r)[:, None] * e
    ee = e[:, :, None] * e[:, None, :]
    hess = d2w(r)[:, None, None] * ee + (dw(r) / r)[:, None, None] * (np.eye(3)[None] - ee)
    worst = np.inf
    for k in np.random.default_rng(seed).uniform(-2 * np.pi, 2 * np.pi, (samples, 3)):
        ph = pts @ k
        d = (hess * (2 - 2 * np.cos(ph))[:, None, None]).sum(0)
        c = (grad * np.sin(ph)[:, None]).sum(0)
        n = np.linalg.norm(c)
        basis = np.linalg.svd(np.eye(3) - np.outer(c, c) / n**2)[0][:, :2] if n > 1e-12 else np.eye(3)
        worst = min(worst, np.linalg.eigvalsh(basis.T @ d @ basis)[0])
    return worst


if __name__ == "__main__":
    cli = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    cli.add_argument("--kernel", choices=["cubic", "wendland"], default="cubic")
    cli.add_argument("--support", type=float, default=2.0, help="H in spacings (Wendland only)")
    args = cli.parse_args()
    sampling = {}
    if args.kernel == "wendland":
        wendland(args.support)
        sampling = {"samples": 4000, "seed": 1}  # its least curvature is small: sample more
    lattices = {
        "cubic": (np.eye(3), 1.0),
        "BCC": ([[-0.5, 0.5, 0.5], [0.5, -0.5, 0.5], [0.5, 0.5, -0.5]], 2 ** (1 / 3)),
        "FCC": ([[0, 0.5, 0.5], [0.5, 0, 0.5], [0.5, 0.5, 0]], 4 ** (1 / 3)),
    }
    for name, (primitive, a) in lattices.items():
        print(f"{name:5s} least curvature on density-preserving modes {least_curvature(neighbours(primitive, a), **sampling):+.2e}")
