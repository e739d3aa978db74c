# Sourced by the scripts that run Mitsuba 3 (scripts/references, scripts/peers): a virtual
# environment with Mitsuba 3 (PyPI), NumPy and OpenEXR in $VENV, and Debian's LLVM 19 for the
# vectorised llvm_ad_rgb variant where apt-get is at hand (DRJIT_LIBLLVM_PATH; without it only
# scalar_rgb runs). Sets ROOT, VENV, PY and builds the release tessera.
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
PY=$VENV/bin/python
cargo build --release -q -p tessera --manifest-path "$ROOT/Cargo.toml"
