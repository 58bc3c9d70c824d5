"""Fusion from Python equals `v2x-fuser fuse` box for box; the numpy path equals the dict path; bad
input raises errors that say what is wrong."""

import math

import numpy as np
import pytest

import v2x_fusion as v
from conftest import load, run

AGENTS = ("agent1.json", "agent2.json")


def stable_id(token):
    """The object id of an instance token (FNV-1a, as the Rust core interns it)."""
    h = 0x811C9DC5
    for b in token.encode():
        h = ((h ^ b) * 0x01000193) & 0xFFFFFFFF
    return 0xFFFFFFFE if h == 0xFFFFFFFF else h


def test_the_csba_family_is_listed():
    assert {"csba-wls", "csba-wls+", "gt-wls", "nms-3d", "dair-v2x-late"} <= set(v.METHODS)


@pytest.mark.parametrize("method", ["csba-wls+", "csba-wls", "dair-v2x-late", "gt-wls"])
def test_fuse_equals_the_cli_box_for_box(untimed, tmp_path, method):
    out = tmp_path / "fused.json"
    run("v2x-fuser", "fuse", "--method", method, "-o", out, *(untimed / a for a in AGENTS))
    cli = load(out)["results"]
    docs = [load(untimed / a)["results"] for a in AGENTS]
    assert len(cli) == 30
    shared = 0
    for sample, expected in cli.items():
        fused = v.fuse([d.get(sample, []) for d in docs], method)
        assert len(fused) == len(expected), sample
        for got, want in zip(fused, expected):
            sources = got.pop("v2x_sources")
            assert sources and set(sources) <= {0, 1}
            shared += len(sources) == 2
            assert got == {k: x for k, x in want.items() if k != "sample_token"}
    assert shared > 30


def test_fuse_files_and_fuse_results_equal_the_cli(generated, tmp_path):
    paths = [generated / a for a in AGENTS]
    run("v2x-fuser", "fuse", "--learn-std", "-o", tmp_path / "cli.json", *paths)
    report = v.fuse_files(paths, tmp_path / "py.json", learn_std=True)
    assert load(tmp_path / "py.json") == load(tmp_path / "cli.json")
    assert report["by_time"] and report["samples"] == 30
    assert report["boxes_in"] > report["boxes_out"] > 0
    assert set(report["learned"]) == {"agent1", "agent2"}
    doc, again = v.fuse_results([load(p) for p in paths], learn_std=True)
    assert doc == load(tmp_path / "cli.json") and again == report


def test_options_reach_the_fusion(generated, tmp_path):
    paths = [generated / a for a in AGENTS]
    flags = ("--no-compensation", "--window-ms", "50", "--learn-std", "--std-flag-ratio", "3")
    run("v2x-fuser", "fuse", *flags, "-o", tmp_path / "cli.json", *paths)
    v.fuse_files(paths, tmp_path / "py.json", compensation=False, window_ms=50, learn_std=True, std_flag_ratio=3)
    assert load(tmp_path / "py.json") == load(tmp_path / "cli.json")
    v.fuse_files(paths, tmp_path / "default.json")
    assert load(tmp_path / "default.json") != load(tmp_path / "cli.json")


def arrays(boxes):
    """A results file's boxes as fuse_arrays takes them."""
    def q_yaw(q):
        w, x, y, z = q
        return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))

    return {
        "center": np.array([b["translation"] for b in boxes]).reshape(-1, 3),
        "size": np.array([[b["size"][1], b["size"][0], b["size"][2]] for b in boxes]).reshape(-1, 3),
        "yaw": np.array([q_yaw(b["rotation"]) for b in boxes]),
        "std": np.array(
            [b["translation_std"] + [b["size_std"][1], b["size_std"][0], b["size_std"][2], b["yaw_std"]] for b in boxes]
        ).reshape(-1, 7),
        "label": np.array([v.CLASSES.index(b["detection_name"]) for b in boxes], dtype=np.int32),
        "score": np.array([b["detection_score"] for b in boxes]),
        "id": np.array([stable_id(b["instance_token"]) if "instance_token" in b else -1 for b in boxes]),
    }


@pytest.mark.parametrize("method", ["csba-wls+", "gt-wls"])
def test_the_numpy_path_equals_the_dict_path(untimed, method):
    docs = [load(untimed / a)["results"] for a in AGENTS]
    compared = 0
    for sample in sorted(docs[0])[:10]:
        per_agent = [d.get(sample, []) for d in docs]
        want = v.fuse(per_agent, method)
        got = v.fuse_arrays([arrays(b) for b in per_agent], method)
        assert got["center"].shape == (len(want), 3) and got["sources"].shape == (len(want), 2)
        for i, w in enumerate(want):
            assert np.allclose(got["center"][i], w["translation"], atol=1e-9)
            assert np.allclose(got["size"][i], [w["size"][1], w["size"][0], w["size"][2]], atol=1e-9)
            assert abs(math.remainder(got["yaw"][i] - q_yaw(w["rotation"]), 2 * math.pi)) < 1e-9
            assert np.allclose(got["std"][i, :3], w["translation_std"], atol=1e-12)
            assert np.allclose(got["std"][i, 6], w["yaw_std"], atol=1e-12)
            assert v.CLASSES[got["label"][i]] == w["detection_name"]
            assert got["score"][i] == pytest.approx(w["detection_score"], abs=1e-12)
            assert got["id"][i] == stable_id(w["instance_token"]) if "instance_token" in w else got["id"][i] == -1
            assert list(np.flatnonzero(got["sources"][i])) == w["v2x_sources"]
            compared += 1
    assert compared > 100


def q_yaw(q):
    w, x, y, z = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def test_velocities_cross_the_numpy_path():
    a = {
        "center": [[0.0, 0.0, 0.0], [30.0, 0.0, 0.0]],
        "size": [[4.5, 1.9, 1.6]] * 2,
        "yaw": [0.0, 0.0],
        "std": [[0.5] * 6 + [0.1]] * 2,
        "label": [0, 0],
        "score": [0.9, 0.8],
        "velocity": [[1.0, 0.0], [math.nan, math.nan]],
        "velocity_std": [[0.5, 0.5], [1.0, 1.0]],
    }
    b = dict(a, center=[[0.2, 0.0, 0.0], [60.0, 0.0, 0.0]], velocity=[[3.0, 0.0], [math.nan, math.nan]])
    out = v.fuse_arrays([a, b])
    order = np.argsort(out["center"][:, 0])
    # the pair at the origin: equal stds, so the plain means
    assert np.allclose(out["center"][order[0]], [0.1, 0.0, 0.0])
    assert np.allclose(out["velocity"][order[0]], [2.0, 0.0])
    assert out["sources"][order[0]].tolist() == [True, True]
    assert np.isnan(out["velocity"][order[1]]).all() and out["sources"][order[1]].tolist() == [True, False]
    assert len(order) == 3


def test_the_velocity_gate_reaches_both_paths():
    # Two boxes 0.2 m apart whose velocities differ by 4 m/s at 0.5 m/s stds: dv^2 = 16 / 0.5 = 32,
    # beyond csba-wls+vel's 13.816, so it keeps them apart where csba-wls+ fuses them.
    a = {
        "center": [[0.0, 0.0, 0.0]],
        "size": [[4.5, 1.9, 1.6]],
        "yaw": [0.0],
        "std": [[0.5] * 6 + [0.1]],
        "label": [0],
        "score": [0.9],
        "velocity": [[1.0, 0.0]],
        "velocity_std": [[0.5, 0.5]],
    }
    b = dict(a, center=[[0.2, 0.0, 0.0]], velocity=[[5.0, 0.0]])
    assert len(v.fuse_arrays([a, b], "csba-wls+")["center"]) == 1
    apart = v.fuse_arrays([a, b], "csba-wls+vel")
    assert sorted(apart["velocity"][:, 0].tolist()) == [1.0, 5.0]
    box = {"translation": [0.0, 0.0, 0.0], "size": [1.9, 4.5, 1.6], "rotation": [1.0, 0.0, 0.0, 0.0],
           "detection_name": "car", "detection_score": 0.9, "translation_std": [0.5] * 3,
           "size_std": [0.1] * 3, "yaw_std": 0.1, "velocity": [1.0, 0.0], "velocity_std": [0.5, 0.5]}
    other = dict(box, translation=[0.2, 0.0, 0.0], velocity=[5.0, 0.0])
    assert len(v.fuse([[box], [other]], "csba-wls+")) == 1
    assert len(v.fuse([[box], [other]], "csba-wls+vel")) == 2


def test_each_dict_has_its_boxs_keys_in_the_writers_order():
    base = {"size": [2.0, 4.5, 1.6], "rotation": [1.0, 0.0, 0.0, 0.0], "detection_name": "car",
            "detection_score": 0.7, "translation_std": [0.5, 0.5, 0.5], "size_std": [0.1, 0.1, 0.1],
            "yaw_std": 0.1}
    plain = lambda x: dict(base, translation=[x, 0.0, 1.0])
    moving = lambda x: dict(plain(x), velocity=[1.0, -0.0], velocity_std=[0.5, 0.5], instance_token=f"o{x}")
    short = ["translation", "size", "rotation", "velocity", "detection_name", "detection_score",
             "attribute_name", "translation_std", "size_std", "yaw_std", "v2x_sources"]
    full = short[:-1] + ["velocity_std", "instance_token", "v2x_sources"]
    # Boxes of two key sets in turn, far apart (each its own group): each dict has its own keys.
    out = v.fuse([[moving(0), plain(20), moving(40), plain(60)]], "csba-wls+")
    assert [list(d) for d in out] == [full, short, full, short]
    assert out[0]["velocity"] == [1.0, 0.0] and math.copysign(1, out[0]["velocity"][1]) == -1
    assert out[1]["velocity"] == [0.0, 0.0] and out[3]["translation"] == [60.0, 0.0, 1.0]
    assert out[2]["instance_token"] == "o40" and out[2]["translation_std"] == [0.5] * 3
    assert list(v.fuse([[plain(0)]], "csba-wls+")[0]) == short
    # Floats, float subclasses, numpy scalars and ints mixed in one list read alike.
    mixed = dict(plain(0), translation=[np.float64(3.0), np.float32(0.5), 1], size=[2.0, 4.5, np.float32(1.5)])
    got = v.fuse([[mixed]], "csba-wls+")[0]
    assert got["translation"] == [3.0, 0.5, 1.0] and got["size"] == [2.0, 4.5, 1.5]
    with pytest.raises(ValueError, match="field 'translation': element 1 is not a finite number"):
        v.fuse([[dict(plain(0), translation=[1.0, "x", 1.0])]])
    with pytest.raises(ValueError, match="field 'translation': element 2 is not a finite number"):
        v.fuse([[dict(plain(0), translation=[1.0, 2.0, math.inf])]])
    with pytest.raises(ValueError, match="field 'size': expected 3 numbers, found 2"):
        v.fuse([[dict(plain(0), size=[2.0, 4.5])]])
    with pytest.raises(ValueError, match="field 'size': expected an array of 3 numbers"):
        v.fuse([[dict(plain(0), size="big")]])
    assert v.fuse([[dict(plain(0), size=(2.0, 4.5, 1.6))]]) == v.fuse([[plain(0)]])


def test_keys_read_from_json_or_made_at_run_time_read_as_written_ones(untimed):
    import json

    boxes = load(untimed / "agent1.json")["results"]
    first = next(iter(boxes.values()))
    want = v.fuse([first, first[::-1]])
    again = json.loads(json.dumps([first, first[::-1]]))  # keys the decoder shares, not interned
    assert v.fuse(again) == want
    made = [[{"".join(k): x for k, x in b.items()} for b in a] for a in again]
    assert v.fuse(made) == want
    # Keys that name no field, of any type, are passed over.
    extra = [[dict(b, **{"translation_": 1, "x": None}) | {5: "five"} for b in a] for a in again]
    assert v.fuse(extra) == want
    # A missing field is missing whichever way the other keys were made.
    no_size = [{k: x for k, x in b.items() if k != "size"} for b in again[0]]
    with pytest.raises(ValueError, match=r"agents\[0\], box 0, field 'size': missing"):
        v.fuse([no_size])


def test_bad_input_says_what_is_wrong(untimed):
    boxes = load(untimed / "agent1.json")["results"]
    first = next(iter(boxes.values()))
    with pytest.raises(ValueError, match="unknown method 'csba'.*csba-wls"):
        v.fuse([first], "csba")
    bad = [dict(first[0], detection_score=1.5)]
    with pytest.raises(ValueError, match=r"agents\[1\], box 0, field 'detection_score'"):
        v.fuse([first, bad])
    no_std = [{k: x for k, x in first[0].items() if not k.endswith("_std")}]
    with pytest.raises(ValueError, match="field 'translation_std': missing"):
        v.fuse([no_std])
    assert len(v.fuse([no_std], default_std="mild")) == 1
    assert len(v.fuse([no_std], default_std=(0.5, 0.2, 5.0))) == 1
    with pytest.raises(ValueError, match="default_std"):
        v.fuse([no_std], default_std="tiny")
    good = arrays(first)
    with pytest.raises(ValueError, match=r"agents\[0\]\['std'\]: shape \(\d+, 6\), expected \(\d+, 7\)"):
        v.fuse_arrays([dict(good, std=good["std"][:, :6])])
    with pytest.raises(ValueError, match=r"agents\[0\]\['label'\]: row 0: a class code is 0 to 9"):
        v.fuse_arrays([dict(good, label=np.full(len(first), 12))])
    with pytest.raises(ValueError, match=r"agents\[0\]\['center'\]: row 0: coordinates must be finite"):
        v.fuse_arrays([dict(good, center=np.full((len(first), 3), np.inf))])
    with pytest.raises(ValueError, match=r"agents\[0\]\['yaw'\]: missing"):
        v.fuse_arrays([{k: x for k, x in good.items() if k != "yaw"}])
    with pytest.raises(ValueError, match=r"agents\[0\]\[.heading.\]: unknown key"):
        v.fuse_arrays([dict(good, heading=good["yaw"])])
    with pytest.raises(ValueError, match="window_ms: must be > 0"):
        v.fuse_results([load(untimed / "agent1.json")], window_ms=0)
    with pytest.raises(ValueError, match=r"confirm_hits: a tracking option \(track_files takes it\)"):
        v.fuse_results([load(untimed / "agent1.json")], confirm_hits=3)
    with pytest.raises(ValueError, match="unknown option 'compensate' .*compensation"):
        v.fuse_results([load(untimed / "agent1.json")], compensate=False)
    with pytest.raises(ValueError, match="min_score: 1.5 is not a chance"):
        v.fuse_results([load(untimed / "agent1.json")], detector=True, min_score=1.5)
    with pytest.raises(ValueError, match=r"documents\[0\], field 'meta.v2x_timestamps'"):
        v.fuse_results([load(untimed / "agent1.json")], learn_std=True)
    with pytest.raises(ValueError, match="cannot read"):
        v.fuse_files([untimed / "absent.json"], untimed / "out.json")
