"""Seeded fuzzer of the G-code reader and of what ``python -m nc parse`` does after it.

Mutates real programs -- the bundled ones (``errpred/scenarios``,
``orient/scenarios``), the inline programs of ``tests/nc/test_gcode.py``, a few
5-axis and arc programs written here, and LinuxCNC's sample programs when
``linuxcnc-uspace`` is installed -- and runs each mutant through the command
line's own ``parse`` (summary: path lengths, times, arcs expanded into chords,
the table printed) and ``parse --json``, in-process, and then through
:func:`nc.path.cutter_locations` (on a table-table A/C machine, or on none), as
``errpred`` and ``orient`` take programs.

Every program ends one of three ways:

* **refused**: an :class:`nc.errors.InputError` (the reader's
  ``NCParseError`` and the like); its message must be one line starting
  ``FILE:LINE:COLUMN: `` -- a refusal that is not is counted as *unclear*;
* **read**: both commands finished;
* **crashed**: any other exception (``RuntimeWarning`` from numpy included:
  the tests turn them into errors), tallied by signature (type, the
  innermost frame inside the project, the message with digits folded).

Mutations: byte flips, digit runs of 1..400 digits, deleted and duplicated
words and lines, huge / NaN / inf / tiny numbers, random letters, random
codes (G2/G3 with large P among them), comment and tape characters,
truncation. Seeds include O-word programs (LinuxCNC's daisy, flowsnake and
retval samples and ``tests/nc/test_owords.py``), whose executed-line bound is
lowered here to 100,000. The address space is capped (``--mem-limit-mb``) so that a
runaway allocation is a ``MemoryError`` in seconds, not a swapped machine.

Usage: nice -n 10 python benchmarks/fuzz_gcode.py [-n 100000] [--seed 1]
       [--show 3] [--save-dir DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import glob
import io
import os
import random
import re
import resource
import sys
import tempfile
import time
import traceback
import warnings
from collections import Counter
from dataclasses import dataclass, field

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, ROOT)

from nc import constants, read_program  # noqa: E402
from nc.cli import build_parser  # noqa: E402
from nc.errors import InputError  # noqa: E402
from nc.kinematics import get_machine  # noqa: E402
from nc.path import cutter_locations  # noqa: E402

#: A mutated O-word loop that no longer ends stops after this many executed lines
#: (the reader's own bound, 5 million, takes some 18 s a program) [lines].
constants.LINUXCNC_MAX_EXECUTED_LINES = 100_000

#: The machine the programs' rotary words are turned into tool axes on.
MACHINE = get_machine("xyzac-trt")

#: LinuxCNC sample programs inside the dialect (as tests/nc/test_linuxcnc_samples.py).
LINUXCNC_SAMPLES = [
    "/usr/share/linuxcnc/ncfiles/3dtest.ngc",
    "/usr/share/linuxcnc/ncfiles/arcspiral.ngc",
    "/usr/share/linuxcnc/ncfiles/cds.ngc",
    "/usr/share/linuxcnc/ncfiles/tort.ngc",
    "/usr/share/doc/linuxcnc/examples/sample-configs/sim/gmoccapy/non_trivial_kinematics/"
    "table-rotary-tilting/examples/impeller-7bl-xyzac.ngc",
    "/usr/share/doc/linuxcnc/examples/sample-configs/sim/gmoccapy/non_trivial_kinematics/"
    "table-rotary-tilting/examples/boat-xyzac.ngc",
    # O-word control flow (nc.owords)
    "/usr/share/linuxcnc/ncfiles/daisy.ngc",
    "/usr/share/linuxcnc/ncfiles/flowsnake.ngc",
    "/usr/share/linuxcnc/ncfiles/retval.ngc",
]

#: Small programs that reach the reader's less common paths.
INLINE_SEEDS = [
    "%\nO0100 (ARCS)\nG21 G90 G17 G94\nG0 X5 Y0 Z0\nG2 I-5 J0 F100\nG3 X5 Y0 Z-2 I-5 P2\n"
    "G18 G2 X10 Z0 Y5 I5 K0\nG19 G3 Y15 Z0 J5 K0\nG17 G2 X15 Y10 R5\nG2 X5 Y10 R-5\nM30\n%\n",
    "G21 G90 G94\nG43.5 H2\nG1 X1 Y0 Z0 I0 J0 K1 F100\nG1 X2 I1 J0 K1\nG49\nM2\n",
    "G21 G90 G94\nG43.4 H1\nG1 X1 Y2 Z3 A10 C20 F100\nG1 X2 B5\nG49\nM2\n",
    "G20 G91 G93\nG1 X1 A90 F2\nG1 X.5 C-45 F4\nG94 G90 G1 X3 F10\nM30\n",
    "G21 G90 G90.1 G17\nG0 X10 Y0\nG3 X0 Y10 I0 J0 F500\nG91.1 G2 X10 Y0 I0 J-10\nM30\n",
    "G21 G90 G54\nT3 M6\nS8000 M3\nG55 G0 X1 Y1\nG56 G1 Z-1 F200\nM5\nM30\n",
    "G21 G90 G64 P0.01\nM8\nG0 X1\nG4 P0.5\nM9\nM2\n",
    "/N10 G21 G90\nN20 G0 X5 ; end comment\nN30 g1x1y2z3f50 (lower case)\nM30\n",
    # canned cycles (nc.cycles) and rotations / tilted planes (nc.rotation)
    "G21 G17 G90 G94\nS1000 M3\nF100\nG0 X0 Y0 Z10\nG98 G81 X10 Y5 Z-5 R2\nX20\n"
    "G99 G83 X30 Z-8 R1 Q2 L2\nG91 G73 X5 Y0 Z-3 R-1 Q1 K3\nG90 G82 X1 Z-1 R1 P0.5\n"
    "G85 X2\nG89 X3 P1\nG86 X4 P0\nG87 X5 Y0 Z-6 R1 I1 J0 K-3\nG84 X6 Z-2 R1\nG80\n"
    "G18 G98 G81 Z2 X3 Y-4 R1\nG19 G83 Y1 Z1 X-3 R1 Q1\nG0 Y0\nM30\n",
    "G21 G17 G90 G94\nF100\nG0 X0 Y0 Z5\nG68 X10 Y0 R90\nG1 X20 Y0\nG91 Y5\n"
    "G90 G3 X10 Y15 I-10 J0\nG81 X1 Z-1 R1\nG80\nG69\nG68 X0 Y0 Z0 I1 J0 K0 R30\nG1 Y2\n"
    "G69\nG68.2 X100 Y0 Z0 I30 J90 K-10\nG53.1\nG0 X0 Y0 Z10\nG1 Z0\nG2 X10 I5\nG69\n"
    "G0 Z100\nG0 B0 C0\nM30\n",
]

#: Options passed with a program, as a user could type them.
ALLOW = "G64,G61,G61.1,G4,M7,M8,M9,M1"

WORD = re.compile(r"[A-Za-z]\s*[-+]?(?:\d+\.?\d*|\.\d+)")
NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)")
LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
CODES = ["G0", "G1", "G2", "G3", "G4", "G17", "G18", "G19", "G20", "G21", "G28", "G40",
         "G43", "G43.4", "G43.5", "G49", "G54", "G59", "G64", "G80", "G81", "G90", "G91",
         "G73", "G83", "G87", "G98", "G99", "G68", "G68.2", "G69", "G53.1",
         "G90.1", "G91.1", "G92", "G93", "G94", "M0", "M1", "M2", "M3", "M4", "M5", "M6",
         "M8", "M9", "M30", "M98", "M99"]
SPECIAL = ["(", ")", ";", "%", "/", "#", "[", "]", "\r", "\t", "\x00", "\x0c", ".", "-",
           "+", "=", "*", "\u00b5", "\u2212", " ", "\n", "O", "E",
           # text that is not ASCII: other scripts' digits, letters whose upper case
           # is longer (sharp s, ligatures), full-width forms, unusual spaces and breaks
           "\u0663", "\uff11", "\u00df", "\ufb00", "\u0131", "\uff38", "\u00a0", "\u2028",
           "\u0085", "\u1680", "\ufeff", "\U0001d7d9"]


def interesting_number(rng: random.Random) -> str:
    """A number that tends to break readers."""
    k = rng.randint(1, 400)
    return rng.choice([
        "9" * k, "1" + "0" * k, "0." + "0" * k + "1", "-" + "9" * k, "." + "9" * k,
        "9" * k + "." + "9" * rng.randint(1, 40), "0." + "0" * rng.randint(300, 330) + "1",
        str(rng.choice([1, -1]) * 10 ** rng.randint(0, 12)),
        "nan", "NaN", "inf", "-inf", "1e308", "1e-320", "0", "-0", ".", "-.", "0.0000001",
        "10000000", "10000001", "9999999.9999", "-10000000", "2147483648", "18446744073709551616",
        str(rng.randint(0, 100)), f"{rng.uniform(-1e4, 1e4):.4f}", str(rng.randint(1, 10 ** 8)),
    ])


def _seed_texts() -> list[tuple[str, str]]:
    seeds: list[tuple[str, str]] = []
    for pattern in ("errpred/scenarios/*/*.nc", "orient/scenarios/*/*.nc",
                    "sim/scenarios/*/*.nc"):
        for path in sorted(glob.glob(os.path.join(ROOT, pattern))):
            with open(path, encoding="utf-8") as fh:
                seeds.append((os.path.relpath(path, ROOT), fh.read()))
    try:
        from tests.nc import test_gcode
        for case in test_gcode.CASES:
            seeds.append((f"tests/nc/test_gcode.py:{case[0]}", case[1]))
        for i, err in enumerate(test_gcode.ERRORS):
            seeds.append((f"tests/nc/test_gcode.py:ERRORS[{i}]", err[0]))
    except ImportError:  # pragma: no cover - the tests are not shipped
        pass
    try:
        from tests.nc import test_owords
        for name, case in test_owords.TABLE.items():
            seeds.append((f"tests/nc/test_owords.py:{name}", case[0]))
    except ImportError:  # pragma: no cover - the tests are not shipped
        pass
    for i, text in enumerate(INLINE_SEEDS):
        seeds.append((f"inline[{i}]", text))
    for path in LINUXCNC_SAMPLES:
        if os.path.exists(path):
            with open(path, encoding="utf-8", errors="replace") as fh:
                seeds.append((path, fh.read()))
    return seeds


def _window(rng: random.Random, text: str, lines: list[str]) -> str:
    """Short programs: the header, a random run of lines and the end of long seeds."""
    if len(lines) <= 80:
        return text
    start = rng.randint(12, len(lines) - 20)
    body = lines[start:start + rng.randint(5, 60)]
    return "\n".join(lines[:12] + body + lines[-4:])


def mutate(rng: random.Random, text: str) -> bytes:
    """One to five mutations of ``text`` (one, half of the time)."""
    s = text
    for _ in range(rng.choice((1, 1, 1, 1, 2, 2, 3, 5))):
        op = rng.randrange(14)
        words = list(WORD.finditer(s))
        nums = list(NUMBER.finditer(s))
        pos = rng.randint(0, len(s))
        if op == 0 and nums:  # a number replaced by an interesting one
            m = rng.choice(nums)
            s = s[:m.start()] + interesting_number(rng) + s[m.end():]
        elif op == 1:  # a digit run inserted
            s = s[:pos] + "".join(rng.choice("0123456789") for _ in range(rng.randint(1, 400))) \
                + s[pos:]
        elif op == 2 and words:  # a word deleted
            m = rng.choice(words)
            s = s[:m.start()] + s[m.end():]
        elif op == 3 and words:  # a word duplicated (here or elsewhere)
            m = rng.choice(words)
            s = s[:pos] + " " + m.group(0) + " " + s[pos:]
        elif op == 4:  # a random word, often one the reader knows
            letter = rng.choice(LETTERS if rng.random() < 0.3 else "XYZABCIJKRFPSTH")
            s = s[:pos] + f" {letter}{interesting_number(rng)} " + s[pos:]
        elif op == 5:  # a random code
            s = s[:pos] + f" {rng.choice(CODES)} " + s[pos:]
        elif op == 6:  # an arc with turns
            p = rng.choice([str(rng.randint(1, 20)), interesting_number(rng)])
            g, r = rng.choice([2, 3]), rng.choice([0.001, 1, 5, 500, interesting_number(rng)])
            if rng.random() < 0.5:  # a full circle: no end point
                arc = f"G{g} I{r} P{p} F100"
            else:
                arc = (f"G{g} X{rng.randint(-50, 50)} Y{rng.randint(-50, 50)} "
                       f"I{rng.randint(-50, 50)} J{rng.randint(-50, 50)} P{p} F100")
            s = s[:pos] + "\n" + arc + "\n" + s[pos:]
        elif op == 7:  # a special character
            s = s[:pos] + rng.choice(SPECIAL) + s[pos:]
        elif op == 8:  # a random letter
            s = s[:pos] + rng.choice(LETTERS + LETTERS.lower()) + s[pos:]
        elif op == 9:  # truncation
            s = s[:pos]
        elif op == 10:  # lines duplicated or swapped
            lines = s.split("\n")
            i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
            if rng.random() < 0.5:
                lines.insert(j, lines[i])
            else:
                lines[i], lines[j] = lines[j], lines[i]
            s = "\n".join(lines)
        elif op == 11 and nums:  # a letter replaced by another letter
            m = rng.choice(words) if words else None
            if m is not None:
                s = s[:m.start()] + rng.choice(LETTERS) + s[m.start() + 1:]
        elif op == 12 and words:  # a code's number replaced (G2 -> G2.5, G1 -> G999...)
            m = rng.choice(words)
            s = s[:m.start() + 1] + rng.choice(["", "0", "00"]) + interesting_number(rng) \
                + s[m.end():]
        else:  # bytes: flip one, or insert a random byte
            b = bytearray(s.encode("utf-8", "surrogatepass"))
            if b and rng.random() < 0.5:
                i = rng.randrange(len(b))
                b[i] = rng.randrange(256)
            else:
                b.insert(min(pos, len(b)), rng.randrange(256))
            return bytes(b)  # may not be text any more: no further text mutations
    return s.encode("utf-8", "surrogatepass")


@dataclass
class Tally:
    """How the programs ended, and the crashes by signature."""

    programs: int = 0
    refused: int = 0
    read: int = 0
    crashed: int = 0
    unclear: int = 0
    refusals: Counter = field(default_factory=Counter)
    messages: Counter = field(default_factory=Counter)
    signatures: Counter = field(default_factory=Counter)
    examples: dict = field(default_factory=dict)
    unclear_examples: list = field(default_factory=list)
    slowest: tuple = (0.0, b"")


def _signature(exc: BaseException) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    inside = [f for f in frames if f.filename.startswith(ROOT)
              and not f.filename.endswith("fuzz_gcode.py")]
    where = f"{os.path.relpath(inside[-1].filename, ROOT)}:{inside[-1].lineno}" if inside \
        else "?"
    msg = re.sub(r"\d+", "N", str(exc).split("\n")[0])[:80]
    return f"{type(exc).__name__} at {where}: {msg}"


def run_one(data: bytes, path: str, parser, rng: random.Random) -> BaseException | None:
    """``python -m nc parse`` and ``parse --json`` on ``data``, then the program's
    cutter locations (as errpred and orient take them) on a 5-axis machine or on
    none; the exception, if any."""
    with open(path, "wb") as fh:
        fh.write(data)
    extra = []
    if rng.random() < 0.3:
        extra += ["--allow", ALLOW]
    if rng.random() < 0.2:
        extra.append("--block-delete")
    sink = io.StringIO()
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(sink):
            warnings.simplefilter("error", RuntimeWarning)
            for argv in (["parse", path, *extra], ["parse", path, "--json", *extra]):
                args = parser.parse_args(argv)
                args.func(args)
            prog = read_program(path, allow=ALLOW.split(",") if extra[:1] == ["--allow"]
                                else (), block_delete="--block-delete" in extra)
            cutter_locations(prog, MACHINE if rng.random() < 0.7 else None)
    except Exception as exc:  # noqa: BLE001 - the point is to classify every exception
        return exc
    return None


def fuzz(n: int, seed: int = 1, workdir: str | None = None, tally: Tally | None = None,
         progress: float = 0.0) -> Tally:
    """Run ``n`` mutated programs; deterministic for a given ``seed``.

    Parameters
    ----------
    n : int
        Number of programs.
    seed : int
        Seed of the mutations and of the options.
    workdir : str, optional
        Directory for the program file (a temporary one by default).
    progress : float [s]
        Print a progress line this often on stderr; 0 for none.
    """
    rng = random.Random(seed)
    seeds = [(text, text.split("\n")) for _, text in _seed_texts()]
    parser = build_parser()
    tally = tally or Tally()
    t_last = time.monotonic()
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        path = os.path.join(tmp, "fuzz.nc")
        for k in range(n):
            text, lines = rng.choice(seeds)
            data = mutate(rng, _window(rng, text, lines))
            t0 = time.perf_counter()
            exc = run_one(data, path, parser, rng)
            dt = time.perf_counter() - t0
            tally.programs += 1
            if dt > tally.slowest[0]:
                tally.slowest = (dt, data)
            if exc is None:
                tally.read += 1
            elif isinstance(exc, InputError):
                tally.refused += 1
                tally.refusals[type(exc).__name__] += 1
                msg = str(exc)
                tally.messages[re.sub(r"[-+.\d]+", "N", msg.split(": ", 1)[-1])[:50]] += 1
                if "\n" in msg or not re.match(re.escape(path) + r":\d+:\d+: ", msg):
                    tally.unclear += 1
                    if len(tally.unclear_examples) < 20:
                        tally.unclear_examples.append((msg, data))
            else:
                tally.crashed += 1
                sig = _signature(exc)
                tally.signatures[sig] += 1
                if sig not in tally.examples or len(data) < len(tally.examples[sig]):
                    tally.examples[sig] = data
            if progress and time.monotonic() - t_last > progress:
                t_last = time.monotonic()
                print(f"  {k + 1:,} programs: {tally.crashed} crashed", file=sys.stderr,
                      flush=True)
    return tally


def report(tally: Tally, wall_s: float, show: int = 3) -> str:
    out = [f"programs {tally.programs:,}: refused {tally.refused:,} "
           f"({', '.join(f'{k} {v:,}' for k, v in tally.refusals.most_common())}), "
           f"read {tally.read:,}, crashed {tally.crashed:,}; unclear refusals "
           f"{tally.unclear:,}; wall {wall_s:.1f} s "
           f"({tally.programs / max(wall_s, 1e-9):,.0f} programs/s); slowest program "
           f"{tally.slowest[0] * 1e3:.0f} ms"]
    for sig, count in tally.signatures.most_common():
        out.append(f"  {count:6d}  {sig}")
        ex = tally.examples[sig]
        out.append("          e.g. " + repr(ex[:300]) + (" ..." if len(ex) > 300 else ""))
    if show:
        out.append("  most common refusals: " + "; ".join(
            f"{m!r} {c}" for m, c in tally.messages.most_common(2 * show)))
    for msg, data in tally.unclear_examples[:show]:
        out.append(f"  unclear: {msg!r:.200} from {data[:120]!r}")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("-n", type=int, default=100_000, help="number of programs")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--mem-limit-mb", type=int, default=3000,
                    help="address-space cap of this process [MB]")
    ap.add_argument("--show", type=int, default=3, help="unclear refusals to show")
    ap.add_argument("--save-dir", help="write one example program per crash signature here")
    args = ap.parse_args(argv)
    cap = args.mem_limit_mb * 2 ** 20
    resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
    t0 = time.perf_counter()
    tally = fuzz(args.n, args.seed, progress=60.0)
    wall = time.perf_counter() - t0
    print(report(tally, wall, args.show))
    if args.save_dir:
        os.makedirs(args.save_dir, exist_ok=True)
        for i, (sig, data) in enumerate(tally.examples.items()):
            with open(os.path.join(args.save_dir, f"crash-{i:02d}.nc"), "wb") as fh:
                fh.write(data)
    return 1 if tally.crashed else 0


if __name__ == "__main__":
    sys.exit(main())
