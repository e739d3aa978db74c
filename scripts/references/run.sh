#!/bin/sh
# Installs Mitsuba 3 (PyPI) with NumPy and OpenEXR in a virtual environment, Debian's LLVM 19
# for Mitsuba's vectorised llvm_ad_rgb variant where apt-get is at hand (else the scalar_rgb
# variant, slower and the same images in distribution), builds tessera, and renders the
# references of make.py into tests/data/references/. Arguments go to make.py.
set -eu
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
VENV=${VENV:-$ROOT/target/references-venv}
LLVM=/usr/lib/x86_64-linux-gnu/libLLVM-19.so
if [ ! -e "$LLVM" ] && command -v apt-get >/dev/null && [ "$(id -u)" = 0 ]; then
    apt-get install -y -q libllvm19 >/dev/null
fi
if [ -e "$LLVM" ]; then
    export DRJIT_LIBLLVM_PATH=$LLVM
fi
if [ ! -x "$VENV/bin/python" ]; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install -q mitsuba==3.9.1 numpy OpenEXR
fi
cargo build --release -q -p tessera --manifest-path "$ROOT/Cargo.toml"
exec "$VENV/bin/python" "$ROOT/scripts/references/make.py" "$@"
