"""Scores a tracking results file (as `v2x-fuser track` writes it) with the official nuScenes
devkit's tracking evaluation (its loader `load_prediction`, `create_tracks`' preparation,
`TrackingEvaluation` with the tracking_nips_2019 configuration) against nuScenes tables, without
the devkit's split, range and lidar-point filters, and prints every column as JSON, to compare
with `v2x-sim eval --tracking --format json` on the same files.

    pip install nuscenes-devkit motmetrics==1.4.0 pandas scikit-learn
    python devkit_tracking_check.py --dataroot DATAROOT --version VERSION TRACKS.json
"""

import argparse
import json
from collections import defaultdict

import numpy as np
from nuscenes import NuScenes
from nuscenes.eval.common.config import config_factory
from nuscenes.eval.common.loaders import load_prediction
from nuscenes.eval.common.utils import center_distance
from nuscenes.eval.tracking.algo import TrackingEvaluation
from nuscenes.eval.tracking.constants import AVG_METRIC_MAP, MOT_METRIC_MAP
from nuscenes.eval.tracking.data_classes import TrackingBox, TrackingMetricData, TrackingMetrics
from nuscenes.eval.tracking.loaders import interpolate_tracks
from nuscenes.eval.tracking.utils import category_to_tracking_name

from devkit_check import tables

COLUMNS = ["amota", "amotp", "mota", "motp", "ids", "frag", "tp", "fp", "fn"]


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
            scores = defaultdict(list)
            for bs in by_t.values():
                for b in bs:
                    scores[b.tracking_id].append(b.tracking_score)
            for bs in by_t.values():
                for b in bs:
                    b.tracking_score = float(np.mean(scores[b.tracking_id]))
        by_t = interpolate_tracks(by_t)
        tracks[scene["token"]] = defaultdict(list, sorted(by_t.items(), key=lambda kv: kv[0]))
    return tracks


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataroot", required=True)
    ap.add_argument("--version", required=True)
    ap.add_argument("results")
    args = ap.parse_args()
    nusc = NuScenes(version=args.version, dataroot=tables(args.dataroot, args.version), verbose=False)
    cfg = config_factory("tracking_nips_2019")  # as TrackingEval: this sets the tracking names
    TrackingMetricData.set_nelem(cfg.num_thresholds)
    pred, _ = load_prediction(args.results, 500, TrackingBox, verbose=False)  # the official loader
    gt = create_tracks(nusc, ground_truth(nusc), True)
    pred = create_tracks(nusc, {t: pred.boxes[t] for t in pred.sample_tokens}, False)
    metrics = TrackingMetrics(cfg)
    for class_name in cfg.class_names:  # as TrackingEval.evaluate, step 2
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
    out = {m: metrics.compute_metric(m) for m in COLUMNS}
    out["classes"] = {c: {m: metrics.label_metrics[m][c] for m in COLUMNS}
                      for c in cfg.class_names if not np.isnan(metrics.label_metrics["amota"][c])}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
