#!/usr/bin/env bash
# Multi-host test: three network namespaces (vehicle, infrastructure, roadside) joined by veth
# links, each running `v2x-sim run SCENARIO --role ...` with explicit endpoints, twice: plain
# peers, then mutual TLS through a router with access control (certificates from
# `v2x-sim certs`); then a city: a second roadside host, two meshed routers, two regional fusers
# on each roadside host, each agent a client of its own roadside's router. The roadside fuser records the fused output, which is scored with `v2x-sim eval`;
# every host reports its own bytes from Zenoh's statistics; the plain run scripts a link change.
# Needs root and iproute2; run from the repository root after `cargo build --release`.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${BIN:-target/release}
if [ "$(id -u)" != 0 ] || ! command -v ip >/dev/null; then
    echo "multi-host test: SKIPPED (needs root and iproute2)"
    exit 0
fi
id=$$
V=v2xveh$id; R=v2xrsu$id; F=v2xroad$id; E=v2xeast$id
tmp=$(mktemp -d)
cleanup() {
    for n in "$V" "$R" "$F" "$E"; do ip netns del "$n" 2>/dev/null || true; done
    rm -rf "$tmp"
}
trap cleanup EXIT
for n in "$V" "$R" "$F" "$E"; do ip netns add "$n"; ip -n "$n" link set lo up; done
# A veth link from namespace $1 (interface $2, address $3) to namespace $4 ($5, $6), up.
veth() {
    ip link add "$2" type veth peer name "$5"
    ip link set "$2" netns "$1"; ip link set "$5" netns "$4"
    ip -n "$1" addr add "$3" dev "$2"; ip -n "$4" addr add "$6" dev "$5"
    ip -n "$1" link set "$2" up; ip -n "$4" link set "$5" up
}
# vehicle <-> roadside on 10.213.1.0/24, infrastructure <-> roadside on 10.213.2.0/24
veth "$V" "vv$id" 10.213.1.2/24 "$F" "vf$id" 10.213.1.1/24
veth "$R" "rr$id" 10.213.2.2/24 "$F" "rf$id" 10.213.2.1/24
# the city's east roadside: <-> west roadside on 10.213.3.0/24, <-> infrastructure on 10.213.4.0/24
veth "$F" "fe$id" 10.213.3.1/24 "$E" "ef$id" 10.213.3.2/24
veth "$R" "re$id" 10.213.4.2/24 "$E" "er$id" 10.213.4.1/24

# One scenario, three hosts: the roadside runs ROADSIDE_ROLES, the vehicle and the roadside unit
# their agent; the summary and the recording are checked.
run_case() {
    local name=$1 scenario=$2 roadside_roles=$3
    echo "  case: $name"
    ip netns exec "$F" timeout 60 "$BIN/v2x-sim" run "$scenario" $roadside_roles --format json --record "$tmp/$name-fused.json" > "$tmp/$name-summary.json" 2> "$tmp/$name-fuser.log" &
    local fpid=$!
    ip netns exec "$V" timeout 60 "$BIN/v2x-sim" run "$scenario" --role veh --format json > "$tmp/$name-veh.json" 2> "$tmp/$name-veh.log" &
    local vpid=$!
    ip netns exec "$R" timeout 60 "$BIN/v2x-sim" run "$scenario" --role rsu --format json > "$tmp/$name-rsu.json" 2> "$tmp/$name-rsu.log" &
    local rpid=$!
    local status=0
    wait "$vpid" || { echo "vehicle role failed:"; cat "$tmp/$name-veh.log"; status=1; }
    wait "$rpid" || { echo "infrastructure role failed:"; cat "$tmp/$name-rsu.log"; status=1; }
    wait "$fpid" || { echo "roadside roles failed:"; cat "$tmp/$name-fuser.log"; status=1; }
    [ "$status" = 0 ] || exit 1
    python3 - "$tmp/$name-summary.json" "$tmp/$name-veh.json" "$tmp/$name-rsu.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
# Every host reports its own bytes from Zenoh's statistics: each agent what it sent, the
# roadside what it received (the fuser's transports in plain peers, the router's with TLS).
for path, a in ((sys.argv[2], "veh"), (sys.argv[3], "rsu")):
    b = json.load(open(path))["bandwidth"][a]
    assert b["wire_bytes_per_frame"] > b["payload_bytes_per_frame"] > 0, b
    assert b["zenoh_frames"] == b["frames"] == 50, b
    assert b["zenoh_payload_bytes_per_frame"] == b["payload_bytes_per_frame"], b
    r = s["bandwidth"][a]
    assert r["received_payload_bytes_per_frame"] > 0, r
    # plain: at the fuser, over the agent's own transport; mutual TLS: at the router beside it
    assert r["received_wire_bytes_per_frame"] > r["received_payload_bytes_per_frame"], r
    print("    %s sent %.0f B/frame on the wire (payload %.0f, Zenoh overhead %.1f B/message); %s received %.0f B/frame"
          % (a, b["wire_bytes_per_frame"], b["payload_bytes_per_frame"], b["overhead_bytes_per_message"],
             "the fuser" if s["security"]["mode"] == "plain" else "the router", r["received_wire_bytes_per_frame"]))
assert s["fuser_traffic"]["rx"]["bytes"] > 0, s["fuser_traffic"]
if s["security"]["mode"] == "plain":
    # the vehicle's link went from 10 to 60 ms at 2.5 s: half the windows wait for it
    assert s["e2e_latency_ms"]["p95_ms"] >= 55.0, s["e2e_latency_ms"]
assert s["frames_scheduled"] == 50, s["frames_scheduled"]
assert s["windows"] >= 45 and s["windows_incomplete"] <= 2, (s["windows"], s["windows_incomplete"])
assert s["fused"]["precision"] == 1.0 and s["fused"]["recall"] == 1.0, s["fused"]
assert s["fused"]["mATE"] < s["agents"]["rsu"]["mATE"], "fusion beats the large-noise agent"
for a in ("veh", "rsu"):
    assert s["counts"][a]["fused"] >= 45, s["counts"][a]
print("    security %s: fused windows %d/%d, mATE fused %.3f m (veh %.3f, rsu %.3f), e2e latency p50 %.1f ms"
      % (s["security"]["mode"], s["windows"], s["frames_scheduled"], s["fused"]["mATE"],
         s["agents"]["veh"]["mATE"], s["agents"]["rsu"]["mATE"], s["e2e_latency_ms"]["p50_ms"]))
PY
    "$BIN/v2x-sim" eval --scenes 1 --seconds 5 --hz 10 --format json "$tmp/$name-fused.json" > "$tmp/$name-eval.json" 2>/dev/null
    python3 -c 'import json,sys; m=json.load(open(sys.argv[1])); assert m["precision"]==1.0 and m["tp"]>=45*20, m; print("    eval of the recording: precision %.4f recall %.4f mATE %.3f m" % (m["precision"], m["recall"], m["mATE"]))' "$tmp/$name-eval.json"
}

# The scenario files' shared parts: the header (namespace, seed, a 5 s town scene at 10 Hz), and
# the two agents, a mild-noise vehicle with a jittered link and a large-noise roadside unit,
# each with its Zenoh settings ($1, $2).
header() {
cat <<TOML
namespace = "$1"
seed = 5
duration_s = 5.0
speed = 1.0

[dataset]
scenes = 1
seconds = 5.0
hz = 10.0

TOML
}

agents() {
cat <<TOML
[[agents]]
name = "veh"
kind = "vehicle"
noise = "mild"
link = { latency_ms = 10.0, jitter_ms = 5.0 }
zenoh = $1

[[agents]]
name = "rsu"
kind = "infrastructure"
noise = "large"
zenoh = $2
TOML
}

{
header multihost
cat <<TOML
[fuser]
method = "csba-wls+"
max_wait_ms = 200.0
zenoh = { mode = "peer", listen = ["tcp/10.213.1.1:7447", "tcp/10.213.2.1:7447"], no_multicast_scouting = true }

TOML
agents '{ mode = "peer", connect = ["tcp/10.213.1.1:7447"], no_multicast_scouting = true }' \
    '{ mode = "peer", connect = ["tcp/10.213.2.1:7447"], no_multicast_scouting = true }'
cat <<TOML

# A scripted event, applied by the vehicle's own host on the scenario clock.
[[events]]
at_s = 2.5
target = "veh"
action = "link"
latency_ms = 60.0
TOML
} > "$tmp/plain.toml"
run_case plain "$tmp/plain.toml" "--role fuser"

# Secure: mutual TLS through a router on the roadside host that holds the access-control policy;
# the fuser and both agents are its clients, each with its own certificate.
"$BIN/v2x-sim" certs --out "$tmp/certs" --ns multihost-secure \
    --listen tls/10.213.1.1:7447 --listen tls/10.213.2.1:7447 \
    --router tls/10.213.1.1:7447 --router tls/10.213.2.1:7447 veh rsu > /dev/null
{
header multihost-secure
cat <<TOML
[security]
mode = "mtls"
certs = "$tmp/certs"

[fuser]
method = "csba-wls+"
max_wait_ms = 200.0
zenoh = { connect = ["tls/10.213.1.1:7447"] }

TOML
agents '{ connect = ["tls/10.213.1.1:7447"] }' '{ connect = ["tls/10.213.2.1:7447"] }'
} > "$tmp/secure.toml"
run_case secure "$tmp/secure.toml" "--role router --role fuser"
# A city: two roadside hosts, each a router (east meshed with west) and the regional fusers of
# two of the town's four 100 m tiles; the vehicle is a client of the west router, the
# infrastructure of the east one. Each roadside records its regions; the two recordings, joined,
# are scored as one.
{
header multihost-city
cat <<TOML
[fuser]
method = "csba-wls+"
max_wait_ms = 200.0

TOML
agents '{ mode = "client", connect = ["tcp/10.213.1.1:7447"], no_multicast_scouting = true }' \
    '{ mode = "client", connect = ["tcp/10.213.4.1:7447"], no_multicast_scouting = true }'
cat <<TOML

[regions]
tile_m = 100.0
halo_m = 30.0

[[regions.routers]]
name = "west"
zenoh = { listen = ["tcp/0.0.0.0:7447"], no_multicast_scouting = true }

[[regions.routers]]
name = "east"
zenoh = { listen = ["tcp/0.0.0.0:7447"], connect = ["tcp/10.213.3.1:7447"], no_multicast_scouting = true }
TOML
for fuser in -1_-1:west -1_0:west 0_-1:east 0_0:east; do
cat <<TOML

[[regions.fusers]]
tile = "${fuser%:*}"
router = "${fuser#*:}"
zenoh = { connect = ["tcp/127.0.0.1:7447"], no_multicast_scouting = true }
TOML
done
} > "$tmp/city.toml"
echo "  case: city"
ip netns exec "$F" timeout 60 "$BIN/v2x-sim" run "$tmp/city.toml" --role router-west --role fuser--1_-1 --role fuser--1_0 --format json --record "$tmp/west.json" > "$tmp/west-summary.json" 2> "$tmp/west.log" &
wpid=$!
ip netns exec "$E" timeout 60 "$BIN/v2x-sim" run "$tmp/city.toml" --role router-east --role fuser-0_-1 --role fuser-0_0 --format json --record "$tmp/east.json" > "$tmp/east-summary.json" 2> "$tmp/east.log" &
epid=$!
ip netns exec "$V" timeout 60 "$BIN/v2x-sim" run "$tmp/city.toml" --role veh --format json > "$tmp/city-veh.json" 2> "$tmp/city-veh.log" &
vpid=$!
ip netns exec "$R" timeout 60 "$BIN/v2x-sim" run "$tmp/city.toml" --role rsu --format json > "$tmp/city-rsu.json" 2> "$tmp/city-rsu.log" &
rpid=$!
status=0
wait "$vpid" || { echo "vehicle role failed:"; cat "$tmp/city-veh.log"; status=1; }
wait "$rpid" || { echo "infrastructure role failed:"; cat "$tmp/city-rsu.log"; status=1; }
wait "$wpid" || { echo "west roadside failed:"; cat "$tmp/west.log"; status=1; }
wait "$epid" || { echo "east roadside failed:"; cat "$tmp/east.log"; status=1; }
[ "$status" = 0 ] || exit 1
python3 - "$tmp/west-summary.json" "$tmp/east-summary.json" "$tmp/west.json" "$tmp/east.json" "$tmp/city-joined.json" "$tmp/city-veh.json" <<'PY'
import json, sys
regions = json.load(open(sys.argv[1]))["regions"] + json.load(open(sys.argv[2]))["regions"]
assert sorted(r["tile"] for r in regions) == ["-1_-1", "-1_0", "0_-1", "0_0"], regions
for r in regions:
    # every region fused (nearly) every frame, from both agents, across the router mesh
    assert r["windows"] >= 45 and r["captures_incomplete"] == 0, r
    assert r["agents_heard"] == ["rsu", "veh"], r
    print("    region %s (router %s): %d windows (%d incomplete), %d boxes published"
          % (r["tile"], r["router"], r["windows"], r["windows_incomplete"], r["fused_objects"]))
veh = json.load(open(sys.argv[6]))["bandwidth"]["veh"]
assert veh["zenoh_frames"] == veh["frames"] == 50, veh
# The regions' recordings are disjoint by construction: joined, they are the city's output.
west, east = json.load(open(sys.argv[3])), json.load(open(sys.argv[4]))
joined = {"meta": west["meta"], "results": {}}
for part in (west, east):
    for token, boxes in part["results"].items():
        joined["results"].setdefault(token, []).extend(boxes)
json.dump(joined, open(sys.argv[5], "w"))
PY
"$BIN/v2x-sim" eval --scenes 1 --seconds 5 --hz 10 --format json "$tmp/city-joined.json" > "$tmp/city-eval.json" 2>/dev/null
python3 -c 'import json,sys; m=json.load(open(sys.argv[1])); assert m["precision"]>=0.99 and m["tp"]>=45*20, m; print("    eval of the joined recordings: precision %.4f recall %.4f mATE %.3f m" % (m["precision"], m["recall"], m["mATE"]))' "$tmp/city-eval.json"
echo "multi-host test: RAN (4 network namespaces over veth: vehicle, infrastructure, two roadside hosts; plain peers, mutual TLS through a router with access control, and a city of four regional fusers over two meshed routers) - passed"
