"""Command line: ``python -m errpred predict|compensate|schedule SCENARIO``, ``python -m
errpred fit TESTS.csv`` (a force law's coefficients from measured mean forces).

Units at this edge: errors in um, forces in N, angles in degrees.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

from nc.atomic import atomic_write
from nc.command import run_command
from nc.errors import InputError

__all__ = ["main"]


def _progress(total: int, label: str, quiet: bool):
    """A rich progress bar; returns (context manager, callback)."""
    from contextlib import nullcontext

    if quiet or total < 50:
        return nullcontext(), None
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    prog = Progress(TextColumn(label), BarColumn(), MofNCompleteColumn(), TextColumn("blocks"),
                    TimeElapsedColumn(), TimeRemainingColumn(), transient=False,
                    console=_console(sys.stderr))
    task = prog.add_task(label, total=total)

    def cb(done: int) -> None:
        prog.update(task, completed=done)

    return prog, cb


def _console(file=None):
    from rich.console import Console

    return Console(file=file, width=None if (file or sys.stdout).isatty() else 110)


def _print_summary(rep: dict, elapsed: float, blocks: int) -> None:
    from rich.table import Table

    s = rep["summary"]
    t = Table(title=f"{rep['scenario']}: predicted machining error", show_header=False,
              box=None)
    t.add_column(style="bold")
    t.add_column()
    t.add_row("blocks", f"{s['blocks']:,} ({blocks / max(elapsed, 1e-9):,.0f} blocks/s)")
    t.add_row("points by status", ", ".join(f"{k} {v:,}" for k, v in
                                            sorted(s["status_counts"].items())))
    if "max_abs_error_um" in s:
        at = s["max_error_at"]
        t.add_row("largest |error|", f"{s['max_abs_error_um']:.2f} um at line {at['line']} "
                  f"({', '.join(f'{v:.3f}' for v in at['point_mm'])} mm)")
        t.add_row("mean error", f"{s['mean_error_um']:+.2f} um (mean |E| "
                  f"{s['mean_abs_error_um']:.2f} um; + = material left)")
        lo, hi = s["error_range_um"]
        t.add_row("range", f"{lo:+.2f} .. {hi:+.2f} um")
    if "walls" in s:
        w = s["walls"]
        t.add_row("walls beside floors", f"largest |error| {w['max_abs_error_um']:.2f} um at line "
                  f"{w['line']} ({w['points']:,} points; the flank's walls: predicted, "
                  "not corrected)")
    if "against_design" in s:
        t.add_row("against design", f"largest |deviation| {s['against_design']['max_abs_um']:.2f}"
                  " um")
    w = s["wear"]
    t.add_row("actual cutting distance", f"up to {w['max_cutting_distance_mm'] / 1e3:.2f} m "
              "on one micro edge")
    if "tool_change" in s:
        t.add_row("tool change", s["tool_change"]["advice"])
    _console().print(t)


def _scenario(path: str):
    from .pipeline import load

    return load(path)


def _cmd_predict(args) -> int:
    from .pipeline import (
        blocks_in_scope,
        build_predictor,
        design_deviation_um,
        write_outputs,
    )

    page = _page_path(args, args.output or (os.path.join(args.plots, "report.json")
                                            if args.plots else None))
    scenario = _scenario(args.scenario)
    if args.lines:
        scenario = _with_lines(scenario, args.lines)
    pred = build_predictor(scenario, sensitivity=False)
    blocks = blocks_in_scope(scenario, pred.program)
    ctx, cb = _progress(len(blocks), "predicting", args.quiet)
    t0 = time.perf_counter()
    with ctx, _dask_client(args) as client:
        prediction = pred.run(blocks, workers=args.workers, progress=cb, client=client,
                              series_lines=[args.revolution_line] if args.revolution_line else ())
    elapsed = time.perf_counter() - t0
    design = design_deviation_um(scenario, prediction) if not args.no_design else None
    rep = write_outputs(scenario, prediction, args.output, args.plots, design,
                        tool_state_path=args.tool_state_out)
    if page:
        from .run_page import write_predict_page

        write_predict_page(page, scenario, prediction, rep, pred.program)
    if not args.quiet:
        _print_summary(rep, elapsed, len(blocks))
        if args.output:
            print(f"report: {args.output}")
        if args.tool_state_out:
            print(f"tool state at the end: {args.tool_state_out}")
        for p in rep.get("plots", []):
            print(f"plot: {p}")
        if page:
            print(f"page: {page}")
    errors = rep["summary"]["errors"]
    if errors:
        from nc.command import Refused

        from .findings import findings_line

        raise Refused(findings_line(errors, str(scenario.program_path)))
    return 0


def _page_path(args, beside: str | None) -> str | None:
    """Where the page goes: ``--page``, else ``beside`` with the suffix ``.html`` (None with
    ``--no-page`` or nothing to put it beside)."""
    if args.no_page:
        return None
    page = args.page or (os.path.splitext(beside)[0] + ".html" if beside else None)
    if page and any(os.path.abspath(page) == os.path.abspath(o)
                    for o in (args.output, getattr(args, "report", None)) if o):
        raise InputError(f"--page: {page} is also an output of the command; name the page "
                         "with --page FILE")
    if args.page and not os.path.isdir(os.path.dirname(os.path.abspath(args.page))):
        raise InputError(f"--page: {args.page}: its directory does not exist")
    return page


def _dask_client(args):
    from .cluster import dask_client

    return dask_client(getattr(args, "scheduler", None), getattr(args, "dask", 0))


def _with_lines(scenario, lines):
    import dataclasses

    from .scenario import check_program_lines

    lo, hi = lines
    if not (0 < lo <= hi):
        raise InputError(f"--lines: expected 0 < FIRST <= LAST, got {lo} {hi}")
    check_program_lines(scenario.read_program(), (lo, hi), str(scenario.program_path),
                        "--lines")
    return dataclasses.replace(scenario, lines=(lo, hi))


def _cmd_compensate(args) -> int:
    import dataclasses
    import json

    from nc.command import Refused

    from .pipeline import compensate_scenario

    page = _page_path(args, args.output)
    scenario = _scenario(args.scenario)
    if args.lines:
        scenario = _with_lines(scenario, args.lines)
    if args.tolerance_um is not None:
        if not (args.tolerance_um >= 0 and args.tolerance_um < float("inf")):
            raise InputError(f"--tolerance-um: expected a finite value >= 0, got "
                             f"{args.tolerance_um}")
        scenario = dataclasses.replace(scenario, correction=dataclasses.replace(
            scenario.correction, verify_tolerance_um=args.tolerance_um))
    t0 = time.perf_counter()
    con = _console(sys.stderr)
    state = {"stage": ""}

    def stage(name: str) -> None:
        state["stage"] = name
        if not args.quiet:
            con.print(f"[dim]{time.perf_counter() - t0:7.1f} s  predicting densely: "
                      f"{name}[/dim]")

    with _dask_client(args) as client:
        res = compensate_scenario(scenario, iterate=True if args.iterate else None,
                                  workers=args.workers, progress=stage, client=client,
                                  tool_state_out=args.tool_state_out)
    v = res.verified
    if args.report:
        # per block: the correction written, or where none is, the last candidate refused
        # (the one the refusal's reason names)
        shown, of = v.comparison, "the correction written"
        if shown is None and v.passes:
            last = v.passes[-1]
            shown, of = last.comparison, (f"the last candidate, refused (pass {last.index}, "
                                          f"attempt {last.attempt})")
        rep = {"scenario": scenario.name, "program": str(scenario.program_path),
               "corrected": res.corrected, "reason": res.reason(),
               "verification_of": of if shown is not None else None,
               "verification": shown.as_dict() if shown is not None else None,
               "passes": [{"pass": p.index, "attempt": p.attempt, "relaxation": p.relaxation,
                           "largest_move_um": round(p.largest_move_mm * 1e3, 3),
                           "accepted": p.accepted, "ok": p.comparison.ok,
                           "before": p.comparison.before.as_dict(),
                           "after": p.comparison.after.as_dict(),
                           "worse_points": int(p.comparison.worse.sum()),
                           "worse_lines": sorted({p.comparison.lines[int(b)]
                                                  for b in p.comparison.worse_blocks
                                                  if int(b) in p.comparison.lines}),
                           "worse_wall_points": (0 if p.comparison.walls is None
                                                 else int(p.comparison.walls.worse.sum()))}
                          for p in v.passes]}
        with atomic_write(args.report) as fh:
            json.dump(rep, fh, indent=1, allow_nan=False)
            fh.write("\n")
    if page:
        from .run_page import write_compensate_page

        write_compensate_page(page, scenario, res)
    if not res.corrected and v.passes:
        raise Refused(f"{scenario.program_path}: nothing written to {args.output}: "
                      f"{res.reason()}")
    with atomic_write(args.output) as fh:
        fh.write(res.text)
    if not res.corrected:          # nothing to move: the program as it is
        if not args.quiet:
            print(f"wrote {args.output} unchanged: {res.reason()}"
                  + (f"; the page: {page}" if page else ""))
        return 0
    if not args.quiet:
        b, a = v.before_stats, v.after_stats
        print(f"wrote {args.output}: {res.iterations} pass(es), {len(v.passes)} dense "
              f"re-predictions, in {time.perf_counter() - t0:.1f} s")
        print(f"  verified on {a.points} points (every {_spacing(scenario):g} mm, block ends "
              f"included), against the original's {b.points}:")
        print(f"  largest |E| {b.max_abs_um:.2f} -> {a.max_abs_um:.2f} um, most negative "
              f"{b.min_um:+.2f} -> {a.min_um:+.2f} um, RMS {b.rms_um:.2f} -> "
              f"{a.rms_um:.2f} um; no point worse than the original by more than "
              f"{v.comparison.tolerance_um:g} um")
        w = v.comparison.walls
        if w is not None:
            def um(x: float, sign: str = "") -> str:
                return f"{x:{sign}.2f}" if math.isfinite(x) else "n/a"

            print(f"  the walls beside the floors (not corrected), at {w.after.points} points "
                  f"against the original's {w.before.points}: largest |E| "
                  f"{um(w.before.max_abs_um)} -> {um(w.after.max_abs_um)} um, most negative "
                  f"{um(w.before.min_um, '+')} -> {um(w.after.min_um, '+')} um; none worse"
                  + (f"; {w.lost} of the original's have no wall of the corrected program "
                     "near them (not compared)" if w.lost else ""))
        elif not scenario.correction.verify_walls:
            print("  walls beside the floors not compared ([correction] verify_walls = "
                  "false)")
        if args.tool_state_out:
            print(f"wrote {args.tool_state_out}: the tool's state after the corrected program")
        if page:
            print(f"wrote {page}: the page (error on the part before and after correction)")
    return 0


def _cmd_schedule(args) -> int:
    from nc.command import Refused

    from .schedule_run import page_default, schedule_scenario, summary_lines

    if args.iterate and not args.correct:
        raise InputError("--iterate: only with --correct (it iterates the correction)")
    page = None if args.no_page else (args.page or page_default(args.output))
    if page and os.path.abspath(page) == os.path.abspath(args.output):
        raise InputError(f"--page: {page} is also the program written; name the page "
                         "with --page FILE")
    if args.page and not os.path.isdir(os.path.dirname(os.path.abspath(args.page))):
        raise InputError(f"--page: {args.page}: its directory does not exist")
    scenario = _scenario(args.scenario)
    if args.lines:
        scenario = _with_lines(scenario, args.lines)
    t0 = time.perf_counter()
    con = _console(sys.stderr)

    def stage(name: str) -> None:
        if not args.quiet:
            con.print(f"[dim]{time.perf_counter() - t0:7.1f} s  predicting densely: "
                      f"{name}[/dim]")

    with _dask_client(args) as client:
        run = schedule_scenario(scenario, tolerance_um=args.tolerance_um,
                                force_limit_N=args.force_limit_n, min_feed=args.min_feed,
                                max_feed=args.max_feed, max_step_pct=args.max_feed_step,
                                rapid_mm_min=args.rapid_mm_min, correct=args.correct,
                                iterate=True if args.iterate else None,
                                workers=args.workers,
                                client=client, progress=stage)
    s = run.schedule
    if page:
        from .schedule_page import write_schedule_page

        write_schedule_page(page, scenario, run)
    if not s.ok:
        raise Refused(f"{scenario.program_path}: nothing written to {args.output}: "
                      f"{s.reason}")
    with atomic_write(args.output) as fh:
        fh.write(s.text)
    if not args.quiet:
        print(f"wrote {args.output}: feeds scheduled, {len(s.predictions)} dense predictions, "
              f"in {time.perf_counter() - t0:.1f} s")
        for line in summary_lines(run, scenario):
            print(line)
        if page:
            print(f"wrote {page}: the page (feeds, error and force per block before and after)")
    return 0


def _cmd_fit(args) -> int:
    import tomllib

    from .fit import fit_law
    from .fit_files import cutting_table, read_tests, write_cutting_table
    from .scenario import cutting_coefficients

    tests = read_tests(args.tests)
    try:
        res = fit_law(args.law, tests, source=args.tests)
    except ValueError as exc:
        raise InputError(f"{args.tests}: {exc}") from None
    text = cutting_table(res, tests, args.tests)
    # never write a table a scenario would refuse: read it back through the loader
    cutting_coefficients(tomllib.loads(text)["cutting"], args.output or "<fit>")
    if not args.quiet:
        _print_fit(res, tests, args.law)
    if args.output:
        write_cutting_table(args.output, text)
        if not args.quiet:
            print(f"wrote {args.output}: the [cutting] table (paste it into a scenario)")
    else:
        print(text, end="")
    return 0


def _print_fit(res, tests, law: str) -> None:
    from rich.table import Table

    con = _console()
    t = Table(title=f"{law} law: coefficients ({len(tests)} tests, RMS residual "
                    f"{res.rms_N:.3g} N, condition {res.condition_number:.3g})")
    t.add_column("coefficient")
    t.add_column("value", justify="right")
    t.add_column("std. error", justify="right")
    vals = res.coefficients.as_dict()
    for n in res.names:
        t.add_row(n, f"{vals[n]:.6g}", f"{res.std_error[n]:.3g}")
    con.print(t)
    r = Table(title="mean force on the tool [N]: measured - model")
    for c in ("test", "fz mm", "ap mm", "ae mm", "mode", "Fx", "Fy", "Fz", "dFx", "dFy", "dFz"):
        r.add_column(c, justify="right")
    for tst, m, d in zip(tests, res.model_N, res.residual_N):
        r.add_row(tst.label.rsplit(":", 1)[-1], f"{tst.fz_mm:g}", f"{tst.ap_mm:g}",
                  f"{tst.ae_mm:g}", tst.mode, *(f"{x:.1f}" for x in tst.force_N),
                  *(f"{x:+.2f}" for x in d))
    con.print(r)


def _spacing(scenario) -> float:
    return scenario.resolution.dense().point_spacing_mm


_TOOL_STATE_HELP = ("write the tool's wear at the end (JSON: each micro edge's cutting "
                    "distance) for the next scenario's [tool] state")


def _parallel_and_lines(p: argparse.ArgumentParser) -> None:
    """The options predict and compensate share: where the geometry stage runs, and the
    program lines in scope."""
    p.add_argument("--workers", type=int, default=1, help="processes for the geometry stage")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run the geometry stage on an existing Dask scheduler "
                        "(e.g. tcp://10.0.0.5:8786)")
    p.add_argument("--dask", type=int, default=0, metavar="N",
                   help="run the geometry stage on a local Dask cluster of N workers")
    p.add_argument("--lines", type=int, nargs=2, metavar=("FIRST", "LAST"),
                   help="only the blocks on these program lines")


def _page_options(p: argparse.ArgumentParser, where: str) -> None:
    """``--page FILE`` and ``--no-page``: the self-contained HTML page of the run."""
    p.add_argument("--page", metavar="FILE",
                   help=f"write the run's self-contained HTML page here (default: {where})")
    p.add_argument("--no-page", action="store_true", help="write no page")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m errpred", description=(
        "Predict the machining error of end milling along an NC program, and correct it."))
    sub = ap.add_subparsers(dest="command", required=True)
    p = sub.add_parser("predict", help="predict the error along the scenario's program")
    p.add_argument("scenario", help="scenario file (TOML)")
    p.add_argument("-o", "--output", help="report (JSON)")
    p.add_argument("--plots", metavar="DIR", help="write plots (PNG) into DIR")
    _page_options(p, "beside the report (-o REPORT.json -> REPORT.html; with --plots only: "
                     "DIR/report.html)")
    _parallel_and_lines(p)
    p.add_argument("--revolution-line", type=int, metavar="LINE",
                   help="plot force and deflection over a revolution at this line "
                        "(default: where |E| is largest)")
    p.add_argument("--no-design", action="store_true",
                   help="skip the comparison with the design surface")
    p.add_argument("--tool-state-out", metavar="FILE",
                   help=_TOOL_STATE_HELP)
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_predict)
    p = sub.add_parser("compensate", help=(
        "write the program corrected against its error, only if its dense re-prediction "
        "is nowhere worse than the original's (exit status 1 and nothing written "
        "otherwise)"))
    p.add_argument("scenario")
    p.add_argument("-o", "--output", required=True, help="corrected program")
    p.add_argument("--iterate", action="store_true",
                   help="predict-correct until the largest change is below the tolerance")
    _parallel_and_lines(p)
    p.add_argument("--tolerance-um", type=float, metavar="UM",
                   help="how much worse than the original the corrected program may be "
                        "anywhere (default: [correction] verify_tolerance_um, 1 um)")
    p.add_argument("--report", metavar="JSON",
                   help="write the verification: before and after per block for the "
                        "correction written (where none is, for the last candidate, "
                        "refused), and each pass's figures and worse lines")
    p.add_argument("--tool-state-out", metavar="FILE",
                   help=_TOOL_STATE_HELP + " (of the corrected program)")
    _page_options(p, "beside the corrected program (-o NAME.nc -> NAME.html); written also "
                     "when no correction is verified, to say why")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_compensate)
    p = sub.add_parser("schedule", help=(
        "write the program with per-block feeds: the highest (within the feed limits and "
        "a change per block) at which the densely re-predicted error stays within a "
        "tolerance and the force within a limit (exit status 1 and nothing written "
        "otherwise)"))
    p.add_argument("scenario")
    p.add_argument("-o", "--output", required=True, help="program with the new feeds")
    p.add_argument("--tolerance-um", type=float, required=True, metavar="UM",
                   help="largest |E| allowed at every predicted point of a scheduled block")
    p.add_argument("--force-limit-n", type=float, required=True, metavar="N",
                   help="largest peak resultant force on the tool allowed")
    p.add_argument("--min-feed", type=float, metavar="MM_MIN",
                   help="lowest feed (default: errpred.constants.DEFAULT_MIN_FEED_FACTOR "
                        "times the smallest programmed cutting feed in scope)")
    p.add_argument("--max-feed", type=float, metavar="MM_MIN",
                   help="highest feed, the machine's or the cutter's (default: "
                        "errpred.constants.DEFAULT_MAX_FEED_FACTOR times the largest "
                        "programmed cutting feed in scope)")
    p.add_argument("--max-feed-step", type=float, metavar="PCT",
                   help="largest change of the schedule's factor on the programmed feed "
                        "from one feed block to the next [%%] (default: "
                        "errpred.constants.MAX_FEED_STEP, 20 %%)")
    p.add_argument("--rapid-mm-min", type=float, metavar="MM_MIN",
                   help="the machine's rapid rate, for the cycle time (default: rapids "
                        "not counted)")
    p.add_argument("--correct", action="store_true",
                   help="correct the program first as compensate does (verified), then "
                        "schedule the corrected program's feeds on its error against the "
                        "original's path")
    p.add_argument("--iterate", action="store_true",
                   help="with --correct: predict-correct until the largest change is below "
                        "the tolerance (as compensate --iterate)")
    _parallel_and_lines(p)
    _page_options(p, "beside the program (-o NAME.nc -> NAME.html); written also when no "
                     "schedule is verified, to say why")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_schedule)
    p = sub.add_parser("fit", help=(
        "identify a force law's coefficients from measured mean forces and write the "
        "[cutting] table"), formatter_class=argparse.RawDescriptionHelpFormatter,
        description=_FIT_HELP)
    p.add_argument("tests", help="tests file (CSV, layout below)")
    from .laws import LAWS

    p.add_argument("--law", default="linear",
                   choices=tuple(n for n, m in LAWS.items() if hasattr(m, "FIT_NAMES")),
                   help="force law to fit (default linear)")
    p.add_argument("-o", "--output", help="write the [cutting] table (TOML) here; default: "
                                          "print it")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=_cmd_fit)
    return ap


_FIT_HELP = """\
Identify a force law's coefficients from mean cutting forces measured in straight cuts
of a flat end mill (slotting or side milling) at several feeds per tooth, by least
squares on the three mean components of every test; print them with their standard
errors and each test's residual, and write the scenario's [cutting] table.

The tests file is CSV with one header row ('#' lines are comments; values illustrative):

  fz_mm,ap_mm,ae_mm,mode,diameter_mm,teeth,rpm,Fx_N,Fy_N,Fz_N
  0.05,2.0,slot,slot,10.0,3,3000,-98.1,206.4,-51.0
  0.10,2.0,3.0,down,10.0,3,3000,-160.2,250.3,-60.1

  fz_mm        feed per tooth [mm]          ap_mm   axial depth of cut [mm]
  ae_mm        radial width [mm] or slot    mode    slot, up or down (optional)
  diameter_mm  tool diameter [mm]           teeth   number of teeth
  rpm          spindle speed (optional, recorded only)
  Fx_N Fy_N Fz_N  mean force ON THE TOOL over whole revolutions [N], tool frame:
               x along the feed, z up the tool axis, y = z cross x (left of the
               feed seen from the spindle). A dynamometer under the workpiece
               reads minus this.

At least two feeds are needed. The helix does not change a flat end mill's mean
force. Laws: linear (Ktc, Krc, Kac [N/mm^2], Kte0, Kre0, Kae0 [N/mm]) and kienzle
(kc11_t/r/a [N/mm^2], mc_t/r/a [-]); the lee-altintas law varies with kappa, which
flat end mill tests do not.
"""


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (2 for bad input)."""
    args = build_parser().parse_args(argv)
    if getattr(args, "workers", 1) < 1:
        print("error: --workers must be >= 1", file=sys.stderr)
        return 2
    return run_command(args.func, args)
