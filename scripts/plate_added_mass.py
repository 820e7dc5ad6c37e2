#!/usr/bin/env python3
"""The reference of tests/deformable.rs's added-mass test: the added mass of
the clamped plate moving in its first bending mode in the test's closed
tank of ideal (inviscid, incompressible) water, from potential flow.

Finite volumes on a Cartesian grid of cell size H: Laplace's equation for
the velocity potential in the water cells, no flux through the tank walls,
and the plate's normal velocity on the faces between water and plate
cells. The water's kinetic energy is T = rho/2 sum_faces H (dphi)^2, and
the added (generalised) mass 2 T / v_tip^2. With the plate's generalised
mass M = rho_s H_p b int (w(x)/w(L))^2 dx, the frequency falls in water by
sqrt(M / (M + m_a)) (the mode shape taken as unchanged).

Checks (`--check`): a flat strip of width b moving across its width in a
box ten widths wide gives C = 1.09 (t = 1 cm, H = 5 mm) and 1.06
(t = 5 mm, H = 2.5 mm) of the 2-D value rho pi b^2 / 4 (1 for a thin
strip in unbounded water; the box and the thickness add a few per cent).

Measured 2026-12-02 (numpy, scipy; 10 s at H = 5 mm, 2 min at 2.5 mm):

    H = 10 mm: C 0.886 of the strip value, ratio 0.5140
    H = 5 mm:  C 0.901, ratio 0.5109
    H = 2.5 mm: C 0.911, ratio 0.5089
    H = 5 mm, walls 4x as far: C 0.828, ratio 0.5270

    python3 scripts/plate_added_mass.py 0.005         # needs numpy, scipy

`--rigid [H]`: the whole plate (its clamped part too) translated rigidly
across its thickness: added mass 11.60 kg at H = 10 mm, 11.70 kg at 5 mm
(the plate's own mass 2.94 kg).
"""
import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

RHO = 1000.0  # water and plate, kg/m^3


def kinetic_energy(lo, hi, h, solid, vel):
    """T of the water in the box [lo, hi] around the body `solid` (a mask
    of cell centres) moving with `vel` (the body's velocity at its cells)."""
    n = [int(round((hi[a] - lo[a]) / h)) for a in range(3)]
    centres = [lo[a] + (np.arange(n[a]) + 0.5) * h for a in range(3)]
    X, Y, Z = np.meshgrid(*centres, indexing="ij")
    body = solid(X, Y, Z)
    water = ~body
    idx = -np.ones(n, dtype=np.int64)
    idx[water] = np.arange(water.sum())
    nw = int(water.sum())
    rows, cols, vals = [], [], []
    b = np.zeros(nw)
    diag = np.zeros(nw)
    v = vel(X, Y, Z)
    for a in range(3):
        s0, s1 = [slice(None)] * 3, [slice(None)] * 3
        s0[a], s1[a] = slice(0, n[a] - 1), slice(1, n[a])
        s0, s1 = tuple(s0), tuple(s1)
        w0, w1, i0, i1 = water[s0], water[s1], idx[s0], idx[s1]
        both = w0 & w1
        r, c = i0[both], i1[both]
        rows += [r, c]
        cols += [c, r]
        vals += [-h * np.ones(r.size)] * 2
        np.add.at(diag, r, h)
        np.add.at(diag, c, h)
        # Faces between the body and water: the body's normal velocity
        # times the face area enters the water cell.
        m = body[s0] & w1
        np.add.at(b, i1[m], v[a][s0][m] * h * h)
        m = w0 & body[s1]
        np.add.at(b, i0[m], -v[a][s1][m] * h * h)
    rows.append(np.arange(nw))
    cols.append(np.arange(nw))
    vals.append(diag)
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(nw, nw))
    b -= b.mean()  # the closed tank: the net flux is 0 up to rounding
    phi, info = spla.cg(A, b, rtol=1e-9, maxiter=20000, M=sp.diags(1.0 / diag))
    assert info == 0, info
    return 0.5 * RHO * phi @ (A @ phi)


def strip(b, t, h, box):
    """C of a strip of width b and thickness t moving across its width."""
    lo, hi = [0.0, -box / 2, -box / 2], [h, box / 2, box / 2]
    T = kinetic_energy(lo, hi, h, lambda X, Y, Z: (np.abs(Y) < t / 2) & (np.abs(Z) < b / 2),
                       lambda X, Y, Z: (0 * X, 1.0 + 0 * X, 0 * X)) / h
    return 2 * T / (RHO * np.pi * b * b / 4)


# tests/deformable.rs's plate: length, thickness, width, m.
L, HP, B = 0.4, 0.04, 0.16


def plate_in_tank(far=1.0):
    """The tank [-0.06, 0.52] x [-0.16, 0.20] x [-0.12, 0.28] m (`far` moves
    the walls other than the clamp's out by that factor) and the mask of the
    plate's cells, its clamped part from the tank wall at x = -0.06 m to 0."""
    lo = [-0.06, -0.16 * far, -0.12 * far]
    hi = [L + 0.12 * far, HP + 0.16 * far, B + 0.12 * far]
    return lo, hi, lambda X, Y, Z: (X < L) & (Y > 0) & (Y < HP) & (Z > 0) & (Z < B)


def plate(h, far=1.0):
    """(C, frequency ratio) of the plate clamped at x = 0 moving in its first
    bending mode, in `plate_in_tank(far)`."""
    kl = 1.875
    k = kl / L
    a = (np.cos(kl) + np.cosh(kl)) / (np.sin(kl) + np.sinh(kl))

    def shape(x):
        return (np.cos(k * x) - np.cosh(k * x)) - a * (np.sin(k * x) - np.sinh(k * x))

    lo, hi, body = plate_in_tank(far)
    T = kinetic_energy(lo, hi, h, body,
                       lambda X, Y, Z: (0 * X, np.where(X > 0, shape(np.maximum(X, 0)) / shape(L), 0.0), 0 * X))
    xs = (np.arange(4000) + 0.5) * L / 4000
    modal = np.sum((shape(xs) / shape(L)) ** 2) * L / 4000
    m_plate = RHO * HP * B * modal
    m_added = 2 * T
    return m_added / (RHO * np.pi * B * B / 4 * modal), np.sqrt(m_plate / (m_plate + m_added))


def rigid(h):
    """Added mass (kg) of the whole plate, clamped part included, translated
    rigidly across its thickness in the same tank: the fluid-side check of
    tests/deformable.rs's added-mass doc (a kinematic plate, no bending)."""
    lo, hi, body = plate_in_tank()
    return 2 * kinetic_energy(lo, hi, h, body, lambda X, Y, Z: (0 * X, 1.0 + 0 * X, 0 * X))


if __name__ == "__main__":
    if sys.argv[1:2] == ["--rigid"]:
        h = float(sys.argv[2]) if len(sys.argv) > 2 else 0.01
        print(f"H = {h} m: the plate translated rigidly, added mass {rigid(h):.2f} kg")
    elif sys.argv[1:2] == ["--check"]:
        print(f"strip t 1 cm, H 5 mm: C = {strip(0.16, 0.01, 0.005, 1.6):.3f}")
        print(f"strip t 5 mm, H 2.5 mm: C = {strip(0.16, 0.005, 0.0025, 1.6):.3f}")
    else:
        h = float(sys.argv[1]) if len(sys.argv) > 1 else 0.005
        far = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0
        c, ratio = plate(h, far)
        print(f"H = {h} m, walls x{far}: C = {c:.3f} of the strip value, frequency ratio {ratio:.4f}")
