"""A rapid leaving a 5-axis move whose axis turns (issue 20): the tool at the move's end
is removed material (the real move swept it), so a retract along the tool axis from there
is no rapid into material; a rapid sideways into the slot's wall still is."""

from __future__ import annotations

import math

import numpy as np

from errpred.geometry import GeometryModel, Resolution
from errpred.raster.meshes import Stock
from errpred.sweeps import build_sweeps, inside_any_sweep
from errpred.tool import Tool
from nc.path import CutterLocations

D, FLUTE = 10.0, 25.0
TILT0, TURN = 40.0, 0.9          # tilt of the slot's tool [deg], the last move's turn [deg]
DEPTH = 6.0                      # the ball's tip under the stock's top [mm]


def _axis(tilt_deg: float) -> np.ndarray:
    t = math.radians(tilt_deg)
    return np.array([0.0, math.sin(t), math.cos(t)])


def _path(last: str) -> CutterLocations:
    """Rapids down beside the stock, a tilted slot along +X whose last 5 mm turn the axis
    by ``TURN`` about the feed direction, then a rapid: ``"axis"`` 40 mm back up the end's
    tool axis, ``"wall"`` 3 mm sideways into the slot's wall."""
    u0, u1 = _axis(TILT0), _axis(TILT0 + TURN)
    end = np.array([25.0, 0.0, -DEPTH])
    after = end + 40.0 * u1 if last == "axis" else end + [0.0, -3.0, 0.0]
    tip = np.array([[-10.0, 0.0, 30.0], [-10.0, 0.0, -DEPTH], [20.0, 0.0, -DEPTH], end,
                    after])
    axis = np.array([u0, u0, u0, u1, u1])
    rapid = np.array([True, True, False, False, True])
    return CutterLocations.from_arrays(tip, axis, 600.0, 6000.0, rapid=rapid)


def _model(last: str) -> GeometryModel:
    stock = Stock.from_box([0.0, -20.0, -20.0], [40.0, 20.0, 0.0])
    tool = Tool("ball", D, flute_length_mm=FLUTE)
    return GeometryModel(tool, stock, _path(last), Resolution(pixel_mm=D / 32))


def test_the_tool_at_a_turning_moves_end_is_inside_its_sweeps():
    """Points all over the flute part of the tool at the end of the turning move (shrunk
    by 1 um) are inside the move's sweeps; without the end's own posture the pieces'
    middle axis leaves the tool's side sticking out by height x sin(turn / 2)."""
    tool = Tool("ball", D, flute_length_mm=FLUTE)
    cl = _path("axis")
    sw = build_sweeps(cl, tool)
    u = cl.axis[3]
    e1 = np.cross(u, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    phi = np.linspace(0.0, 2 * math.pi, 72, endpoint=False)
    h = np.linspace(tool.radius_mm, FLUTE, 40)
    rho = tool.radius_mm - 1e-3
    pts = (cl.tip[3] + h[:, None, None] * u
           + rho * (np.cos(phi)[None, :, None] * e1 + np.sin(phi)[None, :, None] * e2))
    pts = pts.reshape(-1, 3)
    inside = inside_any_sweep(pts, np.ones(len(pts), dtype=np.bool_), sw.p0, sw.d, sw.w,
                              sw.lo, sw.hi, sw.core_radius_mm, sw.corner_radius_mm,
                              sw.top_mm, 1e-6)
    assert inside.all(), f"{(~inside).sum()} of {len(pts)} points outside"


def _tool_points(tool, tip, u, inset=1e-3):
    """Points all over the tool's flute part and ball at (tip, u), ``inset`` inside."""
    e1 = np.cross(u, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    phi = np.linspace(0.0, 2 * math.pi, 72, endpoint=False)
    ring = np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2
    R = tool.radius_mm
    h = np.linspace(R, FLUTE, 40)
    flank = tip + h[:, None, None] * u + (R - inset) * ring[None]
    th = np.linspace(0.0, math.pi / 2, 20)[:, None, None]     # 0: the tip, pi/2: equator
    ball = tip + R * u + (R - inset) * (np.sin(th) * ring[None] - np.cos(th) * u)
    return np.concatenate([flank.reshape(-1, 3), ball.reshape(-1, 3)])


def test_the_tool_where_the_turn_turns_back_is_inside_the_sweeps():
    """Two feed moves turning the axis +0.9 then -0.9 deg: the tool at the corner between
    them (where both moves' pieces are off to the same side) is inside the sweeps."""
    tool = Tool("ball", D, flute_length_mm=FLUTE)
    u0, u1 = _axis(TILT0), _axis(TILT0 + TURN)
    tip = np.array([[-10.0, 0.0, -DEPTH], [20.0, 0.0, -DEPTH], [25.0, 0.0, -DEPTH],
                    [30.0, 0.0, -DEPTH], [60.0, 0.0, -DEPTH]])
    axis = np.array([u0, u0, u1, u0, u0])
    cl = CutterLocations.from_arrays(tip, axis, 600.0, 6000.0)
    sw = build_sweeps(cl, tool)
    pts = _tool_points(tool, tip[2], u1)
    inside = inside_any_sweep(pts, np.ones(len(pts), dtype=np.bool_), sw.p0, sw.d, sw.w,
                              sw.lo, sw.hi, sw.core_radius_mm, sw.corner_radius_mm,
                              sw.top_mm, 1e-6)
    assert inside.all(), f"{(~inside).sum()} of {len(pts)} points outside"


def test_a_retract_along_the_axis_from_a_turning_moves_end_is_no_rapid_into_material():
    model = _model("axis")
    (g,) = model.geometry(4)
    assert g.status == "rapid"


def test_a_rapid_sideways_into_the_wall_is_still_found():
    model = _model("wall")
    (g,) = model.geometry(4)
    assert g.status == "rapid-into-material"
