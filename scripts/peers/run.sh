#!/bin/sh
# Tessera's path tracer against Mitsuba 3's vectorised CPU path tracer (llvm_ad_rgb), side by
# side in one run: installs Mitsuba 3 (scripts/mitsuba/env.sh), builds tessera, and runs
# side_by_side.py (arguments go to it). A benchmark: it prints figures and asserts nothing.
set -eu
. "$(dirname "$0")/../mitsuba/env.sh"
exec "$PY" "$ROOT/scripts/peers/side_by_side.py" "$@"
