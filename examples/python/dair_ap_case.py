"""Scores hand-made cases with the official DAIR-V2X evaluation functions and writes what they
return, for `eval/src/dair_eval/tests.rs` to compare against.

Usage: python3 dair_ap_case.py DAIR_V2X_CHECKOUT OUT.json
(DAIR_V2X_CHECKOUT is a clone of the official DAIR-V2X repository; needs numpy and scipy.)
Boxes are written as centre, size (l, w, h), yaw and class in the vehicle's LiDAR frame; the
ground truth's corners come from the official get_3d_8points, the predictions' are put in
mmdetection3d's corner order, as the official pipeline receives them.
"""
import json
import math
import random
import sys

sys.path.insert(0, sys.argv[1] + "/v2x")
sys.path.insert(0, sys.argv[1] + "/v2x/v2x_utils")
import numpy as np  # noqa: E402
from config import name2id  # noqa: E402
from eval_utils import Evaluator, box3d_iou, perm_label, perm_pred  # noqa: E402
from transformation_utils import get_3d_8points  # noqa: E402

PERM_PRED = [0, 4, 7, 3, 1, 5, 6, 2]
PERM_LABEL = [3, 2, 1, 0, 7, 6, 5, 4]


def label_corners(b):
    (x, y, z), (l, w, h), yaw = b["center"], b["size"], b["yaw"]
    return np.array(get_3d_8points([l, w, h], yaw, [x, y, z - h / 2]))


def pred_corners(b):
    c = label_corners(b)
    mm = np.zeros((8, 3))
    for k in range(8):
        mm[PERM_PRED[k]] = c[PERM_LABEL[k]]
    return mm


def annos(boxes, corners):
    if not boxes:
        return {"boxes_3d": np.zeros((0, 8, 3)), "labels_3d": np.array([]), "scores_3d": np.array([])}
    return {
        "boxes_3d": np.array([corners(b) for b in boxes]),
        "labels_3d": np.array([name2id[b["class"]] for b in boxes]),
        "scores_3d": np.array([b.get("score", 1.0) for b in boxes]),
    }


def box(rng, cls, near=None, score=None):
    if near is None:
        c = [rng.uniform(0, 60), rng.uniform(-30, 30), rng.uniform(-1.5, -0.5)]
        size = {"car": [4.5, 1.9, 1.6], "truck": [8, 2.6, 3.2], "pedestrian": [0.6, 0.6, 1.7], "cyclist": [1.8, 0.6, 1.6]}[cls]
        size = [s * rng.uniform(0.9, 1.1) for s in size]
        yaw = rng.uniform(-math.pi, math.pi)
    else:
        c = [near["center"][i] + rng.gauss(0, [0.3, 0.3, 0.1][i]) for i in range(3)]
        size = [s * rng.uniform(0.85, 1.15) for s in near["size"]]
        yaw = near["yaw"] + rng.gauss(0, 0.15)
    b = {"class": cls, "center": c, "size": size, "yaw": yaw}
    if score is not None:
        b["score"] = score
    return b


def main():
    rng = random.Random(7)
    frames = []
    for f in range(12):
        gt = [box(rng, rng.choice(["car", "car", "truck", "pedestrian", "cyclist"])) for _ in range(rng.randint(0, 7))]
        preds = []
        for g in gt:
            if rng.random() < 0.8:
                preds.append(box(rng, g["class"], near=g, score=round(rng.random(), 2)))
        for _ in range(rng.randint(0, 3)):
            preds.append(box(rng, rng.choice(["car", "pedestrian"]), score=round(rng.random(), 2)))
        # a duplicate of a matched box, and a tie in score
        if preds:
            d = dict(preds[0])
            d["score"] = preds[0]["score"]
            preds.append(d)
        frames.append({"gt": gt, "preds": preds})
    # Exact cases: identical boxes, half overlap, no overlap, a vertical offset.
    frames.append({
        "gt": [{"class": "car", "center": [10, 0, -1], "size": [4, 2, 1.5], "yaw": 0.0},
               {"class": "car", "center": [20, 5, -1], "size": [4, 2, 1.5], "yaw": 0.3}],
        "preds": [{"class": "car", "center": [10, 0, -1], "size": [4, 2, 1.5], "yaw": 0.0, "score": 0.9},
                  {"class": "car", "center": [22, 5, -1], "size": [4, 2, 1.5], "yaw": 0.0, "score": 0.8},
                  {"class": "car", "center": [20, 5, -0.25], "size": [4, 2, 1.5], "yaw": 0.3, "score": 0.7},
                  {"class": "car", "center": [40, -5, -1], "size": [4, 2, 1.5], "yaw": 1.0, "score": 0.95}],
    })
    ious = []
    for fr in frames:
        for g in fr["gt"]:
            for p in fr["preds"]:
                i3, i2 = box3d_iou(label_corners(g)[perm_label], pred_corners(p)[perm_pred])
                ious.append({"gt": g, "pred": p, "iou_3d": float(i3), "iou_bev": float(i2)})
    ev = Evaluator(["car", "pedestrian", "cyclist"])
    for fr in frames:
        ev.add_frame(annos(fr["preds"], pred_corners), annos(fr["gt"], label_corners))
    from eval_utils import compute_ap, iou_threshold_dict  # noqa: E402
    aps = {}
    for view in ["3d", "bev"]:
        for cls in ["car", "pedestrian", "cyclist"]:
            for t in iou_threshold_dict[cls]:
                aps[f"{view} {cls}@{t}"] = float(compute_ap(ev.all_preds[view][cls][t], ev.gt_num[cls][t]))
    with open(sys.argv[2], "w") as f:
        json.dump({"frames": frames, "ious": ious, "ap": aps}, f)
        f.write("\n")


if __name__ == "__main__":
    main()
