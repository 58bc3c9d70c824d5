"""Time per fusion step through Python at 2 agents x 80 boxes: the numpy path (fuse_arrays), the
dict path (fuse), and a straightforward numpy/scipy CSBA-3D + WLS-3D for comparison; with
--criterion, the Rust criterion figure of the same step in the same run.

    python python/benchmarks/bench_fuse.py [--criterion] [--noise mild]
    python python/benchmarks/bench_fuse.py --size 64x200
    python python/benchmarks/bench_fuse.py --calls 300 [--from-json]   # under a profiler

Scenes follow the Rust benches' (fuser/benches/common): 80 objects within 50 m, the same class
mix, one noisy copy per agent at the noise profile's stds; drawn with numpy's generator, so they
are the same distribution, not the same boxes. Every figure is a median over repeats.
"""

import argparse
import json
import os

# One BLAS thread: an idle pool spins on the other core and slows every timing on two cores.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import math
import pathlib
import re
import subprocess
import timeit

import numpy as np
from scipy.optimize import linear_sum_assignment

import v2x_fusion as v

REPO = pathlib.Path(__file__).resolve().parents[2]
MIX = ["car"] * 4 + ["pedestrian"] * 2 + ["barrier", "traffic_cone", "truck", "bicycle"]
TYPICAL = {
    "car": (4.6, 1.95, 1.75),
    "pedestrian": (0.75, 0.67, 1.75),
    "barrier": (0.5, 2.5, 1.0),
    "traffic_cone": (0.4, 0.4, 1.0),
    "truck": (7.0, 2.5, 3.0),
    "bicycle": (1.75, 0.6, 1.3),
}
#: Position, size (m) and yaw (deg) stds of the noise profiles.
PROFILES = {"mild": (0.5, 0.1, 5.0), "moderate": (1.5, 0.5, 20.0), "large": (3.0, 1.0, 60.0)}


def scene(n, agents, noise, seed):
    """One dict of arrays per agent (fuse_arrays' form)."""
    rng = np.random.default_rng(seed)
    pos, size_std, yaw_deg = PROFILES[noise]
    radius = 50.0 * math.sqrt(n / 80)
    classes = [MIX[i] for i in rng.integers(0, len(MIX), n)]
    r = radius * np.sqrt(rng.random(n))
    a = rng.random(n) * 2 * math.pi
    center = np.stack([r * np.cos(a), r * np.sin(a), np.ones(n)], axis=1)
    size = np.array([TYPICAL[c] for c in classes])
    yaw = rng.uniform(-3.1, 3.1, n)
    std = np.tile([pos] * 3 + [size_std] * 3 + [math.radians(yaw_deg)], (n, 1))
    out = []
    for _ in range(agents):
        yaw_k = yaw + std[:, 6] * rng.standard_normal(n)
        out.append(
            {
                "center": center + pos * rng.standard_normal((n, 3)),
                "size": np.maximum(size + size_std * rng.standard_normal((n, 3)), 0.05),
                "yaw": np.arctan2(np.sin(yaw_k), np.cos(yaw_k)),
                "std": std.copy(),
                "label": np.array([v.CLASSES.index(c) for c in classes]),
                "score": np.full(n, 0.8),
            }
        )
    return out


def as_boxes(agent):
    """An agent's arrays as results-file dicts (the dict path's input)."""
    boxes = []
    for i in range(len(agent["score"])):
        l, w, h = agent["size"][i].tolist()
        s = agent["std"][i].tolist()
        half = agent["yaw"][i] / 2
        boxes.append(
            {
                "translation": agent["center"][i].tolist(),
                "size": [w, l, h],
                "rotation": [math.cos(half), 0.0, 0.0, math.sin(half)],
                "detection_name": v.CLASSES[agent["label"][i]],
                "detection_score": float(agent["score"][i]),
                "translation_std": s[:3],
                "size_std": [s[4], s[3], s[5]],
                "yaw_std": s[6],
            }
        )
    return boxes


def pair_costs(a, b):
    """CSBA-3D's cost matrix between two lists of boxes as the paper prints it: dimension, centre
    and orientation scores weighted 0.2 / 0.5 / 0.3, and which pairs are eligible (same class,
    centre within 6 x the noisier position std)."""
    same = a["label"][:, None] == b["label"][None, :]
    va, vb = np.prod(a["size"], axis=1), np.prod(b["size"], axis=1)
    sva = va * np.sqrt(np.sum((a["std"][:, 3:6] / a["size"]) ** 2, axis=1))
    svb = vb * np.sqrt(np.sum((b["std"][:, 3:6] / b["size"]) ** 2, axis=1))
    ratio = va[:, None] / vb[None, :]
    sr = ratio * np.sqrt((sva / va)[:, None] ** 2 + (svb / vb)[None, :] ** 2)
    ds = np.exp(-np.minimum(((ratio - 1) / sr) ** 2, ((1 / ratio - 1) / sr) ** 2) / 2)
    var = a["std"][:, None, :3] ** 2 + b["std"][None, :, :3] ** 2
    dp = a["center"][:, None, :] - b["center"][None, :, :]
    dm = np.sqrt(np.sum(dp * dp / var, axis=2))
    lam = 6 * np.maximum(a["std"][:, None, :3].max(axis=2), b["std"][None, :, :3].max(axis=2))
    cs = np.clip(1 - dm / lam, 0, 1)
    alpha_a, alpha_b = a["yaw"] / a["std"][:, 6], b["yaw"] / b["std"][:, 6]
    os_ = (1 + np.cos(alpha_a[:, None] - alpha_b[None, :])) / 2
    cost = 0.2 * (1 - ds) + 0.5 * (1 - cs) + 0.3 * (1 - os_)
    return cost, same & (cs > 0)


def wls(members):
    """WLS-3D of one group: inverse-variance weighted centre, size and yaw (each yaw unwrapped
    against the surest member's), and the fused stds."""
    y = np.array([np.concatenate([m["center"], m["size"], [m["yaw"]]]) for m in members])
    w = 1 / np.array([m["std"] for m in members]) ** 2
    ref = y[np.argmax(w[:, 6]), 6]
    y[:, 6] = ref + np.arctan2(np.sin(y[:, 6] - ref), np.cos(y[:, 6] - ref))
    z = np.sum(w * y, axis=0) / np.sum(w, axis=0)
    z[6] = np.arctan2(np.sin(z[6]), np.cos(z[6]))
    return {"center": z[:3], "size": z[3:6], "yaw": z[6], "std": 1 / np.sqrt(np.sum(w, axis=0)),
            "label": members[0]["label"], "score": max(m["score"] for m in members)}


def stack(boxes):
    return {k: np.array([b[k] for b in boxes]) for k in ("center", "size", "yaw", "std", "label", "score")}


def numpy_csba_wls(agents):
    """A straightforward numpy/scipy CSBA-3D + WLS-3D for any number of agents, as the method
    reads: the running fused set is associated with each next agent's boxes (scipy's Hungarian
    solver over the dense cost matrix, ineligible pairs priced out), and every group is fused
    from all its members; unmatched boxes are kept."""
    rows = lambda a: [{k: a[k][i] for k in ("center", "size", "yaw", "std", "label", "score")}
                      for i in range(len(a["score"]))]
    groups = [[m] for m in rows(agents[0])]
    fused = [g[0] for g in groups]
    for agent in agents[1:]:
        boxes = rows(agent)
        cost, eligible = pair_costs(stack(fused), agent)
        r, c = linear_sum_assignment(np.where(eligible, cost, 1e6))
        matched = set()
        for i, j in zip(r, c):
            if eligible[i, j]:
                groups[i].append(boxes[j])
                fused[i] = wls(groups[i])
                matched.add(j)
        for j, b in enumerate(boxes):
            if j not in matched:
                groups.append([b])
                fused.append(b)
    return fused


def numpy_pairs(a, b):
    """The two-agent special case vectorized by hand: one cost matrix, one assignment, the WLS of
    every matched pair in array operations."""
    cost, eligible = pair_costs(a, b)
    r, c = linear_sum_assignment(np.where(eligible, cost, 1e6))
    keep = eligible[r, c]
    r, c = r[keep], c[keep]
    wa, wb = 1 / a["std"][r] ** 2, 1 / b["std"][c] ** 2
    ya = np.concatenate([a["center"][r], a["size"][r], a["yaw"][r, None]], axis=1)
    yb = np.concatenate([b["center"][c], b["size"][c], b["yaw"][c, None]], axis=1)
    yb[:, 6] = ya[:, 6] + np.arctan2(np.sin(yb[:, 6] - ya[:, 6]), np.cos(yb[:, 6] - ya[:, 6]))
    return (wa * ya + wb * yb) / (wa + wb), 1 / np.sqrt(wa + wb), len(r)


def median_us(fn, number):
    runs = timeit.repeat(fn, number=number, repeat=25)
    return sorted(runs)[len(runs) // 2] / number * 1e6


def paired_ratio(fast, slow, n_fast, n_slow, repeat=25):
    """The median over repeats of slow's time over fast's, the two timed in turn within each
    repeat, so that the machine's drift during the run moves both alike."""
    ratios = []
    for _ in range(repeat):
        a = timeit.timeit(fast, number=n_fast) / n_fast
        b = timeit.timeit(slow, number=n_slow) / n_slow
        ratios.append(b / a)
    return sorted(ratios)[len(ratios) // 2]


def criterion_us(method, noise):
    """Runs the Rust criterion bench of this step and reads its median (us)."""
    name = f"methods/2x80/{method}/{noise}"
    subprocess.run(
        ["cargo", "bench", "-q", "-p", "v2x-fuser", "--bench", "fusion", "--", f"^{re.escape(name)}$"],
        cwd=REPO, check=True, capture_output=True,
    )
    path = REPO / "target" / "criterion" / "methods_2x80" / method / noise / "new" / "estimates.json"
    return json.loads(path.read_text())["median"]["point_estimate"] / 1e3


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--noise", default="mild", choices=sorted(PROFILES))
    ap.add_argument("--criterion", action="store_true", help="also run the Rust criterion bench")
    ap.add_argument("--size", metavar="AGENTSxOBJECTS",
                    help="instead: the numpy path alone on a larger scene, e.g. 64x200")
    ap.add_argument("--calls", type=int, metavar="N",
                    help="instead: N calls of the dict path (csba-wls) and nothing else, for a profiler")
    ap.add_argument("--from-json", action="store_true", help="with --calls: the dicts from json.loads")
    args = ap.parse_args()
    agents = scene(80, 2, args.noise, 1)
    boxes = [as_boxes(a) for a in agents]
    # The same dicts as a results file gives them: keys the JSON decoder made, not interned.
    read = json.loads(json.dumps(boxes))
    if args.calls is not None:
        for _ in range(args.calls):
            v.fuse(read if args.from_json else boxes, "csba-wls")
        return
    if args.size:
        n_agents, n_objects = (int(x) for x in args.size.split("x"))
        big = scene(n_objects, n_agents, args.noise, 1)
        times = [median_us(lambda m=m: v.fuse_arrays(big, m), 3) / 1e3 for m in ("csba-wls+", "csba-wls")]
        print(f"fuse_arrays at {n_agents} x {n_objects}, {args.noise} noise (median of 25 repeats): "
              f"csba-wls+ {times[0]:.2f} ms, csba-wls {times[1]:.2f} ms")
        return
    print(f"2 agents x 80 boxes, {args.noise} noise (median of 25 repeats)")
    print("| step | csba-wls | csba-wls+ |\n|---|---:|---:|")
    rows = {}
    for label, fn, number in [
        ("fuse_arrays (numpy path)", lambda m: v.fuse_arrays(agents, m), 200),
        ("fuse (dict path)", lambda m: v.fuse(boxes, m), 20),
        ("fuse (dict path, dicts from json.loads)", lambda m: v.fuse(read, m), 20),
    ]:
        rows[label] = [median_us(lambda m=m: fn(m), number) for m in ("csba-wls", "csba-wls+")]
    if args.criterion:
        rows["Rust, criterion (methods/2x80)"] = [criterion_us(m, args.noise) for m in ("csba-wls", "csba-wls+")]
    for label, (a, b) in rows.items():
        print(f"| {label} | {a:.1f} µs | {b:.1f} µs |")
    general = median_us(lambda: numpy_csba_wls(agents), 5)
    pairs = median_us(lambda: numpy_pairs(*agents), 20)
    print(f"| numpy/scipy CSBA-3D + WLS-3D, straightforward | {general:.0f} µs | - |")
    print(f"| numpy/scipy, two agents vectorized by hand | {pairs:.0f} µs | - |")
    dict_over = [paired_ratio(lambda m=m: v.fuse(boxes, m), lambda: numpy_pairs(*agents), 20, 20)
                 for m in ("csba-wls", "csba-wls+")]
    read_over = paired_ratio(lambda: v.fuse(read, "csba-wls"), lambda: numpy_pairs(*agents), 20, 20)
    print(f"\nthe vectorized numpy/scipy peer over the dict path, timed in turn: "
          f"csba-wls {dict_over[0]:.1f}x, csba-wls+ {dict_over[1]:.1f}x; "
          f"dicts from json.loads, csba-wls {read_over:.1f}x")
    numpy_path = rows["fuse_arrays (numpy path)"][0]
    print(f"numpy/scipy over the numpy path (csba-wls): straightforward {general / numpy_path:.1f}x, "
          f"vectorized {pairs / numpy_path:.1f}x; fused boxes: ours {len(v.fuse_arrays(agents, 'csba-wls')['score'])}, "
          f"numpy/scipy {len(numpy_csba_wls(agents))}")
    if args.criterion:
        rust = rows["Rust, criterion (methods/2x80)"]
        print("numpy path over Rust: " + ", ".join(
            f"{m} {p / r:.2f}x" for m, p, r in zip(("csba-wls", "csba-wls+"), rows["fuse_arrays (numpy path)"], rust)))


if __name__ == "__main__":
    main()
