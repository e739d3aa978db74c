#!/usr/bin/env python3
"""Writes scene.json: Veach's multiple-importance-sampling test (thesis, fig. 9.2) — four
rough metal plates, smoothest at the back, each turned to reflect a row of four sphere lights
of radii a factor three apart and equal power toward the camera — over a diffuse floor before
a diffuse wall. Light sampling alone is noisy on the smooth plates with the large lights, BSDF
sampling alone on the rough plates with the small ones. The plates' normals bisect the
directions from each plate's centre to the camera and to the lights' row."""
import json, math

CAMERA = (0.0, 2.0, 15.0)
LIGHTS_AT = (0.0, 3.2, -2.0)
RADII = [0.03, 0.09, 0.27, 0.81]
POWER = 1.5  # radiance × r² of each light
PLATES = [  # centre, GGX α
    ((0.0, 0.55, 3.6), 0.2),
    ((0.0, 0.95, 2.1), 0.09),
    ((0.0, 1.35, 0.6), 0.04),
    ((0.0, 1.75, -0.9), 0.015),
]


def sub(a, b): return tuple(x - y for x, y in zip(a, b))
def add(a, b): return tuple(x + y for x, y in zip(a, b))
def mul(a, s): return tuple(x * s for x in a)
def norm(a): return mul(a, 1 / math.sqrt(sum(x * x for x in a)))
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def r(v): return [round(x, 6) for x in v]


shapes = [
    {"type": "quad", "origin": [-10, 0, -4], "edge_u": [0, 0, 24], "edge_v": [20, 0, 0], "material": "floor"},
    {"type": "quad", "origin": [-10, 0, -4], "edge_u": [20, 0, 0], "edge_v": [0, 10, 0], "material": "wall"},
]
materials = {"floor": {"type": "diffuse", "albedo": 0.4}, "wall": {"type": "diffuse", "albedo": 0.5},
             "emitter": {"type": "diffuse", "albedo": 0}}
for i, (centre, alpha) in enumerate(PLATES):
    n = norm(add(norm(sub(CAMERA, centre)), norm(sub(LIGHTS_AT, centre))))
    u = (8.0, 0.0, 0.0)
    v = mul(norm(cross(n, u)), 1.2)  # u × v points along n: the front faces the camera
    origin = sub(sub(centre, mul(u, 0.5)), mul(v, 0.5))
    name = f"metal{i}"
    materials[name] = {"type": "conductor", "metal": "aluminium", "alpha": alpha}
    shapes.append({"type": "quad", "origin": r(origin), "edge_u": r(u), "edge_v": r(v), "material": name})
for i, radius in enumerate(RADII):
    x = -3.0 + 2.0 * i
    shapes.append({"type": "sphere", "center": [x, LIGHTS_AT[1], LIGHTS_AT[2]], "radius": radius,
                   "material": "emitter", "emission": {"radiance": round(POWER / radius**2, 4)}})

scene = {
    "name": "Veach's MIS test: four rough aluminium plates reflecting four sphere lights of equal power",
    "units": "m",
    "camera": {"type": "pinhole", "position": list(CAMERA), "look_at": [0, 1.4, 0], "fov_deg": 28},
    "film": {"width": 192, "height": 128, "filter": {"type": "gaussian"}},
    "integrator": {"type": "path", "spp": 64, "max_depth": 16, "rr_depth": 5, "seed": 0},
    "materials": materials,
    "shapes": shapes,
}
with open(__file__.replace("make_scene.py", "scene.json"), "w") as f:
    json.dump(scene, f, indent=1)
    f.write("\n")
