"""The patent's rules of thumb checked against the stability analysis (method.md §7).

A D10 two-flute ball end mill finishes a flat wall (normal +Y, feed +X, the
previous pass on the -b side, depth 0.2 mm, pick 0.5 mm, fz 0.1 mm) in steel.
Two dynamics: (a) the workpiece is the flexible side (one wall mode along the
normal, rigid tool); (b) the tool is (two bending modes, rigid wall). The
speed-independent zero-order margin (the lobes' lowest point) is compared
between postures. Tilt > 0 is a pure down-cut, tilt < 0 a pure up-cut
(orient/geometry.py with a clockwise spindle).

Findings (the figures are printed by ``-s``):
* workpiece side: the margin grows with the inclination, and at equal
  inclination up-cut beats down-cut, as the patent says;
* tool side: going from 50 down to 20 deg of inclination helps, as the patent
  says; below about 15 deg it no longer does: near the ball's tip the
  engaged edge and the gain grow again (at 0 deg the margin is about a
  quarter of that at 20 deg). The rule "decrease the inclination" holds only
  down to that point; the planner does not use the rule but the margin.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred.coefficients import CuttingCoefficients
from errpred.dynamics import Compliance, Mode
from errpred.tool import Tool
from orient.dynamics import ModalSystem
from orient.engagement import LocalCut
from orient.gain import process_gain, process_gain_batch
from orient.geometry import posture_axis
from orient.stability import sdm_margin, zoa_critical

TOOL = Tool("ball", 10.0, flutes=2, helix_deg=30.0)
COEFFS = CuttingCoefficients(Ktc_N_mm2=3680.0, Krc_N_mm2=1470.0, Kac_N_mm2=550.0,
                             Kte0_N_mm=37.7, Kre0_N_mm=45.2, Kae0_N_mm=11.3)
N = np.array([0.0, 1.0, 0.0])
F = np.array([1.0, 0.0, 0.0])
CUT = LocalCut(0.2, 0.5, -1, 0.1)
WALL = ModalSystem.from_modes([(Mode.from_frequency(3500.0, 0.01, 3.0e6), N)])
TOOL_MODES = ModalSystem.tool(Compliance.from_modes({
    "x": [Mode.from_frequency(3600.0, 0.03, 1.6e6)],
    "y": [Mode.from_frequency(3700.0, 0.03, 1.7e6)]}))


def _margins(lead_deg, tilt_deg):
    u = posture_axis(N, F, np.radians(lead_deg), np.radians(tilt_deg))
    g = process_gain_batch(TOOL, COEFFS, u, np.broadcast_to(N, u.shape),
                           np.broadcast_to(F, u.shape), CUT)
    wall = np.array([zoa_critical(p, WALL).margin for p in g.P])
    tool = np.array([zoa_critical(p, TOOL_MODES.with_tool_axis(a)).margin
                     for p, a in zip(g.P, u)])
    return wall, tool, g.cut_sense


INCL = np.array([10.0, 20.0, 30.0, 40.0, 50.0])


@pytest.mark.parametrize("via", ["tilt", "lead"])
def test_workpiece_side_more_inclination_helps(via):
    lead, tilt = (np.zeros(5), -INCL) if via == "tilt" else (-INCL, np.zeros(5))
    wall, _, sense = _margins(lead, tilt)
    print(via, "wall-side margin vs inclination", dict(zip(INCL, wall.round(3))))
    assert np.all(sense > 0.9)                       # up-cut postures
    assert np.all(np.diff(wall) > 0)                 # more inclination, more margin
    assert wall[-1] > 2.5 * wall[0]


def test_workpiece_side_up_cut_beats_down_cut_at_equal_inclination():
    up, _, s_up = _margins(np.zeros(5), -INCL)
    down, _, s_down = _margins(np.zeros(5), INCL)
    print("up", up.round(3), "down", down.round(3))
    assert np.all(s_up > 0.9) and np.all(s_down < -0.9)
    assert np.all(up > 1.3 * down)


def test_workpiece_side_up_cut_wins_by_the_time_periodic_method_too():
    rpm = 9000.0
    res = []
    for tilt in (-40.0, 40.0):
        u = posture_axis(N, F, 0.0, math.radians(tilt))
        g = process_gain(TOOL, COEFFS, u, N, F, CUT, spindle_rpm=rpm)
        res.append(sdm_margin(g.H, WALL, rpm, TOOL.flutes).margin)
    print("time-periodic at 9000 rev/min: up-cut", res[0], "down-cut", res[1])
    assert res[0] > 1.3 * res[1]


@pytest.mark.parametrize("via", ["tilt", "lead"])
def test_tool_side_less_inclination_helps_down_to_about_20_deg(via):
    sign = 1.0 if via == "tilt" else -1.0
    lead, tilt = (np.zeros(5), sign * INCL) if via == "tilt" else (sign * INCL, np.zeros(5))
    _, tool, _ = _margins(lead, tilt)
    print(via, "tool-side margin vs inclination", dict(zip(INCL, tool.round(3))))
    i20, i40, i50 = 1, 3, 4
    assert tool[i20] > tool[i40] > tool[i50]


def test_tool_side_rule_breaks_down_at_the_tip():
    """Reported disagreement with the patent: at very small inclination the tip cuts and
    the tool-side margin drops again."""
    _, tool, _ = _margins(np.zeros(3), np.array([0.0, 5.0, 20.0]))
    print("tool-side margin at 0, 5, 20 deg:", tool.round(3))
    assert tool[0] < 0.5 * tool[2]
