"""The planning scenario's public parts that the planner, the job and the simulated
machine share: one machine resolution (with the tool's overhang as the tool length, as
errpred's pipeline has it), the stock as a mesh, and one interference checker."""

from __future__ import annotations

import numpy as np
import pytest

from errpred.pipeline import build_predictor
from nc.kinematics import get_machine, machine_to_toml
from nc.path import cutter_locations
from orient.contacts import ball_contacts
from orient.scenario import ScenarioError, load_plan_scenario
from tests.sim.flexible_wall import MACHINE as HEAD
from tests.sim.flexible_wall import OVERHANG_MM, flexible_wall
from tests.thin_wall import thin_wall_copy, wall_mode


def _scn(tmp_path, edits=None):
    return load_plan_scenario(thin_wall_copy(tmp_path / "scn", edits, wall_mode(6.0e6)))


def test_a_named_machine_gets_the_overhang_as_tool_length_everywhere(tmp_path):
    """Issue 16's flexible wall: a CAM program for a head-table machine, written with the
    tool's overhang as tool length; the planner's machine and errpred's read it alike."""
    scn = load_plan_scenario(flexible_wall(tmp_path / "scn", passes=1,
                                           workpiece=wall_mode(6.0e6)))
    overhang = scn.base.tool.overhang_mm
    m = scn.machine()
    assert m.name == HEAD and m.tool_length_mm == overhang == OVERHANG_MM
    prog = scn.base.read_program()
    pred = build_predictor(scn.base, prog, sensitivity=False)
    ref = cutter_locations(prog, m, chord_tol_mm=scn.base.resolution.chord_tol_mm)
    np.testing.assert_array_equal(pred.cl.tip, ref.tip)
    # the ball on the design where the CAM program cuts; without the tool length the
    # tips move by centimetres
    gap = ball_contacts(ref, scn.base.tool.radius_mm, scn.base.stock.load_design()).gap_mm
    assert np.abs(gap[~ref.rapid]).min() < 1e-3
    zero = cutter_locations(prog, m.with_tool_length(0.0))
    assert np.linalg.norm(zero.tip - ref.tip, axis=1).max() > 10.0
    # an override by name (python -m orient plan --machine) is resolved the same way
    assert scn.machine("xyzbc-head-head").tool_length_mm == overhang


def test_a_machine_file_gets_the_overhang_and_a_machine_is_taken_as_given(tmp_path):
    folder = tmp_path / "scn"
    toml = thin_wall_copy(folder, {'machine = "xyzac-trt"': 'machine = "head.toml"'},
                          wall_mode(6.0e6))
    (folder / "head.toml").write_text(machine_to_toml(get_machine(HEAD, tool_length_mm=5.0)))
    scn = load_plan_scenario(toml)
    m = scn.machine()
    assert m.tool_length_mm == scn.base.tool.overhang_mm
    given = get_machine(HEAD, tool_length_mm=7.0)
    assert scn.machine(given) is given


def test_no_machine_is_an_input_error_naming_the_key(tmp_path):
    scn = _scn(tmp_path, {'machine = "xyzac-trt"\n': ''})
    assert scn.base.resolve_machine() is None
    with pytest.raises(ScenarioError, match="program.machine"):
        scn.machine()


def test_stock_mesh_of_an_stl_and_of_a_box(tmp_path):
    scn = _scn(tmp_path)
    mesh = scn.stock_mesh()
    assert mesh.is_watertight
    lo, hi = mesh.bounds
    np.testing.assert_allclose(lo, [0.0, 0.0, -10.0], atol=1e-6)
    np.testing.assert_allclose(hi, [60.0, 40.0, 30.0], atol=1e-6)
    box = _scn(tmp_path / "box", {'stl = "stock.stl"':
                                  "box_min_mm = [0.0, 0.0, -10.0]\n"
                                  "box_max_mm = [60.0, 40.0, 30.0]"})
    m = box.stock_mesh()
    assert m.is_watertight and m.volume == pytest.approx(60.0 * 40.0 * 40.0)
    assert mesh.volume < m.volume                     # the rib's stock is no full box


def test_interference_checker_takes_the_scenario_options(tmp_path):
    scn = _scn(tmp_path, {"clearance_mm = 1.0": "clearance_mm = 2.5\ngouge_tol_mm = 0.02"})
    chk = scn.interference_checker()
    assert chk.clearance_mm == 2.5 and chk.gouge_tol_mm == 0.02
    assert chk.part_names == ("flank", "shank", "holder")
    # a vertical tool high above the part is clear; one down through the rib collides
    far = chk.check(np.array([[30.0, 20.0, 100.0]]), np.array([[0.0, 0.0, 1.0]]))
    into = chk.check(np.array([[30.0, 20.0, 0.0]]), np.array([[0.0, 0.0, 1.0]]))
    assert not (far.collides[0] or far.gouges[0])
    assert into.collides[0] or into.gouges[0]
