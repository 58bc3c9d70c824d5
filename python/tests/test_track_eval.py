"""The tracker and the evaluation from Python equal `v2x-fuser track` and `v2x-sim eval`."""

import json
import logging

import pytest

import v2x_fusion as v
from conftest import REPO, TOWN, load, run

AGENTS = ("agent1.json", "agent2.json")
TOWN_FLAGS = ("--seconds", TOWN["seconds"], "--hz", TOWN["hz"])


@pytest.fixture(scope="module")
def cli(generated, tmp_path_factory):
    """The CLI's fused and tracking files of the generated agents."""
    out = tmp_path_factory.mktemp("cli")
    paths = [generated / a for a in AGENTS]
    run("v2x-fuser", "fuse", "-o", out / "fused.json", *paths)
    run("v2x-fuser", "track", "-o", out / "tracks.json", *paths)
    return out


def test_track_files_equals_the_cli(generated, cli, tmp_path):
    report = v.track_files([generated / a for a in AGENTS], tmp_path / "tracks.json")
    assert load(tmp_path / "tracks.json") == load(cli / "tracks.json")
    assert report["windows"] == 30 and report["stats"]["births"] > 10


def test_the_tracker_stepped_over_the_fused_windows_equals_the_cli(cli):
    fused = load(cli / "fused.json")
    times = fused["meta"]["v2x_timestamps"]
    expected = load(cli / "tracks.json")["results"]
    tracker = v.Tracker()
    boxes = 0
    for sample in sorted(fused["results"], key=lambda s: times[s]):
        got = tracker.step(times[sample], fused["results"][sample])
        want = expected[sample]
        assert [b["tracking_id"] for b in got] == [b["tracking_id"] for b in want], sample
        for g, w in zip(got, want):
            assert g["tracking_name"] == w["tracking_name"] and g["detection_name"] == w["detection_name"]
            for key in ("translation", "size", "rotation", "velocity", "translation_std"):
                assert g[key] == pytest.approx(w[key], abs=1e-9), (sample, key)
            assert g["tracking_score"] == pytest.approx(w["tracking_score"], abs=1e-12)
            boxes += 1
    assert boxes > 200
    assert tracker.stats["births"] > 10
    tracker.reset()
    assert tracker.stats["live"] == 0


def test_the_tracker_checks_its_input():
    with pytest.raises(ValueError, match="confirm_hits: must be at least 1"):
        v.Tracker(confirm_hits=0)
    with pytest.raises(ValueError, match="unknown association 'hard'"):
        v.Tracker(association="hard")
    with pytest.raises(ValueError, match="box 0, field 'size'"):
        v.Tracker(default_std="mild").step(0, [{"translation": [0, 0, 0], "size": [1, 1],
                                                "rotation": [1, 0, 0, 0], "detection_name": "car",
                                                "detection_score": 0.5}])


def cli_eval(*args):
    return json.loads(run("v2x-sim", "eval", "--format", "json", *TOWN_FLAGS, *args).stdout)


@pytest.fixture(scope="module")
def town():
    return v.GroundTruth.town(**TOWN)


def test_evaluate_equals_the_cli(cli, town, caplog):
    assert len(town) == 30
    with caplog.at_level(logging.INFO, logger="v2x_fusion"):
        by_id = v.evaluate(cli / "fused.json", town)
    assert "scored 30 samples" in caplog.text
    assert by_id == cli_eval(cli / "fused.json")
    assert 0.9 < by_id["precision"] <= 1.0
    by_distance = v.evaluate(cli / "fused.json", town, match="distance", classes=["car", "pedestrian"])
    assert by_distance == cli_eval("--match", "distance", "--classes", "car,pedestrian", cli / "fused.json")
    assert v.evaluate(load(cli / "fused.json"), town) == by_id
    tracking = v.evaluate(cli / "tracks.json", town, tracking=True)
    assert tracking == cli_eval("--tracking", cli / "tracks.json")
    assert 0.5 < tracking["AMOTA"] <= 1.0


def test_evaluate_says_what_is_wrong(cli, town):
    with pytest.raises(ValueError, match="match 'iou'"):
        v.evaluate(cli / "fused.json", town, match="iou")
    with pytest.raises(ValueError, match="not in the ground truth"):
        v.evaluate(cli / "fused.json", v.GroundTruth.town(seconds=2, hz=10))
    with pytest.raises(ValueError, match="unknown class 'tank'"):
        v.evaluate(cli / "fused.json", town, classes=["tank"])
    with pytest.raises(ValueError, match="tracking_id"):
        v.evaluate(cli / "fused.json", town, tracking=True)
    with pytest.raises(ValueError, match="hz > 0"):
        v.GroundTruth.town(hz=0)
    with pytest.raises(ValueError):
        v.GroundTruth.nuscenes("/nonexistent", "v1.0-mini")


def test_through_the_tracks_equals_the_cli(generated, tmp_path):
    paths = [generated / a for a in AGENTS]
    run("v2x-fuser", "track", "--association", "guided", "-o", tmp_path / "cli.json", *paths)
    report = v.track_files(paths, tmp_path / "py.json", association="guided")
    assert load(tmp_path / "py.json") == load(tmp_path / "cli.json")
    assert report["stats"]["births"] > 10
    # The tracker stepped with the agents' own boxes, window by window (the generated agents
    # capture together, so each window holds one frame of each, as captured).
    docs = [load(p) for p in paths]
    times = docs[0]["meta"]["v2x_timestamps"]
    expected = load(tmp_path / "cli.json")["results"]
    tracker = v.Tracker()
    for sample in sorted(docs[0]["results"], key=lambda s: times[s]):
        got = tracker.step_agents(times[sample], [d["results"][sample] for d in docs])
        want = expected[sample]
        assert [b["tracking_id"] for b in got] == [b["tracking_id"] for b in want], sample
        for g, w in zip(got, want):
            assert g["translation"] == pytest.approx(w["translation"], abs=1e-9)
    with pytest.raises(ValueError, match="association: a tracking option"):
        v.fuse_files(paths, tmp_path / "x.json", association="guided")


def test_kitti_folders_track_as_the_cli_tracks_them(tmp_path):
    """A detector's KITTI folders (the V2V4Real-layout fixture's two cars): the same rows as
    `v2x-fuser track --output-format kitti`, a track shown from its second box."""
    cars = REPO / "truth/fixtures/v2v4real/AB3DMOT/data/v2v4real/detection/multi_sensor_differentiable_kalman_filter_Car_train"
    run("v2x-fuser", "track", "--output-format", "kitti", "--output", tmp_path / "cli", cars / "ego", cars / "1")
    v.track_files([cars / "ego", cars / "1"], tmp_path / "py")
    for seq in ("0000.txt", "0001.txt"):
        assert (tmp_path / "py" / seq).read_text() == (tmp_path / "cli" / seq).read_text()
    rows = (tmp_path / "py" / "0000.txt").read_text().splitlines()
    assert not [r for r in rows if r.startswith("0 ")]
    assert len([r for r in rows if r.startswith("1 ")]) == 2


def test_a_detectors_results_files_fuse_and_track_as_the_cli_does(tmp_path):
    """`v2x-sim gen --dataset v2v4real`'s files with `detector=True`: the same files as
    `v2x-fuser fuse --detector` and `track --detector`; without it the tail is kept."""
    root = REPO / "truth/fixtures/v2v4real/AB3DMOT"
    run("v2x-sim", "gen", "--dataset", "v2v4real", "--dataroot", root, "--out", tmp_path / "cars")
    paths = [tmp_path / "cars" / a for a in AGENTS]
    run("v2x-fuser", "fuse", "--detector", "-o", tmp_path / "cli.json", *paths)
    run("v2x-fuser", "track", "--detector", "-o", tmp_path / "cli_tracks.json", *paths)
    v.fuse_files(paths, tmp_path / "py.json", detector=True)
    v.track_files(paths, tmp_path / "py_tracks.json", detector=True)
    assert load(tmp_path / "py.json") == load(tmp_path / "cli.json")
    assert load(tmp_path / "py_tracks.json") == load(tmp_path / "cli_tracks.json")
    scores = sorted(b["detection_score"] for boxes in load(tmp_path / "py.json")["results"].values() for b in boxes)
    assert min(scores) >= 0.2 and len(scores) == 8
    # The members' noisy-OR and a cut at 0.4, as the CLI's flags give them.
    v.fuse_files(paths, tmp_path / "noisy.json", detector=True, existence_model="noisy-or", min_score=0.4)
    run("v2x-fuser", "fuse", "--detector", "--existence-model", "noisy-or", "--min-score", "0.4", "-o", tmp_path / "noisy_cli.json", *paths)
    assert load(tmp_path / "noisy.json") == load(tmp_path / "noisy_cli.json")
    noisy = sorted(b["detection_score"] for boxes in load(tmp_path / "noisy.json")["results"].values() for b in boxes)
    assert len(noisy) == 7 and abs(noisy[-1] - 0.96) < 1e-9
    with pytest.raises(ValueError, match="min_score: 1.5 is not a chance"):
        v.fuse_files(paths, tmp_path / "x.json", detector=True, min_score=1.5)
    v.fuse_files(paths, tmp_path / "kept.json")
    kept = [b for boxes in load(tmp_path / "kept.json")["results"].values() for b in boxes]
    assert len(kept) > len(scores)
    with pytest.raises(ValueError, match="detector"):
        v.fuse_files(paths, tmp_path / "x.json", detector=True, default_std="mild")


def test_each_association_equals_the_cli(cli, generated, tmp_path):
    """``association="assignment"``: the same file as `v2x-fuser track --association assignment`,
    and the same ids window by window from ``Tracker(association="assignment")`` fed the fused
    boxes; ``association="soft"`` is the default's file."""
    paths = [generated / a for a in AGENTS]
    v.track_files(paths, tmp_path / "soft.json", association="soft")
    assert load(tmp_path / "soft.json") == load(cli / "tracks.json")
    run("v2x-fuser", "track", "--association", "assignment", "-o", tmp_path / "cli.json", *paths)
    v.track_files(paths, tmp_path / "py.json", association="assignment")
    assert load(tmp_path / "py.json") == load(tmp_path / "cli.json")
    assert load(cli / "tracks.json") != load(tmp_path / "cli.json")
    fused = load(cli / "fused.json")
    times = fused["meta"]["v2x_timestamps"]
    expected = load(tmp_path / "cli.json")["results"]
    tracker = v.Tracker(association="assignment")
    for sample in sorted(fused["results"], key=lambda s: times[s]):
        got = tracker.step(times[sample], fused["results"][sample])
        want = expected[sample]
        assert [b["tracking_id"] for b in got] == [b["tracking_id"] for b in want], sample
        for g, w in zip(got, want):
            assert g["translation"] == pytest.approx(w["translation"], abs=1e-9), sample
    with pytest.raises(ValueError, match="unknown variant `both`"):
        v.track_files(paths, tmp_path / "x.json", association="both")
    with pytest.raises(ValueError, match="unknown option 'soft'"):
        v.track_files(paths, tmp_path / "x.json", soft=True)
