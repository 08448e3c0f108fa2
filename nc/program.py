"""Parsed NC programs: motion blocks with their modal state.

A :class:`Program` is columnar: one numpy array per quantity, one row per
motion block, so that a 10^6-block program stays compact and fast to
process. :class:`Block` objects are made on demand when a program is indexed
or iterated; they are views for people and for code that handles one block
at a time.

Frames and units (see ``docs/method.md`` §1): everything is in mm and
radians. End points are absolute, in the program's coordinate system (the
workpiece frame of the active work offset, G54...G59), which is what CAM
writes and what LinuxCNC's interpreter reports. :attr:`Program.end_machine`
adds the work offset of each block.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

__all__ = [
    "Modal",
    "Arc",
    "Block",
    "Program",
    "ProgramRows",
    "RAPID",
    "LINEAR",
    "ARC_CW",
    "ARC_CCW",
    "PLANE_AXES",
    "TCP_OFF",
    "TCP_ANGLES",
    "TCP_VECTOR",
    "split_lines",
]

#: Motion codes stored in :attr:`Program.motion` (the G number).
RAPID, LINEAR, ARC_CW, ARC_CCW = 0, 1, 2, 3

#: Tool-centre-point modes stored in :attr:`Modal.tcp`.
TCP_OFF, TCP_ANGLES, TCP_VECTOR = 0, 1, 2  # G49 / G43, G43.4, G43.5

#: For each plane (17, 18, 19): indices of the first and second in-plane axis
#: and of the axial direction, in the order LinuxCNC's canonical ARC_FEED uses.
PLANE_AXES: dict[int, tuple[int, int, int]] = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


@dataclass(frozen=True, slots=True)
class Modal:
    """The modal state a motion block runs under.

    Attributes
    ----------
    plane : int
        17, 18 or 19 (G17 XY, G18 ZX, G19 YZ).
    units : int
        20 (inch) or 21 (mm): the units the *program* speaks at this block.
        Values stored in :class:`Program` are always mm.
    distance : int
        90 (absolute) or 91 (incremental).
    arc_distance : int
        911 (G91.1, IJK incremental from the start, the default) or 901.
    feed_mode : int
        94 (units per minute) or 93 (inverse time).
    spindle_rpm : float
        Programmed spindle speed S [rev/min].
    spindle_dir : int
        +1 clockwise (M3), -1 counter-clockwise (M4), 0 stopped (M5).
    tool : int
        Active tool number (after the last M6); 0 before any change.
    length_offset : int
        H number of the active tool length offset; 0 when cancelled (G49).
    tcp : int
        Tool centre point mode: 0 off, 1 G43.4 (angles), 2 G43.5 (vector).
    wcs : int
        Work coordinate system: 1...6 for G54...G59.
    frame : int
        Row of :attr:`Program.frames`: the offset from the program frame to
        machine coordinates (work offset plus G92/G52 offset) at this block.
    """

    plane: int = 17
    units: int = 21
    distance: int = 90
    arc_distance: int = 911
    feed_mode: int = 94
    spindle_rpm: float = 0.0
    spindle_dir: int = 0
    tool: int = 0
    length_offset: int = 0
    tcp: int = TCP_OFF
    wcs: int = 1
    frame: int = 0

    @property
    def wcs_code(self) -> str:
        """The G code of the work coordinate system, e.g. ``"G54"``."""
        return f"G{53 + self.wcs}"


@dataclass(frozen=True, slots=True)
class Arc:
    """Geometry of a circular or helical arc move.

    Attributes
    ----------
    centre : ndarray, shape (3,) [mm]
        Centre in the arc's plane at the start's axial height.
    normal : ndarray, shape (3,)
        Unit axis of the arc plane (+Z for G17, +Y for G18, +X for G19).
    radius_start, radius_end : float [mm]
        Distances of start and end from the centre, in the plane. They differ
        within the reader's tolerance; expansion blends them linearly.
    sweep_rad : float [rad]
        Signed sweep about ``normal``: positive counter-clockwise (G3),
        negative clockwise (G2); full turns included.
    plane : int
        17, 18 or 19.
    """

    centre: np.ndarray
    normal: np.ndarray
    radius_start: float
    radius_end: float
    sweep_rad: float
    plane: int

    @property
    def turns(self) -> int:
        """Number of times the arc passes the start angle (LinuxCNC's P)."""
        return max(1, math.ceil(abs(self.sweep_rad) / (2 * math.pi) - 1e-12))


@dataclass(frozen=True, slots=True)
class Block:
    """One motion block, as a person reads it.

    Attributes
    ----------
    index : int
        Position among the program's motion blocks.
    line : int
        1-based source line number.
    text : str
        The source line, unchanged.
    motion : int
        0 rapid, 1 linear, 2 clockwise arc, 3 counter-clockwise arc.
    start, end : ndarray, shape (6,) [mm, mm, mm, rad, rad, rad]
        X Y Z A B C before and after the block, absolute, program frame.
    feed : float
        Programmed feed: [mm/min] under G94, [1/min] under G93; NaN if unset.
    modal : Modal
        The state the block runs under.
    arc : Arc or None
        Arc geometry for motion 2 and 3.
    tool_vector : ndarray, shape (3,), or None
        Programmed tool-axis unit vector under G43.5, else None.
    """

    index: int
    line: int
    text: str
    motion: int
    start: np.ndarray
    end: np.ndarray
    feed: float
    modal: Modal
    arc: Arc | None = None
    tool_vector: np.ndarray | None = None


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Program:
    """A parsed NC program: its motion blocks, columnar.

    Attributes
    ----------
    file : str
        Where the program came from (path, or ``"<string>"``).
    lines : tuple of str
        Every source line, unchanged (no line terminators).
    line : ndarray, shape (n,), int
        1-based source line of each motion block.
    motion : ndarray, shape (n,), int8
        0, 1, 2, 3 (G0...G3).
    end : ndarray, shape (n, 6) [mm, rad]
        Absolute X Y Z A B C after each block, program frame.
    initial : ndarray, shape (6,) [mm, rad]
        Position before the first block (the reader assumes the origin).
    feed : ndarray, shape (n,)
        Programmed feed [mm/min] (G94) or [1/min] (G93); NaN where unset.
    modal_index : ndarray, shape (n,), int
        Index into :attr:`modals` for each block.
    modals : tuple of Modal
        The distinct modal states of the program.
    tool_vector : ndarray, shape (n, 3)
        Tool-axis unit vector programmed under G43.5 (modal); NaN elsewhere.
    arc_index : ndarray, shape (n,), int
        Row into the arc arrays, -1 for straight moves.
    arc_centre : ndarray, shape (m, 3) [mm]
    arc_radius : ndarray, shape (m, 2) [mm]
        Start and end radius of each arc.
    arc_sweep : ndarray, shape (m,) [rad]
    arc_plane : ndarray, shape (m,), int
    work_offsets : ndarray, shape (6, 6) [mm, rad]
        Offsets of G54...G59 (rows) added to get machine coordinates.
    number : str or None
        Program number (``O`` word), if any.
    newline : str
        The line terminator of the source (``"\n"`` or ``"\r\n"``).
    allowed : frozenset of str
        Codes the caller allowed to pass without effect.
    block_delete : bool
        Whether lines starting with ``/`` were skipped.
    frames : ndarray, shape (k, 6) [mm, rad]
        The distinct offsets from the program frame to machine coordinates
        (work offset + G92/G52 offset) the program ran under; NaN where a
        G92/G10 L20 was programmed at a position not known.
    reframed : ndarray, shape (j,), int
        Blocks whose start is not the previous block's end as written, because
        the frame changed before them (G92, G52, G10, a switch of work offset):
        the tool did not move, its coordinates did.
    reframed_start : ndarray, shape (j, 6) [mm, rad]
        The start of those blocks in their own frame.
    machine_moves : ndarray, shape (k,), int
        Blocks whose end was given in machine coordinates: G53 moves and the
        second move of G28/G30 (to the reference point).
    drilling : ndarray, shape (d,), int
        Blocks made by canned drilling cycles (G73, G81...: :mod:`nc.cycles`),
        rapids and feeds, one row per move; they share their cycle's source line.
    rotated : ndarray, shape (r,), int
        Blocks written in a rotated frame (G68, G68.2: :mod:`nc.rotation`) or
        under G53.1's tool axis; :attr:`end` is in the work offset's frame.
    ignored : tuple of (str, int, int)
        Codes read and passed over (coolant, dwell, path blending, the
        caller's ``allow``...): code, count, first line; in order of first line.
    strict : bool
        Whether the program was read strictly (see :func:`nc.parse_program`).
    main_m99_line : int
        Source line of the M99 that ended the main program, read as its end
        as Centroid's controls read it (a Fanuc control would start the
        program again: the moves are one pass; :mod:`nc.macro_b`); 0 when
        the program ended otherwise.
    main_open_end_line : int
        Source line of the ``O`` program that the main program's text ran into
        without M30 or M02, read as the main program's end (a control that runs
        on through the file, LinuxCNC or Mach3, would execute that program's
        blocks too; :mod:`nc.macro_b`); 0 when the program ended otherwise.
    metadata : dict
        What a reader keeps beside the moves (the Heidenhain reader:
        ``dialect``, ``name``, ``units``, ``blk_form``); empty for G-code.
    """

    file: str
    lines: tuple[str, ...]
    line: np.ndarray
    motion: np.ndarray
    end: np.ndarray
    initial: np.ndarray
    feed: np.ndarray
    modal_index: np.ndarray
    modals: tuple[Modal, ...]
    tool_vector: np.ndarray
    arc_index: np.ndarray
    arc_centre: np.ndarray
    arc_radius: np.ndarray
    arc_sweep: np.ndarray
    arc_plane: np.ndarray
    work_offsets: np.ndarray = field(default_factory=lambda: np.zeros((6, 6)))
    number: str | None = None
    newline: str = "\n"
    allowed: frozenset[str] = frozenset()
    block_delete: bool = False
    ignored: tuple[tuple[str, int, int], ...] = ()
    strict: bool = False
    main_m99_line: int = 0
    main_open_end_line: int = 0
    frames: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    reframed: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    reframed_start: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    machine_moves: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    drilling: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    rotated: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    metadata: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("line", "motion", "end", "initial", "feed", "modal_index",
                     "tool_vector", "arc_index", "arc_centre", "arc_radius",
                     "arc_sweep", "arc_plane", "work_offsets", "frames", "reframed",
                     "reframed_start", "machine_moves", "drilling", "rotated"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))

    # --- sequence protocol ---------------------------------------------
    def __len__(self) -> int:
        return int(self.line.shape[0])

    def __iter__(self) -> Iterator[Block]:
        for i in range(len(self)):
            yield self[i]

    def __getitem__(self, i: int) -> Block:
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"block index {i} out of range for {n} blocks")
        i %= n
        arc = None
        k = int(self.arc_index[i])
        if k >= 0:
            plane = int(self.arc_plane[k])
            normal = np.zeros(3)
            normal[PLANE_AXES[plane][2]] = 1.0
            arc = Arc(self.arc_centre[k], normal, float(self.arc_radius[k, 0]),
                      float(self.arc_radius[k, 1]), float(self.arc_sweep[k]), plane)
        tv = self.tool_vector[i]
        return Block(
            index=i,
            line=int(self.line[i]),
            text=self.lines[int(self.line[i]) - 1],
            motion=int(self.motion[i]),
            start=self.start[i],
            end=self.end[i],
            feed=float(self.feed[i]),
            modal=self.modals[int(self.modal_index[i])],
            arc=arc,
            tool_vector=None if np.isnan(tv[0]) else tv,
        )

    # --- derived columns -------------------------------------------------
    @property
    def start(self) -> np.ndarray:
        """Start of each block, shape (n, 6) [mm, rad]: the previous end, in the
        block's own frame where the frame changed before it (:attr:`reframed`)."""
        if not len(self):
            return self.end
        start = np.vstack([self.initial[None, :], self.end[:-1]])
        if len(self.reframed):
            start[self.reframed] = self.reframed_start
        return start

    @property
    def known(self) -> np.ndarray:
        """Whether each block's start and end are known, shape (n,), bool.

        False from a G28/G30 whose reference point was not given (the reader
        was not told where the machine's point is) until absolute coordinates
        have given every axis a value again. Positions not known are NaN in
        :attr:`end`; nothing may be predicted or cut-simulated there
        (:func:`nc.path.cutter_locations` refuses such programs).
        """
        start = self.start
        return np.isfinite(start).all(axis=1) & np.isfinite(self.end).all(axis=1)

    @property
    def drilling_mask(self) -> np.ndarray:
        """Whether each block was made by a canned drilling cycle, shape (n,), bool."""
        mask = np.zeros(len(self), dtype=bool)
        mask[self.drilling] = True
        return mask

    def modal_column(self, name: str) -> np.ndarray:
        """One field of :class:`Modal` for every block, shape (n,)."""
        values = np.array([getattr(m, name) for m in self.modals])
        return values[self.modal_index] if len(values) else values

    @property
    def end_machine(self) -> np.ndarray:
        """End points in machine coordinates, shape (n, 6) [mm, rad]: plus each
        block's work offset and G92/G52 offset (NaN where not known)."""
        if len(self.frames):
            return self.end + self.frames[self.modal_column("frame").astype(int)]
        wcs = self.modal_column("wcs").astype(int) - 1
        return self.end + self.work_offsets[wcs]


class ProgramRows:
    """The rows a reader collects, and the :class:`Program` built from them (the
    Heidenhain and Siemens readers' states keep their output here; the G-code
    interpreter, :class:`nc.gcode_interp.Interpreter`, hands its columns over at the end).

    ``o_*`` are per-row lists (``o_end`` and ``o_tv`` flat, 6 and 3 per row), ``a_*``
    per-arc lists (``a_centre`` 3 and ``a_radius`` 2 per arc); ``modals`` the distinct
    modal states, ``modal_ids`` their index by key.
    """

    def init_rows(self) -> None:
        self.modal_ids: dict[tuple, int] = {}
        self.modals: list[Modal] = []
        self.o_line: list[int] = []
        self.o_motion: list[int] = []
        self.o_end: list[float] = []
        self.o_feed: list[float] = []
        self.o_modal: list[int] = []
        self.o_tv: list[float] = []
        self.o_arc: list[int] = []
        self.a_centre: list[float] = []
        self.a_radius: list[float] = []
        self.a_sweep: list[float] = []
        self.a_plane: list[int] = []

    def build_program(self, file: str, lines: tuple[str, ...], newline: str,
                      name: str | None, block_delete: bool, metadata: dict,
                      **extra) -> Program:
        """The :class:`Program` of the rows collected; ``extra``: further fields of it."""
        n = len(self.o_line)
        m = len(self.a_sweep)
        return Program(
            file=file, lines=lines,
            line=np.array(self.o_line, dtype=np.int64),
            motion=np.array(self.o_motion, dtype=np.int8),
            end=np.array(self.o_end, dtype=float).reshape(n, 6),
            initial=np.zeros(6),
            feed=np.array(self.o_feed, dtype=float),
            modal_index=np.array(self.o_modal, dtype=np.int64),
            modals=tuple(self.modals),
            tool_vector=np.array(self.o_tv, dtype=float).reshape(n, 3),
            arc_index=np.array(self.o_arc, dtype=np.int64),
            arc_centre=np.array(self.a_centre, dtype=float).reshape(m, 3),
            arc_radius=np.array(self.a_radius, dtype=float).reshape(m, 2),
            arc_sweep=np.array(self.a_sweep, dtype=float),
            arc_plane=np.array(self.a_plane, dtype=np.int64),
            number=name, newline=newline, block_delete=block_delete,
            metadata=dict(metadata), **extra)


def split_lines(text: str) -> tuple[list[str], str]:
    """A program's lines without terminators, and its newline (``"\n"`` or ``"\r\n"``).

    Split on ``"\n"`` only, as controls count lines (``str.splitlines`` would also
    split at form feeds and other separators); a final empty line is dropped, a
    trailing ``"\r"`` removed from each line. The newline is ``"\r\n"`` when it
    occurs in the first 64 KiB, so a written program keeps the source's.
    """
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    newline = "\n"
    if "\r" in text:
        newline = "\r\n" if "\r\n" in text[:65536] else "\n"
        lines = [ln[:-1] if ln.endswith("\r") else ln for ln in lines]
    return lines, newline
