#!/usr/bin/env python3
"""The table of scripts/bench-auto.sh: per scene, each method's wall seconds to relMSE 1e-2
(from `tessera bench`'s report.json), auto's choice and its ratio to the best fixed method, and
each method's estimated against measured relMSE at its first checkpoint at or below 3e-2
that has an estimate.
With several seeds (`--seeds`), a time is the bench's (the lower median over the seeds), the
pilot's the median, and the estimated-against-measured table shows the first seed's renders.
Usage: bench-auto-table.py bench-report/auto [AUTO_DIR]: with AUTO_DIR (a later run of
`--integrators auto` alone, one folder per scene), auto's figures come from there."""
import json
import pathlib
import sys

root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else "bench-report/auto")
auto_root = pathlib.Path(sys.argv[2]) if len(sys.argv) > 2 else None
LEVEL = 1e-2
rows = []
for report in sorted(root.glob("*/report.json")):
    r = json.loads(report.read_text())
    scene = report.parent.name
    if auto_root and (auto_root / scene / "report.json").exists():
        a = json.loads((auto_root / scene / "report.json").read_text())
        keep = lambda xs: [x for x in xs if x["integrator"] != "auto"]
        r["runs"] = keep(r["runs"]) + [x for x in a["runs"] if x["integrator"] == "auto"]
        r["time_to_error"] = keep(r["time_to_error"]) + [
            x for x in a["time_to_error"] if x["integrator"] == "auto"]
        r["auto"] = a["auto"]
    times = {t["integrator"]: t["wall_s"] for t in r["time_to_error"] if t["rel_mse"] == LEVEL}
    fixed = {k: v for k, v in times.items() if k != "auto" and v is not None}
    best = min(fixed, key=fixed.get) if fixed else None
    auto = times.get("auto")
    # With several seeds, each seed's choice (in seed order where they differ) and the
    # median pilot.
    choices = [a["chosen"] for a in r.get("auto", [])]
    chosen = (choices[0] if len(set(choices)) == 1 else ", ".join(choices)) if choices else "–"
    median = lambda xs: sorted(xs)[(len(xs) - 1) // 2] if xs else None
    pilot = median([a["pilot_s"] for a in r.get("auto", [])])
    # Reports before the pilot said what the render took over from it have no handed_s.
    handed = median([a["handed_s"] for a in r.get("auto", []) if "handed_s" in a])
    ratio = auto / fixed[best] if auto and best else None
    seeds = len(r.get("seeds", []))
    label = f"{scene} {r['width']}×{r['height']}" + (f", {seeds} seeds" if seeds > 1 else "")
    rows.append((label, times, best, chosen, (pilot, handed), ratio, r))

methods = []
for row in rows:
    for k in row[1]:
        if k != "auto" and k not in methods:
            methods.append(k)
print(f"Wall seconds to relMSE {LEVEL:g} (– not reached within the budgets):\n")
print("| scene | " + " | ".join(methods) + " | auto (choice, pilot s, of it handed on) | auto / best |")
print("|---|" + "---:|" * len(methods) + "---|---:|")
for label, times, best, chosen, pilot, ratio, _ in rows:
    cells = []
    for m in methods:
        t = times.get(m)
        cell = "" if m not in times else ("–" if t is None else f"{t:.2f}")
        cells.append(f"**{cell}**" if m == best else cell)
    a = times.get("auto")
    pilot, handed = pilot
    given = f", {handed:.2f}" if handed is not None else ""
    auto_cell = ("–" if a is None else f"{a:.2f}") + f" ({chosen}, {pilot:.2f}{given})" if pilot is not None else "–"
    print(f"| {label} | " + " | ".join(cells) + f" | {auto_cell} | " + (f"{ratio:.2f}" if ratio else "–") + " |")

print("\nEstimated (from the render's own variance) against measured relMSE, at the first checkpoint at or below 3e-2 that has an estimate (one sample has none):\n")
print("| scene | " + " | ".join(methods) + " |")
print("|---|" + "---:|" * len(methods))
for label, *_ , r in rows:
    cells = []
    first = r["seeds"][0]
    for m in methods:
        runs = [x for x in r["runs"] if x["integrator"] == m and x["seed"] == first]
        low = [x for x in runs if x["rel_mse"] <= 3e-2]
        # A render of one sample has no estimate: the first checkpoint that has one.
        hit = next((x for x in low if x["estimated_rel_mse"] is not None),
                   low[0] if low else (runs[-1] if runs else None))
        if hit is None:
            cells.append("")
        elif hit["estimated_rel_mse"] is None:
            cells.append(f"– / {hit['rel_mse']:.1e}")
        else:
            cells.append(f"{hit['estimated_rel_mse']:.1e} / {hit['rel_mse']:.1e} ({hit['estimated_rel_mse'] / hit['rel_mse']:.2f})")
    print(f"| {label} | " + " | ".join(cells) + " |")
