#!/bin/sh
# Speed against error on six scenes with every method and `auto` (issue 25's "must show"):
# `tessera bench` per scene into bench-report/auto/SCENE/, then a table of the wall seconds to
# relMSE 1e-2 with auto's ratio to the best fixed method (scripts/bench-auto-table.py).
# Usage: scripts/bench-auto.sh [--hd] [TESSERA] (default target/release/tessera). Long (about
# an hour with --hd on 2 cores); run it with nothing else running.
# --hd: also the Cornell box at 1920×1080, the size users work at, against Mitsuba 3's
# reference (not committed: scripts/references/run.sh renders it first when it is missing).
set -eu
HD=0
if [ "${1:-}" = --hd ]; then HD=1; shift; fi
T=${1:-target/release/tessera}
OUT=bench-report/auto
ALL=auto,path,bdpt,vcm,photon,sppm,pssmlt,mlt
SPP=1,2,3,4,6,8,12,16,24,32,48,64,96,128,192,256
# Rows whose renders take about a second or less, and the material spheres (whose sun's
# caustics make each seed's error jump), get three seeds: a time is then the bench's lower
# median over them, where one wall-clock reading of a render that short varies by a tenth
# from run to run (and its error by which checkpoint one seed's noise reaches the goal at).
SEEDS=3
run() { # scene reference integrators budgets [report suffix] [seeds]
    echo "== $1 $2"
    "$T" bench "scenes/$1/scene.json" --reference "$2" --integrators "$3" --budgets "$4" \
        --seeds "${6:-1}" --until 0.01 -o "$OUT/$1${5:+-$5}"
}
run cornell-box scenes/cornell-box/reference.exr "$ALL" 1,2,3,4,6,8,12,16,24,32,48 "" $SEEDS
# The same box at 512×512 (Mitsuba's reference, scripts/references/make.py cornell-box/reference-512):
# renders of seconds, where the pilot's fixed cost weighs less.
run cornell-box scenes/cornell-box/reference-512.exr "$ALL" 1,2,3,4,6,8,12,16,24,32,48 512
if [ "$HD" = 1 ]; then
    HD_REF=scenes/cornell-box/reference-1920x1080.exr
    [ -f "$HD_REF" ] || scripts/references/run.sh cornell-box/reference-1920x1080 --out scenes --tessera "$T"
    run cornell-box "$HD_REF" "$ALL" 1,2,3,4,6,8,12,16,24,32,48 1920x1080
else
    echo "== cornell-box 1920x1080: not run (scripts/bench-auto.sh --hd)"
    rm -rf "$OUT/cornell-box-1920x1080" # an earlier run's row is not this run's
fi
run cornell-glass scenes/cornell-glass/reference-128.exr "$ALL" "$SPP" "" $SEEDS
run indirect-room scenes/indirect-room/reference-128.exr "$ALL" "$SPP" "" $SEEDS
# The glass, the indirect room and the material spheres again at sizes where a render takes
# seconds and the pilot's film has thousands of pixels (at most 4096): the glass against
# Mitsuba's reference under the scene's filter (scripts/references/make.py
# cornell-glass/reference-512), the room against BDPT's and the spheres (the scene's own film)
# against VCM's (docs/src/benchmarks/auto.md says how each was made).
run cornell-glass scenes/cornell-glass/reference-512.exr "$ALL" "$SPP" 512
run indirect-room scenes/indirect-room/reference-512x384.exr "$ALL" "$SPP" 512x384
run pool scenes/pool/reference-96.exr "$ALL" "$SPP" "" $SEEDS
run material-spheres scenes/material-spheres/reference-128.exr "$ALL" "$SPP,384,512,768,1024" "" $SEEDS
run material-spheres scenes/material-spheres/reference-480x240.exr "$ALL" "$SPP,384,512,768,1024" 480x240
run translucent scenes/translucent/reference-96.exr \
    auto,path:dipole,path:hierarchical,path:random-walk "$SPP,384,512,768,1024,1536,2048,3072,4096"
python3 scripts/bench-auto-table.py "$OUT"
