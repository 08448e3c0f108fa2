"""Fanuc tool centre point programs (G43.4 angles, G43.5 vector) read back.

A program written by :func:`nc.writer.post` in a Fanuc dialect is read by
:func:`nc.read_program`, and its cutter locations are the written ones within
1 um and 1e-4 deg, on random 5-axis paths (hypothesis) on every named machine.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nc import parse_program
from nc.kinematics import MACHINES, get_machine
from nc.path import CutterLocations, cutter_locations
from nc.program import TCP_ANGLES, TCP_VECTOR
from nc.writer import PostOptions, post

TIP_TOL_MM = 1e-3
AXIS_TOL_DEG = 1e-4


def _path(seed: int, n: int, tilt_max_deg: float) -> CutterLocations:
    """A random smooth-ish 5-axis path: tips in a 100 mm box, axes within a cone of Z."""
    rng = np.random.default_rng(seed)
    tip = np.cumsum(rng.uniform(-3, 3, (n, 3)), axis=0) + [0, 0, 20]
    tilt = np.radians(rng.uniform(0, tilt_max_deg, n))
    az = np.radians(rng.uniform(-180, 180)) + np.cumsum(rng.uniform(-0.3, 0.3, n))
    axis = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    return CutterLocations(tip=tip, axis=axis, feed_mm_min=np.full(n, 800.0),
                           spindle_rpm=np.full(n, 12000.0), block=np.arange(n),
                           rapid=np.zeros(n, dtype=bool))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 40),
       tilt=st.floats(5.0, 60.0), name=st.sampled_from(sorted(MACHINES)),
       dialect=st.sampled_from(["fanuc-g43.4", "fanuc-g43.5"]))
def test_fanuc_tcp_program_reads_back_within_1um_and_1e4_deg(seed, n, tilt, name, dialect):
    machine = get_machine(name)
    cl = _path(seed, n, tilt)
    res = post(cl, machine, PostOptions(dialect=dialect))
    prog = parse_program(res.text)
    tcp = prog.modal_column("tcp")[prog.motion != 0]
    assert set(tcp.tolist()) == {TCP_ANGLES if dialect == "fanuc-g43.4" else TCP_VECTOR}
    back = cutter_locations(prog, machine)
    cut = np.flatnonzero(~back.rapid)
    # every written point, in order, read back (the first feed move descends to point 0)
    assert len(cut) == len(res.tip)
    d_tip = np.linalg.norm(back.tip[cut] - res.tip, axis=1)
    assert d_tip.max() <= TIP_TOL_MM
    cos = np.clip(np.sum(back.axis[cut] * res.axis, axis=1), -1.0, 1.0)
    assert np.degrees(np.arccos(cos)).max() <= AXIS_TOL_DEG
    # and the written points are the input's where they come from it
    src = res.source
    whole = np.isclose(src, np.round(src))
    k = np.round(src[whole]).astype(int)
    assert np.linalg.norm(back.tip[cut][whole] - cl.tip[k], axis=1).max() <= TIP_TOL_MM
    cos_in = np.clip(np.sum(back.axis[cut][whole] * cl.axis[k], axis=1), -1.0, 1.0)
    assert np.degrees(np.arccos(cos_in)).max() <= AXIS_TOL_DEG


def test_g43_4_block_reads_tip_and_angles_hand_checked():
    # G43.4: X Y Z is the tip, A C the machine's angles (xyzac-trt: A tilts, C turns)
    prog = parse_program("G21 G90 G94\nT1 M6\nS1000 M3\nG43.4 H1\nG1 X10 Y0 Z5 A30 C90 F500\n")
    assert prog.modals[prog.modal_index[-1]].tcp == TCP_ANGLES
    np.testing.assert_allclose(prog.end[-1], [10, 0, 5, 0, 0, 0] + np.radians([0, 0, 0, 30, 0, 90]))


def test_g43_5_block_reads_unit_vector_hand_checked():
    prog = parse_program("G21 G90 G94\nT1 M6\nS1000 M3\nG43.5 H1\nG1 X1 Y2 Z3 I1 J0 K1 F500\n")
    np.testing.assert_allclose(prog.tool_vector[-1], [math.sqrt(0.5), 0, math.sqrt(0.5)])
    cl = cutter_locations(prog)
    np.testing.assert_allclose(cl.tip[-1], [1, 2, 3])
