"""The codec: the specification's example bytes, round trips, and errors that name what is wrong."""

import math
import random
import sys

import pytest

import v2x_fusion as v
from conftest import REPO

sys.path.insert(0, str(REPO / "examples" / "python"))
from doc_examples import example  # noqa: E402
from v2x_frame import decode as reference_decode  # noqa: E402

SPEC = (REPO / "docs" / "wire-format.md").read_text()


@pytest.mark.parametrize("name", ["example-bytes", "fused-example-bytes"])
def test_the_specs_examples_decode_as_the_independent_decoder_and_re_encode_byte_for_byte(name):
    payload = example(SPEC, name)
    frame = v.decode(payload)
    assert frame.to_dict() == reference_decode(payload)
    assert v.encode(frame) == payload
    assert v.encode(frame.to_dict()) == payload


def test_the_examples_values():
    agent = v.decode(example(SPEC, "example-bytes"))
    assert (agent.agent, agent.kind, agent.seq, agent.agents) == ("rsu1", "infrastructure", 7, None)
    car, walker = agent.objects
    assert (car.class_name, car.id, car.center) == ("car", 12, [102.5, -48.0, 1.8])
    assert (walker.class_name, walker.size, walker.id) == ("pedestrian", [0.8, 0.6, 1.7], None)
    fused = v.decode(example(SPEC, "fused-example-bytes"))
    assert (fused.agents, fused.complete) == (["rsu1", "veh1"], True)
    assert [o.sources for o in fused.objects] == [["rsu1", "veh1"], ["rsu1"]]


def box(x, **extra):
    b = {
        "translation": [x, 2.0, 1.0],
        "size": [1.9, 4.5, 1.6],
        "rotation": [math.cos(0.25), 0.0, 0.0, math.sin(0.25)],
        "detection_name": "car",
        "detection_score": 0.8,
        "translation_std": [0.2, 0.2, 0.1],
        "size_std": [0.1, 0.1, 0.1],
        "yaw_std": 0.05,
    }
    b.update(extra)
    return b


def test_boxes_encode_into_a_frame_at_their_centroid():
    payload = v.encode_boxes("pyveh", [box(10.0, instance_id=5), box(20.0)], seq=3, capture_us=1_700_000_000_000_000)
    f = v.decode(payload)
    assert (f.agent, f.kind, f.seq, f.capture_us) == ("pyveh", "vehicle", 3, 1_700_000_000_000_000)
    assert f.origin == [15.0, 2.0, 1.0]
    assert [o.center for o in f.objects] == [[10.0, 2.0, 1.0], [20.0, 2.0, 1.0]]
    assert [o.id for o in f.objects] == [5, None]
    # l, w, h on the wire; 0.5 rad of yaw within its 16-bit step
    assert f.objects[0].size == [4.5, 1.9, 1.6]
    assert abs(f.objects[0].yaw - 0.5) < 2 * math.pi / 65536


@pytest.mark.parametrize(
    "payload, message",
    [
        (b"", "empty payload"),
        (b"\x09", "unknown wire version 9"),
        (example(SPEC, "example-bytes")[:-3], "truncated"),
        (example(SPEC, "example-bytes") + b"\x00", "1 trailing bytes"),
    ],
)
def test_bad_payloads_raise_the_decoders_message(payload, message):
    with pytest.raises(v.DecodeError, match=message):
        v.decode(payload)


def test_decode_errors_are_value_errors():
    assert issubclass(v.DecodeError, ValueError) and issubclass(v.EncodeError, ValueError)


def test_encode_errors_name_the_field():
    frame = v.decode(example(SPEC, "example-bytes")).to_dict()
    frame["objects"][1]["center"] = [1.0, 2.0]
    with pytest.raises(v.EncodeError, match=r"objects\[1\]\.center: expected 3 numbers"):
        v.encode(frame)
    frame["objects"][1]["center"] = [1.0, 2.0, 3.0]
    frame["objects"][0]["size"] = [0.0, 1.0, 1.0]
    with pytest.raises(v.EncodeError, match="object 0: field 'size.l' is out of range"):
        v.encode(frame)
    frame["objects"][0]["size"] = [4.0, 2.0, 1.5]
    frame["objects"][0]["class"] = "tank"
    with pytest.raises(v.EncodeError, match="unknown class 'tank'"):
        v.encode(frame)
    frame["objects"][0]["class"] = "car"
    frame["objects"][0]["score"] = float("nan")
    with pytest.raises(ValueError, match="frame: Out of range float"):
        v.encode(frame)
    frame["objects"][0]["score"] = 0.5
    frame["agent"] = "a/b"
    with pytest.raises(v.EncodeError, match="agent name"):
        v.encode(frame)


def test_bad_boxes_name_the_box_and_field():
    with pytest.raises(ValueError, match=r"boxes, box 1, field 'translation_std': missing"):
        v.encode_boxes("pyveh", [box(1.0), {k: x for k, x in box(2.0).items() if k != "translation_std"}])
    payload = v.encode_boxes("pyveh", [{k: x for k, x in box(2.0).items() if k != "translation_std"}], default_std="mild")
    assert len(v.decode(payload).objects) == 1


def test_mutated_bytes_decode_or_raise_decode_error_and_what_decodes_re_encodes():
    rng = random.Random(7)
    accepted = 0
    for name in ("example-bytes", "fused-example-bytes"):
        base = example(SPEC, name)
        for n in range(2000):
            b = bytearray(base)
            for _ in range(rng.randint(1, 3)):
                b[rng.randrange(len(b))] = rng.randrange(256)
            if n % 4 == 0:
                b = b[: rng.randrange(len(b))]
            try:
                frame = v.decode(bytes(b))
            except v.DecodeError:
                continue
            accepted += 1
            assert v.decode(v.encode(frame)) == frame
    assert accepted > 100
