"""Cutter locations: tool tip, tool axis, feed and spindle along a path.

:class:`CutterLocations` is the currency between the packages: CAM output
read from a file, a program turned into points (arcs expanded within a chord
tolerance), planned postures, corrected paths. Arrays, one row per point, in
the workpiece frame (``docs/method.md`` §1): tip [mm], unit tool axis from
the tip toward the spindle, feed [mm/min], spindle speed [rev/min].
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from . import constants as K
from .errors import CLFileError, InputError, NCParseError
from .lexer import words_with_spans
from .program import PLANE_AXES, RAPID, TCP_ANGLES, TCP_OFF, TCP_VECTOR, Program

if TYPE_CHECKING:  # pragma: no cover
    from .kinematics import Machine

__all__ = [
    "CutterLocations",
    "expand_arcs",
    "block_lengths",
    "block_minutes",
    "cutter_locations",
    "read_cl_csv",
    "write_cl_csv",
]


def _check_finite(name: str, a: np.ndarray) -> None:
    if not np.all(np.isfinite(a)):
        bad = int(np.argwhere(~np.isfinite(a))[0][0])
        raise ValueError(f"{name}: row {bad} is not finite (NaN or inf)")


@dataclass(frozen=True, eq=False)
class CutterLocations:
    """Points of a tool path in the workpiece frame.

    Parameters
    ----------
    tip : ndarray, shape (n, 3) [mm]
        Tool tip (lowest point on the tool axis).
    axis : ndarray, shape (n, 3)
        Unit tool axis, tip toward spindle. Normalized on construction;
        vectors off unit length by more than ``nc.constants.UNIT_VECTOR_TOL``
        are refused.
    feed_mm_min : ndarray, shape (n,) [mm/min]
        Feed of the move that ends at each point (tip speed); NaN for rapids.
    spindle_rpm : ndarray, shape (n,) [rev/min]
        Spindle speed.
    block : ndarray, shape (n,), int
        Index of the source block (program block or CL row); -1 when none.
    rapid : ndarray, shape (n,), bool
        True where the move ending at the point is a rapid (G0).
    """

    tip: np.ndarray
    axis: np.ndarray
    feed_mm_min: np.ndarray
    spindle_rpm: np.ndarray
    block: np.ndarray
    rapid: np.ndarray

    def __post_init__(self) -> None:
        tip = np.asarray(self.tip, dtype=float)
        axis = np.asarray(self.axis, dtype=float)
        if tip.ndim != 2 or tip.shape[1] != 3:
            raise ValueError(f"tip: expected shape (n, 3), got {tip.shape}")
        n = tip.shape[0]
        if axis.shape != (n, 3):
            raise ValueError(f"axis: expected shape ({n}, 3), got {axis.shape}")
        _check_finite("tip", tip)
        _check_finite("axis", axis)
        norm = np.linalg.norm(axis, axis=1)
        off = np.abs(norm - 1.0) > K.UNIT_VECTOR_TOL
        if np.any(off):
            i = int(np.argmax(off))
            raise ValueError(f"axis: row {i} has length {norm[i]:.9g}; expected a unit "
                             f"vector (within {K.UNIT_VECTOR_TOL:g})")
        axis = axis / norm[:, None]
        fields = {"tip": tip, "axis": axis}
        for name, dtype in (("feed_mm_min", float), ("spindle_rpm", float),
                            ("block", np.int64), ("rapid", bool)):
            a = np.asarray(getattr(self, name), dtype=dtype)
            if a.shape != (n,):
                raise ValueError(f"{name}: expected shape ({n},), got {a.shape}")
            fields[name] = a
        rapid = fields["rapid"]
        feed = fields["feed_mm_min"]
        bad = ~rapid & ~(feed > 0)
        if np.any(bad):
            i = int(np.argmax(bad))
            raise ValueError(f"feed_mm_min: row {i} is {feed[i]!r}; expected a feed > 0 "
                             "for every cutting move")
        if not np.all(np.isfinite(feed[~rapid])):
            raise ValueError("feed_mm_min: not finite")
        spindle = fields["spindle_rpm"]
        if not np.all(np.isfinite(spindle)) or np.any(spindle < 0):
            raise ValueError("spindle_rpm: expected finite values >= 0")
        for name, a in fields.items():
            a = np.ascontiguousarray(a)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @classmethod
    def from_arrays(cls, tip, axis, feed_mm_min, spindle_rpm=0.0, block=None,
                    rapid=False) -> "CutterLocations":
        """Build from arrays, broadcasting scalars to every point."""
        tip = np.asarray(tip, dtype=float)
        n = tip.shape[0]
        return cls(tip=tip, axis=np.broadcast_to(np.asarray(axis, dtype=float), (n, 3)),
                   feed_mm_min=np.broadcast_to(np.asarray(feed_mm_min, dtype=float), (n,)),
                   spindle_rpm=np.broadcast_to(np.asarray(spindle_rpm, dtype=float), (n,)),
                   block=np.arange(n) if block is None else np.broadcast_to(block, (n,)),
                   rapid=np.broadcast_to(np.asarray(rapid, dtype=bool), (n,)))

    def __len__(self) -> int:
        return int(self.tip.shape[0])

    def take(self, index) -> "CutterLocations":
        """The points selected by ``index`` (slice, mask or integer array)."""
        return CutterLocations(self.tip[index], self.axis[index], self.feed_mm_min[index],
                               self.spindle_rpm[index], self.block[index], self.rapid[index])

    def segment_lengths(self) -> np.ndarray:
        """Tip distance from each point's predecessor, shape (n,) [mm]; 0 first."""
        d = np.zeros(len(self))
        d[1:] = np.linalg.norm(np.diff(self.tip, axis=0), axis=1)
        return d


# ---------------------------------------------------------------------------
def block_lengths(program: Program) -> np.ndarray:
    """Tool-tip path length of each block, shape (n,) [mm].

    Straight moves: the chord. Arcs: the helix length with the mean radius,
    ``sqrt((r |sweep|)^2 + axial^2)``.
    """
    start, end = program.start, program.end
    length = np.linalg.norm(end[:, :3] - start[:, :3], axis=1)
    arcs = program.arc_index >= 0
    if np.any(arcs):
        k = program.arc_index[arcs]
        r = program.arc_radius[k].mean(axis=1)
        axial_idx = np.array([PLANE_AXES[int(p)][2] for p in program.arc_plane[k]])
        rows = np.flatnonzero(arcs)
        axial = end[rows, axial_idx] - start[rows, axial_idx]
        length[arcs] = np.hypot(r * np.abs(program.arc_sweep[k]), axial)
    return length


def block_minutes(program: Program, lengths_mm: np.ndarray | None = None,
                  feeds: np.ndarray | None = None) -> np.ndarray:
    """Time of each block at its feed, shape (n,) [min].

    G94: path length of the programmed axes X Y Z / feed; a move that only
    turns rotary axes takes its feed in deg/min (LinuxCNC's rule). G95: the
    same with feed x spindle speed (F per revolution). G93: 1 / F. Rapids: 0
    (their speed is the machine's, not the program's). A G94/G95 block that
    moves no axis takes 0. A feed of 0 gives inf, a feed per revolution
    without a spindle speed inf or NaN (the readers refuse both).

    Parameters
    ----------
    program : Program
    lengths_mm : ndarray, shape (n,), optional [mm]
        Each block's path length (default :func:`block_lengths`, the
        programmed X Y Z; a caller may give the tool tip's).
    feeds : ndarray, shape (n,), optional [mm/min, mm/rev or 1/min]
        F of each block in its feed mode, in place of the program's (a
        schedule's feeds).
    """
    length = block_lengths(program) if lengths_mm is None else lengths_mm
    feed = program.feed if feeds is None else np.asarray(feeds, dtype=float)
    feed_mode = program.modal_column("feed_mode")
    minutes = np.zeros(len(program))
    cut = program.motion != RAPID
    travel = np.where(length > 0, length,
                      np.degrees(np.abs(program.end[:, 3:] - program.start[:, 3:]).max(axis=1)))
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = cut & (feed_mode == 93)
        minutes[inv] = 1.0 / feed[inv]
        per_min = cut & (feed_mode == 94) & (travel > 0)
        minutes[per_min] = travel[per_min] / feed[per_min]
        per_rev = cut & (feed_mode == 95) & (travel > 0)  # G95: F per spindle revolution
        if np.any(per_rev):
            rpm = program.modal_column("spindle_rpm")[per_rev]
            minutes[per_rev] = travel[per_rev] / (feed[per_rev] * rpm)
    return minutes


def _arc_segments(program: Program, chord_tol_mm: float) -> np.ndarray:
    """Segments per block so that arcs stay within the chord tolerance.

    Raises
    ------
    NCParseError
        Naming the file and line of an arc that would need more than
        ``MAX_ARC_CHORDS`` chords, or of the block at which the program's
        points pass ``MAX_PATH_POINTS``; nothing is expanded then.
    """
    nseg = np.ones(len(program), dtype=np.int64)
    arcs = program.arc_index >= 0
    if np.any(arcs):
        k = program.arc_index[arcs]
        r = program.arc_radius[k].max(axis=1)
        ratio = np.clip(1.0 - chord_tol_mm / np.maximum(r, 1e-12), -1.0, 1.0)
        max_step = 2.0 * np.arccos(ratio)  # angle whose sagitta equals the tolerance
        max_step = np.where(max_step > 0, max_step, np.pi)
        count = np.maximum(np.ceil(np.abs(program.arc_sweep[k])
                                   / np.minimum(max_step, np.pi / 2)), 1.0)
        over = ~(count <= K.MAX_ARC_CHORDS)  # in float: a count may not fit an integer
        if np.any(over):
            j = int(np.argmax(over))
            i = int(np.flatnonzero(arcs)[j])
            raise _block_error(program, i, (
                f"arc of radius {r[j]:.6g} mm sweeping "
                f"{np.degrees(abs(program.arc_sweep[k[j]])):.6g} deg needs {count[j]:,.0f} "
                f"chords at chord tolerance {chord_tol_mm:g} mm; "
                f"expected at most {K.MAX_ARC_CHORDS:,} (nc.constants.MAX_ARC_CHORDS): "
                "fewer turns P, a smaller radius or a larger tolerance"), "PRIJ")
        nseg[arcs] = count.astype(np.int64)
    if nseg.size and int(nseg.sum()) > K.MAX_PATH_POINTS:
        i = int(np.argmax(np.cumsum(nseg) > K.MAX_PATH_POINTS))
        raise _block_error(program, i, (
            f"the path expanded into chords (tolerance {chord_tol_mm:g} mm) passes "
            f"{K.MAX_PATH_POINTS:,} points here (nc.constants.MAX_PATH_POINTS; "
            f"{int(nseg.sum()):,} in all); expected fewer: a shorter program or a larger "
            "chord tolerance"), "")
    return nseg


def _block_error(program: Program, i: int, message: str, letters: str) -> NCParseError:
    """An error naming block ``i``'s file, line and the column of its first word
    among ``letters`` (P, then R, ...), or of its first word."""
    line = int(program.line[i])
    text = program.lines[line - 1] if 0 < line <= len(program.lines) else None
    column = None
    if text is not None:
        words = words_with_spans(text)
        found = [w for c in letters for w in words if w[0] == c] or words
        if found:
            column = found[0][2] + 1
    return NCParseError(message, file=program.file, line=line, column=column, text=text)


def expand_arcs(program: Program, chord_tol_mm: float = K.CHORD_TOL_MM
                ) -> tuple[np.ndarray, np.ndarray]:
    """Points along the program with arcs split into chords.

    Parameters
    ----------
    program : Program
    chord_tol_mm : float [mm]
        Largest distance between an arc and its chords.

    Returns
    -------
    points : ndarray, shape (m, 6) [mm, rad]
        End points of the chords, X Y Z A B C, program frame. The last point of
        each block is the block's end point exactly.
    block : ndarray, shape (m,), int
        Block index each point belongs to.

    Raises
    ------
    NCParseError
        Before any point is made, naming file, line and column, when one arc
        needs more than ``nc.constants.MAX_ARC_CHORDS`` chords or the whole
        path more than ``MAX_PATH_POINTS`` points.
    """
    if not chord_tol_mm > 0 or not math.isfinite(chord_tol_mm):
        raise ValueError(f"chord_tol_mm: expected a finite value > 0, got {chord_tol_mm!r}")
    n = len(program)
    nseg = _arc_segments(program, chord_tol_mm)
    block = np.repeat(np.arange(n), nseg)
    # fraction along the block: j/k for j = 1..k
    first = np.cumsum(nseg) - nseg
    j = np.arange(block.size) - first[block] + 1
    t = j / nseg[block]
    del j, first
    start, end = program.start, program.end
    step = (end - start)[block]  # in place below: fewer temporaries at the peak
    step *= t[:, None]
    pts = start[block]
    pts += step
    del step
    arcs = program.arc_index[block] >= 0
    if np.any(arcs):
        rows = np.flatnonzero(arcs)
        b = block[rows]
        k = program.arc_index[b]
        ta = t[rows]
        centre = program.arc_centre[k]
        planes = program.arc_plane[k]
        r = program.arc_radius[k, 0] + ta * (program.arc_radius[k, 1] - program.arc_radius[k, 0])
        for plane in np.unique(planes):
            sel = planes == plane
            a1, a2, _ = PLANE_AXES[int(plane)]
            rr, bb, cc = rows[sel], b[sel], centre[sel]
            ang0 = np.arctan2(start[bb, a2] - cc[:, a2], start[bb, a1] - cc[:, a1])
            ang = ang0 + ta[sel] * program.arc_sweep[k[sel]]
            pts[rr, a1] = cc[:, a1] + r[sel] * np.cos(ang)
            pts[rr, a2] = cc[:, a2] + r[sel] * np.sin(ang)
        last = np.cumsum(nseg) - 1
        pts[last] = end  # exact block ends
    return pts, block


# ---------------------------------------------------------------------------
def cutter_locations(program: Program, machine: "Machine | None" = None, *,
                     chord_tol_mm: float = K.CHORD_TOL_MM) -> CutterLocations:
    """Tool tip and axis along a program, arcs expanded.

    Parameters
    ----------
    program : Program
    machine : Machine, optional
        Needed when the program moves rotary axes: under G43.4 its angles give
        the tool axis; without tool centre point control its X Y Z A B C are
        machine axes, turned into tip and axis by the forward kinematics.
        3-axis programs (no rotary motion) and G43.5 programs need none.
    chord_tol_mm : float [mm]
        Chord tolerance of the arc expansion.

    Returns
    -------
    CutterLocations
        One point per chord end; rapids flagged, their feed NaN. Feeds in
        inverse time (G93) are turned into tip speed [mm/min].
    """
    known = program.known
    if not known.all():
        i = int(np.argmin(known))
        raise _block_error(program, i, "position not known from this block on (a G28/G30 "
                           "to a reference point that was not given); give the machine's "
                           "point, or program absolute X Y Z before cutting", "XYZ")
    pts, block = expand_arcs(program, chord_tol_mm)
    tcp = program.modal_column("tcp")[block] if len(program) else np.zeros(0, int)
    tip = pts[:, :3].copy()
    axis = np.tile([0.0, 0.0, 1.0], (len(block), 1))
    vec = program.tool_vector[block]
    has_vec = tcp == TCP_VECTOR
    if np.any(has_vec & np.isnan(vec[:, 0])):
        i = int(block[np.argmax(has_vec & np.isnan(vec[:, 0]))])
        raise _block_error(program, i, "G43.5 move before any tool vector I J K was "
                           "programmed; expected I J K in or before this block", "XYZ")
    axis[has_vec] = vec[has_vec]
    rotary = ~has_vec & np.any(np.abs(program.end[:, 3:]) > 0, axis=1)[block]
    rotary |= tcp == TCP_ANGLES
    if np.any(rotary):
        if machine is None:
            i = int(block[np.argmax(rotary)])
            raise _block_error(program, i, "the program moves rotary axes; a machine is "
                               "needed to turn them into a tool axis", "ABC")
        names = machine.rotary_names
        cols = ["XYZABC".index(c) for c in names]
        other = [c for c in "ABC" if c not in names]
        used_other = np.any(np.abs(pts[:, ["XYZABC".index(c) for c in other]]) > 0, axis=1)
        if np.any(used_other):
            raise _block_error(program, int(block[np.argmax(used_other)]),
                               f"the program moves {'/'.join(other)}, which machine "
                               f"{machine.name} does not have", "".join(other))
        joints = np.column_stack([pts[:, :3], pts[:, cols]])
        ftip, faxis = machine.forward(joints)
        direct = rotary & (tcp == TCP_OFF)
        axis[rotary] = faxis[rotary]
        tip[direct] = ftip[direct]
    # tip speed = tip travel in the workpiece / the block's time at its feed
    # (G94 feeds machine X Y Z, G93 gives the time; both differ from the
    # tip's own speed once rotary axes turn)
    start_tip = tip[0] if len(tip) else np.zeros(3)
    if len(program) and np.any(rotary):
        j0 = np.concatenate([program.initial[:3], program.initial[cols]])
        t0, _ = machine.forward(j0[None, :])
        start_tip = t0[0] if tcp[0] == TCP_OFF else program.initial[:3]
    elif len(program):
        start_tip = program.initial[:3]
    seg = np.linalg.norm(np.diff(np.vstack([start_tip[None, :], tip]), axis=0), axis=1)
    tip_len = np.bincount(block, weights=seg, minlength=len(program))
    minutes = block_minutes(program)
    with np.errstate(divide="ignore", invalid="ignore"):
        feed = np.where(minutes > 0, tip_len / minutes, np.nan)
    rapid = program.motion[block] == RAPID
    f = np.where(rapid, np.nan, feed[block])
    spindle = program.modal_column("spindle_rpm")[block]
    # A move that only turns rotary axes has no tip travel, so no tip feed: it
    # takes the feed of the cutting move before it (after it, at the start).
    f = np.where(~rapid & ~(f > 0), np.nan, f)
    cut = np.flatnonzero(~rapid)
    if cut.size:
        fc = f[cut]
        known = np.flatnonzero(np.isfinite(fc))
        if known.size == 0:
            raise _block_error(program, int(block[cut[0]]), "no cutting move moves the tool tip "
                               "(the first is here); cannot give the path a feed", "")
        nearest = np.maximum.accumulate(np.where(np.isfinite(fc), np.arange(fc.size), -1))
        nearest[nearest < 0] = known[0]
        f[cut] = fc[nearest]
    return CutterLocations(tip=tip, axis=axis, feed_mm_min=f, spindle_rpm=spindle,
                           block=block, rapid=rapid)


# ---------------------------------------------------------------------------
_CL_COLUMNS = ("x", "y", "z", "i", "j", "k", "feed")
_CL_OPTIONAL = ("spindle",)


def read_cl_csv(path: str | os.PathLike, *, spindle_rpm: float = 0.0) -> CutterLocations:
    """Read a cutter-location CSV file.

    The file has a header row naming the columns ``x, y, z, i, j, k, feed``
    (tip [mm], unit tool axis, feed [mm/min]) in any order, and optionally
    ``spindle`` [rev/min]. Lines starting with ``#`` are comments.

    Parameters
    ----------
    path : path-like
    spindle_rpm : float [rev/min]
        Spindle speed where the file has no ``spindle`` column.

    Raises
    ------
    CLFileError
        Naming the file, line and column of the first bad value.
    """
    name = os.fspath(path)
    with open(name, newline="", encoding="utf-8") as fh:
        rows = [(i + 1, r) for i, r in enumerate(csv.reader(fh))
                if r and not r[0].lstrip().startswith("#")]
    if not rows:
        raise CLFileError("empty file; expected a header row x,y,z,i,j,k,feed", file=name)
    header_line, header = rows[0]
    cols = [h.strip().lower() for h in header]
    missing = [c for c in _CL_COLUMNS if c not in cols]
    if missing:
        raise CLFileError(f"header lacks column(s) {', '.join(missing)}; expected "
                          "x,y,z,i,j,k,feed[,spindle]", file=name, line=header_line)
    unknown = [c for c in cols if c not in _CL_COLUMNS + _CL_OPTIONAL]
    if unknown:
        raise CLFileError(f"unknown column(s) {', '.join(unknown)}; expected "
                          "x,y,z,i,j,k,feed[,spindle]", file=name, line=header_line)
    want = _CL_COLUMNS + tuple(c for c in _CL_OPTIONAL if c in cols)
    idx = [cols.index(c) for c in want]
    data = np.empty((len(rows) - 1, len(want)))
    for r, (lineno, row) in enumerate(rows[1:]):
        if len(row) != len(cols):
            raise CLFileError(f"{len(row)} fields; expected {len(cols)}", file=name,
                              line=lineno)
        for c, j in enumerate(idx):
            text = row[j].strip()
            try:
                v = float(text)
            except ValueError:
                raise CLFileError(f"{text!r} is not a number", file=name, line=lineno,
                                  column=want[c]) from None
            if not math.isfinite(v):
                raise CLFileError(f"{text!r} is not a finite number", file=name,
                                  line=lineno, column=want[c])
            data[r, c] = v
    if data.shape[0] == 0:
        raise CLFileError("no data rows after the header", file=name, line=header_line)
    lines = np.array([ln for ln, _ in rows[1:]])
    norm = np.linalg.norm(data[:, 3:6], axis=1)
    off = np.abs(norm - 1.0) > K.UNIT_VECTOR_TOL
    if np.any(off):
        r = int(np.argmax(off))
        raise CLFileError(f"tool axis (i, j, k) has length {norm[r]:.9g}; expected a unit "
                          f"vector within {K.UNIT_VECTOR_TOL:g}", file=name,
                          line=int(lines[r]), column="i")
    bad = ~(data[:, 6] > 0)
    if np.any(bad):
        r = int(np.argmax(bad))
        raise CLFileError(f"feed {data[r, 6]!r}; expected a feed > 0 [mm/min]", file=name,
                          line=int(lines[r]), column="feed")
    spindle = data[:, 7] if data.shape[1] > 7 else np.full(len(data), float(spindle_rpm))
    if np.any(spindle < 0):
        r = int(np.argmax(spindle < 0))
        raise CLFileError("negative spindle speed; expected >= 0 [rev/min]", file=name,
                          line=int(lines[r]), column="spindle")
    return CutterLocations(tip=data[:, :3], axis=data[:, 3:6], feed_mm_min=data[:, 6],
                           spindle_rpm=spindle, block=np.arange(len(data)),
                           rapid=np.zeros(len(data), dtype=bool))


def write_cl_csv(path: str | os.PathLike, cl: CutterLocations, *, decimals: int = 6) -> None:
    """Write cutter locations as CSV (cutting moves only), atomically."""
    from .atomic import atomic_write

    keep = ~cl.rapid
    data = np.column_stack([cl.tip[keep], cl.axis[keep], cl.feed_mm_min[keep],
                            cl.spindle_rpm[keep]])
    fmt = f"%.{decimals}f"
    with atomic_write(path) as fh:
        fh.write("x,y,z,i,j,k,feed,spindle\n")
        np.savetxt(fh, data, fmt=fmt, delimiter=",")
