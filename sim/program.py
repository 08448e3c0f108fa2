"""The program and the part as both sides of the machine see them (no I/O of its own)."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from nc.errors import InputError
from nc.path import cutter_locations
from orient.contacts import ball_contacts
from orient.geometry import lead_tilt_of
from orient.cuts import local_cuts
from orient.scenario import PlanScenario

from .constants import CUTTING_GAP_MM

__all__ = ["PartProgram"]


class PartProgram:
    """The scenario's program through its machine, and where the ball meets the part.

    Parameters
    ----------
    scn : orient.scenario.PlanScenario
    points : tuple (first, last), optional
        The stretch of cutter locations that will run (default: all); its highest
        spindle speed sets the local cuts' feed per tooth.
    cuts : bool
        Derive the local cuts (``cuts``; False: none, the geometry alone).

    Attributes
    ----------
    machine, cam
        The machine and the program's cutter locations.
    cam_line : ndarray of int, shape (n,)
        Source line (1-based) of each cutter location's block (0: none).
    contacts : orient.contacts.Contacts
        Ball contacts with the design surface; ``touching`` here is where the simulated
        machine cuts: a feed move whose ball is within ``CUTTING_GAP_MM`` of the design
        or deeper in it (orient's contacts take ``|gap| <= tol``, which made a gouging
        program's deepest points air to the simulation). A ball standing off the design
        by more than the tolerance is still air, even where it reaches into the stock's
        allowance: the local cut assumes the ball on the design.
    touch : ndarray of int
        Cutter locations where the ball touches (cuts).
    rapid_in_material : ndarray of bool
        Rapid moves whose ball ends inside the design (a crash on a machine; the
        simulation does not cut at rapid moves, :class:`sim.verify.Verification` reports
        them as not covered).
    cuts : dict of int -> orient.engagement.LocalCut
        The local cut at each touching cutter location (of the whole program, whatever
        the stretch); empty with ``cuts=False``.
    with_cuts : bool
        The ``cuts`` argument.
    cam_lead, cam_tilt : ndarray [rad]
        The program's own posture at each cutter location.
    first, last : int
        The stretch that runs.
    rpm : float [rev/min]
        Its highest spindle speed.
    """

    def __init__(self, scn: PlanScenario, points: tuple[int, int] | None = None, *,
                 cuts: bool = True) -> None:
        base = scn.base
        self.scn = scn
        self.machine = scn.machine()
        program = base.read_program()
        self.cam = cutter_locations(program, self.machine)
        self.cam_line = np.where(self.cam.block >= 0,
                                 program.line[np.maximum(self.cam.block, 0)], 0)
        self.first, self.last = _bounds(points, len(self.cam))
        first, last = self.first, self.last
        self.design = base.stock.load_design()
        # a corrected program's ball stands micrometres off the design and still cuts; a
        # ball deeper in the design (a gouge) cuts all the more
        contacts = ball_contacts(self.cam, base.tool.radius_mm, self.design,
                                 tol_mm=CUTTING_GAP_MM)
        gap = contacts.gap_mm
        self.contacts = dataclasses.replace(contacts,
                                            touching=~self.cam.rapid & (gap <= CUTTING_GAP_MM))
        self.rapid_in_material = self.cam.rapid & (gap < 0.0)
        self.touch = np.flatnonzero(self.contacts.touching)
        self.rpm = float(np.nanmax(self.cam.spindle_rpm[first:last + 1]))
        # the cut this program makes, from the part (the stock and the program's earlier
        # moves), not the planner's [orient.cut] table: a corrected program cuts deeper
        # than the table says (the bundled thin wall's top pass 0.222-0.229 mm against its
        # 0.2 mm), and the force of that depth is what its verification must see. At every
        # touching location, whatever the stretch: a pass's pick feed is derived from its
        # neighbours (the first pass's from the second)
        self.with_cuts = bool(cuts)
        run = self.touch if cuts else self.touch[:0]
        cuts = local_cuts(scn, self.contacts, run, self.cam, self.rpm,
                          from_part=True) if run.size else []
        self.cuts = dict(zip(run.tolist(), cuts, strict=True))
        lead, tilt = lead_tilt_of(self.cam.axis, self.contacts.normal, self.contacts.feed)
        self.cam_lead, self.cam_tilt = np.asarray(lead), np.asarray(tilt)

    def stretch(self, points: tuple[int, int] | None) -> PartProgram:
        """The same program and part for the stretch ``points`` (None: all), without
        deriving them again where the stretch's highest spindle speed is this one's (the
        local cuts' feed per tooth is taken at it); else made anew for the stretch."""
        first, last = _bounds(points, len(self.cam))
        rpm = float(np.nanmax(self.cam.spindle_rpm[first:last + 1]))
        if rpm != self.rpm:
            return PartProgram(self.scn, points, cuts=self.with_cuts)
        out = copy.copy(self)
        out.first, out.last = first, last
        return out


def _bounds(points: tuple[int, int] | None, n: int) -> tuple[int, int]:
    """``(first, last)`` of a stretch of ``n`` cutter locations (None: all), checked."""
    first, last = (0, n - 1) if points is None else (int(points[0]), int(points[1]))
    if not 0 <= first < last < n:
        raise InputError(f"--points: expected 0 <= FIRST < LAST < {n} (the program's "
                         f"cutter locations), got {points!r}")
    return first, last
