"""errpred.repredict: a program predicted after another that differs a little takes
stage 1 from it where it cannot have changed, and the prediction is that of the whole
program: the same statuses, errors, gains, path lengths and wear as predicting it from
scratch, with the blocks near the change (and only some of the others) computed."""

from __future__ import annotations

import dataclasses
import math
import pickle
import re

import numpy as np
import pytest

from errpred.geometry import Resolution
from errpred.predict import Follow, Predictor
from errpred import constants as K
from errpred.repredict import Repredictor, block_keys
from errpred.tool import Tool
from nc import parse_program

from .cases import STEEL, plane_raster, plane_stock, stiff_tool

R, D = 3.0, 6.0
SLOPE = 20.0
#: a tilted tool (5-axis): lead 10 deg about the cross-feed
_s, _a = math.radians(SLOPE), math.radians(10.0)
AXIS = (math.sin(_s + _a), 0.0, math.cos(_s + _a))


@pytest.fixture(scope="module")
def case():
    tool = Tool("ball", D, flute_length_mm=5)
    stock = plane_stock(SLOPE, 0.2)
    text = plane_raster(SLOPE, R, passes=4, length=48.0, step=1.0, axis=AXIS)
    res = Resolution.default(tool).dense(1.0)
    return tool, stock, text, res


def _predictor(case, text):
    tool, stock, _, res = case
    return Predictor(tool, stock, parse_program(text), STEEL, stiff_tool(), resolution=res)


def _edited(text: str) -> tuple[str, list[int]]:
    """The program with two moves of the second pass 3 um deeper and a vertex added in the
    middle of a third-pass move (a block split in two), both a fifth of the way along
    their passes; the edited lines (0-based)."""
    lines = text.splitlines()
    cut = [i for i, s in enumerate(lines) if s.startswith("G1 X")]
    per_pass = len(cut) // 4
    a = cut[1 * per_pass + per_pass // 5]
    for i in (a, a + 1):
        lines[i] = re.sub(r"Z(-?\d+\.\d+)", lambda m: f"Z{float(m.group(1)) - 0.003:.5f}",
                          lines[i])
    b = cut[2 * per_pass + per_pass // 5]
    p = [np.array([float(v) for v in re.findall(r"[XYZ](-?\d+\.\d+)", lines[k])[:3]])
         for k in (b - 1, b)]
    mid = 0.5 * (p[0] + p[1])
    vec = lines[b][lines[b].index(" I"):]
    lines.insert(b, f"G1 X{mid[0]:.5f} Y{mid[1]:.5f} Z{mid[2]:.5f}{vec}")
    return "\n".join(lines) + "\n", [a, a + 1, b, b + 1]


@pytest.fixture(scope="module")
def long_case(case):
    """Ten passes 1.2 mm apart, 12 mm long (150 blocks): the first four beyond the tool's
    reach of the last; a change near the end is followed to two of stage 2's windows of
    kept states (128 blocks), 63 of them computed again on the way."""
    tool, stock, _, res = case
    return tool, stock, plane_raster(SLOPE, R, passes=10, pick=1.2, length=12.0, step=1.0,
                                     axis=AXIS), res


def _deeper_near_end(text: str, passes: int) -> str:
    """The program with two moves of the last pass, four fifths along it, 3 um deeper (a
    fallback's change near a program's end)."""
    lines = text.splitlines()
    cut = [i for i, s in enumerate(lines) if s.startswith("G1 X")]
    per_pass = len(cut) // passes
    a = cut[(passes - 1) * per_pass + (4 * per_pass) // 5]
    for i in (a, a + 1):
        lines[i] = re.sub(r"Z(-?\d+\.\d+)", lambda m: f"Z{float(m.group(1)) - 0.003:.5f}",
                          lines[i])
    return "\n".join(lines) + "\n"


def _same(got, want):
    assert len(got.points) == len(want.points)
    for p, q in zip(got.points, want.points, strict=True):
        assert p.status == q.status and p.geometry.block == q.geometry.block
        assert p.geometry.path_mm == pytest.approx(q.geometry.path_mm, abs=1e-9)
        if math.isnan(q.E_um):
            assert math.isnan(p.E_um)
        else:
            assert p.E_um == pytest.approx(q.E_um, abs=1e-9)
            np.testing.assert_allclose(p.result.gain, q.result.gain, atol=1e-9)
    np.testing.assert_allclose(got.wear_mm, want.wear_mm, atol=1e-9)


def _lifted(text: str) -> str:
    """The program with 20 moves of the second pass (from its middle on, 20 mm over the
    stock, longer than the tool reaches) made rapids: the material under them left for
    the passes beside, whose own moves did not change (only the program before has
    sweeps there)."""
    lines = text.splitlines()
    cut = [i for i, s in enumerate(lines) if s.startswith("G1 X")]
    per_pass = len(cut) // 4
    a = cut[per_pass + per_pass // 2]
    for i in range(a, a + 20):
        lines[i] = lines[i].replace("G1 ", "G0 ", 1)
    return "\n".join(lines) + "\n"


def test_an_edited_program_is_predicted_as_a_whole_prediction_would(case):
    text = case[2]
    edited, where = _edited(text)
    rp = Repredictor()
    pred_a = _predictor(case, text)
    first = rp.run(pred_a)
    assert rp.stats[-1]["reused"] == 0
    pred = _predictor(case, edited)
    got = rp.run(pred)
    want = _predictor(case, edited).run()
    _same(got, want)
    assert sum(p.status == "predicted" for p in want.points) >= 40   # a case that cuts
    st = rp.stats[-1]
    # the edited blocks and those within the tool's reach computed; the far ends of
    # the passes reused
    assert st["computed"] > 0 and st["reused"] >= 0.25 * st["blocks"], st
    edited = {b for b in range(len(pred.program)) if int(pred.program.line[b]) - 1 in where}
    assert len(edited) == len(where) and not edited & rp.reused
    # a third program after that one (a chain)
    lifted = _lifted(text)
    _same(rp.run(_predictor(case, lifted)), _predictor(case, lifted).run())
    rp.close()


def test_blocks_the_old_programs_moves_reached_are_computed_again(case):
    """Moves made rapids (no sweeps in the new program): the passes beside meet material
    the old program's sweeps had taken, though their own moves did not change. Those
    blocks are computed (the old program's changed sweeps are checked too), and the
    prediction is that of the whole program."""
    text = case[2]
    lifted = _lifted(text)
    rp = Repredictor()
    pred_a = _predictor(case, text)
    first = rp.run(pred_a)
    pred_c = _predictor(case, lifted)
    got = rp.run(pred_c)
    want = _predictor(case, lifted).run()
    _same(got, want)
    keys_a, keys_c = (block_keys(p.model, len(p.program)) for p in (pred_a, pred_c))

    def stage1(out):                   # what stage 1 found, per block (not the wear's E)
        blocks: dict = {}
        for p in out.points:
            g = p.geometry
            blocks.setdefault(g.block, []).append((g.status, g.cutting_pixels,
                                                   g.finished_pixels))
        return blocks

    before, after = stage1(first), stage1(want)
    changed = {b for b, v in after.items() if keys_c[b] == keys_a[b] and before.get(b) != v}
    assert len(changed) >= 10 and not changed & rp.reused, (changed, rp.stats[-1])
    assert rp.stats[-1]["reused"] > 0
    rp.close()


def test_the_same_program_again_is_all_reused_and_the_same(case, monkeypatch):
    """... and followed: its points are taken from the last run, none read back (the
    store copies their bytes) but the last window's, which has no kept state."""
    import errpred.repredict as R

    text = case[2]
    rp = Repredictor()
    a = rp.run(_predictor(case, text))
    read: list[int] = []
    get = R._Store.get
    monkeypatch.setattr(R._Store, "get", lambda self, block: read.append(block) or get(self, block))
    b = rp.run(_predictor(case, text))
    st = rp.stats[-1]
    assert st["computed"] == 0
    n = len(_predictor(case, text).program)
    assert st["followed"] == (n // K.STAGE2_STATE_BLOCKS) * K.STAGE2_STATE_BLOCKS
    assert read and min(read) >= st["followed"]
    _same(b, a)
    rp.close()


def test_nothing_is_reused_at_another_resolution_or_with_another_stock(case):
    tool, stock, text, res = case
    rp = Repredictor()
    rp.run(_predictor(case, text))
    other = Predictor(tool, stock, parse_program(text), STEEL, stiff_tool(),
                      resolution=res.finer(2))
    rp.run(other, [0, 1, 2, 3])
    assert rp.stats[-1]["reused"] == 0
    moved = Predictor(tool, plane_stock(SLOPE, 0.2), parse_program(text), STEEL,
                      stiff_tool(), resolution=res)
    rp.run(moved, [0, 1, 2, 3])
    assert rp.stats[-1]["reused"] == 0
    rp.close()


def test_block_keys_change_with_the_block_and_its_neighbours_only(case):
    text = case[2]
    lines = text.splitlines()
    cut = [i for i, s in enumerate(lines) if s.startswith("G1 X")]
    k = cut[len(cut) // 2]
    lines[k] = re.sub(r"Y(-?\d+\.\d+)", lambda m: f"Y{float(m.group(1)) + 0.001:.5f}",
                      lines[k])
    pa, pb = _predictor(case, text), _predictor(case, "\n".join(lines) + "\n")
    ka, kb = block_keys(pa.model, len(pa.program)), block_keys(pb.model, len(pb.program))
    differ = {b for b in range(len(ka)) if ka[b] != kb[b]}
    b = int(np.flatnonzero(pa.program.line == k + 1)[0])
    # the block itself; the one before (the corner at its end); the two after (the
    # first's start moved, the second's corner check reads the move before it); the
    # third after at most (the tip's feed of the move after the edit changes by rounding)
    assert {b - 1, b, b + 1, b + 2} <= differ <= {b - 1, b, b + 1, b + 2, b + 3}, (b, differ)


def test_stage1_pickles_to_the_same_bytes_after_a_round_trip(case):
    """The follow compares stage 1 point by point by its pickle: a point computed here,
    read back from a worker, and taken from the last run (read back and its block and
    path length replaced) pickles to the same bytes."""
    H = pickle.HIGHEST_PROTOCOL
    pred = _predictor(case, case[2])
    n = 0
    for geoms in pred.geometries(range(len(pred.program))):
        for g in geoms:
            a = pickle.dumps(g, protocol=H)
            back = pickle.loads(a)
            assert pickle.dumps(back, protocol=H) == a
            moved = dataclasses.replace(back, block=g.block, path_mm=g.path_mm + 0.0)
            assert pickle.dumps(moved, protocol=H) == a
            n += g.gen is not None
    assert n > 40


@pytest.mark.parametrize("workers", [1, 2])
def test_a_change_near_the_end_takes_the_points_before_it_and_goes_on_from_there(long_case,
                                                                                  workers):
    """Stage 2 carries the wear: while the blocks are the last run's (their stage 1 the
    same bytes), its points are taken window by window and stage 2 goes on from its kept
    states; the prediction is that of the whole program (stage 1 in this process, or in
    two workers: read back from them)."""
    case = long_case
    text = case[2]
    edited = _deeper_near_end(text, 10)
    rp = Repredictor()
    first = rp.run(_predictor(case, text), workers=workers)
    assert rp.stats[-1]["followed"] == 0
    got = rp.run(_predictor(case, edited), workers=workers)
    want = _predictor(case, edited).run()
    _same(got, want)
    st = rp.stats[-1]
    assert st["followed"] >= K.STAGE2_STATE_BLOCKS and st["followed"] % K.STAGE2_STATE_BLOCKS == 0
    # followed past blocks whose stage 1 was computed again (found the same)
    n = sum(p.block < st["followed"] for p in got.points)
    assert n > 0 and all(p is q for p, q in zip(got.points[:n], first.points[:n]))
    assert any(b not in rp.reused for b in range(st["followed"])), st
    assert not any(p is q for p, q in zip(got.points[n:], first.points[n:]))
    # and a third program from that one, the first again
    _same(rp.run(_predictor(case, text), workers=workers), first)
    assert rp.stats[-1]["followed"] >= st["followed"]
    rp.close()


def test_nothing_is_followed_with_other_stage2_models(case):
    """Other cutting coefficients (stage 1 the same): every block's stage 2 runs again."""
    tool, stock, text, res = case
    rp = Repredictor()
    rp.run(_predictor(case, text))
    harder = STEEL.replace(Ktc_N_mm2=1.5 * STEEL.Ktc_N_mm2)
    other = Predictor(tool, stock, parse_program(text), harder, stiff_tool(), resolution=res)
    got = rp.run(other)
    assert rp.stats[-1]["followed"] == 0 and rp.stats[-1]["computed"] == 0
    _same(got, Predictor(tool, stock, parse_program(text), harder, stiff_tool(),
                         resolution=res).run())
    rp.close()


@pytest.mark.parametrize("differ_at", [None, 0, 70, 130, 150])
def test_a_followed_run_is_the_run_from_the_start(case, differ_at):
    """Predictor.run(follow=...): bit for bit the same points, wear and largest-error
    series as the run from the start, whether it follows to the end, from the start
    on never, or up to a block in a window (that window's stage 2 runs from its start)."""
    text = case[2]
    states = []
    whole = _predictor(case, text).run(states=states.append)
    n = len(_predictor(case, text).program)
    assert [s.blocks for s in states] == list(range(K.STAGE2_STATE_BLOCKS, n + 1,
                                                    K.STAGE2_STATE_BLOCKS))
    stop = n if differ_at is None else differ_at
    follow = Follow(whole.points, {s.blocks: s for s in states}, lambda pos, b: pos < stop)
    got_states = []
    got = _predictor(case, text).run(follow=follow, states=got_states.append)
    assert len(got.points) == len(whole.points)
    taken = (stop // K.STAGE2_STATE_BLOCKS) * K.STAGE2_STATE_BLOCKS
    for p, q in zip(got.points, whole.points, strict=True):
        assert (p is q) == (p.block < taken)
        assert p.status == q.status and (p.E_um == q.E_um or (math.isnan(p.E_um)
                                                              and math.isnan(q.E_um)))
    np.testing.assert_array_equal(got.wear_mm, whole.wear_mm)
    assert got.series.keys() == whole.series.keys()
    assert got.series[-1][-1] == whole.series[-1][-1]
    assert [s.blocks for s in got_states] == [s.blocks for s in states]
    for a, b in zip(got_states, states, strict=True):
        np.testing.assert_array_equal(a.wear_mm, b.wear_mm)


def test_a_run_without_the_sensitivity_pass_takes_stage_1_from_one_with_it(case):
    """A candidate no fit will read is predicted without the sensitivity pass: it takes
    stage 1 from a run with the pass (the points without it are those computed without
    it) and predicts as a whole prediction without it would (gain 0); the other way
    round nothing is taken (the pass is missing there)."""
    tool, stock, text, res = case

    def pred(sens):
        return Predictor(tool, stock, parse_program(text), STEEL, stiff_tool(),
                         resolution=res, sensitivity=sens)

    rp = Repredictor()
    rp.run(pred(True))
    got = rp.run(pred(False))
    assert rp.stats[-1]["computed"] == 0
    want = pred(False).run()
    _same(got, want)
    assert all(p.result.gain == 0.0 for p in got.points if p.result is not None)
    assert all(p.geometry.sensitivity is None for p in got.points)
    rp.run(pred(True))
    assert rp.stats[-1]["reused"] == 0
    rp.close()
