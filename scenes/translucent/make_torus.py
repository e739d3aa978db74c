"""Writes torus.obj: a torus around the z axis (it stands upright facing the camera), major
radius R, minor radius r (cm), with per-vertex normals and outward-facing (counter-clockwise)
triangles. Run: python3 make_torus.py"""
import math

R, r, nu, nv = 2.2, 0.8, 64, 32
verts, norms, faces = [], [], []
for i in range(nu):
    u = 2 * math.pi * i / nu
    for j in range(nv):
        v = 2 * math.pi * j / nv
        n = (math.cos(v) * math.cos(u), math.cos(v) * math.sin(u), math.sin(v))
        verts.append(((R + r * math.cos(v)) * math.cos(u), (R + r * math.cos(v)) * math.sin(u), r * math.sin(v)))
        norms.append(n)
idx = lambda i, j: (i % nu) * nv + (j % nv) + 1
for i in range(nu):
    for j in range(nv):
        a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
        faces += [(a, b, c), (a, c, d)]
# Orient outward: flip all if the first face's normal points inward.
def sub(p, q): return [p[k] - q[k] for k in range(3)]
def cross(p, q): return [p[1]*q[2]-p[2]*q[1], p[2]*q[0]-p[0]*q[2], p[0]*q[1]-p[1]*q[0]]
a, b, c = (verts[k - 1] for k in faces[0])
if sum(x * y for x, y in zip(cross(sub(b, a), sub(c, a)), norms[faces[0][0] - 1])) < 0:
    faces = [(a, c, b) for a, b, c in faces]
with open("torus.obj", "w") as f:
    f.write("# torus R=%g r=%g cm, %d triangles (make_torus.py)\n" % (R, r, len(faces)))
    for p in verts: f.write("v %.6f %.6f %.6f\n" % p)
    for n in norms: f.write("vn %.6f %.6f %.6f\n" % n)
    for t in faces: f.write("f %d//%d %d//%d %d//%d\n" % (t[0], t[0], t[1], t[1], t[2], t[2]))
