#!/usr/bin/env bash
# The Python package: builds and installs it into a venv under target/ (`pip install
# './python[net,test]'`: numpy, pytest and eclipse-zenoh beside it) and runs its tests, the live
# example against a `v2x-fuser node` among them. Run after `cargo build --release`: the tests
# compare the package with the binaries in target/release (V2X_BIN to use others). The package
# is built unoptimised (Cargo profile `quick`, a third of a release build's time): the results
# are the same to the bit, and its speed is measured by python/benchmarks/ on a release build.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=${VENV:-target/pyvenv}
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
MATURIN_PEP517_ARGS="--profile quick" \
    "$VENV/bin/pip" install -q --disable-pip-version-check "./python[net,test]"
"$VENV/bin/pytest" -q -p no:cacheprovider python/tests
