"""A decoder of v2x-fusion frames, written from docs/wire-format.md alone (wire version 3).

decode(payload) -> dict with agent, kind, seq, capture_us, origin and objects; each object has
class, center, size (l, w, h), yaw, score, id (None when absent), std (x, y, z, l, w, h, yaw) and, when present,
velocity and velocity_std. A fused frame also has agents (the window's) and complete, and each of
its objects sources (the names of the agents that contributed). Raises ValueError on anything the
specification does not allow.
"""

import math

VERSION = 3
MAX_OBJECTS = 4096
MAX_WINDOW_AGENTS = 1024
CLASSES = [
    ("car", (4.60, 1.95, 1.75)),
    ("truck", (7.00, 2.50, 3.00)),
    ("bus", (11.00, 2.90, 3.50)),
    ("trailer", (12.00, 2.90, 3.80)),
    ("construction_vehicle", (6.50, 2.80, 3.20)),
    ("pedestrian", (0.75, 0.67, 1.75)),
    ("motorcycle", (2.10, 0.80, 1.50)),
    ("bicycle", (1.75, 0.60, 1.30)),
    ("traffic_cone", (0.40, 0.40, 1.00)),
    ("barrier", (0.50, 2.50, 1.00)),
]
STD_CODE_MAX = 9211


class Reader:
    def __init__(self, data):
        self.data = data
        self.pos = 0

    def u8(self):
        if self.pos >= len(self.data):
            raise ValueError("truncated")
        b = self.data[self.pos]
        self.pos += 1
        return b

    def varint(self, max_bits):
        value, shift = 0, 0
        while True:
            b = self.u8()
            value |= (b & 0x7F) << shift
            shift += 7
            if not b & 0x80:
                break
            if shift >= max_bits + 7:
                raise ValueError("varint too long")
        if value >> max_bits:
            raise ValueError("varint out of range")
        return value

    def zigzag(self, bits):
        n = self.varint(bits)
        return (n >> 1) ^ -(n & 1)

    def raw(self, n):
        if self.pos + n > len(self.data):
            raise ValueError("truncated")
        b = self.data[self.pos : self.pos + n]
        self.pos += n
        return b

    def string(self):
        n = self.varint(64)
        if self.pos + n > len(self.data):
            raise ValueError("truncated")
        s = self.data[self.pos : self.pos + n].decode("utf-8")
        self.pos += n
        return s


def std_of_code(code):
    if not 1 <= code <= STD_CODE_MAX:
        raise ValueError(f"invalid std code {code}")
    return 1e-4 * math.exp((code - 1) / 500.0)


def wrap(a):
    """An angle in (-pi, pi]."""
    r = math.fmod(a + math.pi, 2 * math.pi)
    if r <= 0:
        r += 2 * math.pi
    return r - math.pi


def decode(payload):
    r = Reader(bytes(payload))
    version = r.u8()
    if version != VERSION:
        raise ValueError(f"unknown wire version {version}")
    frame = {"agent": r.string()}
    kind = r.u8()
    if kind & ~0x03:
        raise ValueError(f"invalid kind {kind:#x}")
    frame["kind"] = ["vehicle", "infrastructure"][kind & 0x01]
    frame["seq"] = r.varint(32)
    frame["capture_us"] = r.varint(64)
    origin_cm = [r.zigzag(64) for _ in range(3)]
    frame["origin"] = [c / 100 for c in origin_cm]
    default_std = [std_of_code(r.varint(16)) for _ in range(7)]
    default_vel_std = [std_of_code(r.varint(16)) for _ in range(2)]
    agents = None
    if kind & 0x02:
        complete = r.u8()
        if complete > 1:
            raise ValueError(f"complete must be 0 or 1, not {complete}")
        n = r.varint(64)
        if n > MAX_WINDOW_AGENTS:
            raise ValueError(f"{n} agents, more than {MAX_WINDOW_AGENTS}")
        agents = [r.string() for _ in range(n)]
        if len(set(agents)) != n:
            raise ValueError("an agent is listed twice")
        frame["agents"], frame["complete"] = agents, bool(complete)
    count = r.varint(64)
    if count > MAX_OBJECTS:
        raise ValueError(f"{count} objects, more than {MAX_OBJECTS}")
    objects = []
    for _ in range(count):
        tag = r.u8()
        if tag & 0x80 or (tag & 0x0F) >= len(CLASSES):
            raise ValueError(f"invalid tag {tag:#x}")
        name, typical = CLASSES[tag & 0x0F]
        pos_cm = [r.zigzag(32) for _ in range(3)]
        size_cm = [round(t * 100) + r.zigzag(32) for t in typical]
        if not all(1 <= s <= 100_000 for s in size_cm):
            raise ValueError(f"size out of range {size_cm}")
        yaw = int.from_bytes(bytes([r.u8(), r.u8()]), "little") / 65536 * 2 * math.pi
        score = r.u8()
        if score > 250:
            raise ValueError(f"score code {score}")
        obj = {
            "class": name,
            "center": [(o + p) / 100 for o, p in zip(origin_cm, pos_cm)],
            "size": [s / 100 for s in size_cm],
            "yaw": wrap(yaw),
            "score": score / 250,
            "id": None,
        }
        if tag & 0x40:
            obj["id"] = int.from_bytes(r.raw(4), "little")
            if obj["id"] == 0xFFFFFFFF:
                raise ValueError("id 4294967295 is written by leaving the id out")
        has_std, has_vel = bool(tag & 0x10), bool(tag & 0x20)
        if has_vel:
            obj["velocity"] = [r.zigzag(32) * 0.1 for _ in range(2)]
        obj["std"] = [std_of_code(r.varint(16)) for _ in range(7)] if has_std else default_std
        if has_vel:
            obj["velocity_std"] = (
                [std_of_code(r.varint(16)) for _ in range(2)] if has_std else default_vel_std
            )
        if agents is not None:
            mask = int.from_bytes(r.raw((len(agents) + 7) // 8), "little")
            if mask == 0 or mask >> len(agents):
                raise ValueError(f"source mask {mask:#x} for {len(agents)} agents")
            obj["sources"] = [a for k, a in enumerate(agents) if mask >> k & 1]
        objects.append(obj)
    if r.pos != len(r.data):
        raise ValueError(f"{len(r.data) - r.pos} trailing bytes")
    frame["objects"] = objects
    return frame
