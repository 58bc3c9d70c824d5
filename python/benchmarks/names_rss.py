"""What a fuser keeps for agent names that came and went: a `v2x-fuser node` in its own process,
10,000 liveliness tokens declared on its namespace and undeclared, twice, with the fuser's RSS
before, while they stand and after.

    python python/benchmarks/names_rss.py [--fuser target/release/v2x-fuser] [--names 10000]

Needs eclipse-zenoh (`pip install "./python[net]"`). With `--bare` a bare Zenoh session with a
liveliness subscriber stands in for the fuser, to tell the fuser's own state from Zenoh's.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import zenoh

NS = "rss"


def config(mode, listen=(), connect=()):
    c = zenoh.Config()
    c.insert_json5("mode", json.dumps(mode))
    c.insert_json5("listen/endpoints", json.dumps(list(listen)))
    c.insert_json5("connect/endpoints", json.dumps(list(connect)))
    c.insert_json5("scouting/multicast/enabled", "false")
    return c


def rss_mib(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS"):
                return int(line.split()[1]) / 1024
    raise RuntimeError(f"no VmRSS for process {pid}")


def bare(endpoint):
    """A Zenoh client that only hears liveliness tokens, as the fuser does."""
    s = zenoh.open(config("client", connect=[endpoint]))
    _sub = s.liveliness().declare_subscriber(f"v2x/{NS}/alive/*", lambda _: None)
    time.sleep(3600)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fuser", default="target/release/v2x-fuser")
    ap.add_argument("--names", type=int, default=10000)
    ap.add_argument("--port", type=int, default=17941)
    ap.add_argument("--bare", action="store_true", help="a bare Zenoh session instead of the fuser")
    ap.add_argument("--_bare_child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._bare_child:
        return bare(args._bare_child)
    endpoint = f"tcp/127.0.0.1:{args.port}"
    router = zenoh.open(config("router", listen=[endpoint]))
    if args.bare:
        cmd = [sys.executable, __file__, "--_bare_child", endpoint]
    else:
        cmd = [args.fuser, "node", "--ns", NS, "--connect", endpoint, "--no-multicast-scouting"]
    child = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        s = zenoh.open(config("client", connect=[endpoint]))
        time.sleep(3)
        start = rss_mib(child.pid)
        who = "a bare Zenoh session" if args.bare else "the fuser"
        print(f"{who}: RSS {start:.1f} MiB at start")
        for rnd in range(2):
            tokens = [s.liveliness().declare_token(f"v2x/{NS}/alive/n{rnd}-{i}") for i in range(args.names)]
            time.sleep(3)
            standing = rss_mib(child.pid)
            for t in tokens:
                t.undeclare()
            del tokens
            time.sleep(5)
            after = rss_mib(child.pid)
            print(f"round {rnd + 1}: {args.names} names standing {standing:.1f} MiB, "
                  f"undeclared {after:.1f} MiB ({after - start:+.1f} MiB since the start)")
        s.close()
    finally:
        child.terminate()
        child.wait()
        router.close()


if __name__ == "__main__":
    main()
