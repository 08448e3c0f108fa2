"""Command line: ``python -m orient plan [SCENARIO] -o OUT.nc`` and ``python -m orient lobes``.

``python -m orient plan`` is the planner's own command: it plans lead/tilt and writes
the planned program and its plan report (no error correction, no simulation; the main
job, which does both, is ``python -m sim job``: sim sits above orient, and orient
imports nothing of it). Without SCENARIO the bundled thin wall.

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

__all__ = ["build_parser", "main"]


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
    from .plots_lobes import plot_lobes
    from .pointwise import point_lobes, point_setup

    scn = _scenario(args.scenario)
    setup = point_setup(scn, args.point)
    rpm = None
    if args.rpm:
        lo, hi = args.rpm
        if not (0 < lo < hi and math.isfinite(hi)):
            raise InputError(f"--rpm: expected 0 < LOW < HIGH, got {lo:g} {hi:g}")
        rpm = np.linspace(lo, hi, args.speeds)
    methods = ("zoa", "sdm") if args.method == "both" else (args.method,)
    t0 = time.perf_counter()
    lobes, op = point_lobes(scn, setup, methods, rpm)
    plot_lobes(lobes, op, args.plot)
    for lb in lobes:
        r, m = lb.minimum
        print(f"{lb.method}: lowest limit {lb.depth_mm * m:.4g} mm (margin {m:.3g}) at "
              f"{r:.0f} rev/min")
    print(f"point {setup.index}: operating point {op[0]:g} rev/min, depth {op[1]:g} mm; "
          f"{len(lobes[0].rpm)} speeds in {time.perf_counter() - t0:.1f} s; wrote {args.plot}")
    return 0


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
    b = sub.add_parser("lobes", help="stability lobes at one cutter location")
    b.add_argument("scenario", nargs="?", help="planning scenario TOML (default: bundled)")
    b.add_argument("--plot", required=True, help="PNG file")
    b.add_argument("--point", type=int, help="cutter location index (default: the first "
                                             "cutting point)")
    b.add_argument("--method", choices=("zoa", "sdm", "both"), default="both")
    b.add_argument("--rpm", type=float, nargs=2, metavar=("LOW", "HIGH"),
                   help="speed range [rev/min]")
    b.add_argument("--speeds", type=int, default=200, help="number of speeds")
    b.set_defaults(func=_cmd_lobes)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (2 for bad input)."""
    from nc.command import run_command

    args = build_parser().parse_args(argv)
    return run_command(args.func, args)
