#!/usr/bin/env python3
"""Writes scenes/meshes/drape_tester.obj: the support of a drape tester (Cusick 1968) for scenes/drape_tester.json.

A closed surface of revolution about z: a disc of radius 0.09 m (the tester's 18 cm support) whose top is at
z = 0.3 m, 1 cm thick, on a column of radius 1.5 cm down to z = 0. Triangles are counter-clockwise seen from outside.
"""
import math
import os

SEGMENTS = 96
# The profile (r, z) from the top's centre over the rim and down the column to the bottom's centre.
PROFILE = [(0.0, 0.3), (0.09, 0.3), (0.09, 0.29), (0.015, 0.29), (0.015, 0.0), (0.0, 0.0)]


def main():
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "meshes", "drape_tester.obj")
    verts, index = [], []
    for r, z in PROFILE:
        if r == 0.0:
            index.append([len(verts) + 1] * SEGMENTS)  # a pole: one vertex for every angle
            verts.append((0.0, 0.0, z))
        else:
            index.append([len(verts) + 1 + j for j in range(SEGMENTS)])
            for j in range(SEGMENTS):
                a = 2 * math.pi * j / SEGMENTS
                verts.append((r * math.cos(a), r * math.sin(a), z))
    faces = []
    for i in range(len(PROFILE) - 1):
        for j in range(SEGMENTS):
            k = (j + 1) % SEGMENTS
            a, b, c, d = index[i][j], index[i + 1][j], index[i + 1][k], index[i][k]
            for tri in ((a, b, c), (a, c, d)):
                if len(set(tri)) == 3:  # at a pole one of the two collapses
                    faces.append(tri)
    with open(path, "w") as f:
        f.write("# mgcloth: a drape tester's support (disc radius 0.09 m, top at z = 0.3 m, 1 cm thick, column radius\n"
                "# 1.5 cm), for scenes/drape_tester.json (written by scripts/make_drape_tester.py; edit that, not this file)\n")
        for v in verts:
            f.write("v {:.6f} {:.6f} {:.6f}\n".format(*v))
        for t in faces:
            f.write("f {} {} {}\n".format(*t))


if __name__ == "__main__":
    main()
