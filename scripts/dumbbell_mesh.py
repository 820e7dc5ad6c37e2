#!/usr/bin/env python3
"""Writes scenes/meshes/dumbbell.obj: a closed dumbbell, two balls joined
by a bar, as a surface of revolution about the z axis, centred at the
origin (m). Generated for porosph's mesh example (scenes/mesh_dumbbell.toml);
no third-party geometry.

    python3 scripts/dumbbell_mesh.py > scenes/meshes/dumbbell.obj
"""
import math

BALL = 0.05      # ball radius, m
CENTRE = 0.06    # ball centres at z = +-CENTRE
BAR = 0.022      # bar radius
RINGS = 16       # profile points per ball, pole to junction
SEGMENTS = 48    # around the axis

# Profile (z, r) from the -z pole to the +z pole: each ball from its pole
# across its equator to where it meets the bar (r = BAR); the strip
# between the two junction rings is the bar.
join = math.pi - math.asin(BAR / BALL)
left = [(-(CENTRE + BALL * math.cos(t)), BALL * math.sin(t)) for t in (join * k / RINGS for k in range(1, RINGS + 1))]
profile = left + [(-z, r) for z, r in reversed(left)]

vertices = [(0.0, 0.0, -(CENTRE + BALL))]
for z, r in profile:
    for s in range(SEGMENTS):
        a = 2 * math.pi * s / SEGMENTS
        vertices.append((r * math.cos(a), r * math.sin(a), z))
vertices.append((0.0, 0.0, CENTRE + BALL))
top = len(vertices) - 1

def ring(i, s):
    return 1 + i * SEGMENTS + s % SEGMENTS

# Counter-clockwise seen from outside (normals outward).
faces = []
for s in range(SEGMENTS):
    faces.append((0, ring(0, s + 1), ring(0, s)))
for i in range(len(profile) - 1):
    for s in range(SEGMENTS):
        a, b, c, d = ring(i, s), ring(i, s + 1), ring(i + 1, s + 1), ring(i + 1, s)
        faces.append((a, b, c))
        faces.append((a, c, d))
last = len(profile) - 1
for s in range(SEGMENTS):
    faces.append((top, ring(last, s), ring(last, s + 1)))

# Outward: the signed volume must be positive.
volume = 0.0
for f in faces:
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = (vertices[i] for i in f)
    volume += (ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)) / 6
assert volume > 0, volume

print("# A dumbbell: two balls (r = %g m, centres z = +-%g m) joined by a bar (r = %g m)." % (BALL, CENTRE, BAR))
print("# Written by scripts/dumbbell_mesh.py for porosph (MIT, like the project). Volume %.4e m^3." % volume)
print("o dumbbell")
for x, y, z in vertices:
    print("v %.6f %.6f %.6f" % (x, y, z))
for a, b, c in faces:
    print("f %d %d %d" % (a + 1, b + 1, c + 1))
