"""The links between passes (issue 20): a pass that ends tilted leaves straight along the
CAM's retract in its last posture, the rotary axes turn at the link's top, and the tool
descends in the next pass's first posture.

A 3-axis CAM path of two passes along +X joined by the usual link (``G0`` up to the
clearance height, over, down to 1 mm above the next pass, a feed plunge). The planned
postures are given (a pass tilted 48 deg, as the mold core's passes end under the pole
floor, then another); :func:`orient.plan._place_all` places every point and the writer
writes the program. Before, the retract took the CAM's vertical posture, so the ``G0``
leaving the pass turned B with the ball still at the surface.
"""

from __future__ import annotations

import math

import numpy as np

from nc.gcode import parse_program
from nc.kinematics import get_machine
from nc.path import CutterLocations, cutter_locations
from nc.writer import PostOptions, post
from orient.choice import _APPROACH, _IN_PASS, _RETRACT, _inherited
from orient.contacts import Contacts, feed_directions
from orient.plan import _place_all

R = 5.0
TOP = 25.0                          # the CAM's clearance height (tip) [mm]


def _cam() -> tuple[CutterLocations, np.ndarray]:
    """The CAM path and its touching points: pass 1 at y = 0 (tips on z = 0), the link
    (retract, over, descent), the plunge (air), pass 2 at y = 0.35."""
    xs = np.arange(0.0, 10.01, 1.0)
    p1 = np.c_[xs, np.zeros_like(xs), np.zeros_like(xs)]
    p2 = np.c_[xs[::-1], np.full_like(xs, 0.35), np.zeros_like(xs)]
    link = np.array([[10.0, 0.0, TOP], [10.0, 0.35, TOP], [10.0, 0.35, 1.0]])
    tips = np.vstack([p1, link, p2])
    rapid = np.zeros(len(tips), bool)
    rapid[len(p1):len(p1) + 3] = True
    cam = CutterLocations.from_arrays(tips, [0.0, 0.0, 1.0], np.where(rapid, np.nan, 1600.0),
                                      10000.0, rapid=rapid)
    touching = ~rapid
    touching[len(p1) + 3] = True            # the plunge's end is pass 2's first cut
    return cam, np.flatnonzero(touching)


def _contacts(cam: CutterLocations, idx: np.ndarray) -> Contacts:
    centre = cam.tip + R * cam.axis
    touching = np.zeros(len(cam), bool)
    touching[idx] = True
    n = len(cam)
    return Contacts(centre, centre - [0.0, 0.0, R], np.tile([0.0, 0.0, 1.0], (n, 1)),
                    np.where(touching, 0.0, 1.0), touching, feed_directions(centre, cam.rapid))


def _axis(b_deg: float, c_deg: float) -> np.ndarray:
    b, c = math.radians(b_deg), math.radians(c_deg)
    return np.array([math.sin(b) * math.cos(c), math.sin(b) * math.sin(c), math.cos(b)])


def _plan():
    cam, idx = _cam()
    con = _contacts(cam, idx)
    n1 = int(np.argmax(cam.rapid))              # pass 1's touching points come first
    u = np.array([_axis(-48.0, 90.0) if i < n1 else _axis(-40.0, 110.0) for i in idx])
    tip, axis = _place_all(cam, con, idx, u, R)
    return cam, con, idx, u, CutterLocations(tip, axis, cam.feed_mm_min, cam.spindle_rpm,
                                             cam.block, cam.rapid)


def test_the_link_keeps_the_cam_ball_centre_and_turns_only_at_its_top():
    cam, con, idx, u, cl = _plan()
    ret, over, down = np.flatnonzero(cam.rapid)
    last1, first2 = idx[idx < ret][-1], idx[idx > down][0]
    inh = _inherited(cam, con, idx)
    kind = dict(zip(inh.point.tolist(), inh.kind.tolist()))
    assert (kind[ret], kind[over], kind[down]) == (_RETRACT, _APPROACH, _APPROACH)
    assert all(kind[i] == _IN_PASS for i in np.flatnonzero(~cam.rapid) if i in kind)
    # every link point keeps the CAM's ball centre: the retract is straight up
    np.testing.assert_allclose(cl.tip[[ret, over, down]] + R * cl.axis[[ret, over, down]],
                               con.centre[[ret, over, down]], atol=1e-12)
    # the retract leaves in the last cut's posture, the descent is in the next pass's first
    np.testing.assert_allclose(cl.axis[ret], cl.axis[last1], atol=1e-12)
    np.testing.assert_allclose(cl.axis[over], cl.axis[first2], atol=1e-12)
    np.testing.assert_allclose(cl.axis[down], cl.axis[first2], atol=1e-12)
    # so the axis turns in one move of the link: the one leaving its top, top to top
    turns = np.flatnonzero(np.abs(np.sum(cl.axis[1:] * cl.axis[:-1], axis=1) - 1) > 1e-12) + 1
    assert [i for i in turns if cam.rapid[i]] == [over]
    centre_z = (cl.tip + R * cl.axis)[:, 2]
    assert centre_z[ret] == centre_z[over] == TOP + R


def test_no_rapid_written_turns_the_rotary_axes_below_the_clearance_height():
    """The written program (linuxcnc: machine axes, linearized), read back: every G0 that
    turns B or C starts and ends with the ball no lower than the clearance height."""
    cam, con, idx, u, cl = _plan()
    machine = get_machine("xyzbc-head-table")
    text = post(cl, machine, PostOptions(dialect="linuxcnc")).text
    prog = parse_program(text, file="<links>")
    back = cutter_locations(prog, machine)
    axis_turn = np.r_[False, np.sum(back.axis[1:] * back.axis[:-1], axis=1) < 1 - 1e-9]
    centre_low = (back.tip + R * back.axis)[:, 2] - R          # the ball's lowest point
    moves = np.flatnonzero(back.rapid & axis_turn)
    assert len(moves) >= 1                     # the turn is written, as a rapid
    assert centre_low[moves].min() >= TOP - 1e-3
    assert centre_low[moves - 1].min() >= TOP - 1e-3


def test_a_link_not_straight_above_its_pass_keeps_its_offset_along_the_axis():
    """A 5-axis program's approach along its (tilted) tool axis: the rapid into the pass
    stays that far out along the planned axis (as a pass's air points do), not at the
    CAM's ball centre beside a tilted tool."""
    a = _axis(30.0, 90.0)
    xs = np.arange(0.0, 5.01, 1.0)
    p1 = np.c_[xs, np.zeros_like(xs), np.zeros_like(xs)]
    p2 = p1 + [0.0, 0.35, 0.0]
    tips = np.vstack([p1, p2[0] + 12.0 * a, p2])
    rapid = np.zeros(len(tips), bool)
    rapid[len(p1)] = True
    cam = CutterLocations.from_arrays(tips, a, np.where(rapid, np.nan, 1600.0), 10000.0,
                                      rapid=rapid)
    idx = np.flatnonzero(~rapid)
    con = _contacts(cam, idx)
    u = np.tile(_axis(45.0, 80.0), (len(idx), 1))
    tip, axis = _place_all(cam, con, idx, u, R)
    p, q = len(p1), len(p1) + 1
    assert _inherited(cam, con, idx).kind.tolist().count(_APPROACH) == 1
    np.testing.assert_allclose(axis[p], u[0], atol=1e-12)
    np.testing.assert_allclose(tip[p], con.centre[q] + (12.0 - R) * u[0], atol=1e-9)
