"""Figures a programmer checks first: blocks, path length, time, extent."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from . import constants as K
from .path import block_lengths, block_minutes, expand_arcs
from .program import ARC_CCW, ARC_CW, LINEAR, RAPID, Program

__all__ = ["ProgramSummary", "summarize", "blocks_as_json"]


@dataclass(frozen=True)
class ProgramSummary:
    """Summary of a program (lengths in mm, time in minutes, angles in degrees)."""

    file: str
    lines: int
    motion_blocks: int
    rapid_blocks: int
    linear_blocks: int
    arc_blocks: int
    cutting_length_mm: float
    rapid_length_mm: float
    cutting_time_min: float
    bbox_min_mm: tuple[float, float, float]
    bbox_max_mm: tuple[float, float, float]
    rotary_range_deg: dict[str, tuple[float, float]]
    tools: tuple[int, ...]
    spindle_rpm: tuple[float, float]
    units: tuple[str, ...]
    tcp_modes: tuple[str, ...]
    #: codes read and passed over: (code, count, first line)
    ignored: tuple[tuple[str, int, int], ...] = ()
    #: motion blocks at a position not known (after G28/G30 to a point not
    #: given): left out of the lengths, time and box
    unknown_blocks: int = 0
    unknown_first_line: int | None = None
    #: moves made by canned drilling cycles (G73, G81...): counted here, not
    #: in rapid/linear blocks; their feed moves in drilling length and time,
    #: not in the cutting ones (their rapids are in the rapid length)
    drilling_blocks: int = 0
    drilling_length_mm: float = 0.0
    drilling_time_min: float = 0.0
    #: source line of the M99 that ended the main program (read as its end, as
    #: Centroid's controls do; a Fanuc control would run it again), None if none
    main_m99_line: int | None = None
    #: source line of the O program the main program ran into without M30/M02
    #: (read as its end; a control running on would execute it), None if none
    main_open_end_line: int | None = None

    def as_dict(self) -> dict:
        """Plain types, ready for JSON."""
        return asdict(self)


def summarize(program: Program, chord_tol_mm: float = K.CHORD_TOL_MM) -> ProgramSummary:
    """Summarize a program; the bounding box covers arcs between their ends."""
    known = program.known
    length = np.where(known, block_lengths(program), 0.0)
    rapid = program.motion == RAPID
    drill = program.drilling_mask
    minutes = np.where(known, block_minutes(program, length), 0.0)
    if np.any(known):
        pts, block = expand_arcs(program, chord_tol_mm)
        # every known block's start too: after a position not known, a known
        # block starts where the last unknown one ended
        pts = np.vstack([program.start[known], pts[known[block]]])
        lo, hi = pts[:, :3].min(axis=0), pts[:, :3].max(axis=0)
    else:
        pts = np.zeros((0, 6))
        lo = hi = np.full(3, math.nan)
    rotary = {}
    for j, name in enumerate("ABC"):
        col = pts[:, 3 + j]
        if col.size and np.any(col != 0):
            rotary[name] = (float(np.degrees(col.min())), float(np.degrees(col.max())))
    tcp_names = {0: "off", 1: "G43.4", 2: "G43.5"}
    used = [program.modals[i] for i in np.unique(program.modal_index)]
    rpm = [m.spindle_rpm for m in used]
    return ProgramSummary(
        file=program.file,
        lines=len(program.lines),
        motion_blocks=len(program),
        rapid_blocks=int(np.sum(rapid & ~drill)),
        linear_blocks=int(np.sum((program.motion == LINEAR) & ~drill)),
        arc_blocks=int(np.sum((program.motion == ARC_CW) | (program.motion == ARC_CCW))),
        cutting_length_mm=float(length[~rapid & ~drill].sum()),
        rapid_length_mm=float(length[rapid].sum()),
        cutting_time_min=float(minutes[~drill].sum()),
        drilling_blocks=int(drill.sum()),
        drilling_length_mm=float(length[~rapid & drill].sum()),
        drilling_time_min=float(minutes[drill].sum()),
        bbox_min_mm=tuple(float(v) for v in lo),
        bbox_max_mm=tuple(float(v) for v in hi),
        rotary_range_deg=rotary,
        tools=tuple(sorted({m.tool for m in used})),
        spindle_rpm=(min(rpm), max(rpm)) if rpm else (0.0, 0.0),
        units=tuple(sorted({"inch" if m.units == 20 else "mm" for m in used})),
        tcp_modes=tuple(sorted({tcp_names[m.tcp] for m in used})),
        ignored=program.ignored,
        unknown_blocks=int(np.sum(~known)),
        unknown_first_line=int(program.line[np.argmin(known)]) if not known.all() else None,
        main_m99_line=program.main_m99_line or None,
        main_open_end_line=program.main_open_end_line or None,
    )


def blocks_as_json(program: Program) -> list[dict]:
    """Every motion block as a dict: line, motion code, end point, feed.

    End points are absolute in the program frame: ``xyz_mm`` [mm] and
    ``abc_deg`` [deg]; ``null`` on axes whose position is not known (after a
    G28/G30 whose point was not given). ``feed`` is as programmed in ``feed_mode``: [mm/min]
    for G94, [1/min] for G93; ``null`` when unset (rapids before any F).
    """
    feed_mode = program.modal_column("feed_mode")
    tcp = program.modal_column("tcp")
    drill = program.drilling_mask
    end = program.end
    xyz = np.round(end[:, :3], 9).tolist()
    abc = np.round(np.degrees(end[:, 3:]), 9).tolist()
    if not np.isfinite(end).all():  # not known after G28/G30: null
        xyz = [[None if v != v else v for v in row] for row in xyz]
        abc = [[None if v != v else v for v in row] for row in abc]
    feed = [None if math.isnan(f) else f for f in program.feed.tolist()]
    out = []
    for i in range(len(program)):
        d = {
            "line": int(program.line[i]),
            "motion": f"G{int(program.motion[i])}",
            "xyz_mm": xyz[i],
            "abc_deg": abc[i],
            "feed": feed[i],
            "feed_mode": f"G{int(feed_mode[i])}",
        }
        if drill[i]:
            d["drilling"] = True
        if tcp[i] == 2:
            d["tool_vector"] = np.round(program.tool_vector[i], 12).tolist()
        out.append(d)
    return out
