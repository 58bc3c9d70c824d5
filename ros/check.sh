#!/usr/bin/env bash
# ROS 2 around the project, with independent code on the ROS side (rosbags for messages and
# type hashes, eclipse-zenoh for the transport, in a venv under target/): a fuser publishing
# its fused boxes as DetectedObjects on a ROS 2 topic, and two agents fed by ROS 2 detectors (a
# vision_msgs Detection3DArray on rmw_zenoh's key, an Autoware DetectedObjects on the bridge's).
# Run from the repository root after `cargo build --release`.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-target/release}
VENV=${VENV:-target/pyvenv}
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
"$VENV/bin/python" -c "import zenoh, rosbags, numpy" 2>/dev/null ||
    "$VENV/bin/pip" install -q --disable-pip-version-check "eclipse-zenoh==1.10.*" "rosbags==0.11.*" numpy
"$VENV/bin/python" ros/check/ros_e2e.py hashes
tmp=$(mktemp -d)
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    rm -rf "$tmp"
}
trap cleanup EXIT
port=$("$VENV/bin/python" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
ep="tcp/127.0.0.1:$port"
z=(--no-multicast-scouting)
"$BIN/v2x-fuser" node --ns rosdemo "${z[@]}" -l "$ep" --duration-s 30 --ros-out /v2x/objects \
    --track --ros-out-tracks /v2x/tracks \
    > "$tmp/stats.json" 2> "$tmp/fuser.log" &
pids+=($!)
# The vehicle's lidar at (100, 50) in the map heading +y, as a static transform file.
echo '{"translation": [100, 50, 0], "rotation": [0, 0, 0.7071067811865476, 0.7071067811865476]}' > "$tmp/tf.json"
"$BIN/v2x-agent" --ros-topic /veh/detections --ros-type vision --tf "$tmp/tf.json" \
    --name veh --ns rosdemo "${z[@]}" -e "$ep" 2> "$tmp/veh.log" &
pids+=($!)
"$BIN/v2x-agent" --ros-topic /rsu/objects --ros-type autoware --ros-layout bridge \
    --name rsu --kind infrastructure --ns rosdemo "${z[@]}" -e "$ep" 2> "$tmp/rsu.log" &
pids+=($!)
if ! "$VENV/bin/python" ros/check/ros_e2e.py run "$ep"; then
    for f in "$tmp"/*.log; do echo "== $f" >&2; tail -n 5 "$f" >&2; done
    exit 1
fi
