#!/usr/bin/env python3
"""Writes the glass furnace scene (mesh/furnace_glass.obj, .mtl): the closed emitting cube of
the white furnace (Kd 0, Ke 1 on every inward face) around a smooth glass sphere (illum 6,
Ni 1.5), flat-shaded (each face's vn is its geometric normal) so that shading and geometric
normals agree. Every camera path ends on the walls with throughput exactly 1 (Fresnel-chosen
lobes, 1/eta^2 in, eta^2 out), so the sphere must be invisible: radiance 1 in every pixel.

Standard library only:  python3 data/furnace/make_glass_furnace.py
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))


def icosphere(level):
    t = (1 + 5 ** 0.5) / 2
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
             (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    verts = [tuple(c / math.sqrt(sum(x * x for x in v)) for c in v) for v in verts]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
             (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
             (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(level):
        cache = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = [(verts[a][i] + verts[b][i]) / 2 for i in range(3)]
                n = math.sqrt(sum(x * x for x in m))
                verts.append(tuple(x / n for x in m))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return verts, faces


def main():
    lines = ["# Glass furnace: written by make_glass_furnace.py (see there).",
             "mtllib furnace_glass.mtl", ""]
    nv = nn = 0
    # The cube [-1, 1]^3, one quad per face, facing inward (counter-clockwise seen from inside).
    lines.append("o walls")
    lines.append("usemtl walls")
    cube = [
        ((1, -1, -1), (1, 1, -1), (1, 1, 1), (1, -1, 1), (-1, 0, 0)),
        ((-1, -1, 1), (-1, 1, 1), (-1, 1, -1), (-1, -1, -1), (1, 0, 0)),
        ((-1, 1, -1), (-1, 1, 1), (1, 1, 1), (1, 1, -1), (0, -1, 0)),
        ((-1, -1, 1), (-1, -1, -1), (1, -1, -1), (1, -1, 1), (0, 1, 0)),
        ((-1, -1, -1), (-1, 1, -1), (1, 1, -1), (1, -1, -1), (0, 0, 1)),
        ((1, -1, 1), (1, 1, 1), (-1, 1, 1), (-1, -1, 1), (0, 0, -1)),
    ]
    for *corners, n in cube:
        # Keep the winding counter-clockwise about the inward normal.
        a, b, c = corners[0], corners[1], corners[2]
        e1 = [b[i] - a[i] for i in range(3)]
        e2 = [c[i] - a[i] for i in range(3)]
        cr = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
              e1[0] * e2[1] - e1[1] * e2[0])
        if sum(cr[i] * n[i] for i in range(3)) < 0:
            corners = corners[::-1]
        for p in corners:
            lines.append("v %g %g %g" % p)
        lines.append("vn %g %g %g" % n)
        nn += 1
        lines.append("f " + " ".join("%d//%d" % (nv + k + 1, nn) for k in range(4)))
        nv += 4
    verts, faces = icosphere(3)
    centre, radius = (0.0, 0.0, -0.35), 0.45
    lines.append("o glass")
    lines.append("usemtl glass")
    for v in verts:
        lines.append("v %.7f %.7f %.7f" % tuple(centre[i] + radius * v[i] for i in range(3)))
    for a, b, c in faces:
        pa, pb, pc = verts[a], verts[b], verts[c]
        e1 = [pb[i] - pa[i] for i in range(3)]
        e2 = [pc[i] - pa[i] for i in range(3)]
        n = (e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
             e1[0] * e2[1] - e1[1] * e2[0])
        ln = math.sqrt(sum(x * x for x in n))
        lines.append("vn %.7f %.7f %.7f" % tuple(x / ln for x in n))
        nn += 1
        lines.append("f %d//%d %d//%d %d//%d" % (nv + a + 1, nn, nv + b + 1, nn, nv + c + 1, nn))
    os.makedirs(os.path.join(HERE, "mesh"), exist_ok=True)
    with open(os.path.join(HERE, "mesh", "furnace_glass.obj"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(HERE, "mesh", "furnace_glass.mtl"), "w") as f:
        f.write("# Glass furnace: black walls emitting Ke = 1 around a smooth glass sphere.\n"
                "# Expected radiance everywhere: 1 (the sphere is invisible).\n\n"
                "newmtl walls\nKd 0 0 0\nKs 0 0 0\nKe 1 1 1\nillum 7\n\n"
                "newmtl glass\nKd 0 0 0\nKs 0 0 0\nNi 1.5\nTf 1 1 1\nillum 6\n")


if __name__ == "__main__":
    main()
