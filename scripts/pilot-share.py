#!/usr/bin/env python3
"""What `auto`'s pilot costs beside the render it chooses (issue 25: "pilot cost ≤ 10 % of
the render"): `tessera render --integrator auto --target-error 0.01` on the bench's scenes, at
the bench's sizes and at 1920×1080, printing per render the pilot's wall seconds, the part of
them the render takes over (the chosen method's passes or SPPM's photons, handed on), the
render after the pilot, and two shares:

- pilot / render: the pilot's seconds over the render's after it;
- overhead: what the pilot spent that the render does not reuse, over the chosen method's
  whole render (the work handed on and the render after it).

Usage: scripts/pilot-share.py [TESSERA] [--small | --hd] (default target/release/tessera,
both sizes). A benchmark: it prints figures and asserts nothing; run it with nothing else
running."""
import re
import subprocess
import sys
import tempfile

args = [a for a in sys.argv[1:] if not a.startswith("--")]
flags = {a for a in sys.argv[1:] if a.startswith("--")}
tessera = args[0] if args else "target/release/tessera"
SMALL = [
    ("cornell-box", "256x256"),
    ("cornell-box", "512x512"),
    ("cornell-glass", "128x128"),
    ("indirect-room", "128x96"),
    ("pool", "96x72"),
    ("material-spheres", "128x64"),
    ("translucent", "96x72"),
]
# The translucent torus is left out at 1920×1080: its render takes over a minute at 96×72, and
# 1920×1080 has 300 times its pixels.
HD = [(s, "1920x1080") for s in
      ["cornell-box", "cornell-glass", "indirect-room", "pool", "material-spheres"]]
runs = ([] if "--hd" in flags else SMALL) + ([] if "--small" in flags else HD)

print("| scene | size | chosen | pilot s | handed on s | render s | pilot / render | overhead |")
print("|---|---|---|---:|---:|---:|---:|---:|")
with tempfile.TemporaryDirectory() as out:
    for scene, size in runs:
        cmd = [tessera, "render", f"scenes/{scene}/scene.json", "--size", size,
               "--integrator", "auto", "--target-error", "0.01", "-o", f"{out}/{scene}.exr"]
        done = subprocess.run(cmd, capture_output=True, text=True, check=True)
        text = done.stdout + done.stderr
        chosen = re.search(r"auto: chose (\S+)", text)
        render = re.search(r"render ([0-9.]+) s wall", text)
        pilot = re.search(r"auto's pilot ([0-9.]+) s(?:, ([0-9.]+) s of it)?", text)
        if not (chosen and render and pilot):
            sys.exit(f"{scene} {size}: no auto summary in the output of {' '.join(cmd)}:\n{text}")
        p, r = float(pilot.group(1)), float(render.group(1))
        h = float(pilot.group(2) or 0.0)
        print(f"| {scene} | {size.replace('x', '×')} | {chosen.group(1)} | {p:.2f} | {h:.2f} | "
              f"{r:.2f} | {100 * p / r:.0f} % | {100 * (p - h) / (r + h):.0f} % |", flush=True)
