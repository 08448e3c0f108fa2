"""The correction's fit (errpred.offset) and the rewrite of a program from it (errpred.correct):
uniform and linear errors are followed exactly, noise is not chased, arcs keep their sweep,
full circles stay full circles, air pulls nothing."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from errpred.correct import apply_edit, fit_program
from errpred.offset import LINE, OffsetProblem, second_difference, solve_offsets
from errpred.verification import ErrorField
from nc import parse_program


def _line_problem(n: int, spacing: float, q_seg: np.ndarray, q_t: np.ndarray,
                  wanted_um: np.ndarray) -> OffsetProblem:
    """A straight chain of ``n`` vertices along X, ``spacing`` apart [mm], points on
    segments ``q_seg`` at shares ``q_t``, normal +Y, asking for ``wanted_um`` [um]."""
    verts = np.c_[np.arange(n) * spacing, np.zeros(n), np.zeros(n)]
    q_t = np.asarray(q_t, float)
    q = q_t.size
    return OffsetProblem(
        vertices=verts, movable=np.ones(n, bool), seg_v0=np.arange(n - 1),
        seg_v1=np.arange(1, n), seg_kind=np.full(n - 1, LINE),
        seg_plane=np.tile([0, 1, 2], (n - 1, 1)), seg_centre=np.zeros((n - 1, 3)),
        chains=[np.arange(n)], pt_seg=np.asarray(q_seg), pt_t=q_t,
        pt_w=np.c_[q_t, np.zeros(q)], pt_theta=np.zeros(q),
        pt_normal=np.tile([0.0, 1.0, 0.0], (q, 1)),
        pt_target=np.asarray(wanted_um, float) * 1e-3, pt_weight=np.ones(q))


def _chain_problem(wanted_um: np.ndarray, spacing: float = 1.0) -> OffsetProblem:
    """A straight chain along X, one point at each vertex (the end of each segment, the
    start of the first), normal +Y, asking for ``wanted_um`` [um]."""
    n = len(wanted_um)
    return _line_problem(n, spacing, np.r_[0, np.arange(n - 1)],
                         np.r_[0.0, np.ones(n - 1)], wanted_um)


def test_uniform_and_linear_errors_are_followed_exactly():
    for wanted in (np.full(20, 7.0), np.linspace(-3.0, 9.0, 20)):
        sol = solve_offsets(_chain_problem(wanted))
        np.testing.assert_allclose(sol.moves[:, 1] * 1e3, wanted, atol=1e-3)
        np.testing.assert_allclose(sol.moves[:, [0, 2]], 0.0, atol=1e-9)   # along the normal


def test_a_chain_end_barely_reached_by_a_point_does_not_run_away():
    """The whole mold core's fit moved a chain's end vertex 143.9 um where the points
    asked for a few: the chain's last segment carried one point, 4.5 % along it, and the
    segment before none, so that point's equation alone set the end vertex,
    m_end = residual / t. An end vertex its points weigh on less than half a point
    (OFFSET_PIN) follows its neighbour: no move beyond the wanted range."""
    n = 20
    # points at the end of segments 0..n-4 (and the start), none on segment n-3, one at
    # t = 0.045 on the last
    q_seg = np.r_[0, np.arange(n - 3), n - 2]
    wanted = np.r_[np.full(n - 2, 0.5), 6.4]
    pb = _line_problem(n, 0.5, q_seg, np.r_[0.0, np.ones(n - 3), 0.045], wanted)
    m = solve_offsets(pb).moves[:, 1] * 1e3
    assert np.abs(m).max() <= wanted.max() + 0.05       # 131.4 um at the end without


def test_a_stretch_without_points_is_interpolated_to_the_next_point():
    """The mold core's fit kept a stretch without points (where another pass finished
    the surface) at the 18.9 um of the points before it up to its last vertex, beside
    points asking 8 um: the next point sat at the far end of the following segment, so
    nothing tied that vertex to it, and the candidate cut 9.6 um too deep where the
    pass began to finish. The stretch's moves now go linearly from the last point
    before it to the first after it (without the change, here, the stretch's last
    vertex kept 12.1 um, 1.2 um above the line, and the step to 9.1 um fell on the
    segment whose point is at its far end)."""
    n = 24
    # points at the ends of segments 0..7 (and the start) asking 19 um; none on 8..11;
    # points at the ends of segments 12..22 asking 8 um
    q_seg = np.r_[0, np.arange(8), np.arange(12, n - 1)]
    pb = _line_problem(n, 0.6, q_seg, np.r_[0.0, np.ones(q_seg.size - 1)],
                       np.where(q_seg < 8, 19.0, 8.0))
    m = solve_offsets(pb).moves[:, 1] * 1e3
    a, b = 8, 13                      # the last vertex with a point before, the first after
    lin = m[a] + (m[b] - m[a]) * (np.arange(a, b + 1) - a) / (b - a)
    np.testing.assert_allclose(m[a:b + 1], lin, atol=0.1)


def test_the_correction_is_no_rougher_than_the_error():
    """The bound stated in errpred.offset: the moves' second differences along a chain
    do not exceed the wanted moves' (plus 0.05 um), and point-to-point noise (a zigzag
    of +-1 um on 8 um) is damped, not followed."""
    rng = np.random.default_rng(16)
    x = np.arange(40.0)
    for wanted in (8.0 + rng.normal(0.0, 1.0, 40),
                   8.0 + np.where(np.arange(40) % 2, 1.0, -1.0),
                   5.0 + 3.0 * np.sin(x / 6.0) + rng.normal(0.0, 0.3, 40)):
        pb = _chain_problem(wanted)
        m = solve_offsets(pb).moves
        d2m = np.abs(second_difference(m, pb.vertices))[:, 1] * 1e3
        d2w = np.abs(np.diff(wanted, 2))
        assert d2m.max() <= d2w.max() + 0.05
    zig = 8.0 + np.where(np.arange(40) % 2, 1.0, -1.0)
    m = solve_offsets(_chain_problem(zig)).moves[:, 1] * 1e3
    assert np.ptp(m[5:-5]) < 0.2 * np.ptp(zig)


def _field(prog, points, normals, E_um, blocks) -> ErrorField:
    n = len(points)
    z = np.zeros(n)
    return ErrorField(point_mm=np.asarray(points), tip_mm=np.asarray(points),
                      axis=np.tile([0.0, 0.0, 1.0], (n, 1)), normal=np.asarray(normals),
                      E_um=np.asarray(E_um, float), gain=z, block=np.asarray(blocks),
                      ref_segment=np.asarray(blocks), ref_block=np.asarray(blocks),
                      ref_line=prog.line[np.asarray(blocks)], chain=np.zeros(n, int),
                      s_mm=z, shift_um=z)


def test_a_full_circle_stays_a_full_circle_and_an_arc_keeps_its_sweep():
    """A boss finished by a lead-in, a full circle, a lead-out; then a quarter arc. A
    uniform 10 um left on the circle's wall (normal outward, radial) moves its radius by
    10 um, its centre stays, start = end; the quarter arc keeps its 90 deg sweep."""
    text = "\n".join(["G21 G90 G17", "G0 X-60 Y0 Z5", "G1 Z-1 F1000", "G1 X-50",
                      "G2 X-50 Y0 I50 J0", "G1 X-60", "G0 Z5", "G0 X80 Y0", "G1 Z-1",
                      "G3 X0 Y80 I-80 J0", "G1 X-10", "M30"]) + "\n"
    prog = parse_program(text)
    circle = int(np.flatnonzero(prog.line == 5)[0])
    quarter = int(np.flatnonzero(prog.line == 10)[0])
    pts, nrm, blk = [], [], []
    for b, c, r, a0, sweep in ((circle, (0, 0), 50.0, math.pi, -2 * math.pi),
                               (quarter, (0, 0), 80.0, 0.0, math.pi / 2)):
        for t in np.linspace(0.0, 1.0, 33)[1:]:
            a = a0 + t * sweep
            u = np.array([math.cos(a), math.sin(a), 0.0])
            pts.append(np.array([c[0], c[1], -1.0]) + r * u)
            nrm.append(u)         # the boss inside the tool's circle: outward normal
            blk.append(b)
    field = _field(prog, pts, nrm, np.full(len(pts), 10.0), blk)
    text2, _ = apply_edit(prog, fit_program(prog, field))
    new = parse_program(text2)
    k = int(new.arc_index[circle])
    assert abs(abs(new.arc_sweep[k]) - 2 * math.pi) < 1e-9
    np.testing.assert_allclose(new.start[circle, :3], new.end[circle, :3], atol=1e-4)
    np.testing.assert_allclose(new.arc_centre[k, :2], [0.0, 0.0], atol=2e-4)
    assert new.arc_radius[k, 0] == pytest.approx(50.0 - 0.010, abs=2e-4)
    kq = int(new.arc_index[quarter])
    assert new.arc_sweep[kq] == pytest.approx(math.pi / 2, abs=1e-5)
    assert new.arc_radius[kq, 0] == pytest.approx(80.0 - 0.010, abs=3e-4)
    # the lead-out in air follows the circle's start, the far end of the lead-in stays
    assert new.end[1, 0] == pytest.approx(-60.0, abs=1e-9)


def test_a_block_leaving_the_material_does_not_pull_the_wall():
    """Errors of 12 um along a wall, one point of 2 um where the tool leaves it inside the
    last block, and a lead-out in air: the wall's vertices move 12 um; the last block is
    split where its error changes instead of being tilted, and nothing moves away from
    the wall."""
    text = "\n".join(["G21 G90 G17", "G0 X-15 Y-10 Z5", "G1 Z0 F1000"]
                     + [f"G1 X{x}" for x in range(-5, 76, 10)] + ["M30"]) + "\n"
    prog = parse_program(text)
    wall = [b for b in range(len(prog)) if prog.motion[b] == 1 and prog.end[b, 0] > -10
            and prog.start[b, 0] >= -5]
    pts, E, blk = [], [], []
    for b in wall:
        x0, x1 = prog.start[b, 0], prog.end[b, 0]
        for t in np.linspace(0, 1, 6)[1:]:
            x = x0 + t * (x1 - x0)
            if x <= 60.0:
                pts.append([x, 0.0, 0.0])
                E.append(12.0 if x <= 58.0 else 2.0)
                blk.append(b)
    field = _field(prog, pts, np.tile([0.0, -1.0, 0.0], (len(pts), 1)), E, blk)
    edit = fit_program(prog, field)
    moves_y = edit.moves[:, 1] * 1e3
    # more than two point spacings (4 mm) from the step: 12 um within 1 % (the fit's
    # second differences ring a little after a step, errpred.constants.OFFSET_SMOOTH);
    # next to it (3 mm) the step is spread a little more
    inner = [b for b in wall if prog.end[b, 0] <= 50.0]
    np.testing.assert_allclose(moves_y[inner], 12.0, atol=0.12)
    next_to = [b for b in wall if prog.end[b, 0] == 55.0]
    np.testing.assert_allclose(moves_y[next_to], 12.0, atol=0.5)
    assert np.all(moves_y[edit.movable] >= -1e-3)           # never away from the wall
    last = [b for b in wall if prog.start[b, 0] == 55.0][0]
    assert last in edit.split_fractions


def _raster_units(n: int = 200, pitch: float = 0.25):
    """``n`` straight units along X, one joined chain, two points a unit asking for a
    smooth move along Z with noise, and a kink (a unit that needs a split) at x 30."""
    from errpred.offset import Units

    x = np.arange(n + 1) * pitch
    zero = np.zeros(n)
    units = Units(start=np.c_[x[:-1], zero, zero], end=np.c_[x[1:], zero, zero],
                  kind=np.full(n, LINE), plane=np.tile([0, 1, 2], (n, 1)),
                  centre=np.zeros((n, 3)), radius=np.zeros((n, 2)), sweep=zero,
                  splittable=np.ones(n, bool), joined=np.r_[False, np.ones(n - 1, bool)])
    unit = np.repeat(np.arange(n), 3)
    t = np.tile([0.2, 0.5, 0.9], n)
    px = x[unit] + t * pitch
    rng = np.random.default_rng(3)
    target = 5e-3 * np.sin(px / 6.0) + 2e-4 * rng.normal(size=px.size)
    target += np.where(np.abs(px - 30.1) < 0.05, 3e-3, 0.0)            # a kink: a split
    return units, [list(range(n))], unit, t, target, np.tile([0.0, 0.0, 1.0], (px.size, 1)), px


def test_a_fallback_refit_moves_the_path_near_the_changed_points_only():
    """fit_units(hold=, free=): where the weights changed (points held near x 25, the
    kinked unit near x 30 scaled), the refit is the whole refit's within a small share of
    the change; every vertex farther than FALLBACK_FREE_VERTICES along the chain keeps the
    held edit's move exactly (the units' ends and the split points); the moves stay as
    smooth as the whole refit's; an edit of other units is not held."""
    import dataclasses

    from errpred.constants import FALLBACK_FREE_VERTICES as K
    from errpred.offset import fit_units

    units, chains, unit, t, target, normal, px = _raster_units()
    n = len(units)
    first = fit_units(units, chains, unit, t, target, normal)
    assert first.split_fractions, "the kink splits a unit"
    w = np.ones(px.size)
    w[np.abs(px - 25.0) < 0.8] = 0.0
    w[np.abs(px - 30.1) < 0.3] = 0.5
    free = w != 1.0
    whole = fit_units(units, chains, unit, t, target, normal, weight=w)
    local = fit_units(units, chains, unit, t, target, normal, weight=w, hold=first, free=free)
    change = np.abs(whole.moves[:n] - first.moves[:n]).max()
    assert change > 1e-3                              # the refit does move the path
    assert np.abs(local.moves[:n] - whole.moves[:n]).max() <= 1e-3 * change
    # far from the changed units: exactly the held moves
    changed_units = np.unique(unit[free])
    far = np.array([np.abs(changed_units - u).min() > K + 1 for u in range(n)])
    np.testing.assert_array_equal(local.moves[:n][far], first.moves[:n][far])
    assert np.any(local.moves[:n][~far] != first.moves[:n][~far])
    for u, fr in local.split_fractions.items():
        if far[u] and u in first.split_fractions:
            np.testing.assert_array_equal(local.moves[local.split_vertices[u]],
                                          first.moves[first.split_vertices[u]])
    # as smooth as the whole refit (no step where the held moves begin)
    pos = np.r_[units.start[:1], units.end]
    chain = np.r_[n, np.arange(n)]
    rough = lambda e: np.abs(second_difference(e.moves[chain], pos)).max()  # noqa: E731
    assert rough(local) <= rough(whole) + 1e-5
    # not an edit of these units: a whole refit
    other = dataclasses.replace(first, vertices=first.vertices + 1.0)
    again = fit_units(units, chains, unit, t, target, normal, weight=w, hold=other, free=free)
    np.testing.assert_array_equal(again.moves, whole.moves)


def test_given_moves_of_fixed_vertices_are_honoured_by_the_solver():
    """solve_offsets with fixed_moves: the vertices that may not move move by the given
    amounts, and the free ones are the least-squares fit to them: a uniform wanted move
    with the ends given at it is followed exactly; with the ends given at zero the middle
    still reaches it (the smoothing bends, the points' equations win)."""
    pb = _chain_problem(np.full(40, 5.0))
    mov = np.ones(40, bool)
    mov[[0, 1, 38, 39]] = False
    fixed = np.zeros((40, 3))
    fixed[~mov] = (0.0, 5e-3, 0.0)
    sol = solve_offsets(dataclasses.replace(pb, movable=mov, fixed_moves=fixed))
    # within the ridge's pull (OFFSET_RIDGE: 1e-6 of the move)
    np.testing.assert_allclose(sol.moves[:, 1], 5e-3, atol=2e-8)
    np.testing.assert_array_equal(sol.moves[~mov], fixed[~mov])
    zero = solve_offsets(dataclasses.replace(pb, movable=mov))
    np.testing.assert_array_equal(zero.moves[~mov], 0.0)
    assert abs(zero.moves[20, 1] - 5e-3) < 1e-4
    assert zero.moves[2, 1] < sol.moves[2, 1]


def test_a_fallback_refit_keeps_a_far_split_block_exactly():
    """A unit split in the held edit far from the changed points (a second kink, at
    x 45.1) is split at the same fractions in the refit and its split points keep the
    held moves exactly, though their vertex numbers differ (a nearer unit is newly
    split, so the ids shift)."""
    from errpred.constants import FALLBACK_FREE_VERTICES as K
    from errpred.offset import fit_units

    units, chains, unit, t, target, normal, px = _raster_units()
    target = target + np.where(np.abs(px - 45.1) < 0.05, 3e-3, 0.0)
    first = fit_units(units, chains, unit, t, target, normal)
    far_unit = int(unit[np.argmin(np.abs(px - 45.1))])
    assert far_unit in first.split_fractions
    w = np.ones(px.size)
    w[np.abs(px - 30.1) < 0.3] = 0.0          # the nearer kink held: split otherwise
    free = w != 1.0
    assert np.abs(unit[free] - far_unit).min() > K + 2
    local = fit_units(units, chains, unit, t, target, normal, weight=w, hold=first,
                      free=free)
    np.testing.assert_array_equal(local.split_fractions[far_unit],
                                  first.split_fractions[far_unit])
    np.testing.assert_array_equal(local.moves[local.split_vertices[far_unit]],
                                  first.moves[first.split_vertices[far_unit]])
    assert local.movable[local.split_vertices[far_unit]].all()


def _program_with_arcs_and_circles():
    """A wall along X (1 mm blocks, a kink at x 30.75 that splits its block), a quarter
    arc, a wall along Y, a full circle inside the chain and its continuation; then a
    pass of one full circle alone. Normals radial / outward and continuous."""
    lines = ["G21 G90 G17", "G0 X-5 Y0 Z5", "G1 Z-1 F1000", "G1 X-3", "G1 X0"]
    lines += [f"G1 X{x}" for x in range(1, 41)]
    lines += ["G3 X50 Y10 I0 J10"] + [f"G1 Y{y}" for y in range(11, 41)]
    lines += ["G2 X50 Y40 I-5 J0"] + [f"G1 Y{y}" for y in range(41, 46)]
    lines += ["G1 X60", "G0 Z5", "G0 X100 Y-5", "G1 Z-1", "G1 Y0", "G2 X100 Y0 I10 J0",
              "G1 X95", "G0 Z5", "M30"]
    prog = parse_program("\n".join(lines) + "\n")
    air = {"G1 Z-1 F1000", "G1 X-3", "G1 X60", "G1 Z-1", "G1 Y0", "G1 X95", "G1 X0"}
    pts, nrm, blk, E = [], [], [], []
    for b in range(len(prog)):
        if prog.motion[b] == 0 or lines[int(prog.line[b]) - 1] in air:
            continue
        a, e = prog.start[b, :3], prog.end[b, :3]
        k = int(prog.arc_index[b])
        for t in (0.25, 0.5, 0.75, 1.0):
            if k >= 0:
                c = prog.arc_centre[k]
                ang = math.atan2(a[1] - c[1], a[0] - c[0]) + t * prog.arc_sweep[k]
                u = np.array([math.cos(ang), math.sin(ang), 0.0])
                p = np.array([c[0], c[1], -1.0]) + prog.arc_radius[k, 0] * u
            else:
                p = a + t * (e - a)
                d = (e - a) / np.linalg.norm(e - a)
                u = np.array([d[1], -d[0], 0.0])
            kink = abs(p[0] - 30.75) < 1e-9 and abs(p[1]) < 1e-9
            pts.append(p)
            nrm.append(u)
            blk.append(b)
            E.append(20.0 + 5.0 * math.sin((p[0] + p[1]) / 8.0) + (8.0 if kink else 0.0))
    return prog, np.array(pts), _field(prog, pts, nrm, E, blk)


def test_a_fallback_refit_of_a_program_rewrites_only_the_blocks_near_the_change():
    """fit_program(hold=, free=) and apply_edit (half the moves, as the verified loop's
    relaxation): with the weights changed near x 5 only, the refit program's text is the
    held edit's byte for byte from the block ending at x 20 on (a split block, a quarter
    arc, two full circles) and before the wall; it differs near x 5."""
    prog, pts, field = _program_with_arcs_and_circles()
    first = fit_program(prog, field)
    assert first.split_fractions and first.circles
    w = np.ones(len(pts))
    w[(np.abs(pts[:, 0] - 5.0) < 1.6) & (np.abs(pts[:, 1]) < 1e-9)] = 0.0
    local = fit_program(prog, field, None, w, hold=first, free=w != 1.0)
    held, _ = apply_edit(prog, first, np.full(first.n_vertices, 0.5))
    refit, _ = apply_edit(prog, local, np.full(local.n_vertices, 0.5))
    held, refit = held.splitlines(), refit.splitlines()
    assert held != refit

    def at(text, word):
        return next(k for k, s in enumerate(text) if (s + " ").startswith(f"G1 {word} "))

    assert held[:at(held, "X1")] == refit[:at(refit, "X1")]
    assert held[at(held, "X20"):] == refit[at(refit, "X20"):]
    assert any(s.startswith("G2 X100.") for s in refit)        # the circle was rewritten
    # the full circles far from the change keep the held centre shift and radius change
    # exactly (not the solve's value within rounding)
    for u, (shift, dr) in first.circles.items():
        if prog.end[u, 0] > 20.0:
            assert local.circles[u][1] == dr
            np.testing.assert_array_equal(local.circles[u][0], shift)


def test_an_inch_program_is_corrected_in_quarter_micrometre_steps():
    """CORRECTION_DECIMALS: an inch program's changed words get five decimals (0.254 um),
    a millimetre program's four (0.1 um); with four in inch the correction moved in
    steps of 2.54 um (a 2 um move written as 2.54 um)."""
    for units, scale, decimals in (("G20", 25.4, 5), ("G21", 1.0, 4)):
        text = "\n".join([f"{units} G90 G17", "G0 X-0.6 Y-0.4 Z0.2", "G1 Z0 F40"]
                         + [f"G1 X{x / 10:.1f}" for x in range(0, 31, 5)] + ["M30"]) + "\n"
        prog = parse_program(text)
        wall = [b for b in range(len(prog)) if prog.motion[b] == 1 and prog.start[b, 2] == 0
                and prog.end[b, 0] > prog.start[b, 0]]
        pts, blk = [], []
        for b in wall:
            for t in (0.5, 1.0):
                pts.append(prog.start[b, :3] + t * (prog.end[b, :3] - prog.start[b, :3]))
                blk.append(b)
        field = _field(prog, pts, np.tile([0.0, -1.0, 0.0], (len(pts), 1)),
                       np.full(len(pts), 2.0), blk)
        out, _ = apply_edit(prog, fit_program(prog, field))
        back = parse_program(out)
        dy_um = (back.end[wall, 1] - prog.end[wall, 1]) * 1e3
        np.testing.assert_allclose(np.abs(dy_um), 2.0, atol=0.5 * 10.0 ** -decimals * scale
                                   * 1e3 + 1e-6)
        ys = [ln for ln, was in zip(out.splitlines(), text.splitlines(), strict=True)
              if ln != was]
        assert ys and all(len(ln.split("Y")[1].split()[0].split(".")[1]) == decimals
                          for ln in ys), ys
