"""v2x-fusion on the network, over the ``eclipse-zenoh`` package: an agent that publishes its boxes
to a live fuser, and a subscriber of the fused frames (key space: docs/wire-format.md).

    import zenoh, v2x_fusion.net as net
    with zenoh.open(net.config(connect=["tcp/ROADSIDE:7447"])) as session:
        with net.AgentPublisher(session, "demo", "pyveh") as agent:
            agent.publish(boxes)                     # results-file dicts, stamped now
        with net.FusedSubscriber(session, "demo") as fused:
            frame = fused.recv(timeout=1.0)          # a v2x_fusion.Frame, or None
"""

from __future__ import annotations

import json
import queue
import time
from typing import Any, Callable, Iterable, Mapping, Optional, Sequence

import zenoh

from . import WIRE_VERSION, DecodeError, Frame, Std, _std, decode, encode_boxes

ROOT = "v2x"


def _chunk(what: str, s: str) -> str:
    """A namespace or agent name as one key chunk, as the fuser checks it."""
    if not s or any(c in "/*$?#" or c.isspace() for c in s):
        raise ValueError(f"{what} '{s}': use letters, digits, '-', '_' or '.'")
    return s


def config(connect: Sequence[str] = (), listen: Sequence[str] = (), multicast: bool = False) -> "zenoh.Config":
    """A peer-mode Zenoh configuration with explicit endpoints (e.g. ``tcp/10.0.0.1:7447``) and,
    unless asked, no multicast scouting."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "true" if multicast else "false")
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(list(connect)))
    if listen:
        conf.insert_json5("listen/endpoints", json.dumps(list(listen)))
    return conf


def frame_encoding() -> "zenoh.Encoding":
    """The encoding a frame is published with: bytes, schema ``v2x-frame/VERSION``."""
    return zenoh.Encoding.APPLICATION_OCTET_STREAM.with_schema(f"v2x-frame/{WIRE_VERSION}")


class AgentPublisher:
    """An agent of namespace ``ns``: publishes each capture's boxes as one frame on
    ``v2x/NS/det/NAME`` and holds the liveliness token ``v2x/NS/alive/NAME`` that tells the fuser
    to await it."""

    def __init__(self, session: "zenoh.Session", ns: str, name: str, kind: str = "vehicle", default_std: Std = None):
        self.name, self.kind = _chunk("agent name", name), kind
        self.seq = 0
        self._default_std = _std(default_std)
        key = f"{ROOT}/{_chunk('namespace', ns)}/det/{name}"
        self._publisher = session.declare_publisher(key, encoding=frame_encoding())
        self._token = session.liveliness().declare_token(f"{ROOT}/{ns}/alive/{name}")

    def wait_for_fuser(self, timeout: float = 10.0) -> bool:
        """Waits until a fuser subscribes to this agent's frames; False after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while not self._matching():
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.01)
        return True

    def _matching(self) -> bool:
        # A MatchingStatus at run time (its `matching` is the answer); the package's stubs say bool.
        status = self._publisher.matching_status
        return bool(getattr(status, "matching", status))

    def publish(self, boxes: Iterable[Mapping[str, Any]], capture_us: Optional[int] = None) -> int:
        """Publishes one capture's boxes (results-file dicts), stamped ``capture_us`` (default:
        now, microseconds since the Unix epoch); returns the payload's size in bytes."""
        if capture_us is None:
            capture_us = time.time_ns() // 1000
        payload = encode_boxes(
            self.name, boxes, kind=self.kind, seq=self.seq, capture_us=capture_us, default_std=self._default_std
        )
        self._publisher.put(payload)
        self.seq = (self.seq + 1) % (1 << 32)
        return len(payload)

    def close(self) -> None:
        """Withdraws the liveliness token (the fuser stops awaiting the agent) and the publisher."""
        self._token.undeclare()
        self._publisher.undeclare()

    def __enter__(self) -> "AgentPublisher":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class FusedSubscriber:
    """The fused frames of namespace ``ns`` (``v2x/NS/fused``; with ``tile``, a regional fuser's
    ``v2x/NS/fused/TILE``; with ``tracks``, the tracked boxes instead), each decoded into a
    ``Frame``: handed to ``callback``, or queued for ``recv`` and iteration. A payload that does
    not decode is counted in ``undecodable`` and skipped."""

    def __init__(
        self,
        session: "zenoh.Session",
        ns: str,
        callback: Optional[Callable[[Frame], None]] = None,
        tile: Optional[str] = None,
        tracks: bool = False,
    ):
        key = f"{ROOT}/{_chunk('namespace', ns)}/{'tracks' if tracks else 'fused'}"
        if tile is not None:
            key += "/" + _chunk("tile", tile)
        self.undecodable = 0
        self._queue: "queue.Queue[Frame]" = queue.Queue()
        deliver = callback or self._queue.put

        def on_sample(sample: "zenoh.Sample") -> None:
            try:
                frame = decode(sample.payload.to_bytes())
            except DecodeError:
                self.undecodable += 1
                return
            deliver(frame)

        self._subscriber = session.declare_subscriber(key, on_sample)

    def recv(self, timeout: Optional[float] = None) -> Optional[Frame]:
        """The next fused frame, or None when none came within ``timeout`` s."""
        try:
            return self._queue.get(timeout=timeout)
        except queue.Empty:
            return None

    def __iter__(self):
        while True:
            yield self._queue.get()

    def close(self) -> None:
        """Stops the subscription."""
        self._subscriber.undeclare()

    def __enter__(self) -> "FusedSubscriber":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
