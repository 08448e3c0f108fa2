"""Bad scenario files through the command lines: is each refused in one line, at once?

Makes bad scenario files by mutating the bundled scenarios (errpred's mold-ball,
orient's thin wall): a key's value made NaN, infinite, negative, zero, huge or of
the wrong type, or left out; empty, corrupt and open (not watertight) mesh files;
an empty program, one without a spindle speed, a line range that selects nothing;
resolutions that would not fit the memory budget; counts beyond their limits. Each
goes through a command line in this process (``errpred predict`` for errpred's,
``sim job`` -- the main job, ``--no-dask`` -- for orient's) with a time limit, and is
tallied:

* ``input error``: exit status 2, one line ``error: ...`` on stderr naming the
  scenario file (and, where the case says which, the key), within the limit;
* anything else (``other``): another exit status, a traceback, more than one line,
  a message that does not name the file or the key, or the time limit reached (the
  error came only after long work, or never).

The case list is seeded (``--seed``): which keys get which of the generic values,
and the bytes of the corrupt files. ``tests/test_bad_scenarios.py`` runs every case
(:func:`cases`; each is refused within a fraction of a second) as a parametrized test.

Usage: python benchmarks/fuzz_scenarios.py [--seed 19] [--limit-s 10] [--only errpred|orient]
Exit status: 0 when every case is an input error, 1 otherwise.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import math
import os
import random
import re
import shutil
import signal
import sys
import tempfile
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

ROOT = Path(__file__).resolve().parent.parent
ERRPRED = ROOT / "errpred" / "scenarios" / "mold-ball" / "scenario.toml"
ORIENT = ROOT / "orient" / "scenarios" / "thin-wall" / "scenario.toml"
#: Keys whose values are file paths (made absolute in the mutated copies).
PATH_KEYS = (("stock", "stl"), ("stock", "design_stl"), ("program", "gcode"))

DELETE = object()


# --------------------------------------------------------------------------- TOML out
def _key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(type(v))


def dumps(doc: dict) -> str:
    """A TOML text for ``doc`` (tables, arrays of tables, scalars, NaN and infinity)."""
    out: list[str] = []

    def is_aot(v) -> bool:
        return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)

    def emit(prefix: str, table: dict, header: str | None) -> None:
        if header:
            out.append(header)
        for k, v in table.items():
            if not isinstance(v, dict) and not is_aot(v):
                out.append(f"{_key(k)} = {_value(v)}")
        for k, v in table.items():
            name = f"{prefix}.{_key(k)}" if prefix else _key(k)
            if isinstance(v, dict):
                emit(name, v, f"[{name}]")
            elif is_aot(v):
                for item in v:
                    emit(name, item, f"[[{name}]]")

    emit("", doc, None)
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------- cases
@dataclass
class Case:
    """One bad scenario: ``edit`` changes the parsed document, ``files`` writes extra
    files into the case's folder (name -> bytes), whose paths ``edit`` may use."""

    name: str
    package: str  # "errpred" or "orient"
    key: str | None  # the key the one line must name (None: the file alone)
    edit: Callable[[dict, Path], None]
    files: dict[str, bytes] = field(default_factory=dict)
    text: Callable[[str], str] | None = None  # a change of the written TOML text


def _set(path: str, value) -> Callable[[dict, Path], None]:
    """Set (or, with DELETE, remove) a dotted key; ``modes[0]`` indexes arrays."""
    def edit(doc: dict, folder: Path) -> None:
        parts = path.split(".")
        d = doc
        for p in parts[:-1]:
            m = re.fullmatch(r"(\w+)\[(\d+)\]", p)
            d = d[m.group(1)][int(m.group(2))] if m else d.setdefault(p, {})
        last = parts[-1]
        if value is DELETE:
            d.pop(last, None)
        else:
            d[last] = value(folder) if callable(value) else value
    return edit


def _file(name: str) -> Callable[[Path], str]:
    return lambda folder: str(folder / name)


def _stl_box(open_: bool = False, nan: bool = False, ascii_: bool = False) -> bytes:
    import trimesh

    m = trimesh.creation.box(extents=(80.0, 60.0, 30.0))
    if open_:
        m = trimesh.Trimesh(m.vertices, m.faces[:-2], process=False)
    if nan:
        v = m.vertices.copy()
        v[0, 0] = float("nan")
        m = trimesh.Trimesh(v, m.faces, process=False)
    if ascii_:
        return trimesh.exchange.stl.export_stl_ascii(m).encode()
    return trimesh.exchange.stl.export_stl(m)


def _program_without_s(src: Path) -> bytes:
    return re.sub(rb"S\d+(\.\d*)?", b"", src.read_bytes())


#: Numeric keys of each base scenario: (key, whether it may be left out).
NUMERIC = {
    "errpred": [("tool.diameter_mm", False), ("tool.helix_deg", False),
                ("tool.flute_length_mm", True), ("tool.overhang_mm", True),
                ("tool.holder.diameter_mm", False), ("cutting.Ktc_N_mm2", False),
                ("cutting.Kte0_N_mm", False), ("dynamics.modes[0].frequency_hz", False),
                ("dynamics.modes[0].damping_ratio", False),
                ("dynamics.modes[0].stiffness_N_m", False),
                ("shape_error.wear_rate_um_per_m", True), ("resolution.pixel_mm", True),
                ("resolution.chord_tol_mm", True), ("resolution.angle_step_deg", True)],
    "orient": [("orient.margin_target", True), ("orient.max_rate_deg_per_mm", True),
               ("orient.clearance_mm", True), ("orient.cut.depth_mm", False),
               ("orient.cut.pick_mm", False), ("workpiece.thin_wall.length_mm", False),
               ("workpiece.thin_wall.thickness_mm", False),
               ("workpiece.thin_wall.young_GPa", False),
               ("workpiece.thin_wall.density_kg_m3", False), ("tool.diameter_mm", False)],
}
#: Generic bad values; a negative or zero value only where the key must be positive.
GENERIC = [("nan", float("nan")), ("inf", float("inf")), ("-inf", float("-inf")),
           ("negative", -1.0), ("zero", 0.0), ("huge", 1e300), ("string", "12"),
           ("boolean", True), ("array", [1.0])]
#: Keys that may be zero or negative (left out of those values).
SIGNED = {"tool.helix_deg", "cutting.Kte0_N_mm"}
ZERO_OK = {"orient.clearance_mm", "shape_error.wear_rate_um_per_m",
           "dynamics.modes[0].damping_ratio"}


def _specific() -> list[Case]:
    """The reported findings and the other named cases."""
    E, O = "errpred", "orient"
    c = [
        Case("flutes-1e30", E, "tool.flutes", _set("tool.flutes", 1e30)),
        Case("flutes-1e9", E, "tool.flutes", _set("tool.flutes", 10**9)),
        Case("flutes-int64-max", E, "tool.flutes", _set("tool.flutes", 2**63 - 1)),
        Case("flutes-0", E, "tool.flutes", _set("tool.flutes", 0)),
        Case("diameter-1e300", E, "tool.diameter_mm", _set("tool.diameter_mm", 1e300)),
        Case("pixel-1e-7", E, "resolution.pixel_mm", _set("resolution.pixel_mm", 1e-7)),
        Case("pixel-0.002", E, "resolution.pixel_mm", _set("resolution.pixel_mm", 0.002)),
        Case("micro-edges-1e6", E, "resolution.micro_edges",
             _set("resolution.micro_edges", 10**6)),
        Case("micro-edges-1", E, "resolution.micro_edges", _set("resolution.micro_edges", 1)),
        Case("angle-step-1e-6", E, "resolution.angle_step_deg",
             _set("resolution.angle_step_deg", 1e-6)),
        Case("angle-step-180", E, "resolution.angle_step_deg",
             _set("resolution.angle_step_deg", 180.0)),
        Case("chord-tol-1e-12", E, "resolution.chord_tol_mm",
             _set("resolution.chord_tol_mm", 1e-12)),
        Case("point-spacing-1e-9", E, "resolution.point_spacing_mm",
             _set("resolution.point_spacing_mm", 1e-9)),
        Case("max-iterations-1e9", E, "correction.max_iterations",
             _set("correction.max_iterations", 10**9)),
        Case("lines-beyond", E, "program.lines", _set("program.lines", [10**6, 10**6 + 10])),
        Case("lines-header-only", E, "program.lines", _set("program.lines", [1, 3])),
        Case("lines-reversed", E, "program.lines", _set("program.lines", [300, 200])),
        Case("lines-zero", E, "program.lines", _set("program.lines", [0, 10])),
        Case("gcode-empty", E, "program.gcode", _set("program.gcode", _file("empty.nc")),
             {"empty.nc": b""}),
        Case("gcode-comments-only", E, "program.gcode",
             _set("program.gcode", _file("c.nc")), {"c.nc": b"%\n(nothing to cut)\nM30\n%\n"}),
        Case("gcode-binary", E, "program.gcode", _set("program.gcode", _file("b.nc")),
             {"b.nc": b"G1 X\xff\xfe\x00\x01 Y2\n"}),
        Case("gcode-missing", E, "program.gcode", _set("program.gcode", "nope.nc")),
        Case("gcode-unknown-word", E, "program.gcode", _set("program.gcode", _file("u.nc")),
             {"u.nc": b"G21 G90\nG0 X0 Y0 Z50\nG1 X10 F100 Q7 W3\n"}),
        Case("stl-empty", E, "stock.stl", _set("stock.stl", _file("e.stl")), {"e.stl": b""}),
        Case("stl-text-garbage", E, "stock.stl", _set("stock.stl", _file("g.stl")),
             {"g.stl": b"solid x\n  facet normal what\nendsolid\n"}),
        Case("stl-open", E, "stock.stl", _set("stock.stl", _file("o.stl")),
             {"o.stl": b"@open"}),
        Case("stl-open-ascii", E, "stock.stl", _set("stock.stl", _file("oa.stl")),
             {"oa.stl": b"@open-ascii"}),
        Case("stl-nan-vertex", E, "stock.stl", _set("stock.stl", _file("n.stl")),
             {"n.stl": b"@nan"}),
        Case("stl-truncated", E, "stock.stl", _set("stock.stl", _file("t.stl")),
             {"t.stl": b"@truncated"}),
        Case("stl-random", E, "stock.stl", _set("stock.stl", _file("r.stl")),
             {"r.stl": b"@random"}),
        Case("stl-directory", E, "stock.stl", _set("stock.stl", lambda f: str(f))),
        Case("design-empty", E, "stock.design_stl", _set("stock.design_stl", _file("d.stl")),
             {"d.stl": b""}),
        Case("design-random", E, "stock.design_stl",
             _set("stock.design_stl", _file("dr.stl")), {"dr.stl": b"@random"}),
        Case("box-inverted", E, "stock.box_max_mm", lambda d, f: (
            d["stock"].pop("stl"), d["stock"].update(box_min_mm=[0.0, 0.0, 0.0],
                                                     box_max_mm=[-1.0, 10.0, 10.0]))),
        Case("machine-unknown", E, "program.machine", _set("program.machine", "xyzzy")),
        Case("allow-not-list", E, "program.allow", _set("program.allow", "M8")),
        Case("tool-type-unknown", E, "tool.type", _set("tool.type", "drill")),
        Case("tool-section-missing", E, "tool", lambda d, f: d.pop("tool")),
        Case("dynamics-modes-empty", E, "dynamics.modes", _set("dynamics.modes", [])),
        Case("kappa-decreasing", E, "shape_error.kappa_deg",
             _set("shape_error.kappa_deg", [90.0, 75.0, 60.0, 45.0, 30.0, 15.0, 0.0])),
        Case("tool-state-empty", E, "tool.state", _set("tool.state", _file("s.json")),
             {"s.json": b""}),
        Case("tool-state-garbage", E, "tool.state", _set("tool.state", _file("s2.json")),
             {"s2.json": b"{\"cl_mm\": [1, 2, \"x\"]}"}),
        Case("name-empty", E, "name", _set("name", "")),
        Case("unknown-key", E, "tool.diameter_in", _set("tool.diameter_in", 0.4)),
        Case("toml-broken", E, None, lambda d, f: None,
             text=lambda t: t.replace("[tool]", "[tool", 1)),
        # orient
        Case("grid-zero", O, "orient.grid", _set("orient.grid", [0, 5])),
        Case("grid-huge", O, "orient.grid", _set("orient.grid", [1000, 1000])),
        Case("lead-nan", O, "orient.lead_deg", _set("orient.lead_deg", [float("nan"), 10.0])),
        Case("spindle-steps-1e9", O, "orient.spindle.steps",
             _set("orient.spindle.steps", 10**9)),
        Case("spindle-range-huge", O, "orient.spindle.range_rpm",
             _set("orient.spindle.range_rpm", [1e9, 2e9])),
        Case("cut-depth-beyond-radius", O, "orient.cut.depth_mm",
             _set("orient.cut.depth_mm", 50.0)),
        # (no [orient.cut] is no error: the cut is then taken from the part)
        Case("cut-pick-nan", O, "orient.cut.pick_mm", _set("orient.cut.pick_mm", float("nan"))),
        Case("machined-side-nan", O, "orient.cut.machined_side",
             _set("orient.cut.machined_side", [0.0, float("nan"), 1.0])),
        Case("wall-modes-1e6", O, "workpiece.thin_wall.modes",
             _set("workpiece.thin_wall.modes", 10**6)),
        Case("wall-element-1e-6", O, "workpiece.thin_wall.element_mm",
             _set("workpiece.thin_wall.element_mm", 1e-6)),
        Case("wall-poisson-0.7", O, "workpiece.thin_wall.poisson",
             _set("workpiece.thin_wall.poisson", 0.7)),
        Case("wall-along-zero", O, "workpiece.thin_wall.along",
             _set("workpiece.thin_wall.along", [0.0, 0.0, 0.0])),
        Case("wall-normal-skew", O, "workpiece.thin_wall.normal",
             _set("workpiece.thin_wall.normal", [1.0, 1.0, 0.0])),
        Case("tool-flat", O, "tool.type", _set("tool.type", "flat")),
        Case("design-missing", O, "stock.design_stl", lambda d, f: d["stock"].pop("design_stl")),
        Case("stock-open", O, "stock.stl", _set("stock.stl", _file("o.stl")),
             {"o.stl": b"@open"}),
        Case("stock-corrupt", O, "stock.stl", _set("stock.stl", _file("r.stl")),
             {"r.stl": b"@random"}),
        Case("design-corrupt", O, "stock.design_stl",
             _set("stock.design_stl", _file("dr.stl")), {"dr.stl": b"@random"}),
        Case("orient-gcode-empty", O, "program.gcode", _set("program.gcode", _file("e.nc")),
             {"e.nc": b""}),
        Case("orient-machine-missing", O, "program.machine",
             lambda d, f: d["program"].pop("machine")),
        Case("orient-no-spindle-speed", O, "program.gcode",
             _set("program.gcode", _file("nos.nc")), {"nos.nc": b"@no-s"}),
        Case("orient-flutes-1e9", O, "tool.flutes", _set("tool.flutes", 10**9)),
        Case("orient-pixel-1e-7", O, "resolution.pixel_mm", _set("resolution.pixel_mm", 1e-7)),
        Case("orient-section-not-table", O, "orient", _set("orient", 3)),
    ]
    return c


def _generic(rng: random.Random, per_key: int) -> list[Case]:
    out = []
    for package, keys in NUMERIC.items():
        for key, optional in keys:
            values = [(n, v) for n, v in GENERIC
                      if not (key in SIGNED and n in ("negative", "zero"))
                      and not (key in ZERO_OK and n == "zero")]
            picked = rng.sample(values, min(per_key, len(values)))
            for n, v in picked:
                out.append(Case(f"{package}:{key}={n}", package, key, _set(key, v)))
            if not optional:
                out.append(Case(f"{package}:{key} missing", package, key, _set(key, DELETE)))
    return out


def cases(seed: int = 19, per_key: int = 3) -> list[Case]:
    """Every case: the named ones, then ``per_key`` seeded generic values of each
    numeric key (and its absence, where it is required)."""
    rng = random.Random(seed)
    return _specific() + _generic(rng, per_key)


def _materialize(case: Case, folder: Path, seed: int) -> Path:
    """Write the case's scenario (and its files) into ``folder``; the scenario's path."""
    base = ERRPRED if case.package == "errpred" else ORIENT
    doc = tomllib.loads(base.read_text())
    for sec, k in PATH_KEYS:
        if k in doc.get(sec, {}):
            doc[sec][k] = str((base.parent / doc[sec][k]).resolve())
    rng = random.Random(f"{seed}:{case.name}")
    stock = base.parent / "stock.stl"
    for name, data in case.files.items():
        if data == b"@open":
            data = _stl_box(open_=True)
        elif data == b"@open-ascii":
            data = _stl_box(open_=True, ascii_=True)
        elif data == b"@nan":
            data = _stl_box(nan=True)
        elif data == b"@truncated":
            data = stock.read_bytes()[:1000]
        elif data == b"@random":
            data = bytes(rng.randrange(256) for _ in range(4096))
        elif data == b"@no-s":
            data = _program_without_s(Path(doc["program"]["gcode"]))
        (folder / name).write_bytes(data)
    case.edit(doc, folder)
    text = dumps(doc)
    if case.text is not None:
        text = case.text(text)
    path = folder / f"{case.name.replace(':', '-').replace(' ', '-')}.toml"
    path.write_text(text)
    return path


# --------------------------------------------------------------------------- running
class CaseTimeout(BaseException):
    """The time limit of a case ran out (a BaseException: nothing catches it by accident)."""


@dataclass
class Outcome:
    case: Case
    status: int | None
    seconds: float
    stderr: str
    verdict: str  # "input error" or "other: ..."


def run_case(case: Case, folder: Path, seed: int = 19, limit_s: float = 10.0) -> Outcome:
    """Run one case through its command line in this process."""
    folder.mkdir(parents=True, exist_ok=True)
    scenario = _materialize(case, folder, seed)
    if case.package == "errpred":
        from errpred.cli import main
        argv = ["predict", str(scenario), "-o", str(folder / "report.json"), "-q", "--no-design"]
    else:
        from sim.cli import main
        argv = ["job", str(scenario), "--out", str(folder / "job"), "--no-dask"]
    err, out = io.StringIO(), io.StringIO()

    def alarm(signum, frame):
        raise CaseTimeout

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, limit_s)
    t0 = time.perf_counter()
    status: int | None = None
    crash = ""
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            status = main(argv)
    except CaseTimeout:
        crash = f"no answer within {limit_s:g} s"
    except SystemExit as exc:  # argparse
        status = exc.code if isinstance(exc.code, int) else 1
    except Exception as exc:  # a bug: what the command line would show as a traceback
        crash = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    seconds = time.perf_counter() - t0
    text = err.getvalue().strip()
    return Outcome(case, status, seconds, text, _verdict(case, status, text, crash, scenario))


def _verdict(case: Case, status, text: str, crash: str, scenario: Path) -> str:
    if crash:
        return f"other: {crash}"
    if status != 2:
        return f"other: exit status {status}" + (f" ({text.splitlines()[-1][:80]})"
                                                 if text else "")
    lines = text.splitlines()
    if len(lines) != 1 or not lines[0].startswith("error: "):
        return f"other: {len(lines)} lines on stderr"
    if scenario.name not in lines[0]:
        return "other: the line does not name the scenario file"
    if case.key is not None and case.key not in lines[0]:
        return f"other: the line does not name the key {case.key}"
    return "input error"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=19)
    ap.add_argument("--per-key", type=int, default=3,
                    help="generic bad values tried per numeric key (9: all)")
    ap.add_argument("--limit-s", type=float, default=10.0, help="time limit of a case [s]")
    ap.add_argument("--only", choices=("errpred", "orient"))
    ap.add_argument("-v", "--verbose", action="store_true", help="print every case's line")
    args = ap.parse_args(argv)
    todo = [c for c in cases(args.seed, args.per_key) if args.only in (None, c.package)]
    tmp = Path(tempfile.mkdtemp(prefix="fuzz-scenarios-"))
    outcomes = []
    try:
        for i, case in enumerate(todo):
            o = run_case(case, tmp / f"{i:03d}", args.seed, args.limit_s)
            outcomes.append(o)
            if args.verbose or o.verdict != "input error":
                print(f"{case.package:8s} {case.name:40s} {o.seconds:6.2f} s  {o.verdict}"
                      + (f"\n{'':50s}{o.stderr.splitlines()[0][:150]}"
                         if args.verbose and o.stderr else ""))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    good = sum(o.verdict == "input error" for o in outcomes)
    slowest = max(outcomes, key=lambda o: o.seconds)
    for pkg in ("errpred", "orient"):
        sub = [o for o in outcomes if o.case.package == pkg]
        if sub:
            print(f"{pkg}: {len(sub)} cases, {sum(o.verdict == 'input error' for o in sub)} "
                  f"one-line input errors (exit 2), "
                  f"{sum(o.verdict != 'input error' for o in sub)} other")
    print(f"total: {len(outcomes)} bad scenarios, {good} one-line input errors (exit 2), "
          f"{len(outcomes) - good} other; slowest answer {slowest.seconds:.2f} s "
          f"({slowest.case.name}), seed {args.seed}")
    return 0 if good == len(outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
