#!/usr/bin/env python3
"""Writes assets/meshes/water_surface.obj: a wavy water surface over the Cornell box's floor
(x, z in [0, 555], height 200 +- 18), a grid of 32 x 32 quads with the surface's exact normals
(the scene pool.json's water: manifold NEE through one smooth refraction, issue 24)."""
import math
import sys

N, SIZE, LEVEL, AMP = 32, 555.0, 200.0, 12.0


def height(x, z):
    u, v = x / SIZE, z / SIZE
    return LEVEL + AMP * (math.sin(2 * math.pi * 2 * u) * math.cos(2 * math.pi * 1.5 * v)
                          + 0.5 * math.sin(2 * math.pi * (3 * u + 2 * v)))


def normal(x, z):
    e = 1e-3
    dx = (height(x + e, z) - height(x - e, z)) / (2 * e)
    dz = (height(x, z + e) - height(x, z - e)) / (2 * e)
    n = (-dx, 1.0, -dz)
    l = math.sqrt(sum(c * c for c in n))
    return tuple(c / l for c in n)


out = open(sys.argv[1] if len(sys.argv) > 1 else "assets/meshes/water_surface.obj", "w")
out.write("# A wavy water surface (scripts/make-water-mesh.py); normals point up, out of the water\n")
for j in range(N + 1):
    for i in range(N + 1):
        x, z = SIZE * i / N, SIZE * j / N
        out.write("v %.4f %.4f %.4f\n" % (x, height(x, z), z))
for j in range(N + 1):
    for i in range(N + 1):
        x, z = SIZE * i / N, SIZE * j / N
        out.write("vn %.6f %.6f %.6f\n" % normal(x, z))
for j in range(N):
    for i in range(N):
        a = j * (N + 1) + i + 1
        b, c, d = a + 1, a + N + 2, a + N + 1
        # counter-clockwise seen from above: the face normal points up, as the vertex normals
        out.write("f %d//%d %d//%d %d//%d\n" % (a, a, d, d, c, c))
        out.write("f %d//%d %d//%d %d//%d\n" % (a, a, c, c, b, b))
