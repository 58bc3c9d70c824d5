"""Decodes the two examples of docs/wire-format.md with v2x_frame.py and checks them against the
values the document states, so the decoder and the specification agree without a network.

    python doc_examples.py [docs/wire-format.md]
"""

import sys

from v2x_frame import decode


def example(doc, name):
    start, end = doc.index(f"<!-- {name} -->"), doc.index(f"<!-- /{name} -->")
    hexes = [
        t
        for line in doc[start:end].splitlines()
        for t in line.split("|")[0].split()
        if len(t) == 2 and all(c in "0123456789abcdef" for c in t)
    ]
    return bytes(int(t, 16) for t in hexes)


def main(path):
    doc = open(path).read()
    agent = decode(example(doc, "example-bytes"))
    assert (agent["agent"], agent["kind"], agent["seq"]) == ("rsu1", "infrastructure", 7)
    car, walker = agent["objects"]
    assert (car["class"], car["id"], car["center"]) == ("car", 12, [102.5, -48.0, 1.8]), car
    assert (walker["class"], walker["size"], walker["id"]) == ("pedestrian", [0.8, 0.6, 1.7], None), walker
    assert "agents" not in agent and "sources" not in car
    fused = decode(example(doc, "fused-example-bytes"))
    assert (fused["agent"], fused["agents"], fused["complete"]) == ("fuser", ["rsu1", "veh1"], True)
    assert [o["sources"] for o in fused["objects"]] == [["rsu1", "veh1"], ["rsu1"]]
    for a, b in zip(agent["objects"], fused["objects"]):
        b = dict(b)
        del b["sources"]
        assert a == b, (a, b)
    print("python decoder: both examples of docs/wire-format.md decode as documented")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "docs/wire-format.md")
