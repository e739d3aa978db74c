#!/usr/bin/env python3
"""Renders the Cornell box of scenes/cornell-box with Mitsuba 3 (the renderer of the reference
image and of BENCHMARKS.md), to compare Tessera with it on the same machine in the same run.

    python3 -m venv /tmp/mts && /tmp/mts/bin/pip install mitsuba==3.9.1
    /tmp/mts/bin/python tools/mitsuba_cornell.py --variant scalar_rgb --spp 1024 -o mitsuba.exr

Prints wall and CPU seconds; compare the image with `tessera compare mitsuba.exr
scenes/cornell-box/reference.exr`. Settings follow the reference: path tracer, max depth 64,
Russian roulette from depth 5, independent sampler, box filter, two threads.
"""
import argparse
import os
import resource
import time

import drjit as dr
import mitsuba as mi

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "cornell-box")
ALBEDO = {
    "white": [0.885809, 0.698859, 0.666422],
    "red": [0.570068, 0.0430135, 0.0443706],
    "green": [0.105421, 0.37798, 0.076425],
}
OBJECTS = {
    "floor": "white", "ceiling": "white", "backwall": "white", "rightwall": "green",
    "leftwall": "red", "shortblock": "white", "tallblock": "white",
}


def scene_dict(spp):
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 64, "rr_depth": 5},
        "sensor": {
            "type": "perspective",
            "fov": 39.3077,
            "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=[278, 273, -800], target=[278, 273, 0], up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": 256, "height": 256, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
    }
    for name, albedo in ALBEDO.items():
        d[name] = {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": albedo}}}
    for obj, material in OBJECTS.items():
        d[obj] = {"type": "obj", "filename": os.path.join(HERE, obj + ".obj"), "bsdf": {"type": "ref", "id": material}}
    d["light"] = {
        "type": "obj",
        "filename": os.path.join(HERE, "light.obj"),
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [18.387, 13.9873, 6.75357]}},
    }
    return d


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--variant", default="scalar_rgb")
    p.add_argument("--spp", type=int, default=1024)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("-o", "--output", default="mitsuba.exr")
    a = p.parse_args()
    mi.set_variant(a.variant)
    dr.set_thread_count(a.threads)
    scene = mi.load_dict(scene_dict(a.spp))
    cpu0 = resource.getrusage(resource.RUSAGE_SELF)
    t0 = time.perf_counter()
    image = mi.render(scene, spp=a.spp)
    dr.eval(image)
    dr.sync_thread()
    wall = time.perf_counter() - t0
    cpu1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (cpu1.ru_utime - cpu0.ru_utime) + (cpu1.ru_stime - cpu0.ru_stime)
    mi.util.write_bitmap(a.output, image)
    samples = 256 * 256 * a.spp
    print(f"mitsuba {a.variant}: {a.spp} spp, {wall:.2f} s wall, {cpu:.2f} s CPU, {samples / wall / 1e6:.3f} M samples/s")


if __name__ == "__main__":
    main()
