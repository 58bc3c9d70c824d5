#!/usr/bin/env bash
# The project's CPMs against an independent ASN.1 implementation: asn1tools (in a venv under
# target/), compiled from the same official modules in cpm/asn1, decodes the CPMs that
# `v2x-sim wire` writes for a generated town, field by field, and re-encodes them byte for byte;
# then `v2x-sim wire --read` reads a CPM that asn1tools encoded. Run from the repository root
# after `cargo build --release`.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-target/release}
VENV=${VENV:-target/pyvenv}
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
"$VENV/bin/python" -c "import asn1tools" 2>/dev/null ||
    "$VENV/bin/pip" install -q --disable-pip-version-check "asn1tools==0.169.*"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
origin=48.1374,11.5755
offset=1700000000000000  # the town's clock starts at 0; a CPM's at 2004
"$BIN/v2x-sim" gen --seconds 3 --hz 10 --noise mild+large --out "$tmp/results" 2>/dev/null
"$BIN/v2x-sim" wire "$tmp"/results/*.json --rsu agent2 --map-origin "$origin" \
    --time-offset-us "$offset" --out "$tmp/cpm"
"$VENV/bin/python" cpm/check/cross_check.py ours "$tmp/results" "$tmp/cpm" "$origin" "$offset"
"$VENV/bin/python" cpm/check/cross_check.py theirs "$BIN/v2x-sim" "$origin" "$tmp"
