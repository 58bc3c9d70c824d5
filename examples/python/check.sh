#!/usr/bin/env bash
# The Python client against a live fuser: two `v2x-agent` processes replay generated files to a
# `v2x-fuser node` that records what it publishes; the subscriber (eclipse-zenoh, in a venv this
# script creates) decodes the fused frames with v2x_frame.py, and compare.py checks they are the
# boxes (and provenance) the fuser recorded; doc_examples.py first decodes the specification's
# examples. Run from the repository root after `cargo build --release`.
set -euo pipefail
cd "$(dirname "$0")/../.."
BIN=${BIN:-target/release}
VENV=${VENV:-target/pyvenv}
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import zenoh" 2>/dev/null; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install -q "eclipse-zenoh==1.10.*"
fi
"$VENV/bin/python" examples/python/doc_examples.py docs/wire-format.md
tmp=$(mktemp -d)
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    rm -rf "$tmp"
}
trap cleanup EXIT
town=(--seconds 3 --hz 10 --range 60)
"$BIN/v2x-sim" gen "${town[@]}" --noise mild+large --out "$tmp" 2>/dev/null
port=$("$VENV/bin/python" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
ep="tcp/127.0.0.1:$port"
"$BIN/v2x-fuser" node --ns pyclient --no-multicast-scouting -l "$ep" --duration-s 12 \
    --record "$tmp/fused.json" > "$tmp/stats.json" 2> "$tmp/fuser.log" &
fuser=$!; pids+=("$fuser")
"$VENV/bin/python" examples/python/subscriber.py --ns pyclient --connect "$ep" --duration 11 \
    --out "$tmp/frames.jsonl" 2> "$tmp/sub.log" &
sub=$!; pids+=("$sub")
for _ in $(seq 100); do grep -q subscribed "$tmp/sub.log" 2>/dev/null && break; sleep 0.1; done
grep -q subscribed "$tmp/sub.log" || { cat "$tmp/sub.log"; echo "python client: the subscriber did not start" >&2; exit 1; }
start=$("$VENV/bin/python" -c 'import time; print(f"{time.time() + 2:.3f}")')
for a in "veh vehicle agent1.json" "rsu infrastructure agent2.json"; do
    set -- $a
    "$BIN/v2x-agent" "$tmp/$3" --name "$1" --kind "$2" --ns pyclient --replay "speed=2,start_at=$start" \
        --no-multicast-scouting -e "$ep" 2> "$tmp/$1.log" &
    pids+=($!)
done
wait "$fuser" || { cat "$tmp/fuser.log"; exit 1; }
wait "$sub" || { cat "$tmp/sub.log"; exit 1; }
"$VENV/bin/python" examples/python/compare.py "$tmp/frames.jsonl" "$tmp/fused.json"
