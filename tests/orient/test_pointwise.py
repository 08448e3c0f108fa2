"""orient.pointwise.point_setup with the contacts already found gives the same set-up."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from nc.path import cutter_locations
from orient.contacts import ball_contacts
from orient.pointwise import point_gain, point_setup
from orient.scenario import bundled_scenario, load_plan_scenario


def test_given_contacts_give_the_same_setup():
    scn = load_plan_scenario(bundled_scenario("thin-wall"))
    cam = cutter_locations(scn.base.read_program(), scn.machine())
    design = scn.base.stock.load_design()
    con = ball_contacts(cam, scn.base.tool.radius_mm, design)
    i = int(np.flatnonzero(con.touching)[40])
    axis = cam.axis[i]
    a = point_setup(scn, i, axis=axis, spindle_rpm=9500.0)
    b = point_setup(scn, i, axis=axis, spindle_rpm=9500.0, contacts=con)
    assert a.index == b.index == i and a.spindle_rpm == b.spindle_rpm
    np.testing.assert_array_equal(a.contacts.point, b.contacts.point)
    assert dataclasses.astuple(a.cut) == dataclasses.astuple(b.cut)
    np.testing.assert_array_equal(point_gain(scn, a).H, point_gain(scn, b).H)
    short = ball_contacts(cam.take(np.arange(10)), scn.base.tool.radius_mm, design)
    with pytest.raises(ValueError, match="contacts: 10 cutter locations"):
        point_setup(scn, i, contacts=short)
