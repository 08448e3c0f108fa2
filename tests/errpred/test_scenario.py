"""Scenario files: the bundled scenarios, their geometry, and refused files."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import trimesh

from errpred.scenario import (
    BUNDLED,
    ScenarioError,
    ShapeError,
    bundled_scenario,
    load_scenario,
)

ROOT = Path(__file__).resolve().parents[2]


def _generator():
    """The generator script as a module (for the analytic design surface)."""
    spec = importlib.util.spec_from_file_location(
        "make_errpred_scenarios", ROOT / "scripts" / "make_errpred_scenarios.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def mold():
    s = load_scenario(bundled_scenario("mold-ball"))
    return s, s.read_program()


@pytest.fixture(scope="module")
def wall():
    s = load_scenario(bundled_scenario("wall-radius"))
    return s, s.read_program()


# --------------------------------------------------------------------------- bundled
@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_bundled_scenarios_load(name):
    s = load_scenario(BUNDLED[name])
    assert s.name == name and s.path == BUNDLED[name].resolve()
    assert s.stock.kind == "stl" and s.stock.path.is_file() and s.stock.design_path.is_file()
    assert s.compliance.directions == ("x", "y")
    for modes in s.compliance.modes.values():
        for m in modes:
            assert 1e3 <= m.natural_frequency_hz <= 4.5e3 and 1e6 <= m.k_N_m <= 1e8
            assert 0.02 <= m.damping_ratio <= 0.05
    assert {"cutting", "dynamics", "shape_error"} <= set(s.sources)
    assert s.coefficients.Ktc_N_mm2 > 0 and s.coefficients.Kte1_N_mm2 > 0
    assert s.resolution.pixel_mm == pytest.approx(s.tool.diameter_mm / 64)
    stock = s.stock.load()
    assert not stock.is_box and stock.bounds.shape == (2, 3)
    dev = s.shape_error.radius_deviation_mm(np.radians([0.0, 90.0]), 0.0)
    assert np.all(np.abs(dev) <= 5e-3) and s.shape_error.wear_rate_mm_per_mm > 0


def test_mold_program_parses_with_enough_blocks(mold):
    s, prog = mold
    assert s.tool.kind == "ball" and s.tool.diameter_mm == 10 and s.tool.flutes == 2
    assert len(prog) >= 20_000
    g1 = prog.motion == 1
    step = (prog.end - prog.start)[g1, :3]
    lengths = np.linalg.norm(step, axis=1)[np.hypot(step[:, 0], step[:, 1]) > 0]  # no plunges
    assert np.median(lengths) == pytest.approx(0.4, abs=0.1)
    assert np.percentile(lengths, 99) <= 0.6 + 1e-3 and lengths.max() <= 1.6   # leads 1.5
    rpm = prog.modal_column("spindle_rpm")[g1]
    fz = prog.feed[g1] / (rpm * s.tool.flutes)
    assert np.all((8000 <= rpm) & (rpm <= 12000)) and np.median(fz) == pytest.approx(0.08)


def test_wall_program_matches_the_patent_example(wall):
    s, prog = wall
    t = s.tool
    assert (t.kind, t.diameter_mm, t.corner_radius_mm, t.flutes, t.helix_deg) == \
        ("radius", 20.0, 1.0, 2, 0.0)
    assert 300 <= len(prog) <= 5000
    cut = prog.motion != 0
    assert np.all(prog.modal_column("spindle_rpm")[cut] == 2700)
    assert np.all(prog.feed[cut] == 1300)
    assert np.any(prog.motion == 2)                    # arcs, clockwise: climb outside
    levels = np.unique(np.round(prog.end[cut, 2], 6))
    assert np.allclose(np.diff(levels), 0.5)


def test_description_slices_are_inside_the_programs(mold, wall):
    import re

    for s, prog in (mold, wall):
        spans = [tuple(map(int, m)) for m in re.findall(r"\[(\d+), (\d+)\]", s.description)]
        assert spans
        for a, b in spans:
            n = int(np.count_nonzero((prog.line >= a) & (prog.line <= b)))
            assert 100 <= n <= 400, (s.name, a, b, n)


def _distance_to_design(centres, z_of, R):
    """Shortest distance from points to the surface z = f(x, y): grid, then zoom."""
    g = np.arange(-R - 0.2, R + 0.2001, 0.1)
    du, dv = (a.ravel() for a in np.meshgrid(g, g))
    k = np.arange(-3, 4)
    ku, kv = (a.ravel() for a in np.meshgrid(k, k))
    X, Y, Z = (centres[:, i, None] for i in range(3))
    D = du ** 2 + dv ** 2 + (z_of(X + du, Y + dv) - Z) ** 2
    j = np.argmin(D, axis=1)
    rows, bu, bv, step = np.arange(len(j)), du[j], dv[j], 0.1
    for _ in range(7):
        step /= 3.0
        U, V = bu[:, None] + ku * step, bv[:, None] + kv * step
        D = U ** 2 + V ** 2 + (z_of(X + U, Y + V) - Z) ** 2
        j = np.argmin(D, axis=1)
        bu, bv = U[rows, j], V[rows, j]
    return np.sqrt(D[rows, j])


def test_mold_tips_do_not_gouge_the_design(mold):
    s, prog = mold
    gen = _generator()
    R = s.tool.radius_mm
    idx = np.flatnonzero(prog.motion == 1)
    sample = np.random.default_rng(7).choice(idx, 400, replace=False)
    d = _distance_to_design(prog.end[sample, :3] + [0.0, 0.0, R], gen.design_z, R)
    assert d.min() >= R - 1e-3
    touching = np.abs(d - R) <= 1e-3                  # cutting points, not leads or plunges
    assert touching.mean() > 0.95


def test_mold_stock_contains_the_design(mold):
    s, _ = mold
    gen = _generator()
    rng = np.random.default_rng(3)
    xy = rng.uniform([0.5, 0.5], [59.5, 39.5], size=(300, 2))
    for path, lo, hi in ((s.stock.path, 0.15 - 0.006, 0.15 + 0.006),
                         (s.stock.design_path, 0.0, 0.006)):
        mesh = trimesh.load(path, force="mesh")
        assert mesh.is_watertight and mesh.volume > 0
        origins = np.column_stack([xy, np.full(len(xy), 100.0)])
        loc, ray, _ = mesh.ray.intersects_location(origins, np.tile([0.0, 0.0, -1.0], (len(xy), 1)))
        top = np.full(len(xy), -np.inf)
        np.maximum.at(top, ray, loc[:, 2])
        if path == s.stock.path:                      # stock above the design everywhere
            assert np.all(top > gen.design_z(xy[:, 0], xy[:, 1]))
        # allowance along the surface normal: distance from the mesh top to the design
        d = _distance_to_design(np.column_stack([xy, top]), gen.design_z, 0.5)
        assert np.all(d >= lo) and np.all(d <= hi), (path.name, d.min(), d.max())
    assert Path(s.stock.path).stat().st_size < 4e6


def test_wall_stock_contains_design_and_tool_touches_without_gouging(wall):
    s, prog = wall
    design = s.stock.load_design()
    stock = trimesh.load(s.stock.path, force="mesh")
    assert design.is_watertight and stock.is_watertight
    pts, faces = trimesh.sample.sample_surface(design, 3000, seed=5)
    normals = design.face_normals[faces]
    wall_pts = pts[(np.abs(normals[:, 2]) < 0.5) & (pts[:, 2] > 0.1) & (pts[:, 2] < 39.9)]
    assert len(wall_pts) > 300 and np.all(stock.contains(wall_pts))
    # the corner torus: its core circle stays r away from the design, and touches it
    r, core = s.tool.corner_radius_mm, s.tool.core_radius_mm
    cutting = np.flatnonzero(prog.motion == 1)
    ends = prog.end[cutting[::15]]
    t = np.radians(np.arange(0, 360, 5.0))
    circle = (ends[:, None, :3] + np.stack([core * np.cos(t), core * np.sin(t),
                                           np.full_like(t, r)], axis=1)).reshape(-1, 3)
    _, dist, _ = trimesh.proximity.closest_point(design, circle)
    per_tip = dist.reshape(len(ends), -1).min(axis=1)
    assert per_tip.min() >= r - 1e-3
    assert np.median(per_tip) == pytest.approx(r, abs=2e-3)


def test_bundled_scenario_unknown_name():
    with pytest.raises(ValueError, match="mold-ball"):
        bundled_scenario("nope")


# --------------------------------------------------------------------------- refused files
VALID = """\
name = "tiny"
description = "a box and two lines"

[stock]
box_min_mm = [0.0, 0.0, 0.0]
box_max_mm = [50.0, 40.0, 20.0]

[tool]
type = "ball"
diameter_mm = 10.0
flutes = 2
helix_deg = 30.0

[program]
gcode = "p.nc"
allow = ["M8"]

[cutting]
Ktc_N_mm2 = 2000.0
Krc_N_mm2 = 800.0
Kac_N_mm2 = 300.0
Kte0_N_mm = 30.0
Kre0_N_mm = 35.0
Kae0_N_mm = 10.0
source = "test"

[dynamics]
[[dynamics.modes]]
direction = "x"
frequency_hz = 2000.0
damping_ratio = 0.03
stiffness_N_m = 5.0e6

[[dynamics.modes]]
direction = "y"
mass_kg = 0.03
damping_Ns_m = 25.0
stiffness_N_m = 6.0e6

[shape_error]
kappa_deg = [0.0, 90.0]
radius_deviation_um = [-2.0, 2.0]
wear_rate_um_per_m = 0.1
"""


def _write(tmp_path, text):
    (tmp_path / "p.nc").write_text("G21 G90 G17\nG0 X0 Y0 Z30\nG1 X10 F1000\nM8\nG1 Y10\n")
    (tmp_path / "s.stl").write_bytes(b"")
    path = tmp_path / "scenario.toml"
    path.write_text(text)
    return path


def test_valid_small_scenario_and_defaults(tmp_path):
    s = load_scenario(_write(tmp_path, VALID))
    assert s.stock.kind == "box" and s.stock.bounds == ((0, 0, 0), (50, 40, 20))
    assert s.stock.load().is_box and s.lines is None and s.machine is None
    assert s.allow == ("M8",) and len(s.read_program()) == 3
    assert s.tool.rotation == "cw" and s.tool_change_tolerance_um is None
    from errpred import constants as EK

    assert s.resolution.micro_edges == EK.MICRO_EDGES_ENVELOPE
    assert s.resolution.angle_step_rad == pytest.approx(EK.ANGLE_STEP_RAD)
    assert s.resolution.chord_tol_mm == pytest.approx(EK.CHORD_TOL_MM)
    assert not s.correction.iterate and s.correction.relaxation is None
    assert s.correction.verify_walls is True
    assert s.compliance.modes["y"][0].m_kg == 0.03


def test_shape_error_interpolates_holds_ends_and_signs():
    se = ShapeError("kappa", np.radians([10.0, 50.0]), np.array([-2e-3, 2e-3]), 1e-6)
    k = np.radians([0.0, 10.0, 30.0, 50.0, 90.0])
    assert np.allclose(se.radius_deviation_mm(k, 0.0), [-2e-3, -2e-3, 0.0, 2e-3, 2e-3])
    # a tool smaller than nominal leaves material; wear leaves more
    assert se.material_left_mm(0.0, 0.0) == pytest.approx(2e-3)
    assert se.material_left_mm(0.0, 0.0, cl_mm=1000.0) == pytest.approx(3e-3)
    assert np.all(ShapeError().radius_deviation_mm(k, 1.0) == 0)


@pytest.mark.parametrize("old, new, key", [
    ("flutes = 2\n", "", "tool.flutes"),                                   # missing key
    ("helix_deg = 30.0\n", "helix_deg = 30.0\ncolour = 1\n", "tool.colour"),  # unknown key
    ("diameter_mm = 10.0", "diameter_mm = nan", "tool.diameter_mm"),        # NaN
    ("stiffness_N_m = 5.0e6", "stiffness_N_m = inf", "dynamics.modes[0].stiffness_N_m"),
    ("diameter_mm = 10.0", "diameter_in = 0.4", "tool.diameter_in"),        # wrong unit
    ('type = "ball"', 'type = "bal"', "tool.type"),                        # unknown tool type
    ('gcode = "p.nc"', 'gcode = "missing.nc"', "program.gcode"),            # missing file
    ("[stock]\n", '[stock]\nstl = "s.stl"\n', "stock.stl"),                # both stl and box
    ("box_min_mm = [0.0, 0.0, 0.0]\nbox_max_mm = [50.0, 40.0, 20.0]\n", "", "stock.stl"),
    ("box_max_mm = [50.0, 40.0, 20.0]\n", "", "stock.box_max_mm"),
    ("diameter_mm = 10.0", "diameter_mm = -10.0", "tool.diameter_mm"),
    ("flutes = 2", 'flutes = "two"', "tool.flutes"),
    ("frequency_hz = 2000.0", "frequency_hz = 0.0", "dynamics.modes[0].frequency_hz"),
    ("damping_ratio = 0.03\n", "", "dynamics.modes[0].damping_ratio"),
    ('direction = "y"', 'direction = "x"', "dynamics.modes"),
    ("radius_deviation_um = [-2.0, 2.0]", "radius_deviation_um = [-2.0]",
     "shape_error.radius_deviation_um"),
    ("kappa_deg = [0.0, 90.0]", "kappa_deg = [90.0, 0.0]", "shape_error.kappa_deg"),
    ("Ktc_N_mm2 = 2000.0", "Ktc_N_mm2 = 2000.0\nKtc_N_m2 = 2e9", "cutting.Ktc_N_m2"),
    ('allow = ["M8"]', 'allow = ["M8"]\nlines = [20, 10]', "program.lines"),
    ('allow = ["M8"]', 'allow = ["M8"]\nmachine = "xyzzy"', "program.machine"),
    ("= 0.1\n", '= 0.1\n[resolution]\npixel_mm = 0.0\n', "resolution.pixel_mm"),
    ("= 0.1\n", '= 0.1\n[correction]\niterate = "yes"\n', "correction.iterate"),
    ("= 0.1\n", '= 0.1\n[correction]\nverify_walls = 0\n', "correction.verify_walls"),
    ("= 0.1\n", '= 0.1\n[correction]\nrelaxation = 0.0\n', "correction.relaxation"),
    ("= 0.1\n", '= 0.1\n[correction]\nrelaxation = 1.5\n', "correction.relaxation"),
    # bounds (errpred.constants): values that would run for hours or describe no tool
    ("flutes = 2", "flutes = 25", "tool.flutes"),
    ("flutes = 2", "flutes = 9223372036854775807", "tool.flutes"),
    ("diameter_mm = 10.0", "diameter_mm = 1e300", "tool.diameter_mm"),
    ("Ktc_N_mm2 = 2000.0", "Ktc_N_mm2 = 1e300", "cutting.Ktc_N_mm2"),
    ("Kre0_N_mm = 35.0", "Kre0_N_mm = -1e300", "cutting.Kre0_N_mm"),
    ("damping_ratio = 0.03", "damping_ratio = 1e300", "dynamics.modes[0].damping_ratio"),
    ("mass_kg = 0.03", "mass_kg = 1e-30", "dynamics.modes[1].mass_kg"),
    ("= 0.1\n", '= 0.1\n[correction]\nmax_iterations = 1000000000\n',
     "correction.max_iterations"),
    # the program: a line range must select a motion block (line 4 is M8)
    ('allow = ["M8"]', 'allow = ["M8"]\nlines = [4, 4]', "program.lines"),
    ('allow = ["M8"]', 'allow = ["M8"]\nlines = [100, 200]', "program.lines"),
    # sizes against the memory budget
    ("= 0.1\n", '= 0.1\n[resolution]\npixel_mm = 1e-7\n', "resolution.pixel_mm"),
    ("= 0.1\n", '= 0.1\n[resolution]\npixel_mm = 5.0\n', "resolution.pixel_mm"),
    ("= 0.1\n", '= 0.1\n[resolution]\nmicro_edges = 100000\n', "resolution.micro_edges"),
    ("= 0.1\n", '= 0.1\n[resolution]\nangle_step_deg = 1e-5\n', "resolution.angle_step_deg"),
    ("= 0.1\n", '= 0.1\n[resolution]\nangle_step_deg = 120.0\n', "resolution.angle_step_deg"),
    ("= 0.1\n", '= 0.1\n[resolution]\nchord_tol_mm = 1e-12\n', "resolution.chord_tol_mm"),
    ("= 0.1\n", '= 0.1\n[resolution]\npoint_spacing_mm = 1e-9\n',
     "resolution.point_spacing_mm"),
])
def test_bad_files_name_file_and_key(tmp_path, old, new, key):
    assert old in VALID
    path = _write(tmp_path, VALID.replace(old, new, 1))
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    msg = str(exc.value)
    assert "scenario.toml" in msg and f"{key}:" in msg, msg
    assert exc.value.key == key


def test_messages_say_what_was_expected(tmp_path):
    path = _write(tmp_path, VALID.replace("diameter_mm = 10.0", "diameter_in = 0.4"))
    with pytest.raises(ScenarioError, match="did you mean 'tool.diameter_mm'"):
        load_scenario(path)
    path = _write(tmp_path, VALID.replace('gcode = "p.nc"', 'gcode = "sub/missing.nc"'))
    with pytest.raises(ScenarioError, match=str(tmp_path / "sub" / "missing.nc")):
        load_scenario(path)
    path = _write(tmp_path, VALID.replace('type = "ball"', 'type = "bal"'))
    with pytest.raises(ScenarioError, match="ball, radius, flat"):
        load_scenario(path)
    path = _write(tmp_path, VALID + "\n[[[")
    with pytest.raises(ScenarioError, match="not valid TOML") as exc:
        load_scenario(path)
    assert exc.value.key is None
    with pytest.raises(ScenarioError, match="not found"):
        load_scenario(tmp_path / "absent.toml")


def test_static_model_from_static_compliance_only(tmp_path):
    text = VALID.split("[dynamics]")[0] + (
        '[dynamics]\nmodel = "static"\nstatic_compliance_m_N = { x = 2.0e-7, y = 1.0e-7 }\n')
    s = load_scenario(_write(tmp_path, text))
    assert s.compliance.kind == "static"
    assert s.compliance.static_compliance_m_N == pytest.approx({"x": 2e-7, "y": 1e-7})
    with pytest.raises(ScenarioError, match="dynamics.static_compliance_m_N"):
        load_scenario(_write(tmp_path, VALID.replace(
            "[dynamics]\n", "[dynamics]\nstatic_compliance_m_N = { x = 2.0e-7 }\n")))


def test_memory_budget_names_the_coarsest_pixel_that_fits(tmp_path):
    """The refusal's suggested pixel_mm loads; 5 % finer is refused again (the suggestion
    is the least that fits, rounded up by under 2 %)."""
    import re

    from errpred import constants as EK
    from errpred.limits import resolution_cost

    path = _write(tmp_path, VALID + "[resolution]\npixel_mm = 1e-7\n")
    with pytest.raises(ScenarioError, match="MEMORY_BUDGET_BYTES") as exc:
        load_scenario(path)
    least = float(re.search(r"pixel_mm >= ([0-9.e+-]+)$", str(exc.value)).group(1))
    s = load_scenario(_write(tmp_path, VALID + f"[resolution]\npixel_mm = {least!r}\n"))
    t, r = s.tool, s.resolution
    fits = resolution_cost(t.diameter_mm, t.corner_radius_mm, t.flute_length_mm, t.flutes,
                           r.pixel_mm, r.micro_edges, r.angle_step_rad)
    assert fits.bytes <= EK.MEMORY_BUDGET_BYTES
    with pytest.raises(ScenarioError, match="resolution.pixel_mm"):
        load_scenario(_write(tmp_path, VALID + f"[resolution]\npixel_mm = {least * 0.95!r}\n"))


@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_resolution_cost_counts_what_the_model_makes(name):
    """The estimate's pixels and samples are the bottom template's and the revolution's."""
    from errpred.bottomview import BottomTemplate
    from errpred.engagement import revolution_angles
    from errpred.limits import resolution_cost

    s = load_scenario(bundled_scenario(name))
    t, r = s.tool, s.resolution
    c = resolution_cost(t.diameter_mm, t.corner_radius_mm, t.flute_length_mm, t.flutes,
                        r.pixel_mm, r.micro_edges, r.angle_step_rad)
    edges = t.micro_edges(r.micro_edges)
    theta = revolution_angles(r.angle_step_rad, t.flutes)
    bt = BottomTemplate(t, edges, theta, r.pixel_mm)
    assert c.bottom_pixels == bt.n ** 2
    assert c.samples == pytest.approx(len(edges.rho) * len(theta), rel=0.01)
    # the bundled scenarios are well inside the budget, and so is the convergence
    # test's setting (every discretization 4x finer)
    from errpred import constants as EK

    assert c.bytes < EK.MEMORY_BUDGET_BYTES / 4
    f = r.finer(4)
    assert resolution_cost(t.diameter_mm, t.corner_radius_mm, t.flute_length_mm, t.flutes,
                           f.pixel_mm, f.micro_edges, f.angle_step_rad
                           ).bytes < EK.MEMORY_BUDGET_BYTES


@pytest.mark.parametrize("program, expected", [
    ("", "no motion block"),
    ("%\n(only a comment)\nM30\n%\n", "no motion block"),
    ("G21 G90\nG0 X0 Y0 Z5\nG1 X10 F100 Q7\n", r"p.nc:3:\d+: unknown word Q"),
])
def test_program_is_read_when_the_scenario_is_loaded(tmp_path, program, expected):
    path = _write(tmp_path, VALID)
    (tmp_path / "p.nc").write_text(program)
    with pytest.raises(ScenarioError, match=expected) as exc:
        load_scenario(path)
    assert exc.value.key == "program.gcode" and "\n" not in str(exc.value)


@pytest.mark.parametrize("stl, expected", [
    (b"", "empty file"),
    (b"solid x\n  facet normal what\nendsolid\n", "no triangles|cannot read"),
    ("open", "not watertight"),
])
def test_stock_mesh_is_read_and_must_be_closed(tmp_path, stl, expected):
    text = VALID.replace("box_min_mm = [0.0, 0.0, 0.0]\nbox_max_mm = [50.0, 40.0, 20.0]\n",
                         'stl = "s.stl"\n')
    path = _write(tmp_path, text)
    if stl == "open":
        box = trimesh.creation.box(extents=(50.0, 40.0, 20.0))
        trimesh.Trimesh(box.vertices, box.faces[:-1], process=False).export(tmp_path / "s.stl")
    else:
        (tmp_path / "s.stl").write_bytes(stl)
    with pytest.raises(ScenarioError, match=expected) as exc:
        load_scenario(path)
    assert exc.value.key == "stock.stl" and "s.stl" in str(exc.value)


def test_a_heidenhain_program_predicts_as_the_same_path_in_g_code(tmp_path):
    """``[program] dialect``: the mold-ball scenario with the start of its program
    written as Heidenhain Klartext (L blocks, FMAX, TOOL CALL) predicts the same
    points and errors as the same moves in G-code; "auto" detects it."""
    import dataclasses
    import json
    import math

    from nc import read_program
    from nc.program import RAPID
    from errpred.pipeline import predict
    from errpred.scenario import bundled_scenario

    src = bundled_scenario("mold-ball")
    prog = read_program(src.parent / "finish.nc", allow=("M8", "M9"))
    rows = range(min(len(prog), 60))
    assert all(prog.arc_index[i] < 0 for i in rows)
    gcode = ["G21 G90 G17 G94", "S10000 M3"]
    tnc = ["0 BEGIN PGM START MM", "1 TOOL CALL 1 Z S10000"]
    for i in rows:
        x, y, z = (float(v) for v in prog.end[i, :3])
        rapid = prog.motion[i] == RAPID
        gcode.append(f"{'G0' if rapid else 'G1'} X{x:.4f} Y{y:.4f} Z{z:.4f}"
                     + ("" if rapid else f" F{prog.feed[i]:.0f}"))
        tnc.append(f"{len(tnc)} L X{x:+.4f} Y{y:+.4f} Z{z:+.4f} R0 "
                   + ("FMAX" if rapid else f"F{prog.feed[i]:.0f}"))
    gcode.append("M30")
    tnc.append(f"{len(tnc)} END PGM START MM")
    (tmp_path / "start.nc").write_text("\n".join(gcode) + "\n")
    (tmp_path / "start.h").write_text("\n".join(tnc) + "\n")
    text = src.read_text()
    for name in ("stock.stl", "design.stl"):
        text = text.replace(f'"{name}"', json.dumps(str(src.parent / name)))
    out = {}
    for prog_name, dialect in (("start.nc", None), ("start.h", None), ("start.h", "heidenhain")):
        t = text.replace('gcode = "finish.nc"', f'gcode = "{prog_name}"')
        if dialect:
            t = t.replace("[program]\n", f'[program]\ndialect = "{dialect}"\n')
        path = tmp_path / f"{prog_name}-{dialect}.toml"
        path.write_text(t)
        scn = load_scenario(path)
        assert scn.dialect == (dialect or "auto")
        points = predict(scn).points
        out[(prog_name, dialect)] = [(p.status, p.result.E_um if p.result else None)
                                     for p in points]
    ref = out[("start.nc", None)]
    assert sum(s == "predicted" for s, _ in ref) >= 3
    assert all(math.isfinite(e) for s, e in ref if s == "predicted")
    assert out[("start.h", None)] == ref and out[("start.h", "heidenhain")] == ref
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('gcode = "finish.nc"', 'gcode = "start.nc"')
                   .replace("[program]\n", '[program]\ndialect = "fanuc"\n'))
    with pytest.raises(ScenarioError, match="program.dialect"):
        load_scenario(bad)


def test_program_with_drilling_cycles_is_refused_at_load(tmp_path):
    """The prediction models milling: a canned drilling cycle is refused before any work,
    under program.gcode, naming the program's file and the cycle's line."""
    path = _write(tmp_path, VALID)
    (tmp_path / "p.nc").write_text("G21 G90 G17\nG0 X0 Y0 Z30\nG1 X10 F1000\n"
                                   "G98 G81 X5 Y5 Z-3 R2\nG80\nM2\n")
    with pytest.raises(ScenarioError, match=r"program\.gcode: .*p\.nc:4:1: canned drilling "
                       r"cycle \(4 moves from line 4 on\)") as exc:
        load_scenario(path)
    assert exc.value.key == "program.gcode" and "\n" not in str(exc.value)


def test_predictor_refuses_a_drilling_program():
    """Programs handed to the Predictor directly (not through a scenario) too."""
    from nc import NCParseError, parse_program
    from errpred.predict import Predictor

    prog = parse_program("G21 G90 F100 S1000 M3\nG0 X0 Y0 Z10\nG98 G81 X20 Y0 Z-5 R2\n"
                         "G80\nM2\n", file="d.nc")
    with pytest.raises(NCParseError, match=r"^d\.nc:3:1: canned drilling cycle .* models "
                       "milling only"):
        Predictor(None, None, prog, None, None)


def test_a_siemens_program_reads_as_the_same_path_in_g_code(tmp_path):
    """``[program] dialect = "siemens"`` (and "auto"): the mold-ball scenario's program
    start written as a Sinumerik program (header, G642, CYCLE832, R parameters) reads
    to the same moves, feeds and spindle as the G-code, which is what the prediction
    takes (the Heidenhain test above runs the prediction itself)."""
    import json

    import numpy as np

    from nc import read_program
    from nc.program import RAPID
    from errpred.scenario import bundled_scenario

    src = bundled_scenario("mold-ball")
    prog = read_program(src.parent / "finish.nc", allow=("M8", "M9"))
    rows = range(min(len(prog), 60))
    gcode = ["G21 G90 G17 G94", "S10000 M3"]
    sin = ["%_N_START_MPF", ";$PATH=/_N_MPF_DIR", "N10 G17 G90 G71 G94 G642",
           "N20 S10000 M3", "N30 CYCLE832(0.01,_ORI_FINISH,1)"]
    for i in rows:
        x, y, z = (float(v) for v in prog.end[i, :3])
        rapid = prog.motion[i] == RAPID
        feed = "" if rapid else f" F{prog.feed[i]:.0f}"
        gcode.append(f"{'G0' if rapid else 'G1'} X{x:.4f} Y{y:.4f} Z{z:.4f}{feed}")
        sin.append(f"N{10 * len(sin)} R1={z:.4f} {'G0' if rapid else 'G1'} X{x:.4f} "
                   f"Y{y:.4f} Z=R1{feed}")
    gcode.append("M30")
    sin.append("M30")
    (tmp_path / "start.nc").write_text("\n".join(gcode) + "\n")
    (tmp_path / "start.mpf").write_text("\n".join(sin) + "\n")
    text = src.read_text()
    for name in ("stock.stl", "design.stl"):
        text = text.replace(f'"{name}"', json.dumps(str(src.parent / name)))
    progs = {}
    for prog_name, dialect in (("start.nc", None), ("start.mpf", None),
                               ("start.mpf", "siemens")):
        t = text.replace('gcode = "finish.nc"', f'gcode = "{prog_name}"')
        if dialect:
            t = t.replace("[program]\n", f'[program]\ndialect = "{dialect}"\n')
        path = tmp_path / f"{prog_name}-{dialect}.toml"
        path.write_text(t)
        scn = load_scenario(path)
        assert scn.dialect == (dialect or "auto")
        progs[(prog_name, dialect)] = scn.read_program()
    ref = progs[("start.nc", None)]
    for key in (("start.mpf", None), ("start.mpf", "siemens")):
        p = progs[key]
        assert p.metadata["dialect"] == "siemens"
        np.testing.assert_allclose(p.end, ref.end, atol=1e-12)
        np.testing.assert_array_equal(p.motion, ref.motion)
        np.testing.assert_array_equal(p.feed, ref.feed)
        np.testing.assert_array_equal(p.modal_column("spindle_rpm"),
                                      ref.modal_column("spindle_rpm"))
        np.testing.assert_array_equal(p.modal_column("tcp"), ref.modal_column("tcp"))


@pytest.mark.parametrize("feed, refused", [
    (1000.0, False),                 # 0.05 mm a tooth: a finishing feed
    (49_900.0, False),               # 2.495 mm: just inside 0.5 of the 5 mm radius
    (50_100.0, True),                # 2.505 mm: just beyond
    (10_000_000.0, True),            # a feed scaled by 10,000 (LinuxCNC's 3D_Chips.ngc)
])
def test_a_feed_per_tooth_beyond_the_force_model_is_refused_before_any_work(feed, refused):
    """``MAX_FEED_PER_TOOTH_RADII``: a feed move whose feed per tooth exceeds half the
    tool's radius (D10, 2 flutes, 10,000 rev/min: 50,000 mm/min) is refused by the
    Predictor at its line, before any geometry, naming the feed per tooth and the limit;
    rapids (G0, at any speed) are not feeds."""
    from nc import NCParseError, parse_program
    from nc.path import cutter_locations
    from errpred.conditions import feed_per_tooth_mm
    from errpred.predict import Predictor
    from errpred.tool import Tool

    tool = Tool("ball", 10.0, flutes=2, flute_length_mm=20.0, overhang_mm=40.0)
    prog = parse_program(f"G21 G90 S10000 M3\nG0 X0 Y0 Z10\nG1 Z-1 F1000\n"
                         f"G1 X20 F{feed:.1f}\nG0 Z10\nM2\n", file="f.nc")
    fz = feed_per_tooth_mm(cutter_locations(prog), tool.flutes)
    assert np.nanmax(fz) == pytest.approx(max(feed, 1000.0) / 20_000.0)
    if refused:
        with pytest.raises(NCParseError, match=r"^f\.nc:4: feed .* is 2\.5\d* mm a tooth|"
                           r"^f\.nc:4: feed .* is 500 mm a tooth") as exc:
            Predictor(tool, None, prog, None, None)
        assert "expected at most 2.5 mm (0.5 of the tool's radius" in str(exc.value)
    else:
        assert len(Predictor(tool, None, prog, None, None).cl) == len(fz)
