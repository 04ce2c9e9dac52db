#!/usr/bin/env python3
"""Writes scenes/meshes/funnel.obj, the funnel of scenes/funnel.json and scenes/funnel_small.json.

The funnel is an open surface of revolution about the world z axis (z up), in metres:

  spout   a vertical tube of radius NECK_R from z = SPOUT_BOTTOM up to the neck,
  neck    a fillet of radius NECK_FILLET between the tube and the cone,
  cone    a straight cone whose (unfilleted) lines meet the tube at z = NECK_Z and reach radius MOUTH_R at z = MOUTH_Z,
          MOUTH_Z - NECK_Z over MOUTH_R - NECK_R steep (about 61 degrees from the horizontal),
  rim     a rolled lip: the wall curls outward over a half circle of radius RIM_R until it points straight down.

The mesh is a single sheet (no thickness): cloth contact measures unsigned distances, so the cloth meets it from
either side at the contact layer. Rings of NSEG vertices are spaced along the profile so that the triangles between
them are close to equilateral (ring spacing sqrt(3)/2 of the local arc length, every other ring turned by half a
segment), with at most RIM_STEP_DEG of turning between rings on the curved parts. Faces are oriented with their
normals towards the axis (the funnel's inside).

The scenes (the scene format has no description key, so they are described here):

  scenes/funnel.json        Wang et al. 2018, Fig. 1 and Table 1: a 0.9 m x 0.9 m cotton square of 120,062 vertices
                            (238,740 triangles; the paper: 120K and 238K) falls from 2 cm above the rim into the
                            funnel, through the spout and out; dt = 1/90 s (30 frames/s, 3 substeps), self-contact and
                            contact with the funnel (cloth_contact, 2 mm layer; funnel friction 0.1), fmg to a relative
                            gradient of 1e-3, 45 frames (1.5 s; the small version is through the spout after 1.2 s),
                            obj + glb. Its first frames on the 2 shared cores of the development machine: 74 s for
                            frame 1 (3 steps of 9 FMG cycles, no contact yet) and 130 s for frame 2 (the sheet lands on
                            the rim: 30, then 6 cycles); contact detection took 35-55 % of the step. Extrapolated, the
                            whole run takes several hours there.
  scenes/funnel_small.json  the same scene at 2,500 vertices, 40 frames: about 1 to 1.5 minutes on one core; every
                            step converged, no intersection, the whole sheet below the spout at the end.

The sheet is 0.9 m wide against the rim's 0.875 m outer diameter: a 1 m sheet hangs over the rim by so much that its
outside part balances the part inside and it stays on the rim like a drum (measured: it does not slide in, from a
drop of 2 cm or of 34 cm).

Usage: scripts/make_funnel.py [OUT.obj]   (default: scenes/meshes/funnel.obj next to this script's repository)
The output is deterministic: the same script writes the same bytes.
"""
import math
import os
import sys

NSEG = 48              # vertices per ring
MOUTH_R = 0.40         # m, radius where the cone meets the rolled rim
MOUTH_Z = 1.00         # m, height of that circle
NECK_R = 0.15          # m, radius of the spout
NECK_Z = 0.55          # m, where the cone's line meets the spout's
SPOUT_BOTTOM = 0.25    # m, the spout's open lower end
NECK_FILLET = 0.04     # m, fillet radius between spout and cone
RIM_R = 0.02           # m, radius of the rolled lip
RIM_STEP_DEG = 40.0    # most turning of the profile between two rings


def profile():
    """A dense polyline (r, z) of the profile from the spout's lower end to the lip's end."""
    pts = []
    phi = math.atan2(MOUTH_Z - NECK_Z, MOUTH_R - NECK_R)  # the cone's angle from the horizontal
    turn = math.pi / 2 - phi                               # the neck fillet turns from straight up to the cone
    tangent_len = NECK_FILLET * math.tan(turn / 2)
    fillet_start_z = NECK_Z - tangent_len
    # Spout: straight up.
    n = 2000
    for i in range(n):
        t = i / n
        pts.append((NECK_R, SPOUT_BOTTOM + t * (fillet_start_z - SPOUT_BOTTOM)))
    # Neck fillet: centre to the outside of the tube, turning clockwise in the (r, z) plane.
    c = (NECK_R + NECK_FILLET, fillet_start_z)
    for i in range(n):
        th = math.pi - turn * i / n
        pts.append((c[0] + NECK_FILLET * math.cos(th), c[1] + NECK_FILLET * math.sin(th)))
    # Cone: from the fillet's end to the mouth circle.
    th = math.pi - turn
    p0 = (c[0] + NECK_FILLET * math.cos(th), c[1] + NECK_FILLET * math.sin(th))
    for i in range(n):
        t = i / n
        pts.append((p0[0] + t * (MOUTH_R - p0[0]), p0[1] + t * (MOUTH_Z - p0[1])))
    # Rolled lip: from the cone's direction, clockwise until it points down (a turn of 90 degrees + phi).
    c = (MOUTH_R + RIM_R * math.sin(phi), MOUTH_Z - RIM_R * math.cos(phi))
    th0 = math.pi / 2 + phi
    for i in range(n + 1):
        th = th0 * (1 - i / n)
        pts.append((c[0] + RIM_R * math.cos(th), c[1] + RIM_R * math.sin(th)))
    return pts


def rings():
    """The rings' (r, z), spaced by the local target spacing along the dense profile."""
    pts = profile()
    # Turning per unit length along the polyline, for the curvature limit on the spacing.
    def target(i):
        r = pts[i][0]
        h = math.sqrt(3) / 2 * 2 * math.pi * r / NSEG
        # Curvature from three neighbouring points (0 on straight parts).
        if 0 < i < len(pts) - 1:
            a, b, d = pts[i - 1], pts[i], pts[i + 1]
            v1 = (b[0] - a[0], b[1] - a[1])
            v2 = (d[0] - b[0], d[1] - b[1])
            l1, l2 = math.hypot(*v1), math.hypot(*v2)
            cross = v1[0] * v2[1] - v1[1] * v2[0]
            dot = v1[0] * v2[0] + v1[1] * v2[1]
            ang = abs(math.atan2(cross, dot))
            kappa = ang / (0.5 * (l1 + l2))
            if kappa > 1e-6:
                h = min(h, math.radians(RIM_STEP_DEG) / kappa)
        return h
    # Parameter t = integral of ds / target(s); rings at equal steps of t.
    t = [0.0]
    for i in range(1, len(pts)):
        ds = math.hypot(pts[i][0] - pts[i - 1][0], pts[i][1] - pts[i - 1][1])
        t.append(t[-1] + ds / (0.5 * (target(i - 1) + target(i))))
    count = max(2, round(t[-1]))
    out = []
    j = 0
    for k in range(count + 1):
        tk = t[-1] * k / count
        while j < len(t) - 2 and t[j + 1] < tk:
            j += 1
        span = t[j + 1] - t[j]
        s = 0.0 if span <= 0 else min(1.0, max(0.0, (tk - t[j]) / span))
        out.append((pts[j][0] + s * (pts[j + 1][0] - pts[j][0]), pts[j][1] + s * (pts[j + 1][1] - pts[j][1])))
    return out


def mesh():
    rs = rings()
    verts = []
    for k, (r, z) in enumerate(rs):
        off = 0.5 * (k % 2)
        for j in range(NSEG):
            a = 2 * math.pi * (j + off) / NSEG
            verts.append((r * math.cos(a), r * math.sin(a), z))
    faces = []
    for k in range(len(rs) - 1):
        lo, hi = k * NSEG, (k + 1) * NSEG
        for j in range(NSEG):
            j1 = (j + 1) % NSEG
            if k % 2 == 0:   # lower ring at whole steps, upper at half steps: b_j lies between a_j and a_j+1
                tris = [(lo + j, lo + j1, hi + j), (hi + j, lo + j1, hi + j1)]
            else:            # lower ring at half steps: b_j+1 lies between a_j and a_j+1
                tris = [(lo + j, lo + j1, hi + j1), (lo + j, hi + j1, hi + j)]
            faces.extend(tris)
    # Orient towards the axis: the lower ring runs counter-clockwise seen from above, so (a_j, a_j+1, b) has its
    # normal pointing outward-ish; flip all to point inward.
    faces = [(a, c, b) for (a, b, c) in faces]
    return rs, verts, faces


def quality(verts, faces):
    worst_angle, worst_aspect = 180.0, 0.0
    for f in faces:
        p = [verts[i] for i in f]
        e = [[p[(i + 1) % 3][d] - p[i][d] for d in range(3)] for i in range(3)]
        le = [math.sqrt(sum(c * c for c in x)) for x in e]
        for i in range(3):
            a, b = e[i], e[(i + 2) % 3]
            cosang = -sum(a[d] * b[d] for d in range(3)) / (le[i] * le[(i + 2) % 3])
            worst_angle = min(worst_angle, math.degrees(math.acos(max(-1.0, min(1.0, cosang)))))
        cr = [e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
              e[0][0] * e[1][1] - e[0][1] * e[1][0]]
        area2 = math.sqrt(sum(c * c for c in cr))
        worst_aspect = max(worst_aspect, max(le) ** 2 / area2)  # 2/sqrt(3) ~ 1.155 for equilateral
    return worst_angle, worst_aspect


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "scenes", "meshes", "funnel.obj")
    rs, verts, faces = mesh()
    angle, aspect = quality(verts, faces)
    rim_outer = max(r for r, _ in rs)
    rim_top = max(z for _, z in rs)
    lines = [
        "# mgcloth: a funnel for scenes/funnel.json (written by scripts/make_funnel.py; edit that, not this file)",
        f"# open surface of revolution about z: spout radius {NECK_R} m from z = {SPOUT_BOTTOM} m, cone to radius "
        f"{MOUTH_R} m at z = {MOUTH_Z} m",
        f"# (neck fillet {NECK_FILLET} m), rolled rim of radius {RIM_R} m (outer radius {rim_outer:.4f} m, top "
        f"z = {rim_top:.4f} m)",
        f"# {len(verts)} vertices, {len(faces)} triangles, {len(rs)} rings of {NSEG}; smallest angle {angle:.1f} deg",
    ]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    text = "\n".join(lines) + "\n"
    tmp = out + ".tmp"
    with open(tmp, "w", newline="\n") as fh:
        fh.write(text)
    os.replace(tmp, out)
    print(f"{out}: {len(verts)} vertices, {len(faces)} triangles, {len(rs)} rings; smallest angle {angle:.1f} deg, "
          f"worst l_max^2/(2A) {aspect:.2f}; rim outer radius {rim_outer:.4f} m, top z {rim_top:.4f} m")


if __name__ == "__main__":
    main()
