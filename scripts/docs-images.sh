#!/usr/bin/env bash
# The book's pictures of the methods at about equal time (docs/src/guide/methods.md): the
# indirectly lit room rendered by each method at 256×192 on two threads, its PNG preview kept
# in docs/src/images/methods/. The sample counts were chosen so that each render takes about
# four seconds of wall time on the build machine; the script prints each one's time, and the
# page says what they were. Run with nothing else running.
# Usage: scripts/docs-images.sh [TESSERA] (default target/release/tessera)
set -euo pipefail
cd "$(dirname "$0")/.."
TESSERA="${1:-target/release/tessera}"
OUT=docs/src/images/methods
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
mkdir -p "$OUT"
# method and its --spp (iterations for sppm and vcm)
for run in path:80 bdpt:23 photon:80 sppm:14 vcm:16; do
  method="${run%%:*}"
  spp="${run#*:}"
  start=$(date +%s.%N)
  "$TESSERA" render scenes/indirect-room/scene.json --size 256x192 --threads 2 \
    --integrator "$method" --spp "$spp" -o "$TMP/$method.exr" -q >/dev/null
  end=$(date +%s.%N)
  cp "$TMP/$method.png" "$OUT/$method.png"
  printf '%-7s %5s spp  %6.2f s\n' "$method" "$spp" "$(echo "$end - $start" | bc)"
done
