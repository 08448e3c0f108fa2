"""Command line: ``python -m nc parse|post|check|machines``.

Units at this edge: mm, mm/min and degrees on the screen and in JSON; the
package inside works in mm and radians.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

from .command import run_command
from .constants import SINGULAR_CONE_RAD
from .errors import InputError
from .gcode import ALLOWABLE_EXAMPLES, read_program
from .linuxcnc import Rs274Error
from .summary import blocks_as_json, summarize
from .tables import TableReader

__all__ = ["main"]


def _allow_list(text: str | None) -> list[str]:
    return [t for t in (text or "").replace(" ", ",").split(",") if t]


def _setup(path: str | None) -> tuple[dict | None, dict | None]:
    """Work offsets and reference points from one TOML file (see :func:`_offsets`)."""
    table = _offsets(path)
    if table is None:
        return None, None
    refs = {k: v for k, v in table.items() if k.strip().upper() in ("G28", "G30")}
    return {k: v for k, v in table.items() if k not in refs}, refs


def _offsets(path: str | None) -> dict | None:
    """Work offsets from TOML: ``[G55] xyz_mm = [..]`` and optional ``abc_deg``;
    ``[G28]`` and ``[G30]`` the same way give the machine's reference points
    (machine coordinates)."""
    if path is None:
        return None
    r = TableReader(path)
    out = {}
    for key, table in r.load("offsets file").items():
        if key.strip().upper() not in ("G54", "G55", "G56", "G57", "G58", "G59", "G28", "G30"):
            raise r.fail(key, "expected tables [G54] ... [G59], [G28], [G30]")
        r.keys(r.table(table, key), key, ("xyz_mm",), ("abc_deg",))
        out[key] = r.numbers(table, "xyz_mm", key, length=3) + r.numbers(
            table, "abc_deg", key, length=3, default=[])
    return out


def _machine(arg: str):
    from .kinematics import get_machine, load_machine

    if arg.endswith(".toml") or os.path.sep in arg:
        return load_machine(arg)
    return get_machine(arg)


def _print_summary(s, console=None) -> None:
    from rich.console import Console
    from rich.table import Table

    console = console or Console(width=None if sys.stdout.isatty() else 110)
    t = Table(title=f"{s.file}", show_header=False, box=None, pad_edge=False)
    t.add_column(style="bold")
    t.add_column()
    t.add_row("lines", f"{s.lines:,}")
    t.add_row("motion blocks", f"{s.motion_blocks:,} ({s.rapid_blocks:,} rapid, "
              f"{s.linear_blocks:,} linear, {s.arc_blocks:,} arc)")
    t.add_row("cutting path", f"{s.cutting_length_mm:,.3f} mm")
    t.add_row("rapid path", f"{s.rapid_length_mm:,.3f} mm")
    if s.drilling_blocks:
        t.add_row("drilling (canned cycles)", f"{s.drilling_blocks:,} moves, "
                  f"{s.drilling_length_mm:,.3f} mm at feed, {s.drilling_time_min:,.2f} min")
    minutes = s.cutting_time_min
    t.add_row("milling time at programmed feed" if s.drilling_blocks else
              "time at programmed feed",
              f"{minutes:,.2f} min ({int(minutes // 60)} h {minutes % 60:04.1f} min)")
    lo, hi = s.bbox_min_mm, s.bbox_max_mm
    if all(math.isfinite(v) for v in lo):
        t.add_row("bounding box", "  ".join(f"{a} {lo[i]:.3f} .. {hi[i]:.3f}"
                                            for i, a in enumerate("XYZ")) + " mm")
    for name, (a, b) in s.rotary_range_deg.items():
        t.add_row(f"{name} range", f"{a:.3f} .. {b:.3f} deg")
    t.add_row("tools", ", ".join(f"T{x}" for x in s.tools) or "-")
    t.add_row("spindle", f"{s.spindle_rpm[0]:g} .. {s.spindle_rpm[1]:g} rev/min")
    t.add_row("units in program", ", ".join(s.units) or "-")
    t.add_row("tool centre point", ", ".join(s.tcp_modes) or "-")
    if s.unknown_blocks:
        t.add_row("position not known", f"{s.unknown_blocks:,} blocks from line "
                  f"{s.unknown_first_line} (G28/G30 to a point not given: [G28] / [G30] "
                  "xyz_mm in --offsets); left out of the figures above")
    if s.main_m99_line:
        t.add_row("program end", f"M99 in the main program at line {s.main_m99_line}, read "
                  "as its end (as Centroid's controls read it; a Fanuc control would run "
                  "the program again from its start): the moves are one pass")
    if s.main_open_end_line:
        t.add_row("program end", f"the main program runs into the program at line "
                  f"{s.main_open_end_line} without M30 or M02, read as its end (a control "
                  "that runs on through the file, LinuxCNC or Mach3, would execute that "
                  "program's blocks too: check the program)")
    if s.ignored:
        t.add_row("passed over", ", ".join(
            f"{code} x{count} (line {first})" for code, count, first in s.ignored))
    console.print(t)


def _cmd_parse(args) -> int:
    from .dialects import detect_dialect, read_any

    dialect = None if args.dialect == "auto" else args.dialect
    if dialect is None:
        with open(args.file, "rb") as fh:
            dialect = detect_dialect(fh.read(4096).decode("latin-1"))
    if dialect == "siemens":
        if args.offsets or args.retract_limit is not None:
            raise InputError("--offsets and --retract-limit do not apply to a Siemens "
                             "program (its work offsets are taken as zero)")
        prog = read_any(args.file, "siemens", allow=_allow_list(args.allow),
                        block_delete=args.block_delete,
                        machine=_machine(args.machine) if args.machine else None)
    elif dialect == "heidenhain":
        if args.offsets:
            raise InputError("--offsets applies to G-code (G54...G59); a Heidenhain "
                             "program sets its datum with cycle 7")
        prog = read_any(args.file, "heidenhain", allow=_allow_list(args.allow),
                        block_delete=args.block_delete,
                        retract_limit_mm=args.retract_limit)
    else:
        offsets, refs = _setup(args.offsets)
        prog = read_program(args.file, allow=_allow_list(args.allow),
                            block_delete=args.block_delete, work_offsets=offsets,
                            strict=args.strict, reference_points=refs)
    if args.json:
        json.dump(blocks_as_json(prog), sys.stdout, separators=(",", ":"))
        sys.stdout.write("\n")
    else:
        _print_summary(summarize(prog))
    return 0


def _cmd_post(args) -> int:
    from .path import read_cl_csv
    from .writer import PostOptions, write_program

    cl = read_cl_csv(args.cl, spindle_rpm=args.spindle or 0.0)
    machine = _machine(args.machine)
    if args.tool_length is not None:
        if not (math.isfinite(args.tool_length) and args.tool_length >= 0):
            raise InputError(f"--tool-length: expected a finite value >= 0, got "
                             f"{args.tool_length}")
        machine = machine.with_tool_length(args.tool_length)
    if args.dialect.startswith(("siemens", "heidenhain")):
        # the read-back posts: (writer, options, form of this dialect, program-name
        # characters besides letters and digits, longest name, upper case, label)
        if args.dialect.startswith("siemens"):
            from .siemens_writer import SiemensPostOptions as Options, write_siemens as write

            form = "vector" if args.dialect == "siemens-traori" else "rotary"
            extra, longest, upper, label = "_", 24, True, "Sinumerik TRAORI"
        else:
            from .heidenhain_writer import TNCPostOptions as Options, write_heidenhain as write

            form = "tcpm-angles" if args.dialect == "heidenhain-tcpm" else "ln-vector"
            extra, longest, upper, label = "_-", 64, False, "Klartext"
        name = os.path.splitext(os.path.basename(args.output))[0]
        name = name.upper() if upper else name
        name = "".join(c if c.isalnum() or c in extra else "_" for c in name)[:longest] \
            or "NCPATH"
        popts = Options(
            form=form, program_name=name, tool=args.tool, spindle_rpm=args.spindle,
            linear_decimals=args.decimals, header=not args.no_header,
            source=os.path.basename(args.cl),
            singular_cone_rad=math.radians(args.singular_cone_deg))
        res = write(args.output, cl, machine, popts)
        print(f"wrote {args.output}: {len(cl)} cutter locations, {label} "
              f"{popts.form}, read back within 1 um / 1e-4 deg, "
              f"{res.singular_points} points at the singularity (free axis held)")
        return 0
    try:  # the options' own checks name the option (tool, spindle_rpm, ...)
        opts = PostOptions(
            dialect=args.dialect, tool=args.tool, spindle_rpm=args.spindle,
            linear_decimals=args.decimals, line_numbers=args.line_numbers,
            header=not args.no_header, end_code=None if args.end == "none" else args.end,
            source=os.path.basename(args.cl),
            singular_cone_rad=math.radians(args.singular_cone_deg),
        )
    except ValueError as exc:
        raise InputError(f"post options: {exc}") from None
    res = write_program(args.output, cl, machine, opts)
    print(f"wrote {args.output}: {len(cl)} cutter locations -> {len(res.tip)} points "
          f"({len(res.tip) - len(cl)} inserted by linearization), "
          f"{res.inverse_time_moves} inverse-time moves, "
          f"{res.singular_points} points at the singularity (free axis held)")
    if args.summary:
        prog = read_program(args.output)
        _print_summary(summarize(prog))
    return 0


def _cmd_check(args) -> int:
    from .linuxcnc import compare_with_rs274

    # rs274 alone (no variable file) has its G28/G30 points at machine zero
    zero = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    prog = read_program(args.file, allow=_allow_list(args.allow), strict=args.strict,
                        reference_points={"G28": zero, "G30": zero})
    result = compare_with_rs274(args.file, prog)
    print(result.message, file=sys.stdout if result.ok else sys.stderr)
    return 0 if result.ok else 1


def _cmd_machines(args) -> int:
    from .kinematics import MACHINES, get_machine

    for name in MACHINES:
        m = get_machine(name)
        lim = ", ".join(f"{a.name} {math.degrees(a.min_rad):g}..{math.degrees(a.max_rad):g} deg"
                        for a in m.axes)
        print(f"{name:22s} rotary {'/'.join(m.rotary_names)}  {lim}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m nc", description=(
        "Read G-code, post cutter locations to 5-axis NC programs, check them with "
        "LinuxCNC's interpreter."))
    sub = ap.add_subparsers(dest="command", required=True)

    p = sub.add_parser("parse", help="read a program; print its summary or its blocks as JSON")
    p.add_argument("file")
    p.add_argument("--json", action="store_true",
                   help="print every motion block: line, motion, xyz_mm, abc_deg, feed")
    p.add_argument("--allow", metavar="CODES",
                   help="comma-separated codes to pass over beyond those passed over anyway "
                        f"(coolant, dwell, G64...), e.g. {','.join(ALLOWABLE_EXAMPLES[:3])}")
    p.add_argument("--strict", action="store_true",
                   help="refuse codes that do nothing here unless listed in --allow, and the "
                        "frame and reference codes (G10, G28, G30, G52, G53, G92) and G95")
    p.add_argument("--block-delete", action="store_true", help="skip lines starting with '/'")
    p.add_argument("--offsets", metavar="TOML",
                   help="work offsets: [G55] xyz_mm = [x, y, z]; the machine's G28/G30 "
                        "points (machine coordinates): [G28] xyz_mm = [x, y, z]")
    p.add_argument("--dialect", default="auto", choices=["auto", "gcode", "heidenhain", "siemens"],
                   help="reader to use; auto: Heidenhain if the program starts with BEGIN PGM, "
                        "Siemens if with %%_N_..._MPF or ;$PATH= or its first blocks use "
                        "Sinumerik words (CYCLE800, TRAORI, ...)")
    p.add_argument("--retract-limit", type=float, metavar="MM",
                   help="Heidenhain: the Z that M140 MB MAX retracts to (else refused)")
    p.add_argument("--machine", metavar="MACHINE",
                   help="Siemens: a named machine or machine TOML file, for CYCLE800's "
                        "direct mode (192: the plane from the rotary axis positions)")
    p.set_defaults(func=_cmd_parse)

    p = sub.add_parser("post", help="write an NC program from a cutter-location CSV")
    p.add_argument("cl", help="CSV with columns x,y,z,i,j,k,feed [mm, unit vector, mm/min]")
    p.add_argument("--machine", required=True,
                   help="a named machine (see 'machines') or a machine TOML file")
    p.add_argument("--dialect", default="linuxcnc",
                   choices=["linuxcnc", "fanuc-g43.4", "fanuc-g43.5", "heidenhain-tcpm",
                            "heidenhain-ln", "siemens-traori", "siemens-traori-rot"],
                   help="heidenhain-tcpm: Klartext L X Y Z + rotary angles under FUNCTION "
                        "TCPM; heidenhain-ln: LN with the tool vector; siemens-traori: "
                        "Sinumerik TRAORI with A3= B3= C3= tool vectors; siemens-traori-rot: "
                        "TRAORI with the rotary axis angles")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--tool", type=int, default=1)
    p.add_argument("--tool-length", type=float, metavar="MM",
                   help="tool length [mm] (head machines)")
    p.add_argument("--spindle", type=float, metavar="RPM", help="spindle speed [rev/min]")
    p.add_argument("--decimals", type=int, default=4, help="digits for mm words")
    p.add_argument("--singular-cone-deg", type=float, metavar="DEG",
                   default=math.degrees(SINGULAR_CONE_RAD),
                   help="cone around the C axis inside which C is held (default 0.057)")
    p.add_argument("--line-numbers", action="store_true")
    p.add_argument("--no-header", action="store_true")
    p.add_argument("--end", default="M30", choices=["M30", "M2", "none"])
    p.add_argument("--summary", action="store_true", help="read the result back and summarize")
    p.set_defaults(func=_cmd_post)

    p = sub.add_parser("check", help="compare this reader with LinuxCNC's rs274 on a file")
    p.add_argument("file")
    p.add_argument("--allow", metavar="CODES")
    p.add_argument("--strict", action="store_true")
    p.set_defaults(func=_cmd_check)

    p = sub.add_parser("machines", help="list the named machines")
    p.set_defaults(func=_cmd_machines)
    return ap


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (2 for bad input)."""
    args = build_parser().parse_args(argv)
    return run_command(args.func, args, extra=(Rs274Error,))
