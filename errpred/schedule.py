"""Feed scheduling from the predicted error: per block, the highest feed at which the
error stays within a tolerance and the force within a limit, verified before it is
written.

The error and the force of a block grow with its feed per tooth through the force law
(:mod:`errpred.laws`): linearly under the linear law (the cutting part; the edge part
does not change), less than linearly under Kienzle's. So:

1. The program is predicted densely (:meth:`errpred.geometry.Resolution.dense`: points
   at most ``VERIFY_SPACING_MM`` apart, block ends included) at its own feeds, and once
   more with every scheduled block at a probe feed (the largest allowed; the smallest
   where the block already runs near it). That probe program is a measurement only.
2. Per block, the largest E, the smallest E and the largest peak force are each a
   line in the feed through the two predictions; the block's feed is the highest one
   in ``[min, max]`` at which all three stay ``SCHEDULE_MARGIN`` inside the tolerance
   (``|E| <= T``) and the force limit. A block that cuts nothing gets the largest.
3. The change from block to block is limited: the factor on the programmed feed
   changes by at most ``MAX_FEED_STEP`` of the earlier block's, up or down, within
   each run of feed moves between rapids (the CAM's own feed steps, a plunge then the
   cut, are kept); a block outside the scheduled lines keeps its feed (factor 1: it is
   not predicted) and bounds its neighbours' rise, not their fall (a block that must
   slow down cannot wait for one outside the scope). The largest schedule under the
   per-block caps, by one pass forward and one back.
   Feeds are rounded down to ``FEED_QUANTUM_MM_MIN``.
4. The program with the new ``F`` words (:func:`nc.refeed.rewrite_feeds`, read back)
   is predicted densely. Blocks over a limit get a lower cap (the line through this
   prediction and the nearest other) and step 3-4 repeat, ``SCHEDULE_ROUNDS`` times at
   most. A schedule is accepted only when every scheduled block is within the
   tolerance and the force limit on that dense re-prediction of the text to be
   written; else :func:`schedule_feeds` says which block fails and nothing is
   written.

The cycle time (:func:`cycle_time`) is feed-limited: each block's tool-tip path length
over its programmed feed, rapids at a given rapid rate (not counted when unknown); no
acceleration, no look-ahead slow-down, no tool change or dwell.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from nc.errors import InputError
from nc.gcode import parse_program
from nc.path import CutterLocations, block_minutes
from nc.program import RAPID, Program
from nc.refeed import rewrite_feeds

from .constants import FEED_QUANTUM_MM_MIN, MAX_FEED_STEP, SCHEDULE_MARGIN, SCHEDULE_ROUNDS

__all__ = ["FeedLimits", "BlockLoads", "Round", "Schedule", "CycleTime", "block_loads",
           "block_caps", "limit_steps", "cycle_time", "schedule_feeds"]


@dataclass(frozen=True)
class FeedLimits:
    """The feeds a block may get.

    Attributes
    ----------
    min_mm_min, max_mm_min : float [mm/min]
        Lowest and highest feed.
    max_step : float [-]
        Largest change from one feed block to the next, as a share of the earlier's.
    """

    min_mm_min: float
    max_mm_min: float
    max_step: float = MAX_FEED_STEP

    def __post_init__(self) -> None:
        lo, hi, st = self.min_mm_min, self.max_mm_min, self.max_step
        if not (math.isfinite(lo) and lo > 0):
            raise ValueError(f"min feed: expected a finite value > 0 mm/min, got {lo!r}")
        if not (math.isfinite(hi) and hi >= lo):
            raise ValueError(f"max feed: expected a finite value >= the min feed {lo:g} "
                             f"mm/min, got {hi!r}")
        if hi - lo < FEED_QUANTUM_MM_MIN and math.floor(hi) < math.ceil(lo):
            raise ValueError(f"feeds {lo:g}..{hi:g} mm/min: no whole mm/min in between")
        if not (math.isfinite(st) and st > 0):
            raise ValueError(f"feed step: expected a finite share > 0, got {st!r}")


@dataclass(frozen=True, eq=False)
class BlockLoads:
    """Per block of a program (NaN where it has no predicted value).

    Attributes
    ----------
    E_max_um, E_min_um : ndarray, shape (blocks,) [um]
        Largest and smallest error of the block's predicted points.
    force_N : ndarray, shape (blocks,) [N]
        Largest peak resultant force over a revolution at the block's points that cut.
    """

    E_max_um: np.ndarray
    E_min_um: np.ndarray
    force_N: np.ndarray

    def over(self, blocks: np.ndarray, tolerance_um: float, force_limit_N: float,
             known: BlockLoads | None = None) -> np.ndarray:
        """Of ``blocks``, those over the tolerance or the force limit, and with ``known``
        (another prediction of the same blocks) those that lost their predicted error or
        force where ``known`` has one (not verified)."""
        b = np.asarray(blocks, np.int64)
        with np.errstate(invalid="ignore"):
            bad = ((self.E_max_um[b] > tolerance_um) | (self.E_min_um[b] < -tolerance_um)
                   | (self.force_N[b] > force_limit_N))
        if known is not None:
            bad |= (np.isfinite(known.E_max_um[b]) & ~np.isfinite(self.E_max_um[b])) | (
                np.isfinite(known.force_N[b]) & ~np.isfinite(self.force_N[b]))
        return b[bad]


def block_loads(prediction, n_blocks: int, field=None) -> BlockLoads:
    """:class:`BlockLoads` of a :class:`errpred.predict.Prediction` of a program of
    ``n_blocks`` blocks; with ``field`` (its :class:`errpred.verification.ErrorField`
    against another path, a corrected program's against the original's), the errors
    are the field's."""
    emax = np.full(n_blocks, -np.inf)
    emin = np.full(n_blocks, np.inf)
    force = np.full(n_blocks, -np.inf)
    for p in prediction.points:
        r = p.result
        if r is None:
            continue
        b = p.block
        if math.isfinite(r.peak_force_N):
            force[b] = max(force[b], r.peak_force_N)
        if field is None and p.status == "predicted" and math.isfinite(r.E_um):
            emax[b] = max(emax[b], r.E_um)
            emin[b] = min(emin[b], r.E_um)
    if field is not None and len(field):
        ok = np.isfinite(field.E_um)
        np.maximum.at(emax, field.block[ok], field.E_um[ok])
        np.minimum.at(emin, field.block[ok], field.E_um[ok])
    for a in (emax, emin, force):
        a[~np.isfinite(a)] = np.nan
    return BlockLoads(emax, emin, force)


def _cap_line(f_a, v_a, f_b, v_b, limit):
    """Per block, the highest feed at which the line through (f_a, v_a) and (f_b, v_b)
    stays at or below ``limit``: inf where the line does not rise (a higher feed keeps
    or brings the value down), NaN where it is unknown (the same feed twice, a value
    missing)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (v_b - v_a) / (f_b - f_a)
        cap = f_a + (limit - v_a) / slope
    return np.where(np.isfinite(slope) & (slope > 0), cap,
                    np.where(np.isfinite(slope), np.inf, np.nan))


def block_caps(f_a: np.ndarray, loads_a: BlockLoads, f_b: np.ndarray, loads_b: BlockLoads,
               blocks: np.ndarray, limits: FeedLimits, tolerance_um: float,
               force_limit_N: float, margin: float = SCHEDULE_MARGIN) -> np.ndarray:
    """The highest feed of each of ``blocks`` in ``[min, max]`` at which the lines through
    two predictions (feeds ``f_a`` and ``f_b`` per block) keep the largest E below
    ``(1 - margin) T``, the smallest above ``-(1 - margin) T`` and the force below
    ``(1 - margin)`` times the limit [mm/min]. A line that does not rise caps nothing
    (a corrected program overcuts less at a higher feed); a block with no predicted
    value gets the largest feed; where a line is unknown, a measured value over its
    limit gives the smallest feed."""
    b = np.asarray(blocks, np.int64)
    fa, fb = f_a[b], f_b[b]
    T, Fl = (1.0 - margin) * tolerance_um, (1.0 - margin) * force_limit_N
    caps = np.full(b.size, np.inf)
    for va, vb, lim in ((loads_a.E_max_um[b], loads_b.E_max_um[b], T),
                        (-loads_a.E_min_um[b], -loads_b.E_min_um[b], T),
                        (loads_a.force_N[b], loads_b.force_N[b], Fl)):
        c = _cap_line(fa, va, fb, vb, lim)
        over = (np.nan_to_num(va, nan=-np.inf) > lim) | (np.nan_to_num(vb, nan=-np.inf) > lim)
        c = np.where(np.isnan(c), np.where(over, limits.min_mm_min, np.inf), c)
        caps = np.minimum(caps, c)
    return np.clip(caps, limits.min_mm_min, limits.max_mm_min)


def _chains(program: Program) -> list[np.ndarray]:
    """Runs of consecutive feed blocks (between rapids)."""
    out, cur = [], []
    for b in range(len(program)):
        if int(program.motion[b]) == RAPID:
            if cur:
                out.append(np.array(cur))
            cur = []
        else:
            cur.append(b)
    if cur:
        out.append(np.array(cur))
    return out


def limit_steps(program: Program, caps: dict[int, float], limits: FeedLimits
                ) -> dict[int, float]:
    """The largest feeds at or below ``caps`` (block -> cap [mm/min], the scheduled
    blocks) whose factor on the programmed feed changes by at most ``limits.max_step``
    from one feed block to the next (``f_i / p_i <= (1 + step) f_j / p_j`` both ways;
    the other blocks keep the program's feed, factor 1, and bound their scheduled
    neighbours' rise), rounded down to ``FEED_QUANTUM_MM_MIN`` and kept within the
    limits. The factor, not the feed: the program's own feed changes (a plunge at a
    quarter of the cutting feed, then the cut) are the CAM's and are kept; the
    schedule changes them by at most the step more."""
    q = FEED_QUANTUM_MM_MIN
    lo = math.ceil(limits.min_mm_min / q) * q
    hi = math.floor(limits.max_mm_min / q) * q
    up = 1.0 + limits.max_step
    out: dict[int, float] = {}
    for chain in _chains(program):
        f = np.array([caps.get(int(b), np.nan) for b in chain], float)
        fixed = ~np.isfinite(f)
        prog = np.asarray(program.feed[chain], float)
        f = np.where(fixed, prog, np.clip(np.floor(f / q) * q, lo, hi))
        for order in (range(1, len(f)), range(len(f) - 2, -1, -1)):
            for i in order:
                j = i - 1 if order.step > 0 else i + 1
                if not fixed[i] and np.isfinite(f[j]) and prog[j] > 0:
                    most = math.floor(f[j] / prog[j] * prog[i] * up / q) * q
                    f[i] = max(lo, min(f[i], most))
        for b, v, fx in zip(chain, f, fixed, strict=True):
            if not fx:
                out[int(b)] = float(v)
    return out


@dataclass(frozen=True)
class CycleTime:
    """Feed-limited cycle time of a program (:func:`cycle_time`).

    Attributes
    ----------
    feed_min : float [min]
        Time of the feed moves: tool-tip path length over the programmed feed.
    rapid_min : float [min]
        Time of the rapids at the rapid rate (NaN when it is not known).
    feed_length_mm, rapid_length_mm : float [mm]
    """

    feed_min: float
    rapid_min: float
    feed_length_mm: float
    rapid_length_mm: float

    @property
    def total_min(self) -> float:
        """Feed and rapid time (the feed time alone when the rapid rate is unknown) [min]."""
        return self.feed_min + (self.rapid_min if math.isfinite(self.rapid_min) else 0.0)


def block_lengths(cl: CutterLocations, n_blocks: int) -> np.ndarray:
    """Tool-tip path length of each block [mm], (n_blocks,)."""
    out = np.zeros(n_blocks)
    if len(cl.tip) > 1:
        seg = np.linalg.norm(np.diff(cl.tip, axis=0), axis=1)
        ok = (cl.block[1:] >= 0) & (cl.block[1:] < n_blocks)
        np.add.at(out, cl.block[1:][ok], seg[ok])
    return out


def cycle_time(program: Program, lengths_mm: np.ndarray, blocks: np.ndarray | None = None,
               rapid_mm_min: float | None = None, feeds: np.ndarray | None = None
               ) -> CycleTime:
    """Feed-limited cycle time of ``blocks`` (default: all) of ``program``.

    Each feed block's time is :func:`nc.path.block_minutes` with these lengths
    and ``feeds`` (default the program's, in each block's feed mode: G94 mm/min,
    G95 mm per revolution times the spindle speed, G93 inverse time; a move of
    rotary axes only at its feed in deg/min); each rapid's length over
    ``rapid_mm_min`` (NaN when None). No acceleration.

    Raises
    ------
    InputError
        A G95 block in ``blocks`` with no spindle speed (naming its line).
    """
    n = len(program)
    b = np.arange(n) if blocks is None else np.asarray(blocks, np.int64)
    rapid = program.motion[b] == RAPID
    fb, rb = b[~rapid], b[rapid]
    per_rev = fb[program.modal_column("feed_mode")[fb] == 95]
    if per_rev.size:
        rpm = program.modal_column("spindle_rpm")[per_rev]
        bad = ~(np.isfinite(rpm) & (rpm > 0))
        if np.any(bad):
            i = int(per_rev[np.argmax(bad)])
            raise InputError(f"{program.file}: line {program.line[i]}: feed per revolution "
                             "(G95) with no spindle speed, so its time is not known; expected "
                             "an S > 0 before it")
    t = block_minutes(program, np.asarray(lengths_mm, float), feeds)[fb]
    t = np.where(np.isnan(t), np.inf, t)  # no feed: never there
    rl = float(lengths_mm[rb].sum())
    rt = rl / rapid_mm_min if rapid_mm_min else math.nan
    return CycleTime(float(t.sum()), rt, float(lengths_mm[fb].sum()), rl)


@dataclass
class Round:
    """One dense verification of a schedule: its feeds, loads and the blocks over a limit."""

    feeds: np.ndarray
    loads: BlockLoads
    over: np.ndarray
    prediction: object = None


@dataclass
class Schedule:
    """Result of :func:`schedule_feeds`.

    Attributes
    ----------
    ok : bool
        A schedule within the limits everywhere was verified (``text`` may be written).
    text : str or None
        The program with the scheduled feeds (None when not ok).
    program : Program
        The original.
    blocks : ndarray of int
        The scheduled blocks (feed moves in scope).
    feeds_before, feeds_after : ndarray, shape (blocks of the program,) [mm/min]
        The program's feeds and the last schedule's (the verified one when ok).
    before : BlockLoads
        The original's dense prediction per block.
    probe_feeds : ndarray and probe : BlockLoads
        The probe's feeds and loads.
    rounds : list of Round
        Every verified schedule, in order (the last is the accepted one when ok).
    tolerance_um, force_limit_N : float
    limits : FeedLimits
    reason : str
        One line: the result, or why nothing may be written.
    predictions : list
        Dense predictions: the original, the probe, every round's.
    """

    ok: bool
    text: str | None
    program: Program
    blocks: np.ndarray
    feeds_before: np.ndarray
    feeds_after: np.ndarray
    before: BlockLoads
    probe_feeds: np.ndarray
    probe: BlockLoads
    tolerance_um: float
    force_limit_N: float
    limits: FeedLimits
    reason: str = ""
    rounds: list = field(default_factory=list)
    predictions: list = field(default_factory=list)

    @property
    def after(self) -> BlockLoads:
        """The last verified schedule's loads per block."""
        return self.rounds[-1].loads if self.rounds else self.before


def _worst(loads: BlockLoads, blocks: np.ndarray, program: Program, feeds: np.ndarray,
           tolerance_um: float, force_limit_N: float, names: np.ndarray) -> str:
    """One clause naming the block furthest over a limit (as a share of the limit)."""
    b = np.asarray(blocks, np.int64)
    with np.errstate(invalid="ignore"):
        e = np.fmax(loads.E_max_um[b], -loads.E_min_um[b]) / max(tolerance_um, 1e-12)
        f = loads.force_N[b] / force_limit_N
    e, f = np.nan_to_num(e, nan=0.0), np.nan_to_num(f, nan=0.0)
    i = int(np.argmax(np.maximum(e, f)))
    k = int(b[i])
    if e[i] <= 1.0 and f[i] <= 1.0:      # over only because its prediction was lost
        lost = ~np.isfinite(loads.E_max_um[b]) | ~np.isfinite(loads.force_N[b])
        k = int(b[np.argmax(lost)]) if lost.any() else k
        return (f"line {int(names[k])}: no error or force predicted at F{feeds[k]:g} "
                "mm/min where the programmed feed has one (not verified)")
    what = (f"|E| {max(loads.E_max_um[k], -loads.E_min_um[k]):.2f} um > tolerance "
            f"{tolerance_um:g} um" if e[i] >= f[i] else
            f"peak force {loads.force_N[k]:.1f} N > limit {force_limit_N:g} N")
    return f"line {int(names[k])}: {what} at F{feeds[k]:g} mm/min"


def schedule_feeds(program: Program, predict: Callable[[Program], object],
                   blocks: np.ndarray, limits: FeedLimits, *, tolerance_um: float,
                   force_limit_N: float, rounds: int = SCHEDULE_ROUNDS,
                   margin: float = SCHEDULE_MARGIN,
                   loads: Callable[[Program, object], BlockLoads] | None = None,
                   lines: np.ndarray | None = None,
                   progress: Callable[[str], None] | None = None) -> Schedule:
    """Schedule the feeds of ``blocks`` of ``program`` (see the module docstring).

    Parameters
    ----------
    program : Program
        The program to schedule (G-code; G94 feeds).
    predict : callable
        ``predict(program) -> Prediction``: dense, over the same blocks of any program
        with ``program``'s blocks (only the feeds differ).
    blocks : ndarray of int
        Blocks in scope; their feed moves are scheduled.
    limits : FeedLimits
    tolerance_um : float [um]
        Largest |E| allowed at every predicted point of a scheduled block.
    force_limit_N : float [N]
        Largest peak resultant force on the tool allowed at every point that cuts.
    rounds : int
        Dense verifications at most.
    margin : float [-]
        How far inside the limits the lines through two predictions aim.
    loads : callable, optional
        ``loads(program, prediction) -> BlockLoads`` (default :func:`block_loads` of the
        prediction's own errors; a corrected program's against the original's path).
    lines : ndarray of int, optional
        Per block, the program line a reason names (default the program's own; a
        corrected program's: the original's line).
    progress : callable, optional
        ``progress(stage)`` before each prediction.
    """
    if not (math.isfinite(tolerance_um) and tolerance_um > 0):
        raise ValueError(f"tolerance: expected a finite value > 0 um, got {tolerance_um!r}")
    if not (math.isfinite(force_limit_N) and force_limit_N > 0):
        raise ValueError(f"force limit: expected a finite value > 0 N, got {force_limit_N!r}")
    say = progress or (lambda s: None)
    measure = loads or (lambda prog, pred: block_loads(pred, len(prog)))
    names = program.line if lines is None else np.asarray(lines)
    blocks = np.asarray(blocks, np.int64)
    sched = blocks[program.motion[blocks] != RAPID] if blocks.size else blocks
    f0 = np.asarray(program.feed, float).copy()

    def run(feeds: dict[int, float]) -> tuple[str, object, BlockLoads]:
        text = rewrite_feeds(program, feeds)
        prog = parse_program(text, file=program.file, allow=program.allowed,
                             block_delete=program.block_delete)
        pred = predict(prog)
        return text, pred, measure(prog, pred)

    say("original")
    p0 = predict(program)
    L0 = measure(program, p0)
    fp = f0.copy()
    near_top = f0[sched] >= 0.95 * limits.max_mm_min
    fp[sched] = np.where(near_top, max(limits.min_mm_min, 0.5 * limits.max_mm_min),
                         limits.max_mm_min)
    fp[sched] = np.floor(fp[sched] / FEED_QUANTUM_MM_MIN) * FEED_QUANTUM_MM_MIN
    say("probe")
    _, pp, Lp = run({int(b): float(fp[b]) for b in sched})
    out = Schedule(ok=False, text=None, program=program, blocks=sched, feeds_before=f0,
                   feeds_after=f0.copy(), before=L0, probe_feeds=fp, probe=Lp,
                   tolerance_um=tolerance_um, force_limit_N=force_limit_N, limits=limits,
                   predictions=[p0, pp])
    if sched.size == 0:
        out.reason = "no feed move in scope: nothing to schedule"
        return out
    caps = block_caps(f0, L0, fp, Lp, sched, limits, tolerance_um, force_limit_N, margin)
    cap = {int(b): float(c) for b, c in zip(sched, caps, strict=True)}
    for k in range(1, rounds + 1):
        feeds = limit_steps(program, cap, limits)
        fk = f0.copy()
        for b, v in feeds.items():
            fk[b] = v
        say(f"schedule {k}")
        text, pk, Lk = run(feeds)
        over = Lk.over(sched, tolerance_um, force_limit_N, known=L0)
        out.rounds.append(Round(fk, Lk, over, pk))
        out.predictions.append(pk)
        out.feeds_after = fk
        if over.size == 0:
            out.ok, out.text = True, text
            out.reason = _accepted(out)
            return out
        at_min = [b for b in over if fk[b] <= limits.min_mm_min + FEED_QUANTUM_MM_MIN]
        if at_min:
            out.reason = ("no feed within the limits keeps every block within: "
                          + _worst(Lk, np.array(at_min), program, fk, tolerance_um,
                                   force_limit_N, names)
                          + f" (the lowest allowed feed is {limits.min_mm_min:g} mm/min)")
            return out
        with np.errstate(invalid="ignore"):
            low = over[~((Lk.E_max_um[over] > tolerance_um)
                         | (Lk.force_N[over] > force_limit_N))]
        if low.size:                  # overcut only: a lower feed would deepen it
            k = int(low[np.argmin(Lk.E_min_um[low])])
            out.reason = (f"line {int(names[k])}: E {Lk.E_min_um[k]:+.2f} um < -tolerance "
                          f"{tolerance_um:g} um at F{fk[k]:g} mm/min (overcut: a lower "
                          "feed would cut deeper, a higher one is held by the feed limits "
                          "or the change per block)")
            return out
        # a lower cap for the blocks over: the line through this round and the nearer of
        # the original and the probe (the probe where the round kept the original feed)
        near0 = (np.abs(f0 - fk) <= np.abs(fp - fk)) & (np.abs(f0 - fk) >= FEED_QUANTUM_MM_MIN)
        other_f = np.where(near0, f0, fp)
        other_L = BlockLoads(*(np.where(near0, a, c) for a, c in
                               ((L0.E_max_um, Lp.E_max_um), (L0.E_min_um, Lp.E_min_um),
                                (L0.force_N, Lp.force_N))))
        new = block_caps(other_f, other_L, fk, Lk, over, limits, tolerance_um, force_limit_N,
                         margin=max(2 * margin, SCHEDULE_MARGIN))
        for b, c in zip(over, new, strict=True):
            cap[int(b)] = float(min(c, 0.9 * fk[b], cap[int(b)]))
    out.reason = (f"no verified schedule after {rounds} rounds: "
                  + _worst(out.rounds[-1].loads, out.rounds[-1].over, program,
                           out.feeds_after, tolerance_um, force_limit_N, names))
    return out


def _accepted(s: Schedule) -> str:
    a = s.after
    b = s.blocks
    with np.errstate(invalid="ignore"):
        e = float(np.nanmax(np.fmax(np.abs(a.E_max_um[b]), np.abs(a.E_min_um[b])),
                            initial=0.0))
        f = float(np.nanmax(a.force_N[b], initial=0.0))
    fb, fa = s.feeds_before[b], s.feeds_after[b]
    return (f"verified on the dense re-prediction: largest |E| {e:.2f} um <= {s.tolerance_um:g}"
            f" um, peak force {f:.1f} N <= {s.force_limit_N:g} N on {b.size} feed blocks; "
            f"feeds {fb.min():g}..{fb.max():g} -> {fa.min():g}..{fa.max():g} mm/min")
