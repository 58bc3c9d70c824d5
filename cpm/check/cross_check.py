"""The project's CPMs against an independent ASN.1 implementation (asn1tools, compiled from the
same official modules in cpm/asn1).

    cross_check.py ours RESULTS_DIR CPM_DIR LAT,LON OFFSET_US  # asn1tools decodes what `v2x-sim wire` wrote
    cross_check.py theirs V2X_SIM LAT,LON TMP_DIR     # v2x-sim reads what asn1tools wrote

`ours` decodes every message, checks it field by field against the results file it came from
(within the message's steps) and that asn1tools re-encodes it to the same bytes. `theirs`
encodes a roadside unit's CPM with a car, a pedestrian and an animal, and checks the boxes that
`v2x-sim wire --read` prints.
"""

import glob
import json
import math
import os
import subprocess
import sys

import asn1tools

HERE = os.path.dirname(os.path.abspath(__file__))
ITS_EPOCH_UNIX_MS = 1_072_915_200_000
Z95 = 1.959963984540054
CLASSES = {  # the project's class: the CPM's ObjectClass
    "car": ("vehicleSubClass", 5),
    "truck": ("vehicleSubClass", 8),
    "bus": ("vehicleSubClass", 6),
    "trailer": ("vehicleSubClass", 9),
    "construction_vehicle": ("vehicleSubClass", 10),
    "pedestrian": ("vruSubClass", ("pedestrian", "ordinary-pedestrian")),
    "motorcycle": ("vruSubClass", ("motorcyclist", "motorcycle")),
    "bicycle": ("vruSubClass", ("bicyclistAndLightVruVehicle", "bicyclist")),
    "traffic_cone": ("otherSubClass", 1),
    "barrier": ("otherSubClass", 1),
}


def compile_modules():
    """The CPM modules compiled for UPER.

    asn1tools reads only the first part of a union constraint on an integer (the CPM's
    `TrafficParticipantType (unknown|passengerCar..tram|agricultural)`), so the check gives it
    the union's extent, the range that X.691 encodes such a constraint with (0..14 here)."""
    d = asn1tools.parse_files(sorted(glob.glob(os.path.join(HERE, "..", "asn1", "*.asn"))))

    def widen(module, node):
        if isinstance(node, dict):
            parts = node.get("restricted-to")
            named = d[module]["types"].get(node.get("type"), {}).get("named-numbers")
            if parts and named and len([p for p in parts if p != "..."]) > 1:
                values = [
                    named.get(v, v)
                    for p in parts
                    if p != "..."
                    for v in (p if isinstance(p, tuple) else (p,))
                ]
                node["restricted-to"] = [(min(values), max(values))] + (
                    ["..."] if "..." in parts else []
                )
            for v in node.values():
                widen(module, v)
        elif isinstance(node, list):
            for v in node:
                widen(module, v)

    for m in d:
        widen(m, d[m]["types"])
    return asn1tools.compile_dict(d, "uper")


def metres_per_degree(lat0):
    p = math.radians(lat0)
    lat = 111132.954 - 559.822 * math.cos(2 * p) + 1.175 * math.cos(4 * p)
    lon = 111412.84 * math.cos(p) - 93.5 * math.cos(3 * p) + 0.118 * math.cos(5 * p)
    return lat, lon


def fnv1a(name):
    """The project's stable id of a name or token (station ids, and object ids before their low
    16 bits are taken)."""
    h = 0x811C9DC5
    for b in name.encode():
        h = ((h ^ b) * 0x01000193) & 0xFFFFFFFF
    return h


def check(cond, what):
    if not cond:
        sys.exit(f"FAIL: {what}")


def ours(results_dir, cpm_dir, origin, offset):
    c = compile_modules()
    lat0, lon0 = origin
    m_lat, m_lon = metres_per_degree(lat0)
    n_msgs = n_objs = 0
    for path in sorted(glob.glob(os.path.join(results_dir, "*.json"))):
        doc = json.load(open(path))
        agent = doc["meta"].get("v2x_agent") or os.path.splitext(os.path.basename(path))[0]
        for sample, boxes in doc["results"].items():
            raw = open(os.path.join(cpm_dir, agent, sample + ".uper"), "rb").read()
            msg = c.decode("CollectivePerceptionMessage", raw)
            check(c.encode("CollectivePerceptionMessage", msg) == raw, f"{sample}: re-encoded bytes differ")
            h = msg["header"]
            check((h["protocolVersion"], h["messageId"]) == (2, 14), f"{sample}: header {h}")
            check(h["stationId"] == fnv1a(agent), f"{sample}: station id")
            mc = msg["payload"]["managementContainer"]
            t_ms = (doc["meta"]["v2x_timestamps"][sample] + offset) // 1000
            check(mc["referenceTime"] == t_ms - ITS_EPOCH_UNIX_MS, f"{sample}: reference time")
            ref = mc["referencePosition"]
            at = (
                (ref["longitude"] / 1e7 - lon0) * m_lon,
                (ref["latitude"] / 1e7 - lat0) * m_lat,
                (ref["altitude"]["altitudeValue"] - 0.5) * 0.01,
            )
            containers = {w["containerId"]: w["containerData"] for w in msg["payload"]["cpmContainers"]}
            check(sorted(containers) in ([1, 5], [2, 5]), f"{sample}: containers {sorted(containers)}")
            if 1 in containers:
                c.decode("OriginatingVehicleContainer", containers[1])
            else:
                c.decode("OriginatingRsuContainer", containers[2])
            poc = c.decode("PerceivedObjectContainer", containers[5])
            objs = poc["perceivedObjects"]
            check(poc["numberOfPerceivedObjects"] == len(objs) == len(boxes), f"{sample}: {len(objs)} objects for {len(boxes)} boxes")
            for o, b in zip(objs, boxes):
                where = f"{agent}/{sample} object {o['objectId']}"
                p = o["position"]
                for k, axis in enumerate(["xCoordinate", "yCoordinate", "zCoordinate"]):
                    got = at[k] + (p[axis]["value"] - 0.5) * 0.01
                    check(abs(got - b["translation"][k]) <= 0.005 + 1e-6, f"{where}: {axis} {got} for {b['translation'][k]}")
                    std = b["translation_std"][k]
                    conf = p[axis]["confidence"]
                    check(conf == 4095 if Z95 * std > 40.94 else (conf - 1) * 0.01 < Z95 * std + 1e-9 <= conf * 0.01 + 1e-9, f"{where}: {axis} confidence {conf} for std {std}")
                w, l, hgt = b["size"]  # nuScenes order: width, length, height
                for dim, want in [("objectDimensionX", l), ("objectDimensionY", w), ("objectDimensionZ", hgt)]:
                    got = (o[dim]["value"] - 0.5) * 0.1
                    check(abs(got - want) <= 0.05 + 1e-9, f"{where}: {dim} {got} for {want}")
                q = b["rotation"]
                yaw = math.degrees(2 * math.atan2(q[3], q[0])) % 360
                got = (o["angles"]["zAngle"]["value"] - 0.5) * 0.1
                check(abs((got - yaw + 180) % 360 - 180) <= 0.05 + 1e-6, f"{where}: zAngle {got} for {yaw}")
                cls = o["classification"][0]
                check(cls["objectClass"] == CLASSES[b["detection_name"]], f"{where}: class {cls} for {b['detection_name']}")
                check(abs(cls["confidence"] / 100 - max(b["detection_score"], 0.01)) <= 0.005 + 1e-9, f"{where}: score")
                want = fnv1a(b["instance_token"]) if "instance_token" in b else b.get("instance_id", 65535)
                check(o["objectId"] == want % 65536, f"{where}: id")
                if "velocity" in b and b.get("velocity_std") is not None:
                    kind, v = o["velocity"]
                    check(kind == "cartesianVelocity", f"{where}: velocity {kind}")
                    for k, comp in enumerate(["xVelocity", "yVelocity"]):
                        got = (v[comp]["value"] - 0.5) * 0.01
                        check(abs(got - b["velocity"][k]) <= 0.005 + 1e-9, f"{where}: {comp}")
                n_objs += 1
            n_msgs += 1
    check(n_msgs > 0, "no messages")
    print(f"asn1tools decoded {n_msgs} CPMs ({n_objs} objects) as written, field by field, and re-encoded them byte for byte")


def theirs(v2x_sim, origin, tmp):
    c = compile_modules()
    lat0, lon0 = origin
    cc = lambda v, conf: {"value": v, "confidence": conf}

    def obj(oid, x, y, z, cls, conf):
        return {
            "objectId": oid,
            "measurementDeltaTime": 0,
            "position": {"xCoordinate": cc(x, 50), "yCoordinate": cc(y, 50), "zCoordinate": cc(z, 20)},
            "velocity": ("cartesianVelocity", {"xVelocity": cc(-250, 40), "yVelocity": cc(101, 40)}),
            "angles": {"zAngle": cc(900, 30)},
            "objectDimensionX": cc(45, 3),
            "objectDimensionY": cc(19, 2),
            "objectDimensionZ": cc(16, 1),
            "classification": [{"objectClass": cls, "confidence": conf}],
        }

    poc = c.encode("PerceivedObjectContainer", {
        "numberOfPerceivedObjects": 3,
        "perceivedObjects": [
            obj(7, 1000, -2000, 0, ("vehicleSubClass", 5), 90),
            obj(8, -150, 300, 10, ("vruSubClass", ("pedestrian", "ordinary-pedestrian")), 60),
            obj(9, 0, 0, 0, ("vruSubClass", ("animal", "wild-animal")), 99),
        ],
    })
    rsu = c.encode("OriginatingRsuContainer", {})
    msg = {
        "header": {"protocolVersion": 2, "messageId": 14, "stationId": 4242},
        "payload": {
            "managementContainer": {
                "referenceTime": 600_000_000_123,
                "referencePosition": {
                    "latitude": round(lat0 * 1e7),
                    "longitude": round(lon0 * 1e7),
                    "positionConfidenceEllipse": {"semiMajorConfidence": 4095, "semiMinorConfidence": 4095, "semiMajorOrientation": 3601},
                    "altitude": {"altitudeValue": 1000, "altitudeConfidence": "unavailable"},
                },
            },
            "cpmContainers": [{"containerId": 2, "containerData": rsu}, {"containerId": 5, "containerData": poc}],
        },
    }
    path = os.path.join(tmp, "theirs.uper")
    open(path, "wb").write(c.encode("CollectivePerceptionMessage", msg))
    out = subprocess.run([v2x_sim, "wire", "--read", path, "--map-origin", f"{lat0},{lon0}"], check=True, capture_output=True, text=True).stdout
    doc = json.loads(out)
    check(doc["station_id"] == 4242 and doc["kind"] == "infrastructure", f"sender {doc['station_id']} {doc['kind']}")
    check(doc["capture_us"] == (600_000_000_123 + ITS_EPOCH_UNIX_MS) * 1000, "capture time")
    check(doc["skipped"] == [{"index": 2, "reason": "a class the project has no name for"}], f"skipped {doc['skipped']}")
    boxes = doc["boxes"]
    check([b["detection_name"] for b in boxes] == ["car", "pedestrian"], "classes")
    check([b["instance_id"] for b in boxes] == [7, 8], "ids")
    close = lambda a, b: abs(a - b) < 1e-6
    at = [doc["origin"][0], doc["origin"][1], 9.995]  # altitude 1000 cm: (1000 - 0.5) cm
    check(close(doc["origin"][2], 9.995), f"altitude {doc['origin']}")
    for b, (x, y, z) in zip(boxes, [(1000, -2000, 0), (-150, 300, 10)]):
        want = [at[0] + (x - 0.5) / 100, at[1] + (y - 0.5) / 100, at[2] + (z - 0.5) / 100]
        check(all(close(g, w) for g, w in zip(b["translation"], want)), f"translation {b['translation']} for {want}")
        check(all(close(g, w) for g, w in zip(b["size"], [1.85, 4.45, 1.55])), f"size {b['size']}")
        check(close(2 * math.degrees(math.atan2(b["rotation"][3], b["rotation"][0])), 89.95), "yaw")
        check(close(b["translation_std"][0], 0.5 / Z95) and close(b["translation_std"][2], 0.2 / Z95), "position stds")
        check(close(b["yaw_std"], math.radians(3.0) / Z95), "yaw std")
        check(all(close(g, w) for g, w in zip(b["velocity"], [-2.505, 1.005])), f"velocity {b['velocity']}")
    check([b["detection_score"] for b in boxes] == [0.9, 0.6], "scores")
    print("v2x-sim read asn1tools' CPM: a roadside unit's car and pedestrian, the animal skipped")


if __name__ == "__main__":
    mode = sys.argv[1]
    if mode == "ours":
        ours(sys.argv[2], sys.argv[3], tuple(map(float, sys.argv[4].split(","))), int(sys.argv[5]))
    elif mode == "theirs":
        theirs(sys.argv[2], tuple(map(float, sys.argv[3].split(","))), sys.argv[4])
    else:
        sys.exit(__doc__)
