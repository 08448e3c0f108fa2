"""Tests of nc.kinematics (and the model in nc.machines).

Independent reference: LinuxCNC's trt kinematics (src/emc/kinematics/trtfuncs.c),
transcribed below.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from nc import constants as K
from nc.errors import KinematicsError, MachineFileError
from nc.kinematics import (
    MACHINES,
    Machine,
    RotaryAxis,
    get_machine,
    linearize,
    linuxcnc_trt_machine,
    load_machine,
    machine_to_toml,
    solve_path,
)

DEG = math.pi / 180.0
CONE = K.SINGULAR_CONE_RAD

#: Every named machine with asymmetric, non-zero geometry, plus sign-flipped
#: and a non-orthogonal (45 deg nutating head) custom machine.
MACHS: dict[str, Machine] = {
    "xyzac-trt": get_machine("xyzac-trt", tilt_pivot_mm=(3.0, 40.0, -75.0),
                             rotary_pivot_mm=(12.0, -8.0, 5.0),
                             tilt_limits_rad=(-100 * DEG, 110 * DEG)),
    "xyzbc-trt": get_machine("xyzbc-trt", tilt_pivot_mm=(35.0, -4.0, -60.0),
                             rotary_pivot_mm=(-9.0, 14.0, 2.0)),
    "xyzbc-head-table": get_machine("xyzbc-head-table", tool_length_mm=87.5,
                                    tilt_pivot_mm=(1.5, -2.0, 140.0),
                                    rotary_pivot_mm=(20.0, 30.0, 0.0)),
    "xyzbc-head-head": get_machine("xyzbc-head-head", tool_length_mm=60.0,
                                   tilt_pivot_mm=(0.0, 3.0, 120.0),
                                   rotary_pivot_mm=(-5.0, 4.0, 300.0)),
    "xyzac-trt-flipped": get_machine("xyzac-trt", tilt_pivot_mm=(0.0, -20.0, -50.0),
                                     rotary_pivot_mm=(7.0, 1.0, 0.0), tilt_direction=-1,
                                     rotary_direction=-1),
    "head-head-flipped": get_machine("head-head-bc", tool_length_mm=45.0,
                                     tilt_pivot_mm=(2.0, 0.0, 90.0), tilt_direction=-1,
                                     rotary_direction=-1),
    "nutating-head": Machine("nutating", (
        RotaryAxis("B", (0.0, math.sqrt(0.5), math.sqrt(0.5)), "head", (0.0, 0.0, 100.0)),
        RotaryAxis("C", "z", "head", (1.0, -2.0, 250.0))), tool_length_mm=70.0),
}


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    u, v = np.atleast_2d(u), np.atleast_2d(v)
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.sum(u * v, axis=1))


def _singular_angle(m: Machine, axis: np.ndarray) -> np.ndarray:
    """Angle [rad] between tool axes and the rotary axis line (either sense)."""
    ac = m.axes[1].vector
    a = _angle(axis, np.broadcast_to(ac, np.shape(np.atleast_2d(axis))))
    return np.minimum(a, math.pi - a)


def _random_joints(m: Machine, rng: np.random.Generator, n: int) -> np.ndarray:
    t, c = m.axes
    tlo, thi = max(t.min_rad, -170 * DEG), min(t.max_rad, 170 * DEG)
    clo, chi = max(c.min_rad, -2 * math.pi), min(c.max_rad, 2 * math.pi)
    return np.column_stack([rng.uniform(-300, 300, (n, 3)), rng.uniform(tlo, thi, n),
                            rng.uniform(clo, chi, n)])


# --------------------------------------------------------------------------- forward/inverse
finite = dict(allow_nan=False, allow_infinity=False)


@pytest.mark.parametrize("key", list(MACHS))
@settings(max_examples=80, derandomize=True, deadline=None)
@given(xyz=st.tuples(*[st.floats(-400, 400, **finite)] * 3),
       tilt=st.floats(-1.0, 1.0, **finite), rot=st.floats(-7.0, 7.0, **finite))
def test_forward_inverse_roundtrip(key: str, xyz: tuple, tilt: float, rot: float) -> None:
    m = MACHS[key]
    t = m.axes[0]
    lo, hi = max(t.min_rad, -170 * DEG), min(t.max_rad, 170 * DEG)
    tilt = lo + (tilt + 1.0) / 2.0 * (hi - lo)  # within the limits
    joints = np.array([*xyz, tilt, rot])
    tip, axis = m.forward(joints)
    assume(_singular_angle(m, axis)[0] > 2 * CONE)  # the singular case is tested apart
    sols = m.inverse(tip, axis)
    for sol in sols:
        assert sol.shape == (5,) and np.isfinite(sol).all()
        t2, a2 = m.forward(sol)
        assert np.abs(t2 - tip).max() <= 1e-9
        assert _angle(a2, axis)[0] <= 1e-9
    # one of them is the posture itself (modulo 2 pi)
    d = [np.abs(np.angle(np.exp(1j * (s[3:] - joints[3:])))).max() for s in sols]
    assert min(d) <= 1e-9
    # both solutions differ: the tilt differs, never the same posture
    assert abs(sols[0][3] - sols[1][3]) > 1e-6
    assert sols[0][3] >= sols[1][3]


@pytest.mark.parametrize("key", list(MACHS))
def test_roundtrip_vectorized(key: str) -> None:
    m = MACHS[key]
    rng = np.random.default_rng(7)
    j = _random_joints(m, rng, 2000)
    tip, axis = m.forward(j)
    keep = _singular_angle(m, axis) > 2 * CONE
    assert keep.sum() > 1900
    for sol in m.inverse(tip, axis):
        t2, a2 = m.forward(sol)
        assert np.abs(t2 - tip)[keep].max() <= 1e-9
        assert _angle(a2, axis)[keep].max() <= 1e-9


@pytest.mark.parametrize("key", ["xyzac-trt", "xyzbc-trt", "xyzbc-head-table",
                                 "xyzbc-head-head", "xyzac-trt-flipped", "head-head-flipped"])
def test_two_solutions_flip_tilt(key: str) -> None:
    """Named machines: the solutions are (t, c) and (-t, c + pi)."""
    m = MACHS[key]
    j = _random_joints(m, np.random.default_rng(3), 500)
    j[:, 3] = np.clip(np.abs(j[:, 3]), 5 * DEG, 80 * DEG)
    s0, s1 = m.inverse(*m.forward(j))
    assert np.allclose(s0[:, 3], -s1[:, 3], atol=1e-12)
    assert np.all(s0[:, 3] > 0)
    dc = np.angle(np.exp(1j * (s0[:, 4] - s1[:, 4])))
    assert np.allclose(np.abs(dc), math.pi, atol=1e-9)


@pytest.mark.parametrize("key", list(MACHS))
def test_inverse_at_singularity_holds_free_axis(key: str) -> None:
    m = MACHS[key]
    tip = np.array([[10.0, -20.0, 5.0], [1.0, 2.0, 3.0], [-4.0, 0.0, 8.0]])
    off = 0.5 * CONE
    ac = m.axes[1].vector
    axis = np.array([ac, [math.sin(off), 0.0, math.cos(off)], [0.0, -math.sin(off),
                                                                  math.cos(off)]])
    free = np.array([0.7, -2.0, 3.0])
    s0, s1 = m.inverse(tip, axis, free_rad=free)
    assert np.array_equal(s0, s1)
    assert np.allclose(s0[:, 4], free, atol=1e-12)
    assert np.isfinite(s0).all()
    t2, a2 = m.forward(s0)
    assert np.abs(t2 - tip).max() <= 1e-9  # the tip is always exact
    err = _angle(a2, axis)
    assert err[0] <= 1e-12 and np.all(err <= 2 * off + 1e-12)
    # held rotary angle, best tilt: no other tilt at this C is closer
    for dt in (-1e-5, 1e-5):
        s = s0.copy()
        s[:, 3] += dt
        assert np.all(_angle(m.forward(s)[1], axis) >= err - 1e-12)
    # singular_cone_rad=0: only exactly on the axis is the free value used
    e0, e1 = m.inverse(tip, axis, free_rad=free, singular_cone_rad=0.0)
    assert e0[0, 4] == pytest.approx(free[0]) and not np.array_equal(e0[1:], e1[1:])


def test_analytic_xyzac_trt() -> None:
    m = get_machine("xyzac-trt")
    # A = +90 deg turns the table right-handed about +X: the workpiece's +Y
    # face turns up to face the spindle, so the tool axis seen from the
    # workpiece is +Y; the machine tip (10, 20, 30) is the workpiece point
    # Rx(-90)(10, 20, 30) = (10, 30, -20).
    tip, axis = m.forward([10.0, 20.0, 30.0, 90 * DEG, 0.0])
    assert np.allclose(axis, [0.0, 1.0, 0.0], atol=1e-15)
    assert np.allclose(tip, [10.0, 30.0, -20.0], atol=1e-12)
    # C = +90 deg: machine (10, 0, 0) is workpiece Rz(-90)(10, 0, 0) = (0, -10, 0)
    tip, axis = m.forward([10.0, 0.0, 0.0, 0.0, 90 * DEG])
    assert np.allclose(tip, [0.0, -10.0, 0.0], atol=1e-12)
    # with the A pivot at z = -100 the tip at machine z = 0 swings about it:
    m = get_machine("xyzac-trt", tilt_pivot_mm=(0.0, 0.0, -100.0))
    tip, _ = m.forward([0.0, 0.0, 0.0, 90 * DEG, 0.0])
    assert np.allclose(tip, [0.0, 100.0, -100.0], atol=1e-12)
    # B = +90 deg on xyzbc-trt: the workpiece's -X face turns up
    _, axis = get_machine("xyzbc-trt").forward([0.0, 0.0, 0.0, 90 * DEG, 0.0])
    assert np.allclose(axis, [-1.0, 0.0, 0.0], atol=1e-15)


def test_analytic_head_machines() -> None:
    L, h = 100.0, 150.0  # tool length, head pivot above the spindle nose
    m = get_machine("xyzbc-head-table", tool_length_mm=L, tilt_pivot_mm=(0.0, 0.0, h))
    # B = +90 deg swings the spindle right-handed about +Y: the tool axis
    # (tip -> spindle) becomes +X and the tip, L + h below the pivot, moves to
    # the pivot's -X side: tip = xyz + (-(L + h), 0, L + h).
    tip, axis = m.forward([1.0, 2.0, 3.0, 90 * DEG, 0.0])
    assert np.allclose(axis, [1.0, 0.0, 0.0], atol=1e-15)
    assert np.allclose(tip, [1.0 - (L + h), 2.0, 3.0 + (L + h)], atol=1e-12)
    # tool length is one field; B = 30 deg: offset (-d sin b, 0, d (1 - cos b))
    for length in (L, L + 20.0):
        d = length + h
        tip, _ = m.with_tool_length(length).forward([0.0, 0.0, 0.0, 30 * DEG, 0.0])
        assert np.allclose(tip, [-d * 0.5, 0.0, d * (1 - math.cos(30 * DEG))], atol=1e-12)
    # head-head: C = 90 deg turns the tilted head about Z
    m = get_machine("xyzbc-head-head", tool_length_mm=L, tilt_pivot_mm=(0.0, 0.0, h))
    tip, axis = m.forward([0.0, 0.0, 0.0, 90 * DEG, 90 * DEG])
    assert np.allclose(axis, [0.0, 1.0, 0.0], atol=1e-15)
    assert np.allclose(tip, [0.0, -(L + h), L + h], atol=1e-12)
    # zero posture: the tip is the controlled point, whatever the geometry
    for m in MACHS.values():
        tip, axis = m.forward([5.0, 6.0, 7.0, 0.0, 0.0])
        assert np.allclose(tip, [5.0, 6.0, 7.0], atol=1e-12)
        assert np.allclose(axis, [0.0, 0.0, 1.0], atol=1e-15)


# --------------------------------------------------------------------------- LinuxCNC reference
def linuxcnc_xyzac_forward(j, x_rot_point, y_rot_point, z_rot_point, y_offset, z_offset,
                           tool_offset):
    """Transcribed from linuxcnc src/emc/kinematics/trtfuncs.c, xyzacKinematicsForward."""
    jx, jy, jz, ja, jc = j
    a_rad, c_rad = ja * DEG, jc * DEG
    dy, dz = y_offset, z_offset + tool_offset
    x = (+ math.cos(c_rad) * (jx - x_rot_point)
         + math.sin(c_rad) * math.cos(a_rad) * (jy - dy - y_rot_point)
         + math.sin(c_rad) * math.sin(a_rad) * (jz - dz - z_rot_point)
         + math.sin(c_rad) * dy + x_rot_point)
    y = (- math.sin(c_rad) * (jx - x_rot_point)
         + math.cos(c_rad) * math.cos(a_rad) * (jy - dy - y_rot_point)
         + math.cos(c_rad) * math.sin(a_rad) * (jz - dz - z_rot_point)
         + math.cos(c_rad) * dy + y_rot_point)
    z = (+ 0 - math.sin(a_rad) * (jy - dy - y_rot_point)
         + math.cos(a_rad) * (jz - dz - z_rot_point) + dz + z_rot_point)
    return np.array([x, y, z])


def linuxcnc_xyzbc_forward(j, x_rot_point, y_rot_point, z_rot_point, x_offset, z_offset,
                           tool_offset):
    """Transcribed from linuxcnc src/emc/kinematics/trtfuncs.c, xyzbcKinematicsForward."""
    jx, jy, jz, jb, jc = j
    b_rad, c_rad = jb * DEG, jc * DEG
    dx, dz = x_offset, z_offset + tool_offset
    x = (math.cos(c_rad) * math.cos(b_rad) * (jx - dx - x_rot_point)
         + math.sin(c_rad) * (jy - y_rot_point)
         - math.cos(c_rad) * math.sin(b_rad) * (jz - dz - z_rot_point)
         + math.cos(c_rad) * dx + x_rot_point)
    y = (- math.sin(c_rad) * math.cos(b_rad) * (jx - dx - x_rot_point)
         + math.cos(c_rad) * (jy - y_rot_point)
         + math.sin(c_rad) * math.sin(b_rad) * (jz - dz - z_rot_point)
         - math.sin(c_rad) * dx + y_rot_point)
    z = (math.sin(b_rad) * (jx - dx - x_rot_point)
         + math.cos(b_rad) * (jz - dz - z_rot_point) + dz + z_rot_point)
    return np.array([x, y, z])


def linuxcnc_xyzac_inverse(pos, a_deg, c_deg, x_rot_point, y_rot_point, z_rot_point,
                           y_offset, z_offset, tool_offset):
    """Transcribed from trtfuncs.c, xyzacKinematicsInverse: joints X Y Z."""
    px, py, pz = pos
    a_rad, c_rad = a_deg * DEG, c_deg * DEG
    dy, dz = y_offset, z_offset + tool_offset
    x = (+ math.cos(c_rad) * (px - x_rot_point) - math.sin(c_rad) * (py - y_rot_point)
         + x_rot_point)
    y = (+ math.sin(c_rad) * math.cos(a_rad) * (px - x_rot_point)
         + math.cos(c_rad) * math.cos(a_rad) * (py - y_rot_point)
         - math.sin(a_rad) * (pz - z_rot_point) - math.cos(a_rad) * dy
         + math.sin(a_rad) * dz + dy + y_rot_point)
    z = (+ math.sin(c_rad) * math.sin(a_rad) * (px - x_rot_point)
         + math.cos(c_rad) * math.sin(a_rad) * (py - y_rot_point)
         + math.cos(a_rad) * (pz - z_rot_point) - math.sin(a_rad) * dy
         - math.cos(a_rad) * dz + dz + z_rot_point)
    return np.array([x, y, z])


@pytest.mark.parametrize("kins", ["xyzac-trt", "xyzbc-trt"])
def test_trt_forward_matches_linuxcnc(kins: str) -> None:
    """Mapping: C pivot = (x/y/z-rot-point); A pivot = C pivot + (0, y-offset,
    z-offset), B pivot = C pivot + (x-offset, 0, z-offset); directions +1;
    LinuxCNC's world position = our tool tip (workpiece frame) with the
    tool-offset pin 0; with tool-offset dt its joint Z is the spindle gauge
    point, i.e. our Z + dt, and its world Z is our tip Z + dt."""
    rng = np.random.default_rng(11)
    for _ in range(40):
        p = dict(x_rot_point=rng.uniform(-50, 50), y_rot_point=rng.uniform(-50, 50),
                 z_rot_point=rng.uniform(-50, 50))
        off = rng.uniform(-80, 80, 2)
        if kins == "xyzac-trt":
            p.update(y_offset=off[0], z_offset=off[1])
            ref, tilt_pivot = linuxcnc_xyzac_forward, (0.0, off[0], off[1])
        else:
            p.update(x_offset=off[0], z_offset=off[1])
            ref, tilt_pivot = linuxcnc_xyzbc_forward, (off[0], 0.0, off[1])
        rot = (p["x_rot_point"], p["y_rot_point"], p["z_rot_point"])
        m = get_machine(kins, rotary_pivot_mm=rot,
                        tilt_pivot_mm=tuple(np.add(rot, tilt_pivot)),
                        tilt_limits_rad=(-math.inf, math.inf))
        assert m == linuxcnc_trt_machine(kins + "-kins", **p,
                                         tilt_limits_rad=(-math.inf, math.inf))
        jd = np.concatenate([rng.uniform(-200, 200, 3), rng.uniform(-180, 180, 2)])
        ours = np.concatenate([jd[:3], jd[3:] * DEG])
        tip, _ = m.forward(ours)
        assert np.allclose(tip, ref(jd, **p, tool_offset=0.0), atol=1e-9)
        dt = rng.uniform(0, 150)
        lc = ref(jd + np.array([0, 0, dt, 0, 0]), **p, tool_offset=dt)
        assert np.allclose(tip + [0, 0, dt], lc, atol=1e-9)
        if kins == "xyzac-trt":  # inverse: our solution with these A, C has LinuxCNC's X Y Z
            sols = m.inverse(tip, m.forward(ours)[1])
            s = min(sols, key=lambda s: np.abs(np.angle(np.exp(1j * (s[3:] - ours[3:])))).max())
            assert np.allclose(s[:3], linuxcnc_xyzac_inverse(tip, jd[3], jd[4], **p,
                                                             tool_offset=0.0), atol=1e-9)


# --------------------------------------------------------------------------- path solver
def _circling(n: int, turns: float, tilt: float) -> tuple[np.ndarray, np.ndarray]:
    s = np.linspace(0.0, 1.0, n)
    phi = s * turns * 2 * math.pi
    axis = np.column_stack([math.sin(tilt) * np.cos(phi), math.sin(tilt) * np.sin(phi),
                            np.full(n, math.cos(tilt))])
    tip = np.column_stack([40 * np.cos(phi), 25 * np.sin(phi), 5 * s])
    return tip, axis


@pytest.mark.parametrize("key", list(MACHS))
def test_path_unwraps_rotary_axis(key: str) -> None:
    m = MACHS[key]
    tip, axis = _circling(1441, 3.0, 30 * DEG)  # 3 turns, 0.75 deg a step
    sol = solve_path(m, tip, axis)
    c = np.degrees(sol.joints[:, 4])
    dc = np.diff(c)
    assert np.abs(dc).max() < 3.0
    assert np.all(dc > 0) or np.all(dc < 0)  # monotonic, no 359 -> 0 jumps
    assert abs(c[-1] - c[0]) == pytest.approx(1080.0, abs=1.0)
    assert np.abs(np.diff(sol.joints[:, 3])).max() < 1e-6 or key == "nutating-head"
    t2, a2 = m.forward(sol.joints)
    assert np.abs(t2 - tip).max() <= 1e-9 and _angle(a2, axis).max() <= 1e-9
    assert not sol.singular.any() and not sol.jump.any()
    assert np.all(sol.orientation_error_rad == 0.0)


@pytest.mark.parametrize("key", list(MACHS))
def test_path_through_singularity_holds_rotary(key: str) -> None:
    m = MACHS[key]
    # tool axis sweeps from +30 deg through the rotary axis (exactly, and with
    # points inside the cone) to -30 deg, in a plane not containing the tilt axis
    ang = np.concatenate([np.linspace(30, 1, 30), [0.02, 0.01, 0.0, -0.01, -0.02],
                          np.linspace(-1, -30, 30)]) * DEG
    az = 0.3
    axis = np.column_stack([np.sin(ang) * math.cos(az), np.sin(ang) * math.sin(az),
                            np.cos(ang)])
    tip = np.column_stack([np.linspace(-20, 20, len(ang)), np.zeros(len(ang)),
                           np.full(len(ang), 3.0)])
    sol = solve_path(m, tip, axis)
    sing = sol.singular
    assert sing.sum() == 5 and np.array_equal(np.flatnonzero(sing), np.arange(30, 35))
    c = sol.joints[:, 4]
    assert np.all(c[30:35] == c[29])  # held, not spun
    assert np.abs(np.diff(np.degrees(c))).max() < 3.0
    assert np.abs(np.diff(np.degrees(sol.joints[:, 3]))).max() < 3.0
    assert sol.orientation_error_rad[sing].max() <= 0.02 * DEG + 1e-12
    assert np.all(sol.orientation_error_rad[~sing] == 0.0)
    t2, a2 = m.forward(sol.joints)
    assert np.abs(t2 - tip).max() <= 1e-9
    assert _angle(a2[~sing], axis[~sing]).max() <= 1e-9
    assert not sol.jump.any()
    # starting at the singularity with a given rotary angle: it is held there
    sol2 = solve_path(m, tip[32:], axis[32:], start=[0, 0, 0, 0, 1.25])
    assert np.all(sol2.joints[:3, 4] == 1.25)


def test_path_limits_error_names_index() -> None:
    m = get_machine("xyzac-trt", tilt_limits_rad=(-30 * DEG, 30 * DEG))
    ang = np.linspace(10, 40, 31) * DEG  # 1 deg a step: 31 deg at index 21
    axis = np.column_stack([np.zeros(31), np.sin(ang), np.cos(ang)])
    with pytest.raises(KinematicsError) as ei:
        solve_path(m, np.zeros((31, 3)), axis)
    assert ei.value.index == 21
    assert "point 21" in str(ei.value) and "A = " in str(ei.value) and "outside" in str(ei.value)
    # a linear limit
    m = get_machine("xyzbc-head-table", tool_length_mm=100.0,
                    linear_limits_mm=((-1e3, 1e3), (-1e3, 1e3), (-50.0, 500.0)))
    tip = np.column_stack([np.zeros(10), np.zeros(10), np.linspace(0, -90, 10)])
    with pytest.raises(KinematicsError) as ei:
        solve_path(m, tip, np.tile([0.0, 0.0, 1.0], (10, 1)))
    assert ei.value.index == 6 and "Z = " in str(ei.value)


def test_path_rotary_limit_rewind_needs_jump() -> None:
    m = get_machine("xyzbc-head-table", rotary_limits_rad=(-200 * DEG, 200 * DEG),
                    tilt_limits_rad=(-5 * DEG, 90 * DEG))
    tip, axis = _circling(721, 2.0, 30 * DEG)  # 1 deg a step
    with pytest.raises(KinematicsError) as ei:
        solve_path(m, tip, axis, start=[0, 0, 0, 30 * DEG, -200 * DEG])
    i = ei.value.index
    assert "C = " in str(ei.value) and "jump" in str(ei.value)
    sol = solve_path(m, tip, axis, start=[0, 0, 0, 30 * DEG, -200 * DEG], allow_jumps=True)
    assert np.flatnonzero(sol.jump)[0] == i
    assert m.within_limits(sol.joints).all()
    assert np.all(sol.joints[:, 3] > 0)


def test_path_prefers_continuous_solution() -> None:
    m = get_machine("xyzbc-trt")  # B +-90 deg: both solutions in limits
    tip, axis = _circling(361, 1.0, 20 * DEG)
    sol = solve_path(m, tip, axis)
    b0 = sol.joints[0, 3]
    assert np.allclose(sol.joints[:, 3], b0, atol=1e-12)
    # continuous with a start on the other branch: stays on it
    other = -b0
    start = np.array([0.0, 0.0, 0.0, other, sol.joints[0, 4] + math.pi + 2 * math.pi])
    sol2 = solve_path(m, tip, axis, start=start)
    assert np.allclose(sol2.joints[:, 3], other, atol=1e-12)
    assert abs(sol2.joints[0, 4] - start[4]) < 2 * DEG  # near the start, not re-wrapped
    assert np.abs(np.diff(sol2.joints[:, 4])).max() < 2 * DEG


def test_path_flips_at_singularity_when_limits_demand() -> None:
    # A may not go below -5 deg: crossing the vertical, the continuous branch
    # (A -> negative) leaves the limits; the solver flips C by 180 deg at the
    # singular point, where the orientation does not change.
    m = get_machine("xyzac-trt", tilt_limits_rad=(-5 * DEG, 100 * DEG),
                    tilt_pivot_mm=(0.0, 0.0, -60.0))
    ang = np.linspace(30, -30, 61) * DEG
    axis = np.column_stack([np.zeros(61), np.sin(ang), np.cos(ang)])
    tip = np.column_stack([np.linspace(0, 30, 61), np.zeros(61), np.zeros(61)])
    sol = solve_path(m, tip, axis)
    assert m.within_limits(sol.joints).all()
    assert np.flatnonzero(sol.jump).tolist() == [30] and sol.singular[30]
    dc = np.abs(np.diff(np.degrees(sol.joints[:, 4])))
    assert dc[29] == pytest.approx(180.0, abs=1e-6) and np.delete(dc, 29).max() < 1e-9
    t2, a2 = m.forward(sol.joints)
    assert np.abs(t2 - tip).max() <= 1e-9 and _angle(a2, axis).max() <= 1e-9
    lin = linearize(m, tip, axis, sol.joints)  # spreads the flip
    assert lin.max_deviation_mm <= K.LINEARIZE_TOL_MM
    assert _dense_deviation(m, lin.tip, lin.joints) <= K.LINEARIZE_TOL_MM
    assert np.abs(np.diff(np.degrees(lin.joints[:, 4]))).max() < 5.0
    assert np.all(np.diff(lin.source) >= 0)
    turning = lin.source == 30  # the C turn happens at point 30, tool vertical
    assert np.degrees(np.ptp(lin.joints[turning, 4])) == pytest.approx(180.0, abs=1e-6)
    assert np.allclose(lin.tip[turning], tip[30], atol=1e-12)
    assert np.all(_singular_angle(m, m.forward(lin.joints[turning])[1]) <= CONE)


def test_path_input_validation() -> None:
    m = MACHS["xyzbc-trt"]
    axis = np.tile([0.0, 0.0, 1.0], (3, 1))
    with pytest.raises(ValueError, match="tip"):
        solve_path(m, [[0, 0, 0], [0, np.nan, 0], [0, 0, 0]], axis)
    with pytest.raises(ValueError, match="axis"):
        solve_path(m, np.zeros((3, 3)), [[0, 0, 1], [0, 0, 1.01], [0, 0, 1]])
    with pytest.raises(ValueError, match="joints"):
        m.forward([0, 0, 0, np.inf, 0])
    with pytest.raises(ValueError, match="axis"):
        m.inverse([0, 0, 0], [0, 0, 2.0])
    with pytest.raises(ValueError, match="about"):
        RotaryAxis("B", (0.0, 1.1, 0.0), "head")
    with pytest.raises(ValueError, match="direction"):
        RotaryAxis("B", "y", "head", direction=2)
    assert solve_path(m, np.zeros((0, 3)), np.zeros((0, 3))).joints.shape == (0, 5)


def test_unreachable_orientation() -> None:
    m = MACHS["nutating-head"]  # a 45 deg head reaches 90 deg of tilt at most
    with pytest.raises(KinematicsError) as ei:
        m.inverse(np.zeros((3, 3)), [[0, 0, 1], [1, 0, 0], [0.0, 0.6, -0.8]])
    assert ei.value.index == 2


def test_within_limits() -> None:
    m = get_machine("xyzbc-head-head", rotary_limits_rad=(-math.pi, math.pi),
                    linear_limits_mm=((-1, 1), (-2, 2), (-3, 3)))
    j = np.array([[0, 0, 0, 0, 0], [0, 0, 0, 91 * DEG, 0], [0, 0, 0, 0, 4.0],
                  [0, 2.5, 0, 0, 0], [1, 2, 3, 90 * DEG, -math.pi]], dtype=float)
    assert m.within_limits(j).tolist() == [True, False, False, False, True]
    assert m.within_limits(j[0]) and m.rotary_names == ("B", "C")


# --------------------------------------------------------------------------- linearize
def _dense_deviation(m: Machine, tip: np.ndarray, joints: np.ndarray, k: int = 64) -> float:
    """Largest distance of the tip from the programmed segments, joints moved linearly."""
    f = np.linspace(0, 1, k + 1)[1:-1, None, None]
    jf = joints[None, :-1] + f * (joints[1:] - joints[:-1])[None]
    p = m.forward(jf.reshape(-1, 5))[0].reshape(k - 1, len(tip) - 1, 3)
    a, d = tip[:-1], tip[1:] - tip[:-1]
    t = np.clip(np.sum((p - a) * d, axis=2) / np.maximum(np.sum(d * d, axis=1), 1e-300), 0, 1)
    return float(np.linalg.norm(p - (a + t[..., None] * d), axis=2).max())


def test_linearize_rotation_about_far_pivot() -> None:
    m = get_machine("xyzac-trt", tilt_pivot_mm=(0.0, 10.0, -150.0),
                    rotary_pivot_mm=(5.0, 5.0, 0.0))
    n = 5
    a = np.linspace(0, 90, n) * DEG  # A from 0 to 90 deg while the tip moves straight
    axis = np.column_stack([np.zeros(n), np.sin(a), np.cos(a)])
    tip = np.column_stack([np.linspace(0, 40, n), np.linspace(0, -10, n), np.zeros(n)])
    sol = solve_path(m, tip, axis)
    tol = K.LINEARIZE_TOL_MM
    assert _dense_deviation(m, tip, sol.joints) > 100 * tol
    lin = linearize(m, tip, axis, sol.joints, tol_mm=tol)
    assert len(lin.tip) > 10 * n
    assert lin.max_deviation_mm <= tol
    assert _dense_deviation(m, lin.tip, lin.joints) <= tol
    # original points kept, in order, at integer sources
    assert np.all(np.diff(lin.source) > 0)
    orig = lin.source == np.round(lin.source)
    assert np.array_equal(lin.source[orig], np.arange(n))
    assert np.array_equal(lin.joints[orig], sol.joints)
    # inserted points: on the programmed line, the forward kinematics agrees
    t2, a2 = m.forward(lin.joints)
    regular = _singular_angle(m, lin.axis) > CONE
    assert np.abs(t2 - lin.tip).max() <= 1e-9
    assert _angle(a2[regular], lin.axis[regular]).max() <= 1e-9
    k = np.floor(lin.source).astype(int).clip(max=n - 2)
    fr = lin.source - k
    assert np.allclose(lin.tip, tip[k] + fr[:, None] * (tip[k + 1] - tip[k]), atol=1e-9)
    # joints continuous: the rotary steps shrink with the bisection
    assert np.abs(np.diff(lin.joints[:, 3:], axis=0)).max() < 5 * DEG


def test_linearize_large_path_nothing_to_do() -> None:
    m = MACHS["xyzbc-head-head"]
    tip, axis = _circling(20_000, 3.0, 25 * DEG)
    sol = solve_path(m, tip, axis)
    lin = linearize(m, tip, axis, sol.joints)
    assert lin.max_deviation_mm <= K.LINEARIZE_TOL_MM
    assert len(lin.tip) == len(tip)
    with pytest.raises(ValueError, match="tol_mm"):
        linearize(m, tip, axis, sol.joints, tol_mm=0.0)


# --------------------------------------------------------------------------- TOML
def test_load_named_machine(tmp_path) -> None:
    f = tmp_path / "mill.toml"
    f.write_text('''
kind = "head-table-bc"
name = "nagoya"
tool_length_mm = 95.5

[linear_limits_mm]
z = [-400, 100.5]

[tilt]
pivot_mm = [0.0, 0.5, 150]
min_deg = -95.0
max_deg = 30

[rotary]
pivot_mm = [20.0, -10.0, 0.0]
direction = -1
''')
    m = load_machine(f)
    ref = get_machine("xyzbc-head-table", name="nagoya", tool_length_mm=95.5,
                      tilt_pivot_mm=(0.0, 0.5, 150.0), rotary_pivot_mm=(20.0, -10.0, 0.0),
                      rotary_direction=-1,
                      tilt_limits_rad=(math.radians(-95.0), math.radians(30.0)),
                      linear_limits_mm=((-math.inf, math.inf), (-math.inf, math.inf),
                                        (-400.0, 100.5)))
    assert m == ref


@pytest.mark.parametrize("key", list(MACHS))
def test_toml_round_trip(tmp_path, key: str) -> None:
    m = MACHS[key]
    f = tmp_path / "m.toml"
    f.write_text(machine_to_toml(m))
    back = load_machine(f)
    assert back.name == m.name and back.tool_length_mm == m.tool_length_mm
    assert back.linear_limits_mm == m.linear_limits_mm
    for a, b in zip(back.axes, m.axes):
        assert (a.name, a.about, a.carrier, a.pivot_mm, a.direction) == \
               (b.name, b.about, b.carrier, b.pivot_mm, b.direction)
        assert a.min_rad == pytest.approx(b.min_rad, rel=1e-15)
        assert a.max_rad == pytest.approx(b.max_rad, rel=1e-15)
    j = _random_joints(m, np.random.default_rng(0), 50)
    assert np.allclose(back.forward(j)[0], m.forward(j)[0], atol=1e-12)


@pytest.mark.parametrize("text, key", [
    ('name = "x"\n', "kind"),
    ('kind = "xyzqq"\n', "kind"),
    ('kind = "xyzac-trt"\ntool_length_mm = nan\n', "tool_length_mm"),
    ('kind = "xyzac-trt"\ntool_length_mm = "long"\n', "tool_length_mm"),
    ('kind = "xyzac-trt"\n[tilt]\npivot_mm = [0.0, nan, 0.0]\n', "tilt.pivot_mm"),
    ('kind = "xyzac-trt"\n[tilt]\npivot_mm = [0.0, 1.0]\n', "tilt.pivot_mm"),
    ('kind = "xyzac-trt"\n[tilt]\nmin_deg = nan\n', "tilt.min_deg"),
    ('kind = "xyzac-trt"\n[tilt]\nmin_deg = 50\nmax_deg = 10\n', "tilt.min_deg"),
    ('kind = "xyzac-trt"\n[rotary]\ndirection = 2\n', "rotary.direction"),
    ('kind = "xyzac-trt"\n[rotary]\npivot = [0, 0, 0]\n', "rotary.pivot"),
    ('kind = "xyzac-trt"\n[linear_limits_mm]\nx = [0, nan]\n', "linear_limits_mm.x"),
    ('kind = "xyzac-trt"\ntool = 3\n', "tool"),
    ('kind = "custom"\n[tilt]\nname = "B"\nabout = "y"\ncarrier = "head"\n', "rotary"),
    ('kind = "custom"\n[tilt]\nname = "B"\nabout = "y"\ncarrier = "head"\n'
     '[rotary]\nname = "C"\nabout = "z"\n', "rotary.carrier"),
    ('kind = "custom"\n[tilt]\nname = "B"\nabout = [0, 2, 0]\ncarrier = "head"\n'
     '[rotary]\nname = "C"\nabout = "z"\ncarrier = "head"\n', "tilt.about"),
    ('kind = "custom"\n[tilt]\nname = "B"\nabout = "z"\ncarrier = "head"\n'
     '[rotary]\nname = "C"\nabout = "z"\ncarrier = "head"\n', "axes"),
])
def test_bad_machine_file(tmp_path, text: str, key: str) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(MachineFileError) as ei:
        load_machine(f)
    msg = str(ei.value)
    assert msg.startswith(f"{f}: {key}") and ei.value.key.startswith(key)


def test_unreadable_machine_file(tmp_path) -> None:
    with pytest.raises(MachineFileError, match="none.toml: machine file not found"):
        load_machine(tmp_path / "none.toml")
    with pytest.raises(MachineFileError, match="cannot read"):
        load_machine(tmp_path)  # a folder
    f = tmp_path / "broken.toml"
    f.write_text("kind = \n")
    with pytest.raises(MachineFileError, match="broken.toml"):
        load_machine(f)


def test_registry() -> None:
    assert set(MACHINES) == {"xyzac-trt", "xyzbc-trt", "xyzbc-head-table", "xyzbc-head-head"}
    for name, (t, c) in {"xyzac-trt": ("table", "table"), "head-table-bc": ("head", "table"),
                         "head-head-bc": ("head", "head")}.items():
        m = get_machine(name)
        assert (m.axes[0].carrier, m.axes[1].carrier) == (t, c)
        assert m.axes[0].direction == m.axes[1].direction == 1
    with pytest.raises(ValueError, match="unknown machine"):
        get_machine("xyz")
    m = get_machine("xyzbc-head-table", tool_length_mm=50.0)
    assert m.with_tool_length(80.0).tool_length_mm == 80.0 and m.tool_length_mm == 50.0


def test_linearize_point_budget_and_noisy_singularity() -> None:
    """A tool axis wobbling 2 mrad around the C axis swings C between neighbours."""
    rng = np.random.default_rng(5)
    n = 400
    m = get_machine("xyzac-trt", tilt_pivot_mm=(0.0, 20.0, -35.0))
    tip = np.column_stack([np.linspace(-30, 30, n), np.zeros(n), np.full(n, -2.0)])
    axis = np.column_stack([rng.normal(0, 2e-3, n), rng.normal(0, 2e-3, n), np.ones(n)])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    sol = solve_path(m, tip, axis)
    # bisection cannot converge: inserted points are as singular as their ends
    lin = linearize(m, tip, axis, sol.joints)
    assert lin.max_deviation_mm > 1.0
    with pytest.raises(KinematicsError, match="singular_cone_rad") as info:
        linearize(m, tip, axis, sol.joints, max_points=2 * n)
    assert info.value.index is not None and 0 <= info.value.index < n
    # with a cone wider than the wobble, C is held and nothing explodes
    sol = solve_path(m, tip, axis, singular_cone_rad=0.01)
    lin = linearize(m, tip, axis, sol.joints, singular_cone_rad=0.01)
    assert len(lin.tip) < 2 * n and lin.max_deviation_mm <= K.LINEARIZE_TOL_MM
    assert sol.orientation_error_rad.max() <= 0.01
