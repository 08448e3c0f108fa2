"""The main job on issue 16's flexible wall (tests/sim/flexible_wall.py: a rib 40 mm high,
2.5 mm thick, a D6 ball on a head-table machine; its top pass and a soft wall mode): the
corrected program the job writes is never worse than the planned one, re-predicted here
densely from the written files, independently of the job's own loop; and the job says
which checks fail, with exit status 1."""

from __future__ import annotations

import json

import numpy as np

from errpred.pipeline import build_predictor
from errpred.verification import compare, error_field
from nc import read_program
from nc.path import cutter_locations
from orient.scenario import load_plan_scenario
from orient.workpiece import WorkpieceModel
from sim.cli import main as sim_main

from ..thin_wall import wall_mode
from .flexible_wall import flexible_wall

#: A soft wall mode: the wall bends about as much as the tool [N/m].
WALL_STIFFNESS_N_M = 3.0e6


def test_the_flexible_wall_job_never_writes_a_program_worse_than_the_plan(tmp_path, capsys):
    scn_path = flexible_wall(tmp_path / "scn", passes=1, workpiece=wall_mode(WALL_STIFFNESS_N_M),
                             edits={"grid = [17, 17]": "grid = [7, 7]",
                                    "[orient]\n": "[orient]\nverify_sdm = false\n"})
    out = tmp_path / "out"
    assert sim_main(["job", str(scn_path), "--out", str(out), "--no-dask"]) == 1
    # stderr: the progress display, then one line
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if "error" in ln]
    assert len(err) == 1 and err[0].startswith("error: flexible-wall: check(s) failed: ")
    rep = json.loads((out / "report.json").read_text())
    failed = [k for k, v in rep["checks"].items() if not v]
    assert all(f in err[0] for f in failed)
    final = out / "flexible-wall.NOT-FOR-CUTTING.nc"
    planned = out / "flexible-wall-planned.NOT-FOR-CUTTING.nc"
    assert final.exists() and planned.exists()
    # both programs re-predicted densely, the final against the planned path's surface
    scn = load_plan_scenario(scn_path)
    base = scn.base
    machine = scn.machine(None)
    wp = WorkpieceModel(scn.workpiece)
    stock = base.stock.load()
    dense = base.resolution.dense()
    fields = []
    for path in (planned, final):
        prog = read_program(path)
        pred = build_predictor(base, prog, dense, stock, workpiece=wp.modes_at,
                               machine=machine).run()
        fields.append((prog, pred))
    ref = cutter_locations(fields[0][0], machine, chord_tol_mm=dense.chord_tol_mm)
    before = error_field(fields[0][1], ref, moved=False)
    after = error_field(fields[1][1], ref)
    assert len(before) > 20 and np.abs(before.E_um).max() > 20.0     # a wall that bends
    cmp = compare(before, after, tolerance_um=base.correction.verify_tolerance_um)
    assert cmp.ok, cmp.reason()
    # the job says the same of what it wrote
    corr = rep["correction"]
    assert corr["verified"] == rep["checks"]["correction_verified_nowhere_worse"]
    if corr["verified"]:
        assert cmp.after.rms_um < cmp.before.rms_um
    else:                                   # nothing verified: the plan is what it wrote
        assert np.abs(after.E_um - before.E_um).max() < 0.5
