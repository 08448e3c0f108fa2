"""The local cut at each cutter location where the ball touches: depth and pick feed,
the side of the previous pass, the feed per tooth (what the process gain and the
simulated machine's cut are computed for; the planner's, the point analyses' and the
simulated machine's cut is this one).

From the part (:mod:`orient.part_cuts`: the in-process stock, errpred's stock and swept
tool solids) when the scenario has no ``[orient.cut]``; that table, when given,
overrides it for the whole program."""

from __future__ import annotations

import numpy as np

from nc.path import CutterLocations

from .contacts import Contacts
from .engagement import LocalCut
from .geometry import local_frame
from .part_cuts import cuts_from_part
from .scenario import PlanScenario

__all__ = ["FIRST_PASS_TOLERANCE", "local_cuts"]

#: A previous pass counts if an earlier contact lies within this fraction of the
#: pick feed of where it should be [-].
FIRST_PASS_TOLERANCE = 0.5


def local_cuts(scn: PlanScenario, contacts: Contacts, idx: np.ndarray, cam: CutterLocations,
               spindle_rpm: float, info: dict | None = None, *,
               from_part: bool = False) -> list[LocalCut]:
    """The local cut (depth and pick feed times the safety factor, side of the previous
    pass, feed per tooth at ``spindle_rpm`` [rev/min]) at cutter locations ``idx``.

    Without ``[orient.cut]``: from the part (:func:`orient.part_cuts.cuts_from_part`;
    a location in air gets depth 0, no cut). With it: its depth and pick feed
    everywhere; the previous pass lies on the ``machined_side``, where an earlier cutter
    location of ``idx`` touched within a pick feed (``FIRST_PASS_TOLERANCE`` of it);
    where none did (the first pass of a face), nothing is removed beside the tool and the
    ball cuts on both sides (``previous_side = 0``).

    ``info`` (a dict, optional) is filled with where the cut came from (``source``:
    ``"part"`` or ``"table"``) and, from the part, the seconds taken and the locations
    per state (air, cut, entry, exit).

    ``from_part``: from the part even where the scenario gives ``[orient.cut]`` (the
    simulated machine: the cut the program it runs makes, which a corrected program
    makes deeper than the planner's table says).
    """
    opt = scn.options
    cut = opt.cut
    if cut is None or from_part:
        return _from_part(scn, contacts, idx, cam, spindle_rpm, info)
    if info is not None:
        info["source"] = "table"
    _, b, _ = local_frame(contacts.normal[idx], contacts.feed[idx])
    side = np.sign(b @ cut.machined_side)
    side[np.abs(b @ cut.machined_side) < 1e-6] = 0.0
    side[~_previous_pass_cut(contacts.point[idx], b * side[:, None], cut.pick_mm)] = 0.0
    fz = cam.feed_mm_min[idx] / (spindle_rpm * scn.base.tool.flutes)
    return [LocalCut(cut.depth_mm * opt.safety_factor, cut.pick_mm * opt.safety_factor,
                     int(s), float(z)) for s, z in zip(side, fz)]


def _from_part(scn: PlanScenario, contacts: Contacts, idx: np.ndarray, cam: CutterLocations,
               spindle_rpm: float, info: dict | None) -> list[LocalCut]:
    sf = scn.options.safety_factor
    pc = cuts_from_part(scn.base.tool, scn.base.stock.load(), cam, contacts, idx)
    if info is not None:
        info.update(source="part", seconds=pc.seconds, **pc.counts())
    fz = cam.feed_mm_min[idx] / (spindle_rpm * scn.base.tool.flutes)
    deep = pc.depth_mm * sf
    # a stock top folded by the safety factor's deeper cut (1 + k depth <= 0): flat
    kf = np.where(1.0 + pc.curvature_f_1_mm * deep > 0.1, pc.curvature_f_1_mm, 0.0)
    kb = np.where(1.0 + pc.curvature_b_1_mm * deep > 0.1, pc.curvature_b_1_mm, 0.0)
    return [LocalCut(float(d) * sf, float(p) * sf, int(s), float(z), float(kf), float(kb))
            for d, p, s, z, kf, kb in zip(pc.depth_mm, pc.pick_mm, pc.previous_side, fz,
                                          kf, kb)]


def _previous_pass_cut(points: np.ndarray, toward: np.ndarray, pick_mm: float) -> np.ndarray:
    """True where an earlier point lies about one pick feed along ``toward`` (unit or
    zero vectors, (n, 3)) from each of ``points`` (n, 3) [mm], in path order."""
    from scipy.spatial import cKDTree

    if len(points) == 0 or pick_mm <= 0:
        return np.zeros(len(points), bool)
    tol = FIRST_PASS_TOLERANCE * pick_mm
    tree = cKDTree(points)
    out = np.zeros(len(points), bool)
    for k, near in enumerate(tree.query_ball_point(points + pick_mm * toward, tol)):
        out[k] = bool(near) and min(near) < k and np.any(toward[k])
    return out
