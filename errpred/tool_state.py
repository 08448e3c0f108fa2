"""The tool's wear state in a file: where one run ends, the next one starts.

A prediction carries the actual cutting distance ``cl`` of every micro edge
along the program (``docs/method.md`` §4; the same for every flute). A tool
that has already cut starts the next program from where it stopped, not from
zero: ``python -m errpred predict SCENARIO --tool-state-out state.json``
writes the end state, and the next scenario names it (``[tool] state =
"state.json"``) to start from it.

File format (JSON, UTF-8, written atomically; version 1)::

    {
      "format": "errpred-tool-state",
      "version": 1,
      "tool": {"type": "radius", "diameter_mm": 20.0, "corner_radius_mm": 1.0,
               "flutes": 2},
      "micro_edges": {"count": 92,
                      "kappa_deg": [...],          # contact angle of each micro edge
                      "z_mm": [...]},              # its height above the tip
      "cutting_distance_mm": [...],                # actual cutting distance, one per edge
      "max_cutting_distance_mm": 1234.5,           # for a reader's eye; not read back
      "written_by": {...}                          # provenance (scenario, program, lines,
    }                                              # command); not read back

``cutting_distance_mm[j]`` is micro edge ``j``'s actual cutting distance [mm],
finite and >= 0, in the order of :meth:`errpred.tool.Tool.micro_edges` (tip
first, up the corner arc and the flank). The numbers are written with every
digit (a state read back is the state written).

On reading (:func:`read_tool_state`) the file is checked as a whole: valid
JSON, the format name and version, every key present with the right type,
one finite, non-negative distance per micro edge. :func:`check_compatible`
then refuses a state made for another tool: type, diameter, corner radius,
number of flutes, and the micro edges (their number and positions: the same
tool and ``resolution.micro_edges``). Every problem is one
:class:`ToolStateError` line naming the file and the key.

This module does I/O only; the wear itself is carried by
:class:`errpred.physics.WearState`.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nc.atomic import atomic_write
from nc.errors import InputError

from . import constants as K
from .tool import MicroEdges, Tool

__all__ = ["FORMAT", "VERSION", "ToolState", "ToolStateError", "tool_state_document",
           "write_tool_state", "read_tool_state", "check_compatible"]

#: The ``format`` value of a tool-state file.
FORMAT = "errpred-tool-state"
#: The version this module writes and reads.
VERSION = 1


class ToolStateError(InputError):
    """A tool-state file that cannot be used; the message names file and key."""

    def __init__(self, file: str, key: str | None, message: str) -> None:
        self.file, self.key = file, key
        super().__init__(f"{file}: {key}: {message}" if key else f"{file}: {message}")


@dataclass(frozen=True, eq=False)
class ToolState:
    """A tool's wear state as read from a file.

    Attributes
    ----------
    kind : str
        Tool type (``ball``, ``radius``, ``flat``).
    diameter_mm, corner_radius_mm : float [mm]
    flutes : int
    kappa_rad, z_mm : ndarray, shape (m,) [rad, mm]
        Where the micro edges are.
    cl_mm : ndarray, shape (m,) [mm]
        Actual cutting distance of each micro edge.
    file : str
        Where it was read from (for messages).
    written_by : dict
        The file's provenance, as written.
    """

    kind: str
    diameter_mm: float
    corner_radius_mm: float
    flutes: int
    kappa_rad: np.ndarray
    z_mm: np.ndarray
    cl_mm: np.ndarray
    file: str = ""
    written_by: dict = field(default_factory=dict)


def tool_state_document(tool: Tool, kappa_rad: np.ndarray, z_mm: np.ndarray,
                        cl_mm: np.ndarray, written_by: dict[str, Any] | None = None
                        ) -> dict[str, Any]:
    """The JSON document of a wear state (see the module docstring).

    Parameters
    ----------
    tool : Tool
    kappa_rad, z_mm : ndarray, shape (m,) [rad, mm]
        Where the micro edges are (:class:`errpred.tool.MicroEdges`, or a
        prediction's ``edges_kappa_rad``, ``edges_z_mm``).
    cl_mm : ndarray, shape (m,) [mm]
        Actual cutting distance of each micro edge.
    written_by : dict, optional
        Provenance (JSON-serializable), stored unread.
    """
    cl = np.asarray(cl_mm, dtype=float)
    kappa, z = np.asarray(kappa_rad, dtype=float), np.asarray(z_mm, dtype=float)
    if not (cl.ndim == 1 and kappa.shape == z.shape == cl.shape):
        raise ValueError(f"tool state: {cl.shape} cutting distances for micro edges of shapes "
                         f"{kappa.shape}, {z.shape}")
    if not (np.all(np.isfinite(cl)) and np.all(cl >= 0)):
        raise ValueError("tool state: cutting distances must be finite and >= 0")
    return {
        "format": FORMAT,
        "version": VERSION,
        "tool": {"type": tool.kind, "diameter_mm": float(tool.diameter_mm),
                 "corner_radius_mm": float(tool.corner_radius_mm), "flutes": int(tool.flutes)},
        "micro_edges": {"count": int(cl.shape[0]),
                        "kappa_deg": [float(v) for v in np.degrees(kappa)],
                        "z_mm": [float(v) for v in z]},
        "cutting_distance_mm": [float(v) for v in cl],
        "max_cutting_distance_mm": float(cl.max(initial=0.0)),
        "written_by": dict(written_by or {}),
    }


def write_tool_state(path: str | os.PathLike, tool: Tool, kappa_rad: np.ndarray,
                     z_mm: np.ndarray, cl_mm: np.ndarray,
                     written_by: dict[str, Any] | None = None) -> None:
    """Write a wear state to ``path`` (JSON, atomically; arguments as
    :func:`tool_state_document`)."""
    doc = tool_state_document(tool, kappa_rad, z_mm, cl_mm, written_by)
    with atomic_write(path) as fh:
        json.dump(doc, fh, indent=1, allow_nan=False)
        fh.write("\n")


def _kind(v: Any) -> str:
    names = {dict: "an object", list: "an array", str: "a string", bool: "a boolean",
             int: "an integer", float: "a number", type(None): "null"}
    return names.get(type(v), type(v).__name__)


def _numbers(fail, v: Any, key: str, n: int, *, non_negative: bool) -> np.ndarray:
    if not isinstance(v, list):
        raise fail(key, f"expected an array of {n} numbers, got {_kind(v)}")
    if len(v) != n:
        raise fail(key, f"expected {n} numbers (micro_edges.count), got {len(v)}")
    for i, x in enumerate(v):
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise fail(f"{key}[{i}]", f"expected a number, got {_kind(x)} ({x!r})")
        if not math.isfinite(x):
            raise fail(f"{key}[{i}]", f"expected a finite number, got {x}")
        if non_negative and x < 0:
            raise fail(f"{key}[{i}]", f"expected a value >= 0, got {x:g}")
    return np.asarray(v, dtype=float)


def read_tool_state(path: str | os.PathLike) -> ToolState:
    """Read and check a tool-state file (format: module docstring).

    Raises
    ------
    ToolStateError
        File missing or unreadable, not JSON, another format or version, a key
        missing or of the wrong type, a count that does not match, a NaN,
        infinite or negative distance. One line, naming the file and the key.
    """
    file = os.fspath(path)

    def fail(key, message):
        return ToolStateError(file, key, message)

    try:
        with open(file, encoding="utf-8") as fh:
            doc = json.load(fh)
    except FileNotFoundError:
        raise fail(None, f"tool-state file not found: {os.path.abspath(file)}") from None
    except IsADirectoryError:
        raise fail(None, "is a directory, expected a tool-state file (JSON)") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise fail(None, f"not valid JSON: {exc}") from None
    if not isinstance(doc, dict):
        raise fail(None, f"expected a JSON object, got {_kind(doc)}")
    if doc.get("format") != FORMAT:
        raise fail("format", f"expected {FORMAT!r} (a file written by --tool-state-out), got "
                             f"{doc.get('format')!r}")
    if doc.get("version") != VERSION:
        raise fail("version", f"expected {VERSION}, got {doc.get('version')!r}")
    for k in ("tool", "micro_edges", "cutting_distance_mm"):
        if k not in doc:
            raise fail(k, "missing")
    tool, me = doc["tool"], doc["micro_edges"]
    if not isinstance(tool, dict):
        raise fail("tool", f"expected an object, got {_kind(tool)}")
    if not isinstance(me, dict):
        raise fail("micro_edges", f"expected an object, got {_kind(me)}")
    for k in ("type", "diameter_mm", "corner_radius_mm", "flutes"):
        if k not in tool:
            raise fail(f"tool.{k}", "missing")
    if not isinstance(tool["type"], str):
        raise fail("tool.type", f"expected a string, got {_kind(tool['type'])}")
    dims = {}
    for k in ("diameter_mm", "corner_radius_mm"):
        v = tool[k]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or v < 0:
            raise fail(f"tool.{k}", f"expected a finite number >= 0, got {v!r}")
        dims[k] = float(v)
    fl = tool["flutes"]
    if isinstance(fl, bool) or not isinstance(fl, int) or fl < 1:
        raise fail("tool.flutes", f"expected a whole number >= 1, got {fl!r}")
    for k in ("count", "kappa_deg", "z_mm"):
        if k not in me:
            raise fail(f"micro_edges.{k}", "missing")
    n = me["count"]
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise fail("micro_edges.count", f"expected a whole number >= 1, got {n!r}")
    kappa = _numbers(fail, me["kappa_deg"], "micro_edges.kappa_deg", n, non_negative=False)
    z = _numbers(fail, me["z_mm"], "micro_edges.z_mm", n, non_negative=False)
    cl = _numbers(fail, doc["cutting_distance_mm"], "cutting_distance_mm", n, non_negative=True)
    wb = doc.get("written_by", {})
    return ToolState(tool["type"], dims["diameter_mm"], dims["corner_radius_mm"], fl,
                     np.radians(kappa), z, cl, file, wb if isinstance(wb, dict) else {})


def check_compatible(state: ToolState, tool: Tool, edges: MicroEdges) -> None:
    """Refuse a state made for another tool or another cut into micro edges.

    Raises
    ------
    ToolStateError
        Naming the first mismatch: tool type, diameter, corner radius, flutes,
        number of micro edges, their positions.
    """
    def fail(key, message):
        return ToolStateError(state.file, key, message)

    made = (f"made for a {state.kind} end mill D{state.diameter_mm:g} r{state.corner_radius_mm:g}"
            f" with {state.flutes} flute(s)")
    this = (f"this scenario's tool is a {tool.kind} end mill D{tool.diameter_mm:g} "
            f"r{tool.corner_radius_mm:g} with {tool.flutes} flute(s)")
    tol = K.TOOL_STATE_MATCH_MM
    if state.kind != tool.kind:
        raise fail("tool.type", f"{made}; {this}")
    if abs(state.diameter_mm - tool.diameter_mm) > tol:
        raise fail("tool.diameter_mm", f"{made}; {this}")
    if abs(state.corner_radius_mm - tool.corner_radius_mm) > tol:
        raise fail("tool.corner_radius_mm", f"{made}; {this}")
    if state.flutes != tool.flutes:
        raise fail("tool.flutes", f"{made}; {this}")
    if state.cl_mm.shape[0] != len(edges):
        raise fail("micro_edges.count", f"{state.cl_mm.shape[0]} micro edges; this scenario "
                                        f"cuts its tool into {len(edges)} (resolution."
                                        "micro_edges or tool.flute_length_mm differ)")
    dz = np.abs(state.z_mm - edges.z)
    dk = np.abs(state.kappa_rad - edges.kappa) * tool.radius_mm  # [mm] along the edge
    if max(dz.max(initial=0.0), dk.max(initial=0.0)) > tol:
        j = int(np.argmax(np.maximum(dz, dk)))
        raise fail("micro_edges", f"micro edge {j} sits at z {state.z_mm[j]:.6g} mm, kappa "
                                  f"{math.degrees(state.kappa_rad[j]):.6g} deg; this "
                                  f"scenario's at z {edges.z[j]:.6g} mm, kappa "
                                  f"{math.degrees(edges.kappa[j]):.6g} deg (resolution."
                                  "micro_edges or tool.flute_length_mm differ)")
