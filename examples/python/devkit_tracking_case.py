"""Makes sim/tests/data/tracking_devkit_case.json: a random tracking case (each frame's objects in
shuffled order), a crafted scene where two objects compete for one track, and the figures the
nuScenes devkit's tracking evaluation gives for it (the Rust test sim/tests/sim/tracking_devkit.rs
checks v2x-sim's metrics against them, every column).

    python -m venv venv && venv/bin/pip install nuscenes-devkit motmetrics pandas scikit-learn
    venv/bin/python examples/python/devkit_tracking_case.py sim/tests/data/tracking_devkit_case.json
"""
import json
import sys
from collections import defaultdict

import numpy as np
from nuscenes.eval.common.config import config_factory
from nuscenes.eval.common.utils import center_distance
from nuscenes.eval.tracking.algo import TrackingEvaluation
from nuscenes.eval.tracking.constants import AVG_METRIC_MAP, MOT_METRIC_MAP
from nuscenes.eval.tracking.data_classes import TrackingBox, TrackingMetricData, TrackingMetrics
from nuscenes.eval.tracking.loaders import interpolate_tracks

CLASSES = ["car", "pedestrian", "truck", "traffic_cone"]


def make_case(rng):
    """Three scenes of moving objects, and a noisy tracker's output with misses, gaps,
    ghosts and swapped ids."""
    scenes = []
    next_gt = 1
    for s in range(3):
        n_frames = int(rng.integers(12, 20))
        objects = []
        for _ in range(int(rng.integers(6, 12))):
            objects.append({
                "id": next_gt,
                "class": CLASSES[int(rng.integers(0, len(CLASSES)))],
                "p0": rng.uniform(-40, 40, 2),
                "v": rng.normal(0, 3, 2),
                "first": int(rng.integers(0, n_frames // 2)),
                "last": int(rng.integers(n_frames // 2, n_frames)),
            })
            next_gt += 1
        track_of = {o["id"]: f"t{o['id']}" for o in objects}
        frames = []
        for k in range(n_frames):
            t_us = 1_000_000 * s * 100 + 500_000 * k + int(rng.integers(0, 20_000))
            gt, boxes = [], []
            for o in objects:
                if not (o["first"] <= k <= o["last"]):
                    continue
                xy = o["p0"] + o["v"] * 0.5 * k
                if rng.random() < 0.05 and k not in (o["first"], o["last"]):
                    pass  # an unannotated frame: the devkit fills it in
                else:
                    gt.append({"id": o["id"], "class": o["class"], "xy": list(map(float, xy))})
                if rng.random() < 0.08:
                    track_of[o["id"]] = f"t{o['id']}-{k}"  # a new id for the same object
                if rng.random() < 0.15:
                    continue  # missed
                cls = o["class"] if rng.random() > 0.05 else CLASSES[int(rng.integers(0, 3))]
                boxes.append({
                    "track": track_of[o["id"]],
                    "class": cls,
                    "xy": list(map(float, xy + rng.normal(0, 0.8, 2))),
                    "score": float(rng.uniform(0.2, 1.0)),
                })
            for g in range(int(rng.poisson(1.0))):
                boxes.append({
                    "track": f"ghost{s}-{k}-{g}",
                    "class": CLASSES[int(rng.integers(0, 3))],
                    "xy": list(map(float, rng.uniform(-40, 40, 2))),
                    "score": float(rng.uniform(0.1, 0.7)),
                })
            rng.shuffle(gt)  # the devkit walks a frame's objects in file order, not by id
            frames.append({"t_us": t_us, "gt": gt, "boxes": boxes})
        scenes.append(frames)
    scenes.append(competing_scene())
    return scenes


def competing_scene():
    """Two cars, B listed before A, that both last matched track T and are both near it: in
    frame 2 as annotated, in frame 3 as filled in by interpolation (appended in the order the
    tracks first appear). motmetrics keeps T for the object listed first."""
    t0 = 1_000_000 * 300
    a = lambda x: {"id": 1001, "class": "car", "xy": [x, 0.0]}
    b = lambda x: {"id": 1002, "class": "car", "xy": [x, 0.0]}
    hyp = lambda track, x: {"track": track, "class": "car", "xy": [x, 0.0], "score": 0.9}
    frames = [
        ([b(3.0), a(0.0)], [hyp("T", 0.1), hyp("U", 3.1)]),  # A-T, B-U
        ([b(2.0), a(0.0)], [hyp("T", 2.2)]),  # T leaves A for B: a switch; last[A] = last[B] = T
        ([b(1.5), a(0.5)], [hyp("T", 1.0), hyp("V", 0.4)]),  # both near T: B, listed first, keeps it
        ([], [hyp("T", 1.2), hyp("V", 0.9)]),  # neither annotated: both filled in, B first
        ([b(2.0), a(1.0)], [hyp("T", 2.1), hyp("V", 1.1)]),
    ]
    return [{"t_us": t0 + 500_000 * k, "gt": gt, "boxes": boxes} for k, (gt, boxes) in enumerate(frames)]


def to_tracks(scenes, gt):
    tracks = {}
    for s, frames in enumerate(scenes):
        by_t = defaultdict(list)
        for f in frames:
            by_t[f["t_us"]] = []
            for b in (f["gt"] if gt else f["boxes"]):
                name = b["class"]
                if name == "traffic_cone":
                    continue  # not a tracking class: the devkit's loader drops it
                by_t[f["t_us"]].append(TrackingBox(
                    sample_token=f"s{s}-{f['t_us']}",
                    translation=(b["xy"][0], b["xy"][1], 0.0),
                    size=(1.0, 1.0, 1.0), rotation=(1.0, 0.0, 0.0, 0.0),
                    tracking_id=str(b["id"]) if gt else b["track"],
                    tracking_name=name,
                    tracking_score=-1.0 if gt else b["score"]))
        if not gt:
            mean_track_scores(by_t)
        tracks[f"scene{s}"] = interpolate_tracks(by_t)
        tracks[f"scene{s}"] = defaultdict(list, sorted(tracks[f"scene{s}"].items()))
    return tracks


def mean_track_scores(by_t):
    """As the devkit's create_tracks: each box of a track gets the track's mean score."""
    scores = defaultdict(list)
    for boxes in by_t.values():
        for box in boxes:
            scores[box.tracking_id].append(box.tracking_score)
    for boxes in by_t.values():
        for box in boxes:
            box.tracking_score = float(np.mean(scores[box.tracking_id]))


def tracking_config():
    """The tracking_nips_2019 configuration, set up as TrackingEval sets it (this also sets the
    tracking names the devkit's loader accepts)."""
    cfg = config_factory("tracking_nips_2019")
    TrackingMetricData.set_nelem(cfg.num_thresholds)
    return cfg


def score(cfg, gt, pred):
    """Every column of the devkit's tracking evaluation, overall and per class, from tracks as
    create_tracks makes them (as TrackingEval.evaluate, step 2)."""
    metrics = TrackingMetrics(cfg)
    for class_name in cfg.class_names:
        md = TrackingEvaluation(gt, pred, class_name, center_distance, cfg.dist_th_tp, cfg.min_recall,
                                cfg.num_thresholds, cfg.metric_worst, verbose=False).accumulate()
        best = None if np.all(np.isnan(md.mota)) else np.nanargmax(md.mota)
        if best is not None:
            for name in MOT_METRIC_MAP.values():
                if name:
                    metrics.add_label_metric(name, class_name, md.get_metric(name)[best])
        for name in AVG_METRIC_MAP.keys():
            values = np.array(md.get_metric(AVG_METRIC_MAP[name]))
            if np.all(np.isnan(values)):
                value = np.nan
            else:
                values[np.isnan(values)] = cfg.metric_worst[name]
                value = float(np.nanmean(values))
            metrics.add_label_metric(name, class_name, value)
    columns = ["amota", "amotp", "mota", "motp", "ids", "frag", "tp", "fp", "fn"]
    out = {m: metrics.compute_metric(m) for m in columns}
    out["classes"] = {c: {m: metrics.label_metrics[m][c] for m in columns[:6]}
                      for c in cfg.class_names if not np.isnan(metrics.label_metrics["amota"][c])}
    return out


def evaluate(scenes):
    cfg = tracking_config()
    return score(cfg, to_tracks(scenes, True), to_tracks(scenes, False))


def main():
    rng = np.random.default_rng(7)
    scenes = make_case(rng)
    expected = evaluate(scenes)
    json.dump({"scenes": scenes, "devkit": expected}, open(sys.argv[1], "w"), separators=(",", ":"))
    print(json.dumps(expected, indent=1))


if __name__ == "__main__":
    main()
