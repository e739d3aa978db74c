#!/usr/bin/env python3
"""Independent references for the test suite: the repository's test scenes rendered by
Mitsuba 3, written to tests/data/references/<scene>.exr with each pixel's variance.

Each scene is exported by `tessera export` (the scene as Tessera resolved it: triangles, sphere
lights, radiance with the exposure folded in) and rendered by Mitsuba's own path tracer
(`path`, or `volpathmis` through the dielectric boundary of a translucent object) in
`batches` independent renders of `spp` samples with seeds 0, 1, …; the reference is their
mean and its variance the batches' sample variance over `batches` (the variance of the mean).
The film is box-filtered: a pixel is the integral of radiance over its square, which the
tests render the same way; a bench reference may name the scene's own filter instead.

    scripts/references/run.sh            # installs Mitsuba 3 and renders every test scene
    scripts/references/run.sh veach-mis  # one scene
    scripts/references/run.sh cornell-box/reference-512 --out scenes  # the bench's 512² box
    scripts/references/run.sh cornell-box/reference-1920x1080 --out scenes  # its HD box

Prints, per scene, Mitsuba's time and the reference's own relMSE (mean variance over
(r² + 0.01)). The header of each EXR names the renderer, variant, integrator, spp and
batches.
"""
import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))

# An optional sixth entry: render under the scene's own film filter, not a box.
SCENE_FILTER = "scene filter"


def scene_rfilter(scene_file):
    """Mitsuba's rfilter for the film filter of `scene_file` (Tessera's defaults where unset)."""
    import json

    with open(os.path.join(ROOT, scene_file)) as f:
        desc = json.load(f).get("film", {}).get("filter", {"type": "box"})
    kind = desc.get("type", "box")
    if kind == "box":
        return '<rfilter type="box"/>'
    if kind == "gaussian":
        return f'<rfilter type="gaussian"><float name="stddev" value="{desc.get("sigma", 0.5)}"/></rfilter>'
    sys.exit(f"{scene_file}: no Mitsuba rfilter for its {kind} filter")


# name: (scene file, size, integrator, spp per batch, batches). Tessera's bounces are capped
# at 64 in the tests (Mitsuba's max_depth counts segments: 65). A random walk inside marble
# takes thousands of medium events, which Mitsuba's volumetric path tracers count as depth
# (hence no cap) and play Russian roulette on: its survival is capped at 0.95 per event, so
# a walk of a thousand events survives with 0.95^1000 — unbiased, but in practice every long
# walk dies and the marble comes out several times too dark. Marble absorbs almost nothing:
# the walks end by leaving, and roulette is off (rr_depth beyond any walk).
SCENES = {
    # The bench's references (scripts/bench-auto.sh) are named by their place under `scenes/`
    # (`--out scenes`) and made only when named. The Cornell box at a size where a render
    # takes seconds.
    "cornell-box/reference-512": ("scenes/cornell-box/scene.json", (512, 512), {"type": "path", "max_depth": 65}, 1024, 4),
    # The same box at the size users work at (`scripts/bench-auto.sh --hd`); not committed
    # (tens of MB): the bench script renders it when it is missing.
    "cornell-box/reference-1920x1080": ("scenes/cornell-box/scene.json", (1920, 1080), {"type": "path", "max_depth": 65}, 64, 16),
    # The Cornell glass likewise (its caustics make the path tracer's samples noisy, hence
    # many), under the scene's own filter, which the bench renders: a Gaussian of σ 0.5 px,
    # which Mitsuba cuts at 4σ and Tessera at 3σ less its value there (weights that differ by
    # about 1 % of the peak).
    "cornell-glass/reference-512": ("scenes/cornell-glass/scene.json", (512, 512), {"type": "path", "max_depth": 65}, 256, 16, SCENE_FILTER),
    "cornell-glass": ("scenes/cornell-glass/scene.json", (64, 64), {"type": "path", "max_depth": 65}, 16384, 16),
    "indirect-room": ("scenes/indirect-room/scene.json", (64, 48), {"type": "path", "max_depth": 65}, 16384, 16),
    "veach-mis": ("scenes/veach-mis/scene.json", (96, 64), {"type": "path", "max_depth": 65}, 8192, 16),
    "translucent": ("scenes/translucent/scene.json", (64, 48), {"type": "volpathmis", "max_depth": -1, "rr_depth": 1000000}, 1024, 16),
}


def write_exr(path, mean, var, header):
    import OpenEXR

    channels = {}
    for c, name in enumerate("RGB"):
        channels[name] = np.ascontiguousarray(mean[..., c], dtype=np.float32)
        channels["variance." + name] = np.ascontiguousarray(var[..., c], dtype=np.float32)
    header = dict(header, compression=OpenEXR.ZIP_COMPRESSION, type=OpenEXR.scanlineimage)
    with OpenEXR.File(header, channels) as f:
        f.write(path)


def render(name, tessera, out_dir, variant):
    import mitsuba as mi

    scene_file, (w, h), integrator, spp, batches, *own = SCENES[name]
    rfilter = [scene_rfilter(scene_file)] if own else []
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [tessera, "export", os.path.join(ROOT, scene_file), "--size", f"{w}x{h}", "-o", tmp],
            check=True,
        )
        xml = os.path.join(tmp, "scene.xml")
        if rfilter:
            with open(xml) as f:
                text = f.read()
            box = '<rfilter type="box"/>'
            if box not in text:
                sys.exit(f"{name}: the exported scene has no {box} to replace")
            with open(xml, "w") as f:
                f.write(text.replace(box, rfilter[0]))
        scene = mi.load_file(xml)
    integ = mi.load_dict(integrator)
    start = time.time()
    total = np.zeros((h, w, 3))
    total2 = np.zeros((h, w, 3))
    for seed in range(batches):
        img = np.array(mi.render(scene, integrator=integ, spp=spp, seed=seed), dtype=np.float64)[..., :3]
        total += img
        total2 += img * img
        print(f"  {name}: batch {seed + 1}/{batches} ({time.time() - start:.0f} s)", flush=True)
    mean = total / batches
    # The batches' sample variance, over `batches`: the variance of their mean.
    var = np.maximum(total2 / batches - mean * mean, 0.0) / (batches - 1)
    seconds = time.time() - start
    rel = float(np.mean(var / (mean * mean + 0.01)))
    header = {
        "renderer": f"Mitsuba {mi.__version__} ({variant})",
        "integrator": ", ".join(f"{k} {v}" for k, v in integrator.items()),
        "spp": f"{spp} x {batches} batches (seeds 0..{batches - 1}), independent sampler, "
        + (rfilter[0] if rfilter else "box filter"),
        "variance": "variance of the mean: the batches' sample variance / batches",
        "scene": scene_file,
    }
    path = os.path.join(out_dir, f"{name}.exr")
    os.makedirs(os.path.dirname(path), exist_ok=True)
    write_exr(path, mean, var, header)
    print(f"{name}: {w}x{h}, {spp * batches} spp in {seconds:.0f} s; reference relMSE {rel:.2e}; wrote {path}")


def main():
    p = argparse.ArgumentParser()
    # By default the test suite's references; the bench's (SCENE/NAME) only when named.
    p.add_argument("scenes", nargs="*", default=[n for n in SCENES if "/" not in n])
    p.add_argument("--variant", default=None, help="llvm_ad_rgb where libLLVM is found, else scalar_rgb")
    p.add_argument("--tessera", default=os.path.join(ROOT, "target", "release", "tessera"))
    p.add_argument("--out", default=os.path.join(ROOT, "tests", "data", "references"))
    args = p.parse_args()
    import mitsuba as mi

    variant = args.variant or ("llvm_ad_rgb" if os.environ.get("DRJIT_LIBLLVM_PATH") else "scalar_rgb")
    mi.set_variant(variant)
    os.makedirs(args.out, exist_ok=True)
    for name in args.scenes:
        if name not in SCENES:
            sys.exit(f"unknown scene {name}: expected one of {', '.join(SCENES)}")
        render(name, args.tessera, args.out, variant)


if __name__ == "__main__":
    main()
