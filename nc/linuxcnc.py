"""Run LinuxCNC's standalone interpreter ``rs274`` and read its canonical calls.

LinuxCNC's ``rs274`` (Debian package ``linuxcnc-uspace``) interprets a
program offline and prints the canonical machining calls it would send to
the motion controller: ``STRAIGHT_TRAVERSE``, ``STRAIGHT_FEED`` and
``ARC_FEED`` with the end point of every move. This module runs it and turns
those calls into arrays comparable with :class:`~nc.program.Program`, which
is how programs this package writes (and reads) are checked against a real
interpreter.

``rs274`` prints positions with 4 decimals in the program's current length
units (``USE_LENGTH_UNITS``), rotary axes in degrees, and always reads its
tool table in inches.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .constants import MM_PER_INCH
from .program import PLANE_AXES, Program

__all__ = [
    "rs274_path",
    "Rs274Error",
    "CanonMoves",
    "Comparison",
    "run_rs274",
    "compare_with_rs274",
    "write_tool_table",
]

_CALL = re.compile(r"^\s*\d+\s+N\S*\s+([A-Z_]+)\((.*)\)\s*$")
_PLANES = {"CANON_PLANE_XY": 17, "CANON_PLANE_XZ": 18, "CANON_PLANE_YZ": 19}


def rs274_path() -> str | None:
    """Path of the ``rs274`` executable, or None when LinuxCNC is absent."""
    return shutil.which("rs274")


class Rs274Error(RuntimeError):
    """``rs274`` refused the program; the message is its own."""


@dataclass(frozen=True)
class CanonMoves:
    """The moves ``rs274`` reported, converted to this package's units.

    Attributes
    ----------
    kind : ndarray, shape (n,), str
        ``"TRAVERSE"``, ``"FEED"`` or ``"ARC"``.
    end : ndarray, shape (n, 6) [mm, mm, mm, deg, deg, deg]
        End point of each move in the program frame.
    resolution : ndarray, shape (n,) [mm]
        Half the last printed digit for each move's linear axes (0.00005 in
        the program's units), the best agreement the printout allows.
    turns : ndarray, shape (n,), int
        Signed turns of arcs (LinuxCNC's rotation argument), 0 for lines.
    centre : ndarray, shape (n, 3) [mm]
        Arc centre in the arc's plane (the axial coordinate and every
        coordinate of straight moves are NaN).
    lines : tuple of str
        The raw canonical output.
    """

    kind: np.ndarray
    end: np.ndarray
    resolution: np.ndarray
    turns: np.ndarray
    centre: np.ndarray
    lines: tuple[str, ...]


def write_tool_table(path: str | os.PathLike, lengths_mm: Mapping[int, float]) -> None:
    """Write a LinuxCNC tool table; ``rs274`` reads its lengths in inches.

    Parameters
    ----------
    path : path-like
        Where to write the ``.tbl`` file.
    lengths_mm : mapping of int to float [mm]
        Tool number -> tool length.
    """
    with open(path, "w", encoding="ascii") as fh:
        for tool, length in sorted(lengths_mm.items()):
            fh.write(f"T{int(tool)} P{int(tool)} Z{length / MM_PER_INCH:.6f} D0.0\n")


def run_rs274(path: str | os.PathLike, *, tool_lengths_mm: Mapping[int, float] | None = None,
              block_delete: bool = False, timeout_s: float = 120.0) -> CanonMoves:
    """Interpret ``path`` with LinuxCNC's ``rs274`` and collect its moves.

    Parameters
    ----------
    path : path-like
        The program.
    tool_lengths_mm : mapping, optional
        Tool table [mm]; a table with tool 1 of length 0 is used by default
        (``rs274`` needs one).
    block_delete : bool
        Turn the block-delete switch on (``-b``).
    timeout_s : float [s]
        Give up after this long.

    Raises
    ------
    FileNotFoundError
        When ``rs274`` is not installed.
    Rs274Error
        When ``rs274`` reports an error in the program (its message and the
        block, on one line) or does not finish within ``timeout_s``.
    """
    exe = rs274_path()
    if exe is None:
        raise FileNotFoundError("rs274 not found: install Debian's linuxcnc-uspace "
                                "(apt-get install --no-install-recommends linuxcnc-uspace)")
    with tempfile.TemporaryDirectory(prefix="rs274-") as tmp:
        tbl = os.path.join(tmp, "tool.tbl")
        write_tool_table(tbl, tool_lengths_mm or {1: 0.0})
        out = os.path.join(tmp, "canon.txt")
        # rs274 runs in the temporary folder: the program's path must not be relative
        args = [exe, "-t", tbl, "-g"] + (["-b"] if block_delete else []) + [
            os.path.abspath(path), out]
        try:
            proc = subprocess.run(args, capture_output=True, text=True, timeout=timeout_s,
                                  stdin=subprocess.DEVNULL, cwd=tmp)
        except subprocess.TimeoutExpired:
            raise Rs274Error(f"rs274 did not finish {os.fspath(path)} within "
                             f"{timeout_s:g} s") from None
        text = open(out, encoding="utf-8", errors="replace").read() if os.path.exists(out) else ""
    if proc.returncode != 0:
        msg = (proc.stderr.strip() or proc.stdout.strip()).replace("executing", "").strip()
        # one line: rs274 prints its message, then the block it refused
        msg = " | ".join(ln.strip() for ln in msg.splitlines() if ln.strip())
        if not msg:     # no message of rs274's own: how it ended says what happened
            code = proc.returncode
            msg = (f"killed by {signal.Signals(-code).name}" if code < 0
                   else f"exit status {code}") + ", no message"
        raise Rs274Error(f"rs274 refused {os.fspath(path)}: {msg}")
    return parse_canon(text)


def parse_canon(text: str) -> CanonMoves:
    """Turn ``rs274`` canonical output into :class:`CanonMoves`."""
    scale = 1.0
    plane = 17
    pos = np.zeros(6)
    kinds, ends, res, turns, centres = [], [], [], [], []
    lines = tuple(text.splitlines())
    for raw in lines:
        m = _CALL.match(raw)
        if not m:
            continue
        name, args = m.group(1), m.group(2)
        if name == "USE_LENGTH_UNITS":
            scale = MM_PER_INCH if "INCH" in args else (10.0 if "CM" in args else 1.0)
        elif name == "SELECT_PLANE":
            plane = _PLANES[args.strip()]
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            v = [float(x) for x in args.split(",")]
            end = np.array(v[:6])
            end[:3] *= scale
            kinds.append("TRAVERSE" if name == "STRAIGHT_TRAVERSE" else "FEED")
            ends.append(end)
            res.append(0.5e-4 * scale)
            turns.append(0)
            centres.append(np.full(3, np.nan))
            pos = end
        elif name == "ARC_FEED":
            v = [float(x) for x in args.split(",")]
            a1, a2, ax = PLANE_AXES[plane]
            end = pos.copy()
            end[a1], end[a2], end[ax] = v[0] * scale, v[1] * scale, v[5] * scale
            end[3:] = v[6:9]
            kinds.append("ARC")
            ends.append(end)
            res.append(0.5e-4 * scale)
            turns.append(int(v[4]))
            centre = np.full(3, np.nan)
            centre[a1], centre[a2] = v[2] * scale, v[3] * scale
            centres.append(centre)
            pos = end
    n = len(kinds)
    return CanonMoves(kind=np.array(kinds, dtype=object), end=np.array(ends).reshape(n, 6),
                      resolution=np.array(res), turns=np.array(turns, dtype=int),
                      centre=np.array(centres).reshape(n, 3), lines=lines)


@dataclass(frozen=True)
class Comparison:
    """This package's reading of a program against ``rs274``'s.

    Attributes
    ----------
    ok : bool
        Same number and kind of moves, end points within the printed
        resolution (0.00005 in the program's units, 0.00005 deg).
    moves : int
        Moves reported by ``rs274``.
    max_mm, max_deg : float
        Largest end-point difference [mm], [deg].
    message : str
        One line for people.
    """

    ok: bool
    moves: int
    max_mm: float
    max_deg: float
    message: str


_KINDS = {0: "TRAVERSE", 1: "FEED", 2: "ARC", 3: "ARC"}


def compare_with_rs274(path: str | os.PathLike, program: Program, **kwargs) -> Comparison:
    """Run ``rs274`` on ``path`` and compare its moves with ``program``.

    Parameters
    ----------
    path : path-like
        The program file.
    program : Program
        This package's reading of the same file.
    **kwargs
        Passed to :func:`run_rs274`.
    """
    canon = run_rs274(path, **kwargs)
    name = os.fspath(path)
    if len(canon.kind) != len(program):
        return Comparison(False, len(canon.kind), np.inf, np.inf,
                          f"{name}: rs274 reports {len(canon.kind)} moves, this reader "
                          f"{len(program)}")
    kinds = [_KINDS[int(m)] for m in program.motion]
    if kinds != list(canon.kind):
        i = next(k for k, (a, b) in enumerate(zip(kinds, canon.kind)) if a != b)
        return Comparison(False, len(kinds), np.inf, np.inf,
                          f"{name}:{program.line[i]}: rs274 makes a {canon.kind[i]} move, "
                          f"this reader a {kinds[i]} move")
    d_mm = np.abs(program.end[:, :3] - canon.end[:, :3])
    d_deg = np.abs(np.degrees(program.end[:, 3:]) - canon.end[:, 3:])
    ok = bool(np.all(d_mm <= canon.resolution[:, None] + 1e-9)
              and np.all(d_deg <= 0.5e-4 + 1e-9))
    max_mm = float(d_mm.max(initial=0.0))
    max_deg = float(d_deg.max(initial=0.0))
    word = "agrees" if ok else "DISAGREES"
    return Comparison(ok, len(kinds), max_mm, max_deg,
                      f"rs274 {word} with this reader on {name}: {len(kinds)} moves, largest "
                      f"difference {max_mm:.2g} mm, {max_deg:.2g} deg (rs274 prints 4 "
                      "decimals)")
