"""Scores a tracking results file (as `v2x-fuser track` writes it) with the official nuScenes
devkit's tracking evaluation (its loader `load_prediction`, `create_tracks`' preparation,
`TrackingEvaluation` with the tracking_nips_2019 configuration) against nuScenes tables, without
the devkit's split, range and lidar-point filters, and prints every column as JSON, to compare
with `v2x-sim eval --tracking --format json` on the same files.

    pip install nuscenes-devkit motmetrics==1.4.0 pandas scikit-learn
    python devkit_tracking_check.py --dataroot DATAROOT --version VERSION TRACKS.json
"""

import json
from collections import defaultdict

from nuscenes.eval.common.loaders import load_prediction
from nuscenes.eval.tracking.data_classes import TrackingBox
from nuscenes.eval.tracking.loaders import interpolate_tracks
from nuscenes.eval.tracking.utils import category_to_tracking_name

from devkit_check import open_dataset
from devkit_tracking_case import mean_track_scores, score, tracking_config


def ground_truth(nusc):
    """Every sample's boxes as the devkit's load_gt makes them, in sample_annotation.json order."""
    gt = {}
    for sample in nusc.sample:
        boxes = []
        for ann_token in sample["anns"]:
            ann = nusc.get("sample_annotation", ann_token)
            name = category_to_tracking_name(ann["category_name"])
            if name is None:
                continue
            boxes.append(TrackingBox(
                sample_token=sample["token"], translation=ann["translation"], size=ann["size"],
                rotation=ann["rotation"], velocity=nusc.box_velocity(ann_token)[:2],
                tracking_id=ann["instance_token"], tracking_name=name, tracking_score=-1.0))
        gt[sample["token"]] = boxes
    return gt


def create_tracks(nusc, boxes, gt):
    """The devkit's create_tracks without the split filter: per scene, per timestamp in time
    order, the boxes; predictions at their track's mean score; every track interpolated."""
    tracks = {}
    for scene in nusc.scene:
        by_t = defaultdict(list)
        token = scene["first_sample_token"]
        while token:
            sample = nusc.get("sample", token)
            by_t[sample["timestamp"]] = list(boxes.get(token, []))
            token = sample["next"]
        if not gt:
            mean_track_scores(by_t)
        by_t = interpolate_tracks(by_t)
        tracks[scene["token"]] = defaultdict(list, sorted(by_t.items(), key=lambda kv: kv[0]))
    return tracks


def main():
    args, nusc = open_dataset(__doc__)
    cfg = tracking_config()  # before loading: it sets the tracking names the loader accepts
    pred, _ = load_prediction(args.results, 500, TrackingBox, verbose=False)  # the official loader
    gt = create_tracks(nusc, ground_truth(nusc), True)
    pred = create_tracks(nusc, {t: pred.boxes[t] for t in pred.sample_tokens}, False)
    out = score(cfg, gt, pred)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
