"""The page of ``errpred schedule`` (self-contained HTML, :mod:`errpred.page`).

It says what a person needs to judge the schedule without the program: the limits,
the verdict of the dense verification, the cycle time before and after (and its
model), the feed per block, the largest |E| and the peak force per block before and
after against the tolerance and the force limit, and every verified round.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

import numpy as np

from .constants import PAGE_TABLE_ROWS
from .page import Figure, Section, render_page
from .page_plots import png_bytes

if TYPE_CHECKING:
    from .scenario import Scenario
    from .schedule_run import ScheduleRun

__all__ = ["schedule_page", "write_schedule_page"]


def _abs_e(loads, b: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return np.fmax(np.abs(loads.E_max_um[b]), np.abs(loads.E_min_um[b]))


def _f(v: float, fmt: str = ".2f") -> str:
    return "-" if not math.isfinite(v) else format(v, fmt)


def _plots(run: ScheduleRun) -> tuple[bytes, bytes]:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    s = run.schedule
    b = s.blocks
    x = np.arange(b.size)
    lines = s.program.line[b]
    ticks = x[:: max(1, b.size // 12)]
    fig, ax = plt.subplots(figsize=(8.5, 3.2), layout="constrained")
    ax.step(x, s.feeds_before[b], where="mid", label="programmed", color="0.45")
    ax.step(x, s.feeds_after[b], where="mid",
            label="scheduled" + ("" if s.ok else " (last round, not written)"), color="C0")
    for v, lab in ((s.limits.min_mm_min, "min"), (s.limits.max_mm_min, "max")):
        ax.axhline(v, ls="--", lw=0.8, color="C3")
        ax.annotate(lab, (x[-1] if x.size else 0, v), fontsize=8, color="C3",
                    va="bottom", ha="right")
    ax.set_xticks(ticks, [str(int(li)) for li in lines[ticks]], fontsize=8)
    ax.set_xlabel("program line of the feed block")
    ax.set_ylabel("feed [mm/min]")
    ax.legend(fontsize=8)
    feed_png = png_bytes(fig)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8.5, 5.0), sharex=True, layout="constrained")
    a1.plot(x, _abs_e(s.before, b), "o-", ms=3, color="0.45", label="programmed feeds")
    a1.plot(x, _abs_e(s.after, b), "o-", ms=3, color="C0", label="scheduled feeds")
    a1.axhline(s.tolerance_um, ls="--", color="C3", label="tolerance")
    a1.set_ylabel("largest |E| [um]")
    a1.legend(fontsize=8)
    a2.plot(x, s.before.force_N[b], "o-", ms=3, color="0.45")
    a2.plot(x, s.after.force_N[b], "o-", ms=3, color="C0")
    a2.axhline(s.force_limit_N, ls="--", color="C3")
    a2.set_ylabel("peak force [N]")
    a2.set_xticks(ticks, [str(int(li)) for li in lines[ticks]], fontsize=8)
    a2.set_xlabel("program line of the feed block")
    return feed_png, png_bytes(fig)


def schedule_page(scenario: Scenario, run: ScheduleRun) -> str:
    """The page of ``errpred schedule``.

    Parameters
    ----------
    scenario : Scenario
    run : ScheduleRun
        The schedule, its verification rounds and the cycle times.
    """
    from .schedule_run import minutes

    s = run.schedule
    b = s.blocks
    lim = s.limits
    verdict = ("Feeds scheduled, verified: " if s.ok else "Nothing written: ") + s.reason + "."
    scope = (f"lines {scenario.lines[0]}-{scenario.lines[1]}" if scenario.lines
             else "the whole program")
    rapid = (f"rapids at {run.rapid_mm_min:g} mm/min" if run.rapid_mm_min
             else "rapids not counted (the rapid rate was not given)")
    limit_rows = (("limit", "value"),
                  ("feed", f"{lim.min_mm_min:g} .. {lim.max_mm_min:g} mm/min"),
                  ("change of the factor on the programmed feed from one feed block to "
                   "the next", f"at most {lim.max_step * 100:g} %"),
                  ("error", f"|E| <= {s.tolerance_um:g} um at every predicted point"),
                  ("force", f"peak resultant force <= {s.force_limit_N:g} N"))
    ct_rows = [("cycle time", "programmed feeds", "scheduled feeds", "change")]
    for name, bef, aft in (("scheduled lines", run.scope_before, run.scope_after),
                           ("whole program", run.program_before, run.program_after)):
        ch = (aft.total_min / bef.total_min - 1.0) * 100 if bef.total_min else 0.0
        ct_rows.append((name, minutes(bef.total_min), minutes(aft.total_min),
                        f"{ch:+.1f} %"))
    sections = [Section("Result", paragraphs=(
        f"Scenario {scenario.name} ({scenario.path}), program {scenario.program_path}, "
        f"{scope}: {b.size} feed blocks scheduled. The original, a probe at other feeds "
        "and every schedule were predicted densely (points at most "
        f"{scenario.resolution.dense().point_spacing_mm:g} mm apart, block ends included); "
        "a schedule is written only when that prediction of the very text to be written "
        "keeps every scheduled block within the tolerance and the force limit.",
        ("The program was corrected first as errpred compensate does ("
         + run.compensation.reason() + "); the corrected program's feeds were scheduled, "
         "its errors measured against the original's path, and 'programmed feeds' below "
         "are the corrected program's at the original feeds." if run.compensation is not None
         else "The program was scheduled as it is (not corrected)."),
        f"Cycle time model: feed-limited, each block's tool-tip path length over its "
        f"programmed feed, {rapid}; no acceleration, look-ahead, dwell or tool change."),
        tables=(limit_rows, tuple(ct_rows)))]
    if b.size:
        feed_png, load_png = _plots(run)
        sections.append(Section("Feed per block", figures=(Figure(
            feed_png, "Programmed and scheduled feed of each scheduled block, in program "
                      "order; dashed: the feed limits."),)))
        sections.append(Section("Error and force per block", figures=(Figure(
            load_png, "Largest |E| (dense points) and peak resultant force of each block, "
                      "at the programmed and the scheduled feeds; dashed: the tolerance and "
                      "the force limit."),)))
        rows = [("line", "length [mm]", "F before", "F after", "|E| before [um]",
                 "|E| after [um]", "force before [N]", "force after [N]")]
        eb, ea = _abs_e(s.before, b), _abs_e(s.after, b)
        for i, k in enumerate(b[:PAGE_TABLE_ROWS]):
            rows.append((str(int(s.program.line[k])), f"{run.lengths_mm[k]:.2f}",
                         f"{s.feeds_before[k]:g}", f"{s.feeds_after[k]:g}", _f(eb[i]),
                         _f(ea[i]), _f(s.before.force_N[k], ".1f"),
                         _f(s.after.force_N[k], ".1f")))
        more = (f"The first {PAGE_TABLE_ROWS} of {b.size} blocks." if b.size > PAGE_TABLE_ROWS
                else "")
        sections.append(Section("Per block", paragraphs=(more,) if more else (),
                                 tables=(tuple(rows),)))
    round_rows = [("round", "blocks over a limit", "largest |E| [um]", "peak force [N]",
                   "feeds [mm/min]")]
    for k, r in enumerate(s.rounds, 1):
        e = _abs_e(r.loads, b)
        f = r.loads.force_N[b]
        round_rows.append((str(k), str(r.over.size),
                           _f(float(np.nanmax(e, initial=0.0)) if b.size else math.nan),
                           _f(float(np.nanmax(f, initial=0.0)) if b.size else math.nan, ".1f"),
                           f"{r.feeds[b].min():g} .. {r.feeds[b].max():g}" if b.size else "-"))
    sections.append(Section("Verified rounds", paragraphs=(
        "Each round is a dense prediction of the program with that round's feeds; blocks "
        "over a limit get a lower feed in the next round.",), tables=(tuple(round_rows),)))
    return render_page(f"errpred schedule: {scenario.name}", verdict, sections, good=s.ok)


def write_schedule_page(path: str | os.PathLike, scenario: Scenario, run: ScheduleRun) -> None:
    """:func:`schedule_page` written atomically to ``path``."""
    from .run_page import write_page_text

    write_page_text(path, schedule_page(scenario, run))
