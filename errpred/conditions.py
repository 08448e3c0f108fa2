"""A program's cutting conditions checked against the tool before anything is predicted.

The force model takes the chip thickness as ``fz sin(phi)`` (``docs/method.md`` §4), the
first term of the trochoidal tooth path's; a feed per tooth that is a large share of
the tool's radius is outside it, and in practice a program's mistake (a feed scaled
by a wrong factor, a feed meant in inches per minute read in millimetres). Such a
program is refused at its first such block, naming the line, instead of being
predicted at errors of metres.
"""

from __future__ import annotations

import numpy as np

from nc.errors import NCParseError
from nc.path import CutterLocations
from nc.program import Program

from . import constants as K
from .tool import Tool

__all__ = ["feed_per_tooth_mm", "largest_feed_per_tooth_mm", "refuse_feed_beyond_model"]


def feed_per_tooth_mm(cl: CutterLocations, flutes: int) -> np.ndarray:
    """Feed per tooth of the move ending at each cutter location [mm], (n,): the feed
    over the spindle speed and the flutes; NaN for rapids and where the spindle stands
    or the feed is unset."""
    feed = np.asarray(cl.feed_mm_min, float)
    rpm = np.abs(np.asarray(cl.spindle_rpm, float))
    with np.errstate(divide="ignore", invalid="ignore"):
        fz = feed / (rpm * flutes)
    return np.where(cl.rapid | ~(rpm > 0) | ~np.isfinite(fz), np.nan, fz)


def largest_feed_per_tooth_mm(tool: Tool) -> float:
    """The largest feed per tooth the force model accepts for ``tool`` [mm]:
    ``MAX_FEED_PER_TOOTH_RADII`` of its radius."""
    return K.MAX_FEED_PER_TOOTH_RADII * tool.radius_mm


def refuse_feed_beyond_model(program: Program, cl: CutterLocations, tool: Tool) -> None:
    """Refuse a program whose feed per tooth exceeds ``MAX_FEED_PER_TOOTH_RADII`` of the
    tool's radius (:mod:`errpred.constants`).

    Parameters
    ----------
    program : Program
        The program ``cl`` comes from (for the line named).
    cl : CutterLocations
        Its cutter locations (feeds [mm/min], spindle speeds [rev/min]).
    tool : Tool

    Raises
    ------
    nc.errors.NCParseError
        At the first such block's line: the feed, the speed, the feed per tooth and
        the largest the model accepts.
    """
    fz = feed_per_tooth_mm(cl, tool.flutes)
    limit = largest_feed_per_tooth_mm(tool)
    over = np.flatnonzero(fz > limit)
    if not over.size:
        return
    k = int(over[0])
    b = int(cl.block[k])
    line = int(program.line[b]) if 0 <= b < len(program) else None
    text = program.lines[line - 1] if line is not None and line - 1 < len(program.lines) else ""
    raise NCParseError(
        f"feed {cl.feed_mm_min[k]:.6g} mm/min at {abs(cl.spindle_rpm[k]):.6g} rev/min is "
        f"{fz[k]:.4g} mm a tooth for the {tool.flutes}-flute D{tool.diameter_mm:g} tool "
        f"({over.size} move{'s' if over.size > 1 else ''} so); expected at most "
        f"{limit:.4g} mm ({K.MAX_FEED_PER_TOOTH_RADII:g} of the tool's radius, "
        "errpred.constants.MAX_FEED_PER_TOOTH_RADII: the force model's chip thickness "
        "holds below it); check the program's feeds and units",
        file=program.file, line=line, text=text)
