"""Command line: ``python -m orient plan [SCENARIO] -o OUT.nc`` and ``python -m orient lobes``.

``python -m orient plan`` is the planner's own command: it plans lead/tilt and writes
the planned program and its plan report (no error correction, no simulation; the main
job, which does both, is ``python -m sim job``: sim sits above orient, and orient
imports nothing of it). Without SCENARIO the bundled thin wall.
``python -m orient lobes`` gives advice at one cutter location
(:mod:`orient.advice`): lobes of the CAM and the planned posture, a suggested
spindle speed, the largest stable depth and pick feed over a safety factor.

Units at the command line: mm, degrees, rev/min. Bad input ends in one line
naming the file and the key, exit status 2, and nothing written. A plan with
points that have no feasible posture (:attr:`orient.plan.PlanResult.infeasible`)
ends in one line saying how many and where, exit status 1, and nothing
written, unless a fallback is allowed (``--allow-fallback`` or ``[orient]
allow_fallback = true``): then the CAM posture is kept there, one warning line
is printed and the status is 0.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

from errpred.cluster import dask_client
from nc.errors import InputError

from .constants import LOBES_SDM_DISAGREE, LOBES_SPEED_MARGIN

__all__ = ["build_parser", "main"]

#: Speeds of the lobe diagram by default [-] (zero-order: milliseconds each) ...
LOBES_DEFAULT_SPEEDS = 200
#: ... and with ``--method sdm`` (seconds each on the bundled wall) [-].
LOBES_SDM_DEFAULT_SPEEDS = 40


def _console():
    from rich.console import Console

    return Console(file=sys.stderr, width=None if sys.stderr.isatty() else 110)


def _scenario(path: str | None):
    from .scenario import bundled_scenario, load_plan_scenario

    return load_plan_scenario(path if path else bundled_scenario())


def _cmd_plan(args) -> int:
    from nc.path import cutter_locations
    from nc.writer import DIALECTS, PostOptions, round_trip_error, write_program

    from .constants import MAX_SPINDLE_RPM
    from .plan import plan
    from .plots import plot_margin_along_path, plot_margin_grid
    from .report import infeasible_summary, write_plan_report

    # the options, before the scenario and the planning
    if args.output is None:
        raise InputError("-o OUT.nc: missing; the planned program to write (the main job, "
                         "which also corrects the error and verifies in simulation: "
                         "python -m sim job [SCENARIO])")
    if args.dialect is not None and args.dialect not in DIALECTS:
        raise InputError(f"--dialect: {args.dialect!r}; expected one of {', '.join(DIALECTS)}")
    if args.spindle_rpm is not None and not (0 < args.spindle_rpm <= MAX_SPINDLE_RPM):
        raise InputError(f"--spindle-rpm: expected 0 < RPM <= {MAX_SPINDLE_RPM:g}, got "
                         f"{args.spindle_rpm:g}")
    scn = _scenario(args.scenario)
    out = os.path.abspath(args.output)
    for p in [out] + ([os.path.abspath(args.report)] if args.report else []):
        if not os.path.isdir(os.path.dirname(p)):
            raise FileNotFoundError(f"{p}: directory {os.path.dirname(p)} does not exist")
    # --machine is resolved as the scenario's program.machine: with the tool's overhang as
    # its tool length (orient.scenario.PlanScenario.machine)
    machine = scn.machine(args.machine) if args.machine else None
    con = _console()
    t0 = time.perf_counter()
    with con.status("planning") as status:
        def progress(stage, done, total):
            if done == total or done % 50 == 0:
                status.update(f"{stage}: {done}/{total} cutter locations")
        with dask_client(args.scheduler, args.dask or 0) as client:
            res = plan(scn, machine=machine, spindle_rpm=args.spindle_rpm, progress=progress,
                       client=client)
    if len(res.infeasible):
        what = infeasible_summary(res)
        if not (args.allow_fallback or scn.options.allow_fallback):
            print(f"error: {what}; nothing written (--allow-fallback, or allow_fallback = "
                  f"true in [orient], keeps the CAM posture there)", file=sys.stderr)
            return 1
        print(f"warning: {what}; the CAM posture is kept there (fallback allowed), flagged "
              f"'infeasible' in the plan report", file=sys.stderr)
    opts = PostOptions(dialect=args.dialect or scn.options.dialect, spindle_rpm=res.spindle_rpm,
                       source=f"orient plan of {scn.name}")
    post = write_program(out, res.cl, res.machine, opts)
    # round trip: the written program read back through nc's reader and kinematics
    from nc import read_program

    back = cutter_locations(read_program(out), res.machine)
    err = round_trip_error(post, back)
    rep_path = args.report or os.path.splitext(out)[0] + "-plan.json"
    rep = write_plan_report(rep_path, res, scenario=str(scn.path), program=out)
    rep_s = rep["summary"]
    if args.plots:
        os.makedirs(args.plots, exist_ok=True)
        d = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(res.cl.tip, axis=0),
                                                          axis=1))])
        cutting = np.zeros(len(res.cl), bool)
        cutting[res.touching_index] = True
        plot_margin_along_path(d, res.cam_margin, res.margin,
                               os.path.join(args.plots, "margin_along_path.png"),
                               cutting=cutting, title=f"{scn.name}: stability margin along "
                                                      f"the path")
        r = int(np.argmin(res.cam_margin[res.touching_index]))
        i = int(res.touching_index[r])
        plot_margin_grid(res.grid_lead_rad, res.grid_tilt_rad, res.grid_margin[r],
                         res.grid_feasible[r], os.path.join(args.plots, "margin_grid.png"),
                         chosen=(res.lead_rad[i], res.tilt_rad[i]),
                         cam=(res.cam_lead_rad[i], res.cam_tilt_rad[i]),
                         title=f"{scn.name}: margin over lead/tilt at point {i} "
                               f"(block {int(res.cl.block[i])})",
                         clip=scn.options.margin_target)
    print(f"planned {rep_s['cutting_points']} cutting points of {rep_s['points']} in "
          f"{time.perf_counter() - t0:.1f} s at {res.spindle_rpm:g} rev/min")
    print(f"margin min {rep_s['cam_margin_min']} -> {rep_s['margin_min']}, median "
          f"{rep_s['cam_margin_median']} -> {rep_s['margin_median']}; points below 1: "
          f"{rep_s['points_below_1_before']} -> {rep_s['points_below_1_after']}")
    for c in res.sdm_checks:
        print(f"  point {c['point']}: zero-order {c['zoa_margin']:.3f}, time-periodic "
              f"{c['sdm_margin']:.3f} ({c['kind']})")
    print(f"collisions of the planned postures: {rep_s['planned_collisions']}; round trip "
          f"through {res.machine.name}: {err[0]:.2g} mm, {math.degrees(err[1]):.2g} deg")
    print(f"wrote {out} ({len(post.text.splitlines())} lines) and {rep_path}")
    return 0


def _cmd_lobes(args) -> int:
    from .constants import LOBES_SAFETY_FACTOR, MAX_SPINDLE_RPM, MAX_SPINDLE_STEPS
    from .pointwise import LOBE_RANGE

    # the options, before the scenario and any work
    if args.rpm:
        lo, hi = args.rpm
        if not (0 < lo < hi <= MAX_SPINDLE_RPM):
            raise InputError(f"--rpm: expected 0 < LOW < HIGH <= {MAX_SPINDLE_RPM:g}, got "
                             f"{lo:g} {hi:g}")
    speeds = args.speeds if args.speeds is not None else \
        (LOBES_SDM_DEFAULT_SPEEDS if args.method == "sdm" else LOBES_DEFAULT_SPEEDS)
    if not 2 <= speeds <= MAX_SPINDLE_STEPS:
        raise InputError(f"--speeds: expected 2 to {MAX_SPINDLE_STEPS}, got {speeds}")
    sf = LOBES_SAFETY_FACTOR if args.safety_factor is None else args.safety_factor
    if not (math.isfinite(sf) and 1.0 <= sf <= 10.0):
        raise InputError(f"--safety-factor: expected 1 <= FACTOR <= 10, got {sf:g}")
    plot = os.path.abspath(args.plot)
    if not os.path.isdir(os.path.dirname(plot)):
        raise FileNotFoundError(f"{plot}: directory {os.path.dirname(plot)} does not exist")
    t0 = time.perf_counter()
    scn = _scenario(args.scenario)
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn,
                               TextColumn, TimeElapsedColumn)

    from .advice import advise
    from .plots_lobes import plot_lobes
    from .pointwise import point_setup

    con = _console()
    # the bar on a terminal only (elsewhere it would leave blank lines in the log)
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=con, transient=True,
                  disable=not con.is_terminal) as bar:
        task = bar.add_task("set-up: contacts, local cut, the workpiece's modes", total=None)
        setup = point_setup(scn, args.point)
        t_setup = time.perf_counter() - t0
        if args.rpm:
            rpm = np.linspace(args.rpm[0], args.rpm[1], speeds)
        elif scn.options.spindle is not None:
            rpm = np.linspace(*scn.options.spindle.range_rpm, speeds)
        else:
            rpm = np.linspace(LOBE_RANGE[0] * setup.spindle_rpm,
                              LOBE_RANGE[1] * setup.spindle_rpm, speeds)

        def progress(stage, done, total):
            bar.update(task, description=stage, completed=done,
                       total=total if total > 1 else None)

        adv = advise(scn, setup, rpm, method=args.method, safety_factor=sf, progress=progress)
    plot_lobes([lb for _, lb in adv.lobes], (setup.spindle_rpm, setup.cut.depth_mm), plot,
               labels=[lab for lab, _ in adv.lobes],
               suggested=(adv.suggested_rpm, adv.window_depth_mm))
    pl = adv.planned
    for lab, lb in adv.lobes:
        r, m = lb.minimum
        print(f"{lab}: lowest limit {lb.depth_mm * m:.4g} mm (margin {m:.3g}) at "
              f"{r:.0f} rev/min")
    if not pl.feasible:
        print("warning: no candidate posture is feasible at this point; the planned posture "
              "shown is the CAM's", file=sys.stderr)
    print(f"point {setup.index}: programmed {setup.spindle_rpm:g} rev/min, depth "
          f"{setup.cut.depth_mm:g} mm, pick feed {setup.cut.pick_mm:g} mm; planned posture "
          f"lead {pl.lead_deg:.1f}, tilt {pl.tilt_deg:.1f} deg (this point alone, no "
          f"smoothness along the path)")
    if adv.sdm_disagrees:
        print(f"note: the time-periodic check is more than "
              f"{100 * LOBES_SDM_DISAGREE:g} % below the zero-order lobes near the "
              f"suggested speed (engaged {100 * adv.engaged_fraction:.0f} % of the tooth "
              f"period); the limits below are time-periodic")
    print(f"suggested spindle speed {adv.suggested_rpm:.0f} rev/min (stable depth at least "
          f"{adv.window_depth_mm:.3g} mm within +-{100 * LOBES_SPEED_MARGIN:g} % of it, "
          f"gain-scaled)")
    print(f"largest stable depth {_limit(adv.depth_limit)} at pick feed "
          f"{setup.cut.pick_mm:g} mm -> use at most {_limit(adv.depth_limit, sf)} "
          f"(safety factor {sf:g}; {adv.limit_method})")
    if adv.setup.cut.previous_side == 0:
        print("largest stable pick feed: no previous pass beside this point (the first pass "
              "cuts on both sides): the pick feed does not enter here; try --point on a "
              "later pass")
    else:
        print(f"largest stable pick feed {_limit(adv.pick_limit)} at depth "
              f"{setup.cut.depth_mm:g} mm -> use at most {_limit(adv.pick_limit, sf)} "
              f"(safety factor {sf:g}; {adv.limit_method})")
    stages = ", ".join(f"{k} {v:.1f}" for k, v in adv.seconds.items())
    print(f"{len(rpm)} speeds; lobes command time {time.perf_counter() - t0:.1f} s (set-up "
          f"{t_setup:.1f}, {stages}); wrote {plot}")
    return 0


def _limit(lim, factor: float = 1.0) -> str:
    """A limit [mm] divided by ``factor``, "at least" when the search hit its cap."""
    return f"{'at least ' if lim.capped else ''}{lim.value / factor:.3g} mm"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m orient", description=(
        "Chatter-aware lead/tilt planning for 5-axis ball-end milling."))
    sub = p.add_subparsers(dest="cmd", required=True)
    # no abbreviations: --out (the main job's folder, python -m sim job) must not be
    # taken for --output and write a program where a folder was meant
    a = sub.add_parser("plan", allow_abbrev=False,
                       help="plan lead/tilt and write the planned program and its report "
                            "(the main job: python -m sim job)")
    a.add_argument("scenario", nargs="?", help="planning scenario TOML (default: the bundled "
                                               "thin-wall)")
    a.add_argument("-o", "--output", metavar="OUT.nc",
                   help="the NC program to write (required; no error correction, no "
                        "simulation)")
    a.add_argument("--machine", help="named machine or machine file (.toml), tool length "
                                     "from the tool's overhang (default: the scenario's "
                                     "program.machine)")
    a.add_argument("--dialect", help="linuxcnc, fanuc-g43.4 or fanuc-g43.5 (default: the "
                                     "scenario's)")
    a.add_argument("--spindle-rpm", type=float, help="plan at this speed [rev/min]")
    a.add_argument("--report", help="JSON report (default: OUT-plan.json)")
    a.add_argument("--plots", help="folder for the PNG plots")
    a.add_argument("--allow-fallback", action="store_true",
                   help="where no posture is feasible keep the CAM posture (flagged, a "
                        "warning) instead of refusing with status 1")
    g = a.add_mutually_exclusive_group()
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="compute gains and margins on an existing Dask scheduler")
    g.add_argument("--dask", type=int, default=None, metavar="N",
                   help="local Dask cluster of N workers (default: none)")
    a.set_defaults(func=_cmd_plan)
    b = sub.add_parser("lobes", help="stability lobes at one cutter location, a suggested "
                                     "spindle speed and the largest stable depth and pick feed",
                       description=(
        "Stability lobes at one cutter location for the CAM posture and the planned one "
        "(the planner's choice at this point alone), a suggested spindle speed (the "
        "largest stable depth at the planned posture, lowest within "
        "+-LOBES_SPEED_MARGIN of the speed) and the patent's 8th embodiment: the "
        "largest stable axial depth and pick feed there, divided by a safety factor. "
        "Depths on the plot are the cut's depth times the margin (the gain scaled); the "
        "limits printed recompute the ball's engagement at each trial cut."))
    b.add_argument("scenario", nargs="?", help="planning scenario TOML (default: bundled)")
    b.add_argument("--plot", required=True, help="PNG file")
    b.add_argument("--point", type=int, help="cutter location index (default: the first "
                                             "cutting point)")
    b.add_argument("--method", choices=("auto", "zoa", "sdm"), default="auto", help=(
        "auto (default): zero-order lobes (fast), checked by the time-periodic method at "
        "a few speeds across the suggested speed's window, where the average process gain "
        "can be wrong: intermittent cuts (low radial immersion, a ball cutting a small "
        "part of the tooth period) have flip lobes the zero-order method misses; the "
        "limits by the time-periodic method when the check is more than 5 %% lower. "
        "zoa: zero-order only. sdm: time-periodic lobes everywhere (slow: seconds per "
        "speed)"))
    b.add_argument("--rpm", type=float, nargs=2, metavar=("LOW", "HIGH"),
                   help="speed range [rev/min] (default: the scenario's [orient.spindle] "
                        "range_rpm, else 0.5 to 1.6 times the programmed speed)")
    b.add_argument("--speeds", type=int, default=None,
                   help=f"number of speeds (default {LOBES_DEFAULT_SPEEDS}, "
                        f"{LOBES_SDM_DEFAULT_SPEEDS} with --method sdm)")
    b.add_argument("--safety-factor", type=float, default=None,
                   help="the largest stable depth and pick feed are divided by it "
                        "(default: orient.constants.LOBES_SAFETY_FACTOR, 1.5)")
    b.set_defaults(func=_cmd_lobes)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (2 for bad input)."""
    from nc.command import run_command

    args = build_parser().parse_args(argv)
    return run_command(args.func, args)
