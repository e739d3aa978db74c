#!/usr/bin/env python3
"""Tessera's path tracer against Mitsuba 3's vectorised CPU path tracer, side by side in one
run on this machine: efficiency = 1 / (relMSE x CPU seconds), both renderers against the same
converged Mitsuba reference.

Each scene is exported by `tessera export` (triangles, sphere lights, radiance with the
exposure folded in) and rendered with a box filter by both at 256x256 with 2 threads:
Mitsuba's `path` (llvm_ad_rgb, independent sampler, max_depth 65 = 64 scattering events,
Russian roulette from depth 5) and `tessera render --integrator path` at the scene's own
settings. Mitsuba renders once at 4 spp first, outside the clock, so that its JIT kernels are
compiled (and cached) before the timed renders: `--seeds` of them per renderer and budget
(3 by default; Mitsuba seeds 1..N, Tessera 0..N-1), whose mean relMSE and CPU time are
reported, since one render's relMSE at a few hundred samples is heavy-tailed where caustics
are (the glass). The reference is Mitsuba at `--reference-spp` (batches of 1024 spp, seeds
100, 101, ...), kept in target/peers/ and reused while the scene file is unchanged.

CPU seconds are the process CPU time of the render (Mitsuba: this process's, around the
render and its read-back; Tessera: the child process's, scene loading and BVH build
included). relMSE is the mean over pixels and channels of (x - r)^2 / (r^2 + 0.01), as
`tessera bench` computes it.

    scripts/peers/run.sh                          # both scenes, 256 and 1024 spp
    scripts/peers/run.sh cornell-glass --spp 256  # one scene, one budget
    scripts/peers/run.sh --spp 256 --seeds 1      # one render each, quicker
"""
import argparse
import hashlib
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
SCENES = {
    "cornell-box": "scenes/cornell-box/scene.json",
    "cornell-glass": "scenes/cornell-glass/scene.json",
}
SIZE = (256, 256)
THREADS = 2
REF_BATCH = 1024


def rel_mse(x, r):
    return float(np.mean((x - r) ** 2 / (r * r + 0.01)))


def read_rgb(path):
    import OpenEXR

    with OpenEXR.File(path) as f:
        ch = f.channels()
        for rgb in ("RGB", "RGBA"):
            if rgb in ch:
                return np.asarray(ch[rgb].pixels, dtype=np.float64)[..., :3]
        return np.stack([np.asarray(ch[c].pixels, dtype=np.float64) for c in "RGB"], axis=-1)


def children_cpu():
    u = resource.getrusage(resource.RUSAGE_CHILDREN)
    return u.ru_utime + u.ru_stime


def prepare(name, tessera, tmp):
    """The scene copied to `tmp` with a box filter, and its Mitsuba export."""
    src = os.path.join(ROOT, SCENES[name])
    folder = os.path.join(tmp, name)
    shutil.copytree(os.path.dirname(src), folder, ignore=shutil.ignore_patterns("*.exr"))
    scene_json = os.path.join(folder, "scene.json")
    with open(src) as f:
        desc = json.load(f)
    desc["film"]["filter"] = {"type": "box"}
    with open(scene_json, "w") as f:
        json.dump(desc, f, indent=1)
    w, h = SIZE
    mi_dir = os.path.join(folder, "mitsuba")
    subprocess.run([tessera, "export", scene_json, "--size", f"{w}x{h}", "-o", mi_dir], check=True,
                   stdout=subprocess.DEVNULL)
    digest = hashlib.sha256(open(src, "rb").read()).hexdigest()[:12]
    return scene_json, os.path.join(mi_dir, "scene.xml"), digest


def mitsuba_render(mi, scene, integrator, spp, seed):
    """(image, CPU s, wall s) of one Mitsuba render, read back to NumPy."""
    c0, w0 = time.process_time(), time.time()
    img = np.array(mi.render(scene, integrator=integrator, spp=spp, seed=seed), dtype=np.float64)[..., :3]
    return img, time.process_time() - c0, time.time() - w0


def reference(mi, name, scene, integrator, spp, digest):
    out = os.path.join(ROOT, "target", "peers", f"{name}-{SIZE[0]}x{SIZE[1]}-{spp}spp-{digest}.npy")
    if os.path.exists(out):
        return np.load(out)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    batches = max(1, spp // REF_BATCH)
    total = np.zeros((SIZE[1], SIZE[0], 3))
    start = time.time()
    for b in range(batches):
        img, _, _ = mitsuba_render(mi, scene, integrator, REF_BATCH, 100 + b)
        total += img
        print(f"  {name} reference: batch {b + 1}/{batches} ({time.time() - start:.0f} s)", flush=True)
    ref = total / batches
    np.save(out, ref)
    return ref


def tessera_render(tessera, scene_json, spp, seed, out):
    w, h = SIZE
    c0, w0 = children_cpu(), time.time()
    subprocess.run([tessera, "render", scene_json, "--integrator", "path", "--spp", str(spp),
                    "--seed", str(seed), "--size", f"{w}x{h}", "--threads", str(THREADS), "--quiet",
                    "-o", out], check=True, stdout=subprocess.DEVNULL)
    return read_rgb(out), children_cpu() - c0, time.time() - w0


def main():
    p = argparse.ArgumentParser()
    p.add_argument("scenes", nargs="*", default=list(SCENES))
    p.add_argument("--spp", default="256,1024", help="budgets, comma-separated")
    p.add_argument("--reference-spp", type=int, default=16384)
    p.add_argument("--tessera", default=os.path.join(ROOT, "target", "release", "tessera"))
    p.add_argument("--seeds", type=int, default=3,
                   help="renders per renderer and budget (Mitsuba seeds 1.., Tessera 0..); "
                        "relMSE and CPU s are their means")
    args = p.parse_args()
    import drjit as dr
    import mitsuba as mi

    if not os.environ.get("DRJIT_LIBLLVM_PATH"):
        sys.exit("Mitsuba's llvm_ad_rgb variant needs Debian's libllvm19 (DRJIT_LIBLLVM_PATH): run scripts/peers/run.sh")
    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(THREADS)
    integrator = mi.load_dict({"type": "path", "max_depth": 65, "rr_depth": 5})
    budgets = [int(s) for s in args.spp.split(",")]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes:
            if name not in SCENES:
                sys.exit(f"unknown scene {name}: expected one of {', '.join(SCENES)}")
            scene_json, xml, digest = prepare(name, args.tessera, tmp)
            scene = mi.load_file(xml)
            ref = reference(mi, name, scene, integrator, args.reference_spp, digest)
            mitsuba_render(mi, scene, integrator, 4, 0)  # JIT warm-up, not timed
            for spp in budgets:
                # Per seed: CPU s, wall s, relMSE (and for Tessera its mean over the reference's).
                m_runs, t_runs = [], []
                for i in range(args.seeds):
                    m_img, m_cpu, m_wall = mitsuba_render(mi, scene, integrator, spp, 1 + i)
                    t_img, t_cpu, t_wall = tessera_render(args.tessera, scene_json, spp, i, os.path.join(tmp, "t.exr"))
                    m_runs.append((m_cpu, m_wall, rel_mse(m_img, ref)))
                    t_runs.append((t_cpu, t_wall, rel_mse(t_img, ref), np.mean(t_img) / np.mean(ref)))
                m_cpu, m_wall, m_rel = np.mean(m_runs, axis=0)
                t_cpu, t_wall, t_rel, mean = np.mean(t_runs, axis=0)
                ratio = (m_rel * m_cpu) / (t_rel * t_cpu)
                rows.append((name, spp, m_cpu, m_wall, m_rel, t_cpu, t_wall, t_rel, ratio, mean))
                spread = ""
                if args.seeds > 1:
                    m_rels, t_rels = [r[2] for r in m_runs], [r[2] for r in t_runs]
                    spread = (f" (relMSE over {args.seeds} seeds: Mitsuba {min(m_rels):.3g}-{max(m_rels):.3g}, "
                              f"Tessera {min(t_rels):.3g}-{max(t_rels):.3g})")
                print(f"{name} {spp} spp: Mitsuba {m_cpu:.1f} CPU s relMSE {m_rel:.3g}; "
                      f"Tessera {t_cpu:.1f} CPU s relMSE {t_rel:.3g}; ratio {ratio:.2f}{spread}", flush=True)
    print()
    print(f"{SIZE[0]}x{SIZE[1]}, {THREADS} threads, reference Mitsuba {args.reference_spp} spp, "
          f"{args.seeds} seed(s) per renderer and budget; efficiency = 1 / (relMSE x CPU s); ratio = Tessera's / Mitsuba's")
    print()
    print("| scene | spp | Mitsuba llvm CPU s (wall) | relMSE | Tessera path CPU s (wall) | relMSE | Tessera mean / ref | ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for name, spp, m_cpu, m_wall, m_rel, t_cpu, t_wall, t_rel, ratio, mean in rows:
        print(f"| {name} | {spp} | {m_cpu:.1f} ({m_wall:.1f}) | {m_rel:.3g} | {t_cpu:.1f} ({t_wall:.1f}) | "
              f"{t_rel:.3g} | {mean:.4f} | {ratio:.2f} |")


if __name__ == "__main__":
    main()
