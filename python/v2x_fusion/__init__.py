"""v2x-fusion from Python: the wire codec, late fusion (CSBA-3D + WLS-3D and the baselines), the
tracker and the evaluation protocols of the project's Rust core.

Boxes are dicts in the nuScenes detection-results form (``translation``, ``size`` as w, l, h,
``rotation`` as a quaternion, ``detection_name``, ``detection_score``, and the stds
``translation_std``, ``size_std``, ``yaw_std``), the same fields a results file holds, checked by
the same parser. ``fuse_arrays`` takes numpy arrays instead. ``v2x_fusion.net`` (with the
``eclipse-zenoh`` package) publishes to and subscribes from a live fuser. The API is documented in
docs/python.md.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from . import _native
from ._native import WIRE_VERSION, DecodeError, EncodeError, GroundTruth

__all__ = [
    "CLASSES",
    "METHODS",
    "WIRE_VERSION",
    "DecodeError",
    "EncodeError",
    "Frame",
    "GroundTruth",
    "Object",
    "Tracker",
    "decode",
    "encode",
    "encode_boxes",
    "evaluate",
    "fuse",
    "fuse_arrays",
    "fuse_files",
    "fuse_results",
    "track_files",
]

#: The ten nuScenes detection classes; a class's code (``fuse_arrays``' ``label``) is its index.
CLASSES: tuple = tuple(_native.CLASSES)
#: Every fusion method by name, with a one-line description (as ``v2x-fuser fuse --help``).
METHODS: dict = dict(_native.METHODS)

_log = logging.getLogger("v2x_fusion")

Std = Union[str, Sequence[float], None]
PathLike = Union[str, "os.PathLike[str]"]


@dataclass
class Object:
    """One box of a frame: class, centre (m), size (l, w, h in m), yaw (rad), score, id (None when
    the agent gave none), stds (x, y, z, l, w, h, yaw), and velocity (m/s) with its stds when the
    agent measured it; in a fused frame, the names of the agents whose boxes went into it."""

    class_name: str
    center: list
    size: list
    yaw: float
    score: float
    std: list
    id: Optional[int] = None
    velocity: Optional[list] = None
    velocity_std: Optional[list] = None
    sources: Optional[list] = None

    def to_dict(self) -> dict:
        """The object as a dict, with the keys of ``examples/python/v2x_frame.py``."""
        d = {
            "class": self.class_name,
            "center": list(self.center),
            "size": list(self.size),
            "yaw": self.yaw,
            "score": self.score,
            "id": self.id,
            "std": list(self.std),
        }
        if self.velocity is not None:
            d["velocity"] = list(self.velocity)
            d["velocity_std"] = list(self.velocity_std if self.velocity_std is not None else (1.0, 1.0))
        if self.sources is not None:
            d["sources"] = list(self.sources)
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Object":
        """An object from its dict (``to_dict``'s keys)."""
        return cls(
            class_name=d["class"],
            center=list(d["center"]),
            size=list(d["size"]),
            yaw=d["yaw"],
            score=d["score"],
            std=list(d["std"]),
            id=d.get("id"),
            velocity=d.get("velocity"),
            velocity_std=d.get("velocity_std"),
            sources=d.get("sources"),
        )


@dataclass
class Frame:
    """One agent's boxes at one capture time, as the wire carries them; a fused frame also lists
    the window's agents and whether every awaited agent was in it."""

    agent: str
    kind: str
    seq: int
    capture_us: int
    objects: list = field(default_factory=list)
    origin: list = field(default_factory=lambda: [0.0, 0.0, 0.0])
    agents: Optional[list] = None
    complete: Optional[bool] = None

    def to_dict(self) -> dict:
        """The frame as a dict: ``agent``, ``kind``, ``seq``, ``capture_us``, ``origin``,
        ``objects`` (each ``Object.to_dict``) and, for a fused frame, ``agents`` and ``complete``."""
        d = {
            "agent": self.agent,
            "kind": self.kind,
            "seq": self.seq,
            "capture_us": self.capture_us,
            "origin": list(self.origin),
            "objects": [o.to_dict() for o in self.objects],
        }
        if self.agents is not None:
            d["agents"] = list(self.agents)
            d["complete"] = True if self.complete is None else self.complete
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Frame":
        """A frame from its dict (``to_dict``'s keys)."""
        return cls(
            agent=d["agent"],
            kind=d["kind"],
            seq=d["seq"],
            capture_us=d["capture_us"],
            objects=[Object.from_dict(o) for o in d["objects"]],
            origin=list(d.get("origin", (0.0, 0.0, 0.0))),
            agents=d.get("agents"),
            complete=d.get("complete"),
        )


def _plain(x: Any) -> Any:
    """numpy scalars and arrays as Python numbers and lists, for JSON."""
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"{type(x).__name__} is not a number, string, list or dict")


def _dumps(value: Any, what: str) -> str:
    try:
        return json.dumps(value, allow_nan=False, default=_plain)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{what}: {e}") from None


def _list(boxes: Iterable[Any]) -> list:
    return boxes if type(boxes) is list else list(boxes)


def _std(default_std: Std) -> Optional[str]:
    """``default_std`` as the CLI spells it: a profile name or POS,SIZE,YAW_DEG."""
    if default_std is None or isinstance(default_std, str):
        return default_std
    values = list(default_std)
    if len(values) != 3:
        raise ValueError("default_std: expected a profile name or (pos_m, size_m, yaw_deg)")
    return ",".join(repr(float(v)) for v in values)


def decode(payload: bytes) -> Frame:
    """Decodes a frame from its wire bytes; raises ``DecodeError`` with the decoder's message."""
    return Frame.from_dict(json.loads(_native.decode_json(bytes(payload))))


def encode(frame: Union[Frame, Mapping[str, Any]]) -> bytes:
    """Encodes a frame (a ``Frame`` or its dict) into wire bytes; raises ``EncodeError`` naming the
    field the wire cannot carry."""
    d = frame.to_dict() if isinstance(frame, Frame) else frame
    return _native.encode_json(_dumps(d, "frame"))


def encode_boxes(
    agent: str,
    boxes: Iterable[Mapping[str, Any]],
    *,
    kind: str = "vehicle",
    seq: int = 0,
    capture_us: int = 0,
    default_std: Std = None,
) -> bytes:
    """Encodes an agent's boxes (results-file dicts) as one frame's wire bytes, its origin their
    centroid: what ``v2x_fusion.net.AgentPublisher`` sends."""
    return _native.encode_boxes(agent, kind, seq, capture_us, _list(boxes), _std(default_std))


def fuse(
    agents: Sequence[Iterable[Mapping[str, Any]]],
    method: str = "csba-wls+",
    *,
    default_std: Std = None,
) -> list:
    """Fuses one time step: ``agents[k]`` is agent k's boxes (results-file dicts, with their stds
    or a ``default_std``: mild, moderate, large or (pos_m, size_m, yaw_deg)). Returns the fused
    boxes as results-file dicts with their stds and ``v2x_sources``, the indices of the agents
    whose boxes went into each."""
    return _native.fuse_step([_list(a) for a in agents], method, _std(default_std))


def fuse_arrays(agents: Sequence[Mapping[str, Any]], method: str = "csba-wls+") -> dict:
    """Fuses one time step of arrays, without a Python object per box. ``agents[k]`` maps
    ``center`` (N, 3), ``size`` (N, 3: l, w, h), ``yaw`` (N,), ``std`` (N, 7: x, y, z, l, w, h,
    yaw), ``label`` (N,: class codes, indices into ``CLASSES``) and ``score`` (N,), and optionally
    ``id`` (N,: -1 for none), ``velocity`` and ``velocity_std`` (N, 2; a NaN row of velocity: none).
    Arrays of another dtype (or lists) are converted once. Returns the same keys for
    the fused boxes (``velocity`` NaN where a box has none) and ``sources`` (M, K booleans: which
    agents went into each box)."""
    return _native.fuse_arrays([a if type(a) is dict else dict(a) for a in agents], method)


def _options(options: Mapping[str, Any]) -> dict:
    """The keyword options as the native half reads them: the fuser's settings under their
    scenario keys (docs/guide.md), paths as strings, ``default_std`` as its text."""
    out = dict(options)
    if "default_std" in out:
        out["default_std"] = _std(out["default_std"])
    if "existence_model" in out:
        out["existence_model"] = os.fspath(out["existence_model"])
    if out.get("std_models") is not None:
        out["std_models"] = {k: os.fspath(v) for k, v in out["std_models"].items()}
    return out


def fuse_results(documents: Sequence[Mapping[str, Any]], method: str = "csba-wls+", **options: Any) -> tuple:
    """Fuses whole results documents in memory, one per agent, as ``fuse_files`` fuses files.
    Returns the fused document and the report (``fuse_files``)."""
    texts = [_dumps(d, f"documents[{k}]") for k, d in enumerate(documents)]
    doc, report = _native.fuse_documents(texts, _options(dict(options, method=method)))
    return json.loads(doc), json.loads(report)


def fuse_files(
    paths: Sequence[PathLike], output: PathLike, method: str = "csba-wls+", **options: Any
) -> dict:
    """Reads one results file per agent, fuses and writes ``output``: ``v2x-fuser fuse``.

    Options: the fuser's settings under the names of a scenario's ``[fuser]`` table, each the
    flag of its name (``window_ms``: ``--window-ms``; ``compensation=False``:
    ``--no-compensation``; ``std_models`` {"agentN": path}; ``registration`` {key: value}),
    with their defaults there (docs/guide.md), and ``default_std``, ``time_scale`` and
    ``align_to`` (the reference agent's index, 0-based: ``--align --align-to N+1``). An unknown
    key is an error that lists the known ones. Returns the report: samples, boxes in and out,
    whether frames were grouped by capture time, registration and learned stds."""
    opts = _options(dict(options, method=method))
    return json.loads(_native.run_files([os.fspath(p) for p in paths], os.fspath(output), opts, False))


def track_files(
    paths: Sequence[PathLike], output: PathLike, method: str = "csba-wls+", **options: Any
) -> dict:
    """Reads, fuses, tracks and writes a nuScenes tracking results file: ``v2x-fuser track``.
    Takes ``fuse_files``' options and the tracking ones: ``association`` ("soft", the default:
    each track updated with its boxes weighed by the chance each is its own, "assignment": the
    box of the best assignment, or "guided": each agent's boxes through the tracks), ``confirm_hits``, ``max_misses`` and ``all_classes``;
    returns the windows, boxes, the tracker's counters (live, births, deaths) and learned stds."""
    opts = _options(dict(options, method=method))
    return json.loads(_native.run_files([os.fspath(p) for p in paths], os.fspath(output), opts, True))


class Tracker:
    """Follows fused boxes over time, window by window, as ``v2x-fuser track`` and the node's
    ``--track`` do: an interacting-multiple-model Kalman filter per track, each updated with the
    boxes in its gate weighed by the chance each is its own (``association="assignment"``: the
    box of the best assignment alone), confirmation after ``confirm_hits`` and an end after ``max_misses``
    missed windows (each left out: ``v2x-fuser track``'s default)."""

    def __init__(
        self,
        confirm_hits: Optional[int] = None,
        max_misses: Optional[int] = None,
        all_classes: bool = False,
        time_scale: float = 1.0,
        default_std: Std = None,
        association: Optional[str] = None,
    ):
        self._inner = _native.Tracker(
            confirm_hits, max_misses, all_classes, float(time_scale), _std(default_std), association
        )

    def step(self, t_us: int, boxes: Iterable[Mapping[str, Any]]) -> list:
        """Steps the tracks to the window at ``t_us`` (microseconds, increasing) with its boxes
        (results-file dicts); returns the tracked boxes with ``tracking_id`` (a string, as the
        nuScenes tracking format has it), ``tracking_name`` and ``tracking_score``."""
        return self._inner.step(int(t_us), _list(boxes))

    def step_agents(self, t_us: int, agents: Sequence[Iterable[Mapping[str, Any]]], method: str = "csba-wls+") -> list:
        """Steps the tracks with each agent's boxes (``agents[k]``, brought to ``t_us``) through the
        tracks: CSBA-3D with ``method``'s parameters associates them with the tracks' predictions
        and with each other (``v2x-fuser track --association guided``, docs/method.md §8.1); returns the
        tracked boxes as ``step`` does."""
        return self._inner.step_agents(int(t_us), [_list(a) for a in agents], method)

    @property
    def stats(self) -> dict:
        """Confirmed tracks alive now (``live``), confirmed so far (``births``), ended so far
        (``deaths``)."""
        live, births, deaths = self._inner.stats()
        return {"live": live, "births": births, "deaths": deaths}

    def reset(self) -> None:
        """Ends every track."""
        self._inner.reset()


def evaluate(
    results: Union[PathLike, Mapping[str, Any]],
    ground_truth: GroundTruth,
    *,
    tracking: bool = False,
    match: str = "auto",
    at: str = "frame",
    all_frames: bool = False,
    classes: Optional[Sequence[str]] = None,
) -> dict:
    """Scores a results file (a path) or document (a dict) against the ground truth: the figures
    ``v2x-sim eval --format json`` prints. ``match``: auto, id (the paper's protocol) or distance
    (the nuScenes detection benchmark); ``at``: frame or capture; ``tracking``: the nuScenes
    tracking benchmark (AMOTA, ...). The note the CLI prints goes to the ``v2x_fusion`` logger."""
    if isinstance(results, Mapping):
        label, text = "results", _dumps(results, "results")
    else:
        label = os.fspath(results)
        with open(label) as f:
            text = f.read()
    metrics, note = _native.evaluate_json(
        ground_truth, text, label, tracking, match, at, all_frames, list(classes) if classes else None
    )
    if note:
        _log.info(note)
    return json.loads(metrics)
