#!/bin/sh
# Installs Mitsuba 3 (scripts/mitsuba/env.sh), builds tessera, and renders the references of
# make.py into tests/data/references/ (Mitsuba's llvm_ad_rgb variant where Debian's LLVM 19
# is at hand, else scalar_rgb: slower, the same images in distribution). Arguments go to
# make.py.
set -eu
. "$(dirname "$0")/../mitsuba/env.sh"
exec "$PY" "$ROOT/scripts/references/make.py" "$@"
