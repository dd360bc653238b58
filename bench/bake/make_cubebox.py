#!/usr/bin/env python3
"""A bake benchmark scene the size of TinyRender's `cubebox_subdivided` (FORMAT.md §6:
35,476 triangles; that mesh is not in the shared data): a closed-front Cornell-style room
and two boxes, every face an N x N grid of quads, all `illum 7` diffuse, a subdivided ceiling
light with `Ke 7`, and a real-time `gi` TOML with samplesByVertex 300 and the maxDepth and
roulette of `cbox_gi_high_realtime.toml`.

With N = 34: 34,880 triangles, 18,496 vertex keys (a grid vertex is shared by the quads of
its face; faces meet at edges with different normals, so their vertices stay apart).

Usage: make_cubebox.py OUT_DIR [N] [SAMPLES]"""
import os
import sys

out = sys.argv[1]
n = int(sys.argv[2]) if len(sys.argv) > 2 else 34
samples = int(sys.argv[3]) if len(sys.argv) > 3 else 300
os.makedirs(out, exist_ok=True)

verts, normals, faces = [], [], []  # faces: (material, [(v, vn) * 3])


def grid(material, origin, du, dv, normal, cells):
    """A parallelogram origin + s*du + t*dv, s, t in [0, 1], as cells x cells quads wound so
    that their geometric normal is `normal`."""
    normals.append(normal)
    vn = len(normals)
    base = len(verts)
    for j in range(cells + 1):
        for i in range(cells + 1):
            s, t = i / cells, j / cells
            verts.append(tuple(origin[k] + s * du[k] + t * dv[k] for k in range(3)))
    cross = (
        du[1] * dv[2] - du[2] * dv[1],
        du[2] * dv[0] - du[0] * dv[2],
        du[0] * dv[1] - du[1] * dv[0],
    )
    flip = sum(cross[k] * normal[k] for k in range(3)) < 0
    for j in range(cells):
        for i in range(cells):
            a = base + j * (cells + 1) + i + 1
            b, c, d = a + 1, a + cells + 2, a + cells + 1
            for tri in ((a, b, c), (a, c, d)):
                if flip:
                    tri = (tri[0], tri[2], tri[1])
                faces.append((material, [(v, vn) for v in tri]))


def box(material, x0, x1, z0, z1, h, cells):
    """The five visible faces (no bottom) of an axis-aligned box on the floor."""
    grid(material, (x0, h, z0), (x1 - x0, 0, 0), (0, 0, z1 - z0), (0, 1, 0), cells)
    grid(material, (x0, 0, z1), (x1 - x0, 0, 0), (0, h, 0), (0, 0, 1), cells)
    grid(material, (x0, 0, z0), (x1 - x0, 0, 0), (0, h, 0), (0, 0, -1), cells)
    grid(material, (x0, 0, z0), (0, 0, z1 - z0), (0, h, 0), (-1, 0, 0), cells)
    grid(material, (x1, 0, z0), (0, 0, z1 - z0), (0, h, 0), (1, 0, 0), cells)


r, top = 0.8, 1.6
grid("floor", (-r, 0, -r), (2 * r, 0, 0), (0, 0, 2 * r), (0, 1, 0), n)
grid("ceiling", (-r, top, -r), (2 * r, 0, 0), (0, 0, 2 * r), (0, -1, 0), n)
grid("backWall", (-r, 0, -r), (2 * r, 0, 0), (0, top, 0), (0, 0, 1), n)
grid("leftWall", (-r, 0, -r), (0, 0, 2 * r), (0, top, 0), (1, 0, 0), n)
grid("rightWall", (r, 0, -r), (0, 0, 2 * r), (0, top, 0), (-1, 0, 0), n)
box("tallBox", -0.5, -0.1, -0.5, -0.1, 0.95, n)
box("shortBox", 0.1, 0.5, 0.05, 0.45, 0.45, n)
grid("light", (-0.2, top - 0.005, -0.2), (0.4, 0, 0), (0, 0, 0.4), (0, -1, 0), 10)

materials = {
    "floor": (0.725, 0.71, 0.68),
    "ceiling": (0.725, 0.71, 0.68),
    "backWall": (0.725, 0.71, 0.68),
    "leftWall": (0.63, 0.065, 0.05),
    "rightWall": (0.14, 0.45, 0.091),
    "tallBox": (0.725, 0.71, 0.68),
    "shortBox": (0.725, 0.71, 0.68),
    "light": (0.78, 0.78, 0.78),
}
with open(os.path.join(out, "cubebox.mtl"), "w") as f:
    for name, kd in materials.items():
        ke = 7 if name == "light" else 0
        f.write(f"newmtl {name}\nKd {kd[0]} {kd[1]} {kd[2]}\nKs 0 0 0\nKe {ke} {ke} {ke}\nillum 7\n\n")
with open(os.path.join(out, "cubebox.obj"), "w") as f:
    f.write("mtllib cubebox.mtl\n")
    for v in verts:
        f.write("v %.6f %.6f %.6f\n" % v)
    for vn in normals:
        f.write("vn %d %d %d\n" % vn)
    current = None
    for material, tri in faces:
        if material != current:
            f.write(f"o {material}\nusemtl {material}\n")
            current = material
        f.write("f " + " ".join(f"{v}//{vn}" for v, vn in tri) + "\n")
with open(os.path.join(out, "cubebox_gi.toml"), "w") as f:
    f.write(
        f"""[input]
objfile = "cubebox.obj"

[camera]
eye = [ 0.0, 0.8, 3.8 ]
at = [ 0.0, 0.8, 0.0 ]
up = [ 0.0, 1.0, 0.0 ]
fov = 30.0

[film]
width = 800
height = 600

[renderer]
realtime = true
type = "gi"
maxDepth = 12
rrProb = 0.95
rrDepth = 5
samplesByVertex = {samples}
"""
    )
print(f"{out}/cubebox_gi.toml: {len(faces)} triangles, {len(verts)} vertices")
