"""Checks that the frames the Python subscriber decoded are the fused frames the fuser recorded:
same frames (by capture time), same boxes, same classes and ids, and centres, sizes and scores
within the wire's quantization (docs/wire-format.md: 0.5 cm, 0.002); the recording holds the
values before quantization. The provenance (window agents, completeness, each box's source
agents) must be exactly the recorded one (meta.v2x_provenance).

    python compare.py frames.jsonl fused.json
"""

import json
import sys


def main(jsonl, recorded):
    decoded = {}
    for line in open(jsonl):
        f = json.loads(line)
        if f["key"].endswith("/fused"):
            assert "v2x-frame/3" in f["encoding"], f"fused frames' encoding: {f['encoding']}"
            decoded[f"t{f['capture_us']}"] = f
    doc = json.load(open(recorded))
    results, provenance = doc["results"], doc["meta"]["v2x_provenance"]
    assert decoded, "the subscriber decoded no fused frame"
    assert set(decoded) == set(results), (
        f"{len(decoded)} frames decoded, {len(results)} recorded; "
        f"only decoded: {sorted(set(decoded) - set(results))[:3]}, "
        f"only recorded: {sorted(set(results) - set(decoded))[:3]}"
    )
    boxes, shared = 0, 0
    for key, frame in decoded.items():
        objects, rec, prov = frame["objects"], results[key], provenance[key]
        assert frame["agents"] == prov["agents"], (key, frame["agents"], prov["agents"])
        assert frame["complete"] == prov["complete"], key
        assert [o["sources"] for o in objects] == prov["sources"], key
        shared += sum(len(o["sources"]) > 1 for o in objects)
        assert len(objects) == len(rec), f"{key}: {len(objects)} decoded vs {len(rec)} recorded"
        for o, r in zip(objects, rec):
            assert o["class"] == r["detection_name"], (key, o["class"], r["detection_name"])
            cm = 0.005 + 1e-9
            assert all(abs(a - b) <= cm for a, b in zip(o["center"], r["translation"])), (key, o, r)
            l, w, h = o["size"]
            assert all(abs(a - b) <= cm for a, b in zip([w, l, h], r["size"])), (key, o, r)
            assert abs(o["score"] - r["detection_score"]) <= 0.002 + 1e-9, (key, o, r)
            assert o["id"] == r.get("instance_id"), (key, o, r)
            boxes += 1
    assert 0 < shared < boxes, "want boxes fused from two agents and boxes seen by one"
    print(
        f"python client: {len(decoded)} fused frames, {boxes} boxes decoded ({shared} from two"
        " agents or more), boxes and provenance as recorded"
    )


if __name__ == "__main__":
    main(*sys.argv[1:3])
