"""Analysis at one cutter location of a planning scenario: its cut, its dynamics, its lobes.

The planner works on whole paths; a person checking one point wants its
stability lobes (both methods) with the operating point, for the CAM posture
or the planned one. :func:`point_setup` gathers what that needs from the
scenario alone (no planning run); :func:`point_lobes` draws on it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nc.errors import InputError
from nc.path import cutter_locations

from .contacts import Contacts, ball_contacts
from .cuts import local_cuts
from .dynamics import ModalSystem
from .engagement import LocalCut
from .gain import ProcessGain, process_gain
from .scenario import PlanScenario
from .stability import Lobes, stability_lobes
from .workpiece import WorkpieceModel
from .constants import LOBE_RANGE, LOBE_SPEEDS

__all__ = ["LOBE_SPEEDS", "PointSetup", "point_lobes", "point_setup"]



@dataclass(frozen=True, eq=False)
class PointSetup:
    """One cutter location: its contact, local cut, dynamics and spindle speed."""

    index: int
    contacts: Contacts
    cut: LocalCut
    system: ModalSystem
    spindle_rpm: float
    axis: np.ndarray


def point_setup(scn: PlanScenario, point: int | None = None, axis=None,
                spindle_rpm: float | None = None, *,
                workpiece: WorkpieceModel | None = None,
                contacts: Contacts | None = None) -> PointSetup:
    """Set up the analysis at cutter location ``point`` of the CAM path.

    Parameters
    ----------
    scn : PlanScenario
    point : int, optional
        Index into the CAM path's cutter locations; default the first point
        where the ball touches the design.
    axis : array_like, shape (3,), optional
        Tool axis to analyse (default: the CAM's at that point).
    spindle_rpm : float, optional [rev/min]
        Operating speed (default: the program's at that point), the feed per tooth
        kept.
    workpiece : orient.workpiece.WorkpieceModel, optional
        The part's model already built over its cutter locations (the planner's
        ``PlanResult.workpiece``); default: built for this point (its finite elements
        take seconds).
    contacts : orient.contacts.Contacts, optional
        The ball contacts of the CAM path already found (the planner's
        ``PlanResult.contacts``, the same for the planned path: the ball centre is kept);
        default: found here (FCL, about 1.2 ms a cutter location on the mold core).
    """
    cam = cutter_locations(scn.base.read_program(), scn.machine())
    if contacts is None:
        contacts = ball_contacts(cam, scn.base.tool.radius_mm, scn.base.stock.load_design())
    elif len(contacts.touching) != len(cam):
        raise ValueError(f"contacts: {len(contacts.touching)} cutter locations, the "
                         f"scenario's CAM path has {len(cam)}")
    idx = np.flatnonzero(contacts.touching)
    if len(idx) == 0:
        raise InputError(f"{scn.base.program_path}: the ball never touches the design")
    if point is None:
        point = int(idx[0])
    if not (0 <= point < len(cam)) or not contacts.touching[point]:
        raise InputError(f"--point: {point} is not a cutter location where the ball touches "
                         f"the design (the first such point is {int(idx[0])}, the last "
                         f"{int(idx[-1])})")
    rpm0 = float(cam.spindle_rpm[point])
    # the same local cut as the planner's (the first pass of a face cuts on both sides)
    cut = local_cuts(scn, contacts, idx, cam, rpm0)[int(np.searchsorted(idx, point))]
    rpm = rpm0 if spindle_rpm is None else float(spindle_rpm)
    u = cam.axis[point] if axis is None else np.asarray(axis, dtype=float)
    wp = workpiece if workpiece is not None else WorkpieceModel(scn.workpiece,
                                                                contacts.point[point][None])
    system = wp.system_at(ModalSystem.tool(scn.base.compliance), contacts.point[point])
    return PointSetup(point, contacts, cut, system.with_tool_axis(u), rpm, u)


def point_gain(scn: PlanScenario, setup: PointSetup) -> ProcessGain:
    """Process gain (with H over a tooth period) of the set-up point."""
    i = setup.index
    return process_gain(scn.base.tool, scn.base.coefficients, setup.axis,
                        setup.contacts.normal[i], setup.contacts.feed[i], setup.cut,
                        spindle_rpm=setup.spindle_rpm)


def point_lobes(scn: PlanScenario, setup: PointSetup, methods=("zoa", "sdm"),
                rpm=None) -> tuple[list[Lobes], tuple[float, float]]:
    """Stability lobes at the set-up point, and the operating point (rpm, depth mm)."""
    g = point_gain(scn, setup)
    if rpm is None:
        rpm = np.linspace(LOBE_RANGE[0] * setup.spindle_rpm, LOBE_RANGE[1] * setup.spindle_rpm,
                          LOBE_SPEEDS)
    depth = setup.cut.depth_mm
    out = [stability_lobes(g.H, setup.system, scn.base.tool.flutes, rpm, method=m,
                           depth_mm=depth) for m in methods]
    return out, (setup.spindle_rpm, depth)
