"""Memory of chatter-free postures and the conditions they were cut under.

Implements the learning of JP2010-260120 (Nagoya), sixth embodiment
([0095]-[0097], claim 8, item (17)): while no chatter is detected, store the
tool posture and the cutting conditions of the place; when chatter occurs, go
to a stored posture whose conditions are nearest ([0097]: "the tool posture at
the most similar cutting conditions (depth, pick feed, feed direction ...)").

Conditions (:class:`CuttingConditions`): spindle speed, depth of cut, pick
feed, surface normal and feed direction (unit vectors, workpiece frame; the
feed projected onto the plane normal to the surface) and a tool identifier.
Postures are lead and tilt [rad] as in ``orient/geometry.py``.

Distance between two conditions with the same tool (different tools are never
similar; they are not compared)::

    d^2 = (ln(rpm1 / rpm2) / speed_rel)^2 + ((depth1 - depth2) / depth_mm)^2
        + ((pick1 - pick2) / pick_mm)^2
        + (|n1 - n2| / angle_rad)^2 + (|f1 - f2| / angle_rad)^2

with the scales of :class:`MemoryScales`: one unit of distance is about a
10 % speed difference, 0.1 mm of depth or pick feed, or 10 degrees between
normals or feed directions (``|n1 - n2| = 2 sin(angle / 2)``, the chord, which is
the angle for small angles and keeps the distance Euclidean in a feature
space). Queries are brute force for small memories and use
:class:`scipy.spatial.cKDTree` (per tool) from ``KDTREE_MIN_ENTRIES`` entries on.

Files: JSON, written atomically (temporary file + ``os.replace``), read back
with every field checked; a bad file raises :class:`PostureMemoryError`
naming the file, the entry and the key.
"""

from __future__ import annotations

import json
import math
import numbers
import os
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from nc.atomic import atomic_write
from nc.errors import InputError
from nc.checks import real_number as _real
from .constants import (
    DEFAULT_ANGLE_RAD,
    DEFAULT_DEPTH_MM,
    DEFAULT_PICK_MM,
    DEFAULT_SPEED_REL,
    KDTREE_MIN_ENTRIES,
    MIN_FEED_SINE,
    MIN_VECTOR_NORM,
)

__all__ = [
    "FILE_FORMAT",
    "FILE_VERSION",
    "CuttingConditions",
    "MemoryMatch",
    "MemoryScales",
    "PostureMemory",
    "PostureMemoryError",
    "RememberedPosture",
]

#: ``format`` tag and ``version`` of the JSON file.
FILE_FORMAT = "orient.posture_memory"
FILE_VERSION = 1
#: Vectors within this of unit length (and feeds within this of perpendicular)
#: are stored as given, so that normalizing twice changes no bit [-].
_UNIT_TOL = 4.0 * np.finfo(float).eps


class PostureMemoryError(InputError):
    """A posture-memory file that cannot be read; the message names file, entry, key."""


def _unit(name: str, value: Any) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: expected 3 finite components, got {value!r}")
    norm = float(np.linalg.norm(v))
    if norm < MIN_VECTOR_NORM:
        raise ValueError(f"{name}: expected a non-zero vector, got {value!r}")
    # already unit (e.g. read back from a file): keep the bits, so storing is idempotent
    return v if abs(norm - 1.0) <= _UNIT_TOL else v / norm


@dataclass(frozen=True)
class CuttingConditions:
    """Conditions of a cutter location, in normalized form.

    Parameters
    ----------
    spindle_rpm : float [rev/min]
        > 0.
    depth_mm : float [mm]
        Depth of cut, >= 0.
    pick_mm : float [mm]
        Pick feed (step-over), >= 0.
    normal : array_like, shape (3,) [-]
        Surface normal, outward of the workpiece; stored normalized.
    feed_dir : array_like, shape (3,) [-]
        Feed direction; stored projected onto the plane normal to ``normal``
        and normalized (refused if parallel to the normal).
    tool_id : str
        Identifier of the tool (and holder); conditions of different tools are
        never compared.
    """

    spindle_rpm: float
    depth_mm: float
    pick_mm: float
    normal: tuple[float, float, float]
    feed_dir: tuple[float, float, float]
    tool_id: str

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "spindle_rpm", _real("spindle_rpm", self.spindle_rpm, ">0"))
        set_(self, "depth_mm", _real("depth_mm", self.depth_mm, ">=0"))
        set_(self, "pick_mm", _real("pick_mm", self.pick_mm, ">=0"))
        n = _unit("normal", self.normal)
        f = _unit("feed_dir", self.feed_dir)
        if abs(f @ n) > _UNIT_TOL:
            f = f - (f @ n) * n
            if np.linalg.norm(f) < MIN_FEED_SINE:
                raise ValueError(f"feed_dir: expected a direction not parallel to the normal, "
                                 f"got {self.feed_dir!r}")
            f = _unit("feed_dir", f)
        set_(self, "normal", tuple(float(c) for c in n))
        set_(self, "feed_dir", tuple(float(c) for c in f))
        if not isinstance(self.tool_id, str) or not self.tool_id:
            raise ValueError(f"tool_id: expected a non-empty string, got {self.tool_id!r}")


@dataclass(frozen=True)
class MemoryScales:
    """Scales of the condition distance: one unit of distance per ...

    Parameters
    ----------
    speed_rel : float [-]
        ... this relative spindle-speed difference (as ``ln`` of the ratio).
    depth_mm : float [mm]
        ... this difference in depth of cut.
    pick_mm : float [mm]
        ... this difference in pick feed.
    angle_rad : float [rad]
        ... this angle between normals or between feed directions (chord).
    """

    speed_rel: float = DEFAULT_SPEED_REL
    depth_mm: float = DEFAULT_DEPTH_MM
    pick_mm: float = DEFAULT_PICK_MM
    angle_rad: float = DEFAULT_ANGLE_RAD

    def __post_init__(self) -> None:
        for name in ("speed_rel", "depth_mm", "pick_mm", "angle_rad"):
            _real(name, getattr(self, name), ">0")

    def features(self, c: CuttingConditions) -> np.ndarray:
        """Feature vector, shape (9,) [-], whose Euclidean distances are the distances."""
        return np.concatenate([
            [math.log(c.spindle_rpm) / self.speed_rel, c.depth_mm / self.depth_mm,
             c.pick_mm / self.pick_mm],
            np.asarray(c.normal) / self.angle_rad, np.asarray(c.feed_dir) / self.angle_rad])


@dataclass(frozen=True)
class RememberedPosture:
    """A chatter-free posture and its conditions.

    Attributes
    ----------
    conditions : CuttingConditions
    lead_rad, tilt_rad : float [rad]
    note : str
        Free text (where it came from).
    """

    conditions: CuttingConditions
    lead_rad: float
    tilt_rad: float
    note: str = ""


@dataclass(frozen=True)
class MemoryMatch:
    """A remembered posture and its distance [-] to the queried conditions."""

    entry: RememberedPosture
    distance: float


class PostureMemory:
    """Chatter-free postures with their conditions; nearest-condition queries.

    Parameters
    ----------
    scales : MemoryScales
        Scales of the distance.
    """

    def __init__(self, scales: MemoryScales | None = None) -> None:
        self.scales = MemoryScales() if scales is None else scales
        if not isinstance(self.scales, MemoryScales):
            raise TypeError(f"scales: expected MemoryScales, got {type(scales).__name__}")
        self._entries: list[RememberedPosture] = []
        self._features: list[np.ndarray] = []
        self._by_tool: dict[str, list[int]] = {}
        self._trees: dict[str, cKDTree] = {}

    def __len__(self) -> int:
        return len(self._entries)

    @property
    def entries(self) -> tuple[RememberedPosture, ...]:
        """All remembered postures, in the order they were remembered."""
        return tuple(self._entries)

    def remember(self, conditions: CuttingConditions, lead_rad: float, tilt_rad: float,
                 note: str = "") -> RememberedPosture:
        """Store a chatter-free posture.

        Parameters
        ----------
        conditions : CuttingConditions
        lead_rad, tilt_rad : float [rad]
        note : str

        Returns
        -------
        RememberedPosture
        """
        if not isinstance(conditions, CuttingConditions):
            raise TypeError(f"conditions: expected CuttingConditions, "
                            f"got {type(conditions).__name__}")
        entry = RememberedPosture(conditions, _real("lead_rad", lead_rad),
                                  _real("tilt_rad", tilt_rad), str(note))
        self._by_tool.setdefault(conditions.tool_id, []).append(len(self._entries))
        self._entries.append(entry)
        self._features.append(self.scales.features(conditions))
        self._trees.pop(conditions.tool_id, None)
        return entry

    def distance(self, a: CuttingConditions, b: CuttingConditions) -> float:
        """Normalized distance between two conditions [-] (inf for different tools)."""
        if a.tool_id != b.tool_id:
            return math.inf
        return float(np.linalg.norm(self.scales.features(a) - self.scales.features(b)))

    def nearest(self, conditions: CuttingConditions, k: int = 1,
                max_distance: float = math.inf) -> list[MemoryMatch]:
        """The ``k`` remembered postures with the nearest conditions (same tool).

        Parameters
        ----------
        conditions : CuttingConditions
        k : int
            Number wanted, >= 1.
        max_distance : float [-]
            Matches farther than this are dropped.

        Returns
        -------
        list of MemoryMatch
            Sorted by increasing distance (ties: earlier remembered first);
            fewer than ``k`` (possibly none) when the memory has fewer matches.
        """
        if not isinstance(conditions, CuttingConditions):
            raise TypeError(f"conditions: expected CuttingConditions, "
                            f"got {type(conditions).__name__}")
        if isinstance(k, bool) or not isinstance(k, numbers.Integral) or k < 1:
            raise ValueError(f"k: expected an integer >= 1, got {k!r}")
        if not (isinstance(max_distance, numbers.Real) and max_distance >= 0):
            raise ValueError(f"max_distance: expected a value >= 0, got {max_distance!r}")
        idx = self._by_tool.get(conditions.tool_id, [])
        if not idx:
            return []
        q = self.scales.features(conditions)
        kk = min(int(k), len(idx))
        if len(idx) >= KDTREE_MIN_ENTRIES:
            tree = self._trees.get(conditions.tool_id)
            if tree is None:
                tree = cKDTree(np.array([self._features[i] for i in idx]))
                self._trees[conditions.tool_id] = tree
            dist, pos = tree.query(q, k=kk)
            dist, pos = np.atleast_1d(dist), np.atleast_1d(pos)
        else:
            feats = np.array([self._features[i] for i in idx])
            d_all = np.linalg.norm(feats - q, axis=1)
            pos = np.argsort(d_all, kind="stable")[:kk]
            dist = d_all[pos]
        return [MemoryMatch(self._entries[idx[int(p)]], float(d))
                for d, p in zip(dist, pos, strict=True) if d <= max_distance]

    # --- files -----------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready contents (see :meth:`save`)."""
        return {
            "format": FILE_FORMAT, "version": FILE_VERSION,
            "scales": asdict(self.scales),
            "entries": [{**asdict(e.conditions), "normal": list(e.conditions.normal),
                         "feed_dir": list(e.conditions.feed_dir), "lead_rad": e.lead_rad,
                         "tilt_rad": e.tilt_rad, "note": e.note} for e in self._entries],
        }

    def save(self, path: str | os.PathLike) -> None:
        """Write the memory to a JSON file, atomically.

        Parameters
        ----------
        path : path-like
            Target file; its directory must exist.
        """
        text = json.dumps(self.to_dict(), indent=1, allow_nan=False)
        with atomic_write(path) as fh:
            fh.write(text + "\n")

    @classmethod
    def from_dict(cls, data: Any, source: str = "<dict>") -> PostureMemory:
        """Memory from :meth:`to_dict` output; errors name ``source``, entry and key."""
        def fail(msg: str) -> PostureMemoryError:
            return PostureMemoryError(f"{source}: {msg}")

        if not isinstance(data, dict):
            raise fail(f"expected a JSON object at the top, got {type(data).__name__}")
        if data.get("format") != FILE_FORMAT:
            raise fail(f"format: expected {FILE_FORMAT!r}, got {data.get('format')!r}")
        if data.get("version") != FILE_VERSION:
            raise fail(f"version: expected {FILE_VERSION}, got {data.get('version')!r}")
        try:
            scales = MemoryScales(**data.get("scales", {}))
        except (TypeError, ValueError) as exc:
            raise fail(f"scales: {exc}") from None
        entries = data.get("entries")
        if not isinstance(entries, list):
            raise fail(f"entries: expected a list, got {type(entries).__name__}")
        mem = cls(scales)
        keys = ("spindle_rpm", "depth_mm", "pick_mm", "normal", "feed_dir", "tool_id",
                "lead_rad", "tilt_rad")
        for i, e in enumerate(entries):
            if not isinstance(e, dict):
                raise fail(f"entries[{i}]: expected an object, got {type(e).__name__}")
            missing = [key for key in keys if key not in e]
            if missing:
                raise fail(f"entries[{i}]: missing key {missing[0]!r}")
            unknown = sorted(set(e) - set(keys) - {"note"})
            if unknown:
                raise fail(f"entries[{i}]: unknown key {unknown[0]!r}")
            try:
                cond = CuttingConditions(e["spindle_rpm"], e["depth_mm"], e["pick_mm"],
                                         e["normal"], e["feed_dir"], e["tool_id"])
                mem.remember(cond, e["lead_rad"], e["tilt_rad"], e.get("note", ""))
            except (TypeError, ValueError) as exc:
                raise fail(f"entries[{i}]: {exc}") from None
        return mem

    @classmethod
    def load(cls, path: str | os.PathLike) -> PostureMemory:
        """Read a memory written by :meth:`save`.

        Parameters
        ----------
        path : path-like

        Raises
        ------
        FileNotFoundError
            No such file.
        PostureMemoryError
            Not JSON, wrong format or version, or a bad entry (named).
        """
        path = os.fspath(path)
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
        try:
            data = json.loads(text, parse_constant=_refuse_constant)
        except (json.JSONDecodeError, ValueError) as exc:
            raise PostureMemoryError(f"{path}: not valid JSON: {exc}") from None
        return cls.from_dict(data, source=path)


def _refuse_constant(name: str) -> float:
    raise ValueError(f"non-finite number {name} not allowed")
