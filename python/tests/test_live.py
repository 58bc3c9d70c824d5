"""The live example against a running fuser: a Python agent (examples/live_agent.py, this package
over eclipse-zenoh) and a `v2x-agent` publish to `v2x-fuser node`; the fused frames the example
decodes are the frames the fuser recorded, with boxes fused from both agents."""

import json
import os
import socket
import subprocess
import sys
import time

import pytest

from conftest import BIN, REPO, load

pytest.importorskip("zenoh", reason="the live example needs eclipse-zenoh (pip install './python[net]')")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_python_agent_joins_a_live_fuser(generated, tmp_path):
    ep = f"tcp/127.0.0.1:{free_port()}"
    ns = f"py{os.getpid()}"
    record = tmp_path / "fused.json"
    procs = []

    def start(*cmd, log):
        p = subprocess.Popen([str(c) for c in cmd], stdout=subprocess.DEVNULL, stderr=open(tmp_path / log, "w"))
        procs.append(p)
        return p

    def wait(p, log, timeout=40):
        try:
            code = p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            pytest.fail(f"{log} did not finish within {timeout} s: {(tmp_path / log).read_text()}")
        assert code == 0, (tmp_path / log).read_text()

    try:
        fuser = start(BIN / "v2x-fuser", "node", "--ns", ns, "--no-multicast-scouting", "-l", ep,
                      "--duration-s", 10, "--record", record, log="fuser.log")
        start_at = time.time() + 3
        example = start(sys.executable, REPO / "python" / "examples" / "live_agent.py", "--ns", ns,
                        "--connect", ep, "--name", "pyveh", "--speed", 2, "--start-at", start_at,
                        "--linger", 3, "--out", tmp_path / "frames.jsonl", generated / "agent1.json",
                        log="example.log")
        rsu = start(BIN / "v2x-agent", generated / "agent2.json", "--name", "rsu", "--kind", "infrastructure",
                    "--ns", ns, "--replay", f"speed=2,start_at={start_at}", "--no-multicast-scouting", "-e", ep,
                    log="rsu.log")
        wait(fuser, "fuser.log")
        wait(example, "example.log")
        wait(rsu, "rsu.log")
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()

    assert "published 30 frames" in (tmp_path / "example.log").read_text()
    decoded = {f"t{f['capture_us']}": f for f in map(json.loads, open(tmp_path / "frames.jsonl"))}
    doc = load(record)
    results, provenance = doc["results"], doc["meta"]["v2x_provenance"]
    assert decoded and set(decoded) == set(results)
    both = 0
    for key, frame in decoded.items():
        assert frame["agents"] == provenance[key]["agents"]
        assert [o["sources"] for o in frame["objects"]] == provenance[key]["sources"]
        assert len(frame["objects"]) == len(results[key])
        for o, r in zip(frame["objects"], results[key]):
            assert o["class"] == r["detection_name"]
            assert all(abs(a - b) <= 0.005 + 1e-9 for a, b in zip(o["center"], r["translation"]))
        both += sum(set(o["sources"]) == {"pyveh", "rsu"} for o in frame["objects"])
    assert both > 100, f"{both} boxes fused from the Python agent and the roadside unit"
