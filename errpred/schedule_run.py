"""``python -m errpred schedule``: a scenario's program with per-block feeds from its
predicted error and force (:mod:`errpred.schedule`), verified densely before it is
written, with the cycle time before and after.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from nc.command import Refused
from nc.errors import InputError
from nc.path import cutter_locations
from nc.program import RAPID

from .constants import (
    DEFAULT_MAX_FEED_FACTOR,
    DEFAULT_MIN_FEED_FACTOR,
    MAX_FEED_PER_TOOTH_RADII,
    MAX_FEED_STEP,
)
from .conditions import largest_feed_per_tooth_mm
from .pipeline import blocks_in_scope, build_predictor
from .scenario import Scenario
from .schedule import CycleTime, FeedLimits, Schedule, block_lengths, cycle_time, schedule_feeds

__all__ = ["ScheduleRun", "feed_limits", "schedule_scenario"]


@dataclass
class ScheduleRun:
    """A scenario's schedule and its cycle times.

    Attributes
    ----------
    schedule : Schedule
    scope_before, scope_after : CycleTime
        Of the scheduled lines (every block on them, rapids included).
    program_before, program_after : CycleTime
        Of the whole program.
    rapid_mm_min : float or None [mm/min]
    lengths_mm : ndarray, shape (blocks,) [mm]
        Tool-tip path length of each block of the scheduled program.
    compensation : Compensation or None
        With ``correct``: the verified correction the feeds were scheduled on (its
        program is the one scheduled; errors are against the original's path).
    """

    schedule: Schedule
    scope_before: CycleTime
    scope_after: CycleTime
    program_before: CycleTime
    program_after: CycleTime
    rapid_mm_min: float | None
    lengths_mm: np.ndarray
    compensation: object = None


def _finite_positive(name: str, v: float | None) -> None:
    if v is not None and not (math.isfinite(v) and v > 0):
        raise InputError(f"{name}: expected a finite value > 0, got {v}")


def feed_limits(scenario: Scenario, program, blocks: np.ndarray, min_feed: float | None,
                max_feed: float | None, max_step_pct: float | None) -> FeedLimits:
    """The allowed feeds: the options given, else ``DEFAULT_MIN_FEED_FACTOR`` times the
    smallest and ``DEFAULT_MAX_FEED_FACTOR`` times the largest programmed cutting feed
    in scope (no machine file gives feed limits); the step ``MAX_FEED_STEP`` unless
    given [%]."""
    _finite_positive("--min-feed", min_feed)
    _finite_positive("--max-feed", max_feed)
    _finite_positive("--max-feed-step", max_step_pct)
    b = np.asarray(blocks, np.int64)
    feed = b[program.motion[b] != RAPID] if b.size else b
    f = program.feed[feed]
    if feed.size and not np.all(np.isfinite(f) & (f > 0)):
        i = int(feed[np.argmax(~(np.isfinite(f) & (f > 0)))])
        raise InputError(f"{scenario.program_path}: line {program.line[i]}: a feed move "
                         "without a feed; expected an F word before it")
    if np.any(program.modal_column("feed_mode")[feed] == 93):
        raise InputError(f"{scenario.program_path}: inverse-time feed (G93) in scope; "
                         "expected feeds in mm/min (G94) to schedule")
    lo = min_feed if min_feed is not None else (
        DEFAULT_MIN_FEED_FACTOR * float(f.min()) if f.size else 1.0)
    hi = max_feed if max_feed is not None else (
        DEFAULT_MAX_FEED_FACTOR * float(f.max()) if f.size else lo)
    # the force model's bound on the feed per tooth (errpred.conditions) at the slowest
    # spindle speed in scope: the default is kept within it, a --max-feed beyond refused
    rpm = np.abs(program.modal_column("spindle_rpm")[feed]) if feed.size else np.zeros(0)
    rpm = rpm[rpm > 0]
    if rpm.size:
        tool = scenario.tool
        bound = largest_feed_per_tooth_mm(tool) * tool.flutes * float(rpm.min())
        if max_feed is not None and max_feed > bound:
            raise InputError(f"--max-feed: {max_feed:g} mm/min is {max_feed / bound:.3g} times "
                             f"the feed at which a tooth takes {MAX_FEED_PER_TOOTH_RADII:g} of "
                             f"the tool's radius at {rpm.min():g} rev/min ({bound:g} mm/min, "
                             "errpred.constants.MAX_FEED_PER_TOOTH_RADII); expected at most that")
        hi = min(hi, bound)
    if hi < lo:
        raise InputError(f"--max-feed: {hi:g} mm/min is below the min feed {lo:g} mm/min")
    step = MAX_FEED_STEP if max_step_pct is None else max_step_pct / 100.0
    try:
        return FeedLimits(lo, hi, step)
    except ValueError as exc:
        raise InputError(f"feed limits: {exc}") from None


def schedule_scenario(scenario: Scenario, *, tolerance_um: float, force_limit_N: float,
                      min_feed: float | None = None, max_feed: float | None = None,
                      max_step_pct: float | None = None, rapid_mm_min: float | None = None,
                      correct: bool = False, iterate: bool | None = None,
                      workers: int = 1, client=None,
                      progress: Callable[[str], None] | None = None) -> ScheduleRun:
    """Schedule the feeds of the scenario's program over its line range (see
    :func:`errpred.schedule.schedule_feeds`); every prediction is dense
    (:meth:`errpred.geometry.Resolution.dense`).

    With ``correct`` the program is first corrected and verified as ``errpred
    compensate`` does (:func:`errpred.pipeline.compensate_scenario`), and the feeds of
    the corrected program are scheduled with its errors measured against the original's
    path (:func:`errpred.verification.error_field`): the tolerance holds for the
    corrected error at the new feeds. A program with nothing to correct is scheduled as
    it is. ``iterate``: the correction's passes (None: the scenario's ``[correction]``).

    Raises
    ------
    nc.errors.InputError
        Bad limits, a feed move without a feed, inverse-time feeds.
    nc.command.Refused
        The original program has an error-level finding (a rapid move into material, a
        cut deeper than the flutes: :mod:`errpred.findings`), or with ``correct`` no
        correction was verified.
    """
    from .findings import error_findings, findings_line
    from .schedule import block_loads
    from .verification import error_field

    for name, v in (("--tolerance-um", tolerance_um), ("--force-limit-n", force_limit_N)):
        _finite_positive(name, v)
    _finite_positive("--rapid-mm-min", rapid_mm_min)
    original = scenario.read_program()
    scope0 = np.asarray(blocks_in_scope(scenario, original), np.int64)
    feed_limits(scenario, original, scope0, min_feed, max_feed, max_step_pct)  # early
    res = scenario.resolution.dense()
    machine = scenario.resolve_machine()
    comp = None
    program, origin = original, np.arange(1, len(original.lines) + 1)
    if correct:
        from .pipeline import compensate_scenario

        say = progress or (lambda s: None)
        comp = compensate_scenario(scenario, iterate=iterate, workers=workers, client=client,
                                   progress=lambda st: say(f"correcting, {st}"))
        if not comp.corrected and comp.verified.passes:
            raise Refused(f"{scenario.program_path}: --correct: {comp.reason()}")
        if comp.corrected:
            program, origin = comp.program, comp.origin
    blocks = _line_blocks(scenario, program, origin)
    blocks = blocks[np.isin(blocks, _scope_blocks(scenario, program, origin))]
    limits = feed_limits(scenario, program, blocks, min_feed, max_feed, max_step_pct)
    stock = scenario.stock.load()
    ref = cutter_locations(original, machine, chord_tol_mm=res.chord_tol_mm)

    def predict(prog):
        pred = build_predictor(scenario, prog, res, stock, machine=machine, sensitivity=False)
        out = pred.run([int(b) for b in blocks], workers=workers, client=client)
        if prog is original:
            found = error_findings(out)
            if found:
                raise Refused(findings_line(found, str(scenario.program_path)))
        return out

    def loads(prog, pred):
        if program is original:
            return block_loads(pred, len(prog))
        return block_loads(pred, len(prog), error_field(pred, ref, original.line))

    sched = schedule_feeds(program, predict, blocks, limits, tolerance_um=tolerance_um,
                           force_limit_N=force_limit_N, loads=loads,
                           lines=np.asarray(origin)[program.line - 1], progress=progress)
    lengths0 = block_lengths(ref, len(original))
    lengths = (lengths0 if program is original else block_lengths(
        cutter_locations(program, machine, chord_tol_mm=res.chord_tol_mm), len(program)))
    lines0 = _line_blocks(scenario, original, None)
    lines = _line_blocks(scenario, program, origin)
    return ScheduleRun(
        schedule=sched,
        scope_before=cycle_time(original, lengths0, lines0, rapid_mm_min),
        scope_after=cycle_time(program, lengths, lines, rapid_mm_min, sched.feeds_after),
        program_before=cycle_time(original, lengths0, None, rapid_mm_min),
        program_after=cycle_time(program, lengths, None, rapid_mm_min, sched.feeds_after),
        rapid_mm_min=rapid_mm_min, lengths_mm=lengths, compensation=comp)


def _scope_blocks(scenario: Scenario, program, origin) -> np.ndarray:
    """The blocks predicted: every block, or those from the scenario's lines."""
    if scenario.lines is None:
        return np.arange(len(program))
    return _line_blocks(scenario, program, origin)


def _line_blocks(scenario: Scenario, program, origin) -> np.ndarray:
    """Blocks of ``program`` from the scenario's lines of the original (all without
    lines); ``origin``: per source line of ``program``, the original's line (None: the
    same)."""
    if scenario.lines is None:
        return np.arange(len(program))
    lo, hi = scenario.lines
    line = program.line if origin is None else np.asarray(origin)[program.line - 1]
    return np.flatnonzero((line >= lo) & (line <= hi))


def minutes(t: float) -> str:
    """A time in minutes as ``m min s s`` (or seconds under a minute)."""
    s = t * 60.0
    return f"{s:.2f} s" if s < 60 else f"{int(s // 60)} min {s % 60:04.1f} s"


def summary_lines(run: ScheduleRun, scenario: Scenario) -> list[str]:
    """The command's report: limits, the verification, the cycle times."""
    s = run.schedule
    lim = s.limits
    b = s.blocks
    scope = (f"lines {scenario.lines[0]}-{scenario.lines[1]}" if scenario.lines
             else "the whole program")
    rapid = (f"rapids at {run.rapid_mm_min:g} mm/min" if run.rapid_mm_min
             else "rapids not counted (no --rapid-mm-min)")
    out = [f"  {b.size} feed blocks scheduled on {scope}: feeds {lim.min_mm_min:g}.."
           f"{lim.max_mm_min:g} mm/min, the factor on the programmed feed changing at most "
           f"{lim.max_step * 100:g} % per block; "
           f"|E| <= {s.tolerance_um:g} um, peak force <= {s.force_limit_N:g} N",
           f"  {s.reason}"]
    comp = run.compensation
    if comp is not None:
        out.insert(1, "  corrected first, the errors against the original's path: "
                   + comp.reason())
    for name, before, after in (("scheduled lines", run.scope_before, run.scope_after),
                                ("whole program", run.program_before, run.program_after)):
        change = (after.total_min / before.total_min - 1.0) * 100 if before.total_min else 0.0
        out.append(f"  cycle time ({name}, feed-limited, {rapid}): "
                   f"{minutes(before.total_min)} -> {minutes(after.total_min)} "
                   f"({change:+.1f} %)")
    return out


def page_default(output: str) -> str:
    """The page beside the program: ``NAME.nc`` -> ``NAME.html``."""
    return os.path.splitext(output)[0] + ".html"
