#!/usr/bin/env bash
# The Python package: builds its wheel, installs it into a venv under target/ (with its `net` and
# `test` extras: numpy, pytest and eclipse-zenoh) and runs its tests, the live example against a
# `v2x-fuser node` among them. Run after `cargo build --release`: the tests compare the package
# with the binaries in target/release (V2X_BIN to use others). The package is built unoptimised
# (Cargo profile `quick`, a third of a release build's time): the results are the same to the
# bit, and its speed is measured by python/benchmarks/ on a release build.
#
# `check.sh build` only builds the wheel (in a venv of its own, so it may run beside other
# scripts using target/pyvenv), `check.sh test` only installs and tests the wheel built last;
# without an argument, both.
set -euo pipefail
cd "$(dirname "$0")/.."
phase=${1:-all}
VENV=${VENV:-target/pyvenv}
WHEELS=target/pywheels
if [ "$phase" != test ]; then
    BUILD_VENV=target/pybuild
    [ -x "$BUILD_VENV/bin/python" ] || python3 -m venv "$BUILD_VENV"
    rm -rf "$WHEELS"
    MATURIN_PEP517_ARGS="--profile quick" "$BUILD_VENV/bin/pip" wheel -q \
        --disable-pip-version-check --no-deps -w "$WHEELS" ./python
fi
if [ "$phase" != build ]; then
    [ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
    wheel=$(ls "$WHEELS"/v2x_fusion-*.whl)
    pip=("$VENV/bin/pip" install -q --disable-pip-version-check)
    "${pip[@]}" --force-reinstall --no-deps "$wheel"
    "${pip[@]}" "$wheel[net,test]"
    "$VENV/bin/pytest" -q -p no:cacheprovider python/tests
fi
