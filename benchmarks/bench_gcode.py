"""Reader throughput on a CAM-style 3-axis finishing program.

Generates a raster finishing program over a smooth freeform surface (ball
end mill, zig-zag passes joined by G3/G2 turn-arounds, modal coordinates
written only when they change, 3 decimals, as CAM posts write them), then
times :func:`nc.read_program` on it.

Prints: lines, lines per second, peak memory of the parse (tracemalloc), and
the ratio to a baseline run in the same process: Python's own ``re.findall``
tokenization of the same text, which is a floor for any pure-Python reader.
Then the same kind of program with LinuxCNC '#' expressions (nc.macro), and a
LinuxCNC O-word program (nc.owords): a sub with a while loop and an if per
move, called once per pass, timed as moves and expanded lines per second.

Usage: python benchmarks/bench_gcode.py [--lines N] [--repeat R]
"""

from __future__ import annotations

import argparse
import math
import os
import re
import statistics
import sys
import tempfile
import time
import tracemalloc

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from nc import read_program  # noqa: E402
from nc.owords import expand_owords  # noqa: E402


def oword_program(passes: int) -> str:
    """A LinuxCNC raster finish written with O-words: 400 moves per pass [mm]."""
    return "\n".join([
        "G21 G90 G17", "#<_step>=0.05", "o<pass> sub", "  #<k>=0",
        "  o10 while [#<k> LT 400]", "    #<x>=[#<k>*#<_step>]", "    o11 if [#2 LT 0]",
        "      #<x>=[[399-#<k>]*#<_step>]", "    o11 endif",
        "    G1 X#<x> Z[2*SIN[#<x>/7*57.29578]*COS[#1/5*57.29578]-3] F1500",
        "    #<k>=[#<k>+1]", "  o10 endwhile", "o<pass> endsub",
        "G0 X0 Y0 Z25", "G1 Z2 F2000", "#<y>=0 #<d>=1", f"o1 repeat [{passes}]",
        "  G1 Y#<y>", "  o<pass> call [#<y>] [#<d>]", "  #<y>=[#<y>+0.4] #<d>=[-#<d>]",
        "o1 endrepeat", "G0 Z25", "M30", ""])


def finishing_program(n_lines: int) -> str:
    """A raster finishing program of about ``n_lines`` lines [mm]."""
    out = ["%", "O1001 (FREEFORM FINISH R3 BALL)", "G21 G17 G90 G94 G40 G49 G80",
           "T5 M6", "G54", "S12000 M3", "G43 H5", "G0 X0. Y0. Z25.", "G1 Z2. F2000."]
    step_x, pick = 0.05, 0.4
    per_pass = 400
    y = 0.0
    direction = 1
    lastz = None
    n = 0
    f_first = True
    while len(out) < n_lines:
        for k in range(per_pass):
            x = (k if direction > 0 else per_pass - 1 - k) * step_x
            z = 2.0 * math.sin(x / 7.0) * math.cos(y / 5.0) - 3.0
            words = [f"X{x:.3f}"]
            if k == 0:
                words.append(f"Y{y:.3f}")
            zs = f"Z{z:.3f}"
            if zs != lastz:
                words.append(zs)
                lastz = zs
            if k == 0:
                words.insert(0, "G1")
            if f_first:
                words.append("F1500.")
                f_first = False
            out.append(" ".join(words))
            n += 1
        # turn-around: a half circle to the next pass
        r = pick / 2
        code = "G3" if direction > 0 else "G2"
        out.append(f"{code} Y{y + pick:.3f} I0. J{r:.3f}")
        y += pick
        direction = -direction
    out += ["G0 Z25.", "M5", "G49", "M30", "%"]
    return "\n".join(out) + "\n"


def macro_b_program(n_moves: int) -> str:
    """The finishing raster of :func:`finishing_program` as a Fanuc macro B program:
    a WHILE loop of G65 calls, one per pass, each pass a WHILE loop of 400 G1
    blocks; about ``n_moves`` moves, 5 executed blocks a move [mm]."""
    passes = max(1, n_moves // 400)
    return f"""%
O1000 (MACRO B RASTER)
G21 G17 G90 G94 G40 G49 G80
G0 X0. Y0. Z25.
G1 Z2. F2000.
#100=0
WHILE [#100 LT {passes}] DO1
G65 P9000 Y[#100*0.4]
#100=#100+1
END1
G0 Z25.
M30
O9000 (ONE PASS, Y=#25)
#10=0
WHILE [#10 LT 400] DO2
#24=#10*0.05
G1 X#24 Y#25 Z[2.*SIN[#24/7.*57.2957795]*COS[#25/5.*57.2957795]-3.] F1500.
#10=#10+1
END2
M99
%
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lines", type=int, default=120_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    text = finishing_program(args.lines)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "finish.nc")
        with open(path, "w") as fh:
            fh.write(text)
        n_lines = text.count("\n")
        token = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))|(\S)")
        best_base = math.inf
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            with open(path) as fh:
                for line in fh.read().splitlines():
                    token.findall(line.upper())
            best_base = min(best_base, time.perf_counter() - t0)
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            prog = read_program(path)
            times.append(time.perf_counter() - t0)
        best = min(times)
        # the same program with LinuxCNC parameters: every X word an expression
        macro = path + ".ngc"
        with open(macro, "w") as fh:
            # (without the O number line, which with '#' would make it Fanuc macro B)
            body = re.sub(r"(?m)^O\d+.*\n", "", text)
            fh.write("#1=0\n" + re.sub(r"X(-?[\d.]+)", r"X[\1+#1]", body))
        macro_times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            read_program(macro)
            macro_times.append(time.perf_counter() - t0)
        # Fanuc macro B: the raster made by WHILE loops and G65 calls (nc.macro_b)
        fanuc = path + ".fanuc.nc"
        with open(fanuc, "w") as fh:
            fh.write(macro_b_program(n_lines))
        macro_b_times, macro_b_cpu = [], []
        for _ in range(args.repeat):
            t0, c0 = time.perf_counter(), time.process_time()
            macro_b_moves = len(read_program(fanuc))
            macro_b_times.append(time.perf_counter() - t0)
            macro_b_cpu.append(time.process_time() - c0)
        oword = path + ".oword.ngc"
        with open(oword, "w") as fh:
            fh.write(oword_program(max(1, args.lines // 1200)))
        oword_times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            oprog = read_program(oword)
            oword_times.append(time.perf_counter() - t0)
        with open(oword) as fh:
            expanded = len(expand_owords(fh.read().split("\n"), oword)[0])
        tracemalloc.start()
        read_program(path)
        _, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
    print(f"program: {n_lines} lines, {len(prog)} motion blocks, "
          f"{len(text) / 1e6:.1f} MB")
    print(f"read_program: {best * 1e3:.0f} ms best of {args.repeat} -> "
          f"{n_lines / best:,.0f} lines/s (target >= 200,000)")
    print(f"read_program: min {n_lines / max(times):,.0f} / median "
          f"{n_lines / statistics.median(times):,.0f} / max {n_lines / best:,.0f} lines/s "
          f"over {args.repeat} repeats")
    print(f"read_program, X words as '#' expressions (nc.macro): median "
          f"{n_lines / statistics.median(macro_times):,.0f} lines/s, best "
          f"{n_lines / min(macro_times):,.0f} lines/s")
    mb = statistics.median(macro_b_times)
    print(f"read_program, Fanuc macro B raster (nc.macro_b, WHILE + G65, 5 executed blocks "
          f"a move): {macro_b_moves} moves, median {macro_b_moves / mb:,.0f} produced "
          f"lines/s ({5 * macro_b_moves / mb:,.0f} executed blocks/s), best "
          f"{macro_b_moves / min(macro_b_times):,.0f} lines/s; median "
          f"{macro_b_moves / statistics.median(macro_b_cpu):,.0f} lines per CPU-second")
    ot = statistics.median(oword_times)
    print(f"read_program, LinuxCNC O-word program (nc.owords: sub, while, if per move): "
          f"{len(oprog)} moves from {expanded} expanded lines; median "
          f"{len(oprog) / ot:,.0f} moves/s, {expanded / ot:,.0f} expanded lines/s")
    print(f"baseline re.findall tokenize only: {best_base * 1e3:.0f} ms -> "
          f"{n_lines / best_base:,.0f} lines/s; reader/baseline time ratio "
          f"{best / best_base:.2f}")
    print(f"peak memory during parse (tracemalloc): {peak / 1e6:.1f} MB "
          f"({peak / n_lines:.0f} B/line, source text included)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
