"""Shared fixtures: the project's binaries (V2X_BIN, default target/release of the repository) and
agents' results files the simulator generates once per session."""

import json
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
BIN = pathlib.Path(os.environ.get("V2X_BIN", REPO / "target" / "release"))
#: The synthetic town of the generated files (v2x-sim gen's flags; GroundTruth.town's arguments).
TOWN = {"seconds": 3.0, "hz": 10.0}


def run(*args, **kw):
    """Runs one of the project's binaries, failing the test with its stderr."""
    exe = BIN / args[0]
    if not exe.exists():
        pytest.fail(f"{exe} is missing: build the workspace first (cargo build --release)")
    p = subprocess.run([str(exe), *map(str, args[1:])], capture_output=True, text=True, **kw)
    assert p.returncode == 0, f"{args}: {p.stderr}"
    return p


def load(path):
    with open(path) as f:
        return json.load(f)


@pytest.fixture(scope="session")
def generated(tmp_path_factory):
    """A vehicle (mild noise) and a roadside unit (large noise) over 3 s of the town at 10 Hz:
    agent1.json and agent2.json, with capture times and ids."""
    out = tmp_path_factory.mktemp("gen")
    run("v2x-sim", "gen", "--seconds", TOWN["seconds"], "--hz", TOWN["hz"], "--range", 60,
        "--noise", "mild+large", "--out", out)
    return out


@pytest.fixture(scope="session")
def untimed(generated, tmp_path_factory):
    """The generated files without capture times: fused by sample token, as they are."""
    out = tmp_path_factory.mktemp("untimed")
    for name in ("agent1.json", "agent2.json"):
        doc = load(generated / name)
        del doc["meta"]["v2x_timestamps"]
        (out / name).write_text(json.dumps(doc))
    return out
