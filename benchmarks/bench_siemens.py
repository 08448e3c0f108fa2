"""Lines per second of the Siemens Sinumerik reader on a generated 100k-line program.

The program mixes what CAM writes for an 840D: numbered G1 lines with and
without feed, rapids, G2/G3 arcs with I J (and CR=), R-parameter
arithmetic and (with --five-axis) TRAORI blocks with A3= B3= C3= tool
vectors. With --loops the program is a short one whose FOR, WHILE and
IF/ELSE blocks run a zigzag of moves (``loop_program``): its speed is given in
blocks executed (and moves) per CPU-second, since it has few lines.
Run: ``PYTHONPATH=. python benchmarks/bench_siemens.py [--five-axis | --loops]``.
"""

from __future__ import annotations

import argparse
import math
import time

import nc.siemens
from nc.siemens import parse_siemens


def program(n_lines: int, five_axis: bool = False) -> str:
    out = ["%_N_BENCH_MPF", ";$PATH=/_N_MPF_DIR", "G17 G90 G71 G94 G642", "T1 M6", "D1",
           "S12000 M3", "CYCLE832(0.01,_ORI_FINISH,1)", "R1=-1.5"]
    if five_axis:
        out.append("TRAORI")
    i = 0
    px = py = 0.0  # where the last move ended (arcs start there)
    while len(out) < n_lines - 1:
        x, y = 50 + 40 * math.cos(i * 1e-3), 50 + 40 * math.sin(i * 1e-3)
        k = i % 10
        if k in (8, 9):
            x, y = px, py
        if five_axis:
            b = math.radians(20 + 10 * math.sin(i * 1e-2))
            c = math.radians((i * 0.1) % 360)
            out.append(f"G1 X{x:.4f} Y{y:.4f} Z{-1 - (i % 7) * 0.1:.4f} "
                       f"A3={math.sin(b) * math.cos(c):.7f} B3={math.sin(b) * math.sin(c):.7f} "
                       f"C3={math.cos(b):.7f} F1200")
        elif k < 6:
            out.append(f"G1 X{x:.4f} Y{y:.4f} Z=R1" + (" F1500" if k == 0 else ""))
        elif k == 6:
            out.append("G0 Z5.")
        elif k == 7:
            out.append("G1 Z-1.5 F800")
        elif k == 8:
            out.append(f"G2 X{x:.4f} Y{y - 4:.4f} I0 J-2 ; half circle")
            y -= 4
        else:
            out.append(f"G3 X{x:.4f} Y{y + 4:.4f} CR=2")
            y += 4
        if k != 6 and k != 7:
            px, py = x, y
        i += 1
    out.append("M30")
    return "\n".join(ln if ln.startswith((";", "%")) else f"N{10 * (j + 1)} {ln}"
                     for j, ln in enumerate(out)) + "\n"


def loop_program(n_moves: int) -> str:
    """A zigzag of about ``n_moves`` moves made by loops: FOR over rows, WHILE over
    columns, IF/ELSE for the direction, R and DEF variables with SIN."""
    cols = 500
    rows = max(1, n_moves // cols)
    return f"""%_N_BENCHLOOP_MPF
;$PATH=/_N_MPF_DIR
N10 G17 G90 G71 G94 G642
N20 T1 M6
N30 S12000 M3
N40 DEF INT ROW, COL
N50 DEF REAL XX, YY
N60 G0 X0 Y0 Z5
N70 G1 Z-1 F1500
N80 FOR ROW=0 TO {rows - 1}
N90   YY=ROW*0.5
N100  COL=0
N110  WHILE COL<{cols}
N120    IF ROW MOD 2 == 0
N130      XX=COL*0.2
N140    ELSE
N150      XX=({cols}-1-COL)*0.2
N160    ENDIF
N170    G1 X=XX Y=YY Z=-1-0.1*SIN(COL*3)
N180    COL=COL+1
N190  ENDWHILE
N200 ENDFOR
N210 G0 Z50
N220 M30
"""


def _bench_loops(n_moves: int) -> None:
    text = loop_program(n_moves)
    counts: list[int] = []
    run = nc.siemens.run

    def counting(*args):
        counts.append(run(*args))
        return counts[-1]

    nc.siemens.run = counting
    best = math.inf
    try:
        for _ in range(3):
            t0 = time.process_time()
            prog = parse_siemens(text)
            best = min(best, time.process_time() - t0)
    finally:
        nc.siemens.run = run
    print(f"{text.count(chr(10))} lines, {counts[-1]:,} blocks executed, {len(prog):,} moves: "
          f"{best:.2f} CPU s, {counts[-1] / best:,.0f} blocks and {len(prog) / best:,.0f} "
          "moves per CPU-second")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--lines", type=int, default=100_000)
    ap.add_argument("--five-axis", action="store_true")
    ap.add_argument("--loops", action="store_true",
                    help="a program of loops making --lines moves")
    a = ap.parse_args()
    if a.loops:
        _bench_loops(a.lines)
        return
    text = program(a.lines, a.five_axis)
    best = math.inf
    for _ in range(3):
        t0 = time.process_time()
        prog = parse_siemens(text)
        best = min(best, time.process_time() - t0)
    n = text.count("\n")
    print(f"{n:,} lines, {len(prog):,} moves: {best:.2f} CPU s, "
          f"{n / best:,.0f} lines per CPU-second")


if __name__ == "__main__":
    main()
