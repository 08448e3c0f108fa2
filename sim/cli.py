"""Command line of the simulated machine and of the main job.

``python -m sim job [SCENARIO]``
    the main job (:mod:`sim.job_cli`): plan, predict and correct the error, write the
    program, verify it in the simulated machine, and write the page (the planner
    alone: ``python -m orient plan``);
``python -m sim serve [SCENARIO]``
    the simulated NC behind a Modbus TCP server (127.0.0.1:5020 unless told);
``python -m sim controller --host H --port P``
    the controller side: chatter watch and re-orientation over Modbus;
``python -m sim run [SCENARIO]``
    both (the controller as a separate process, over TCP on loopback), open
    loop and closed loop, then a JSON report and a spectrum plot.

SCENARIO is an orient planning scenario (default: ``sim/scenarios/thin-wall``,
orient's bundled thin wall with a wider inclination range for the controller).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from errpred.spindle import tooth_frequency
from nc.atomic import atomic_write
from nc.errors import InputError

from .constants import DEFAULT_POINTS, DEFAULT_PORT

__all__ = ["main"]


#: The bundled closed-loop scenario.
BUNDLED = Path(__file__).resolve().parent / "scenarios" / "thin-wall" / "scenario.toml"


def _scenario(path: str | None):
    from orient.scenario import load_plan_scenario

    return load_plan_scenario(path if path else BUNDLED)


def _nc(args: argparse.Namespace, workpiece=None):
    """The scenario and its simulated NC from the command line's machine arguments
    (``workpiece``: a workpiece model of the same scenario and stretch to use instead
    of building one: its finite elements take most of the NC's set-up)."""
    from .machine import SimulatedNC
    from .sensors import Accelerometers

    if not (math.isfinite(args.noise) and args.noise >= 0):
        raise InputError(f"--noise: expected a finite value >= 0, got {args.noise}")
    scale = getattr(args, "time_scale", 1.0)
    if not (math.isfinite(scale) and scale > 0):
        raise InputError(f"--time-scale: expected a finite value > 0, got {scale}")
    port = getattr(args, "port", 0)
    if not 0 <= port <= 65535:
        raise InputError(f"--port: expected 0 to 65535, got {port}")
    scn = _scenario(args.scenario)
    return scn, SimulatedNC(scn, points=tuple(args.points),
                            sensors=Accelerometers(noise_rms_m_s2=args.noise), seed=args.seed,
                            workpiece=workpiece)


def _cmd_serve(args: argparse.Namespace) -> int:
    from .server import NCServer

    _, nc = _nc(args)
    srv = NCServer(nc, host=args.host, port=args.port, time_scale=args.time_scale,
                   autostart=args.autostart)
    with srv:
        print(f"simulated NC on {args.host}:{srv.port} ({len(nc.cam)} cutter locations, "
              f"running {nc.first}..{nc.last}; "
              f"{'running' if args.autostart else 'waiting for cycle_start'}); Ctrl-C stops",
              file=sys.stderr, flush=True)
        try:
            t0 = time.monotonic()
            while not srv.wait_finished(0.2):
                if args.duration and time.monotonic() - t0 > args.duration:
                    break
            while args.linger and time.monotonic() - t0 < args.duration + args.linger:
                time.sleep(0.2)
        except KeyboardInterrupt:
            pass
    if srv.error is not None:
        print(f"error: the NC faulted: {srv.error}", file=sys.stderr)
        return 1
    return 0


def _cmd_controller(args: argparse.Namespace) -> int:
    from .controller import Controller, NCClient, ProgramGeometry

    geo = ProgramGeometry(_scenario(args.scenario))
    client = NCClient(args.host, args.port)
    t0 = time.monotonic()
    while not client.connect():
        if time.monotonic() - t0 > args.connect_timeout:
            print(f"error: no Modbus server at {args.host}:{args.port}", file=sys.stderr)
            return 1
        time.sleep(0.2)
    try:
        ctl = Controller(client, geo, strategy=args.strategy, act=not args.open_loop)
        client.write(cycle_start=1)
        log = ctl.run(max_s=args.max_s)
    except ConnectionError as exc:
        print(f"error: lost the NC: {exc}", file=sys.stderr)
        return 1
    finally:
        client.close()
    out = {"detections": log.detections, "commands": log.commands,
           "missed_samples": log.missed_samples}
    if args.log:
        with atomic_write(args.log) as fh:
            json.dump(out, fh, indent=1)
    print(f"controller: {len(log.detections)} chatter polls, "
          f"{sum(1 for c in log.commands if c[1] is not None)} orientation commands, "
          f"{log.missed_samples} samples missed", file=sys.stderr)
    return 0


def _one_run(args: argparse.Namespace, closed: bool, tmp: str,
             workpiece=None) -> dict[str, Any]:
    from orient.detect import ChatterDetector

    from .report import summarize_run
    from .sensors import detector_settings
    from .server import NCServer

    _, nc = _nc(args, workpiece)
    srv = NCServer(nc, port=0, time_scale=args.time_scale, record=True, autostart=False)
    log_path = os.path.join(tmp, f"controller-{'closed' if closed else 'open'}.json")
    with srv:
        cmd = [sys.executable, "-m", "sim", "controller", "--port", str(srv.port),
               "--log", log_path, "--max-s", str(args.max_s)]
        if args.scenario:
            cmd += ["--scenario", args.scenario]
        if not closed:
            cmd.append("--open-loop")
        cmd += ["--strategy", args.strategy]
        proc = subprocess.run(cmd, check=False, capture_output=True, text=True,
                              timeout=args.max_s + 120)
        srv.wait_finished(30.0)
    if proc.returncode != 0:
        raise RuntimeError(f"controller process failed ({proc.returncode}): "
                           f"{proc.stderr.strip()[-500:]}")
    with open(log_path, encoding="utf-8") as fh:
        clog = json.load(fh)
    t, counts, cutting = srv.recorded()
    acc = counts * nc.sensors.lsb_m_s2
    det = ChatterDetector(detector_settings(nc.sensors))
    summ = summarize_run(t, acc, nc.surface.arrays(), det, nc.rpm, nc.tool.flutes,
                         clog["commands"], cutting=cutting)
    summ["controller_missed_samples"] = clog["missed_samples"]
    summ["events"] = [{"time_s": e[0], "what": e[1]} for e in srv.events]
    summ["server_error"] = None if srv.error is None else repr(srv.error)
    return {"summary": summ, "t": t, "acc": acc, "rpm": nc.rpm, "teeth": nc.tool.flutes,
            "fs": nc.sensors.sample_rate_hz, "workpiece": nc.workpiece}


def _stretch(r: dict, start_s: float, length_s: float) -> np.ndarray:
    m = (r["t"] >= start_s) & (r["t"] < start_s + length_s)
    return r["acc"][m]


def _cmd_run(args: argparse.Namespace) -> int:
    from .plots import plot_spectra

    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="sim-run-") as tmp:
        closed = _one_run(args, True, tmp)
        # the open loop on the same workpiece model (built once: 12-15 s of finite
        # elements a run)
        opened = None if args.no_compare else _one_run(args, False, tmp,
                                                       workpiece=closed["workpiece"])
    report: dict[str, Any] = {"scenario": args.scenario or "bundled thin-wall",
                              "points": list(args.points), "spindle_rpm": closed["rpm"],
                              "closed_loop": closed["summary"]}
    if opened is not None:
        report["open_loop"] = opened["summary"]
    cs = closed["summary"]
    lines = [f"closed loop: first chatter at {cs.get('first_detection_s')} s"]
    if cs.get("chatter_stops_after_rev") is not None:
        lines.append(f"  chatter stopped {cs['chatter_stops_after_rev']:.0f} revolutions after "
                     f"the first detection ({len(cs['commands'])} orientation commands)")
    else:
        lines.append("  chatter did not stop")
    for name, r in (("closed", closed), ("open", opened)):
        if r is not None and "surface" in r["summary"]:
            s = r["summary"]["surface"]
            lines.append(f"  {name:>6} loop surface: chatter marks {s['chatter_marks_um']:.2f} um "
                         f"(last half {s['tail_chatter_marks_um']:.2f} um), mean offset "
                         f"{s['mean_offset_um']:.1f} um, peak-to-peak {s['peak_to_peak_um']:.1f} um;"
                         f" chatter windows after detection "
                         f"{r['summary']['chatter_share_after_detection']:.0%}")
    report["wall_s"] = time.monotonic() - t0
    if args.report:
        with atomic_write(args.report) as fh:
            json.dump(report, fh, indent=1, default=_json_default)
    plot_path = args.plot
    if args.html and not plot_path:
        plot_path = os.path.join(tempfile.mkdtemp(prefix="sim-run-plot-"), "spectra.png")
    if plot_path:
        t_det = cs.get("first_detection_s") or 0.0
        end = float(closed["t"][-1]) if closed["t"].size else 0.0
        panels = [("closed loop: at the first detection (before) and at the end (after)",
                   _stretch(closed, max(0.0, t_det - 0.1), 0.2), _stretch(closed, end - 0.5, 0.5))]
        if opened is not None:
            oend = float(opened["t"][-1])
            panels.append(("end of the cut: open loop (before) and closed loop (after)",
                           _stretch(opened, oend - 0.5, 0.5), _stretch(closed, end - 0.5, 0.5)))
        plot_spectra(plot_path, panels, closed["fs"], tooth_frequency(closed["rpm"], closed["teeth"]))
    if args.html:
        _write_html(args.html, report, lines, plot_path)
    print("\n".join(lines))
    return 0


def _write_html(path: str, report: dict[str, Any], lines: list[str], plot_path: str) -> None:
    from errpred.page import Figure, Section, write_page

    cs = report["closed_loop"]
    op = report.get("open_loop")
    stopped = cs.get("chatter_stops_after_rev")
    verdict = (f"With the controller on, chatter stopped {stopped:.0f} spindle revolutions "
               f"after it was first detected." if stopped is not None else
               "With the controller on, chatter did not stop.")
    rows = [("", "closed loop", "open loop" if op else "")]

    def val(r, key, fmt="{:.2f}"):
        if r is None:
            return ""
        v = r.get(key)
        return "-" if v is None else fmt.format(v)

    def surf(r, key):
        return "" if r is None or "surface" not in r else f"{r['surface'][key]:.2f}"

    rows += [("first chatter detected at [s]", val(cs, "first_detection_s"),
              val(op, "first_detection_s")),
             ("side of the first detection", str(cs.get("first_cause", "-")),
              str(op.get("first_cause", "-")) if op else ""),
             ("chatter stops after [rev]", val(cs, "chatter_stops_after_rev", "{:.0f}"),
              val(op, "chatter_stops_after_rev", "{:.0f}")),
             ("windows with chatter after detection", val(cs, "chatter_share_after_detection",
                                                          "{:.0%}"),
              val(op, "chatter_share_after_detection", "{:.0%}")),
             ("chatter marks, last half [um]", surf(cs, "tail_chatter_marks_um"),
              surf(op, "tail_chatter_marks_um")),
             ("chatter marks, whole cut [um]", surf(cs, "chatter_marks_um"),
              surf(op, "chatter_marks_um")),
             ("mean surface offset [um]", surf(cs, "mean_offset_um"), surf(op, "mean_offset_um"))]
    if op is None:
        rows = [r[:2] for r in rows]
    cmds = [("time [s]", "lead [deg]", "tilt [deg]", "acknowledged", "why")]
    cmds += [(f"{c['time_s']:.3f}", f"{c['lead_deg']:+.1f}", f"{c['tilt_deg']:+.1f}",
              {1: "applied", 2: "refused (interference)", 3: "refused (axis limit)"}.get(
                  c["ack"], str(c["ack"])), c["reason"])
             for c in cs["commands"] if c["lead_deg"] is not None]
    with open(plot_path, "rb") as fh:
        png = fh.read()
    setting = (f"Scenario: {report['scenario']}, cutter locations {report['points'][0]} to "
               f"{report['points'][1]}, {report['spindle_rpm']:.0f} rev/min; the NC ran in "
               "real time, the controller was a separate process that saw only the Modbus "
               "registers.")
    sections = [
        Section("Result", paragraphs=(*lines, setting), tables=(tuple(rows),)),
        Section("Orientation commands", tables=(tuple(cmds),) if len(cmds) > 1 else (),
                paragraphs=() if len(cmds) > 1 else ("No command was sent.",)),
        Section("Acceleration spectra", figures=(Figure(
            png, ("Spindle accelerometers: the broad chatter peaks between the "
                  "tooth-passing lines (grey) before, and what is left after.")),)),
    ]
    write_page(path, "Simulated machining with chatter control", verdict, sections,
               good=stopped is not None)


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return None if not math.isfinite(float(o)) else float(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(f"not JSON-serializable: {type(o).__name__}")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m sim", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)

    def machine_args(a: argparse.ArgumentParser) -> None:
        a.add_argument("scenario", nargs="?", default=None,
                       help="orient scenario file (default: sim's bundled thin wall)")
        a.add_argument("--points", nargs=2, type=int, default=list(DEFAULT_POINTS),
                       metavar=("FIRST", "LAST"), help="cutter locations to run")
        a.add_argument("--time-scale", type=float, default=1.0,
                       help="simulated seconds per wall second (1: real time)")
        a.add_argument("--noise", type=float, default=0.5, help="sensor noise [m/s^2 rms]")
        a.add_argument("--seed", type=int, default=0, help="sensor noise seed")

    s = sub.add_parser("serve", help="the simulated NC behind Modbus TCP")
    machine_args(s)
    s.add_argument("--host", default="127.0.0.1", help="address to bind (default loopback)")
    s.add_argument("--port", type=int, default=DEFAULT_PORT)
    s.add_argument("--autostart", action="store_true",
                   help="run the program at once (else wait for cycle_start)")
    s.add_argument("--duration", type=float, default=0.0,
                   help="stop after this many wall seconds (0: at the program's end)")
    s.add_argument("--linger", type=float, default=0.0,
                   help="keep serving this many seconds after the end")
    s.set_defaults(func=_cmd_serve)

    c = sub.add_parser("controller", help="controller side over Modbus")
    c.add_argument("--host", default="127.0.0.1")
    c.add_argument("--port", type=int, default=DEFAULT_PORT)
    c.add_argument("--scenario", default=None, help="the program's scenario (default bundled)")
    c.add_argument("--open-loop", action="store_true", help="detect only, do not re-orient")
    c.add_argument("--strategy", choices=("eigen", "detector"), default="eigen",
                   help="orient's rule: largest margin nearby (eigen) or the patent's cause "
                        "rules (detector)")
    c.add_argument("--max-s", type=float, default=600.0, help="give up after this [s]")
    c.add_argument("--connect-timeout", type=float, default=10.0)
    c.add_argument("--log", default=None, help="write the controller's log (JSON) here")
    c.set_defaults(func=_cmd_controller)

    from .job_cli import add_job_arguments
    from .job_cli import run as run_job

    j = sub.add_parser("job", help="the main job: plan, correct, write and verify a CAM "
                                   "program, and report")
    add_job_arguments(j)
    j.set_defaults(func=run_job)

    r = sub.add_parser("run", help="serve, control over TCP, report (open and closed loop)")
    machine_args(r)
    r.add_argument("--report", default=None, help="JSON report file")
    r.add_argument("--plot", default=None, help="PNG of the acceleration spectra")
    r.add_argument("--html", default=None, help="self-contained HTML page of the result")
    r.add_argument("--no-compare", action="store_true", help="closed loop only")
    r.add_argument("--strategy", choices=("eigen", "detector"), default="eigen",
                   help="the controller's rule (see python -m sim controller -h)")
    r.add_argument("--max-s", type=float, default=600.0)
    r.set_defaults(func=_cmd_run)
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (2 for bad input)."""
    from nc.command import run_command

    args = build_parser().parse_args(argv)
    return run_command(args.func, args)
