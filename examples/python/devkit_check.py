"""Scores a results file with the official nuScenes devkit's detection algorithms (accumulate,
calc_ap, calc_tp, DetectionMetrics with the detection_cvpr_2019 configuration) against nuScenes
tables, without the devkit's range and lidar-point filters, and prints the figures as JSON, to
compare with `v2x-sim eval --match distance --format json` on the same files.

    pip install nuscenes-devkit
    python devkit_check.py --dataroot DATAROOT --version VERSION RESULTS.json
"""

import argparse
import json
import os
import tempfile

import numpy as np
from nuscenes import NuScenes
from nuscenes.eval.common.config import config_factory
from nuscenes.eval.common.data_classes import EvalBoxes
from nuscenes.eval.common.utils import center_distance
from nuscenes.eval.detection.algo import accumulate, calc_ap, calc_tp
from nuscenes.eval.detection.constants import TP_METRICS
from nuscenes.eval.detection.data_classes import DetectionBox, DetectionMetricDataList, DetectionMetrics
from nuscenes.eval.detection.utils import category_to_detection_name


def ground_truth(nusc, samples):
    gt = EvalBoxes()
    for token in samples:
        boxes = []
        for ann_token in nusc.get("sample", token)["anns"]:
            ann = nusc.get("sample_annotation", ann_token)
            name = category_to_detection_name(ann["category_name"])
            if name is None:
                continue
            boxes.append(
                DetectionBox(
                    sample_token=token,
                    translation=ann["translation"],
                    size=ann["size"],
                    rotation=ann["rotation"],
                    velocity=nusc.box_velocity(ann_token)[:2],
                    detection_name=name,
                    attribute_name="",
                )
            )
        gt.add_boxes(token, boxes)
    return gt


def tables(dataroot, version):
    """The dataroot, or a temporary copy of its tables with a placeholder map table when it has
    none (the devkit insists on one; detection evaluation does not use it)."""
    src = os.path.join(dataroot, version)
    if os.path.exists(os.path.join(src, "map.json")):
        return dataroot
    root = tempfile.mkdtemp(prefix="devkit-")
    os.makedirs(os.path.join(root, version))
    for name in os.listdir(src):
        os.symlink(os.path.abspath(os.path.join(src, name)), os.path.join(root, version, name))
    logs = [log["token"] for log in json.load(open(os.path.join(src, "log.json")))]
    with open(os.path.join(root, version, "map.json"), "w") as f:
        json.dump([{"token": "map", "log_tokens": logs, "category": "", "filename": ""}], f)
    return root


def open_dataset(doc):
    """The command line (--dataroot, --version, a results file) and the nuScenes tables it names."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("--dataroot", required=True)
    ap.add_argument("--version", required=True)
    ap.add_argument("results")
    args = ap.parse_args()
    return args, NuScenes(version=args.version, dataroot=tables(args.dataroot, args.version), verbose=False)


def main():
    args, nusc = open_dataset(__doc__)
    results = json.load(open(args.results))["results"]
    pred = EvalBoxes.deserialize(results, DetectionBox)
    # Every annotated sample is scored; those the file lacks have no predictions.
    samples = [s["token"] for s in nusc.sample]
    for s in samples:
        if s not in pred.sample_tokens:
            pred.add_boxes(s, [])
    gt = ground_truth(nusc, samples)
    cfg = config_factory("detection_cvpr_2019")
    data = DetectionMetricDataList()
    for name in cfg.class_names:
        for th in cfg.dist_ths:
            data.set(name, th, accumulate(gt, pred, name, center_distance, th))
    metrics = DetectionMetrics(cfg)
    for name in cfg.class_names:
        for th in cfg.dist_ths:
            metrics.add_label_ap(name, th, calc_ap(data[(name, th)], cfg.min_recall, cfg.min_precision))
        for metric in TP_METRICS:
            md = data[(name, cfg.dist_th_tp)]
            if name == "traffic_cone" and metric in ["attr_err", "vel_err", "orient_err"]:
                tp = np.nan
            elif name == "barrier" and metric in ["attr_err", "vel_err"]:
                tp = np.nan
            else:
                tp = calc_tp(md, cfg.min_recall, metric)
            metrics.add_label_tp(name, metric, tp)
    s = metrics.serialize()
    out = {"mAP": s["mean_ap"], "NDS": s["nd_score"]}
    out.update({f"m{k}": v for k, v in zip(["ATE", "ASE", "AOE", "AVE", "AAE"], [s["tp_errors"][m] for m in TP_METRICS])})
    out["AP"] = s["label_aps"]
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
