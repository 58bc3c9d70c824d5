"""A Python detector joining a live fuser: publishes each sample of a results file as one frame,
at the data's own pace on this machine's clock, and writes every fused frame it gets back as a
JSON line.

    python live_agent.py --ns demo --connect tcp/ROADSIDE:7447 --name pyveh detections.json

Give several agents the same --start-at (Unix seconds) and --speed and their frames land in the
same windows of the fuser (v2x-agent replays with the same two flags).
"""

import argparse
import json
import sys
import time

import zenoh

from v2x_fusion import net


def schedule(doc, hz):
    """The samples in capture order with their offsets (s) from the first: from the file's
    meta.v2x_timestamps when it has them, else the file's order at `hz`."""
    stamps = (doc.get("meta") or {}).get("v2x_timestamps")
    samples = list(doc["results"])
    if stamps and all(s in stamps for s in samples):
        samples.sort(key=lambda s: stamps[s])
        t0 = stamps[samples[0]]
        return [(s, (stamps[s] - t0) / 1e6) for s in samples]
    return [(s, k / hz) for k, s in enumerate(samples)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", help="a nuScenes detection-results file (the detector's output)")
    ap.add_argument("--ns", default="default", help="the scenario namespace")
    ap.add_argument("--connect", action="append", default=[], help="endpoint, e.g. tcp/127.0.0.1:7447")
    ap.add_argument("--name", default="pyveh", help="this agent's name")
    ap.add_argument("--kind", default="vehicle", choices=["vehicle", "infrastructure"])
    ap.add_argument("--default-std", default=None, help="stds of boxes without them: mild, moderate, large")
    ap.add_argument("--hz", type=float, default=10.0, help="frame rate of a file without capture times")
    ap.add_argument("--speed", type=float, default=1.0, help="playback speed factor")
    ap.add_argument("--start-at", type=float, default=None, help="Unix time of the first capture (default: now)")
    ap.add_argument("--linger", type=float, default=2.0, help="seconds to keep receiving after the last frame")
    ap.add_argument("--out", default=None, help="write the fused frames here instead of stdout")
    args = ap.parse_args()

    with open(args.results) as f:
        doc = json.load(f)
    out = open(args.out, "w") if args.out else sys.stdout

    def on_fused(frame):
        out.write(json.dumps(frame.to_dict()) + "\n")
        out.flush()

    with zenoh.open(net.config(connect=args.connect)) as session:
        with net.FusedSubscriber(session, args.ns, callback=on_fused), net.AgentPublisher(
            session, args.ns, args.name, args.kind, default_std=args.default_std
        ) as agent:
            if not agent.wait_for_fuser(timeout=30.0):
                sys.exit(f"{args.name}: no fuser subscribed within 30 s (is v2x-fuser node running in namespace {args.ns}?)")
            print(f"{args.name}: a fuser is subscribed", file=sys.stderr, flush=True)
            start = args.start_at if args.start_at is not None else time.time()
            sent = 0
            for sample, offset in schedule(doc, args.hz):
                at = start + offset / args.speed
                time.sleep(max(0.0, at - time.time()))
                sent += agent.publish(doc["results"][sample], capture_us=round(at * 1e6))
            print(f"{args.name}: published {agent.seq} frames, {sent} bytes", file=sys.stderr, flush=True)
            time.sleep(args.linger)


if __name__ == "__main__":
    main()
