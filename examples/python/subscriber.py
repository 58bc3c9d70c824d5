"""Subscribes to a v2x-fusion namespace with the eclipse-zenoh package and prints every frame it
decodes as one JSON line: fused frames (v2x/NS/fused) and, with --detections, every agent's.

    python subscriber.py --ns demo --connect tcp/ROADSIDE:7447 [--detections] [--out frames.jsonl]

Stops after --duration seconds, or on Ctrl-C.
"""

import argparse
import json
import sys
import time

import zenoh

from v2x_frame import decode


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ns", default="default", help="the scenario namespace")
    ap.add_argument("--connect", action="append", default=[], help="endpoint, e.g. tcp/127.0.0.1:7447")
    ap.add_argument("--detections", action="store_true", help="also every agent's frames")
    ap.add_argument("--duration", type=float, default=None, help="seconds to listen")
    ap.add_argument("--out", default=None, help="write JSON lines here instead of stdout")
    args = ap.parse_args()

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    if args.connect:
        conf.insert_json5("connect/endpoints", json.dumps(args.connect))
    out = open(args.out, "w") if args.out else sys.stdout

    def on_sample(sample):
        try:
            frame = decode(sample.payload.to_bytes())
        except ValueError as e:
            print(f"{sample.key_expr}: undecodable frame: {e}", file=sys.stderr)
            return
        frame["key"] = str(sample.key_expr)
        frame["encoding"] = str(sample.encoding)
        out.write(json.dumps(frame) + "\n")
        out.flush()

    with zenoh.open(conf) as session:
        subs = [session.declare_subscriber(f"v2x/{args.ns}/fused", on_sample)]
        if args.detections:
            subs.append(session.declare_subscriber(f"v2x/{args.ns}/det/*", on_sample))
        # Tell whoever waits for us that we are subscribed.
        token = session.liveliness().declare_token(f"v2x/{args.ns}/observer/python")
        print("subscribed", file=sys.stderr, flush=True)
        try:
            if args.duration is None:
                while True:
                    time.sleep(1)
            else:
                time.sleep(args.duration)
        except KeyboardInterrupt:
            pass
        token.undeclare()


if __name__ == "__main__":
    main()
