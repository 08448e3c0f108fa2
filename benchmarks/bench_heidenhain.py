"""Lines per second of the Heidenhain reader on a generated 100k-line program.

The program mixes what CAM writes: L lines with and without feed, rapid
moves, CC + C arcs, polar CP arcs and (with --five-axis) TCPM L X Y Z B C
blocks. Run: ``PYTHONPATH=. python benchmarks/bench_heidenhain.py``.
"""

from __future__ import annotations

import argparse
import math
import time

from nc.heidenhain import parse_heidenhain


def program(n_lines: int, five_axis: bool = False) -> str:
    out = ["BEGIN PGM BENCH MM", "BLK FORM 0.1 Z X+0 Y+0 Z-40", "BLK FORM 0.2 X+100 Y+100 Z+0",
           "TOOL CALL 1 Z S12000", "M3"]
    if five_axis:
        out.append("FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS")
    i = 0
    while len(out) < n_lines - 2:
        x, y = 50 + 40 * math.cos(i * 1e-3), 50 + 40 * math.sin(i * 1e-3)
        k = i % 10
        if five_axis:
            out.append(f"L X{x:+.4f} Y{y:+.4f} Z{-1 - (i % 7) * 0.1:+.4f} "
                       f"B{20 + 10 * math.sin(i * 1e-2):+.4f} C{(i * 0.1) % 360:+.4f} F1200")
        elif k < 6:
            out.append(f"L X{x:+.4f} Y{y:+.4f} Z-1.0000 R0" + (" F1500" if k == 0 else ""))
        elif k == 6:
            out.append(f"L Z+5 FMAX")
        elif k == 7:
            out.append("CC IX+0 IY-2")
        elif k == 8:
            out.append("C IX+0 IY-4 DR+")
        else:
            out.append("CP IPA-90 DR- ; polar")
        i += 1
    out += ["M30", "END PGM BENCH MM"]
    return "\n".join(f"{j} {b}" for j, b in enumerate(out)) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--lines", type=int, default=100_000)
    ap.add_argument("--five-axis", action="store_true")
    a = ap.parse_args()
    text = program(a.lines, a.five_axis)
    best = math.inf
    for _ in range(3):
        t0 = time.process_time()
        prog = parse_heidenhain(text)
        best = min(best, time.process_time() - t0)
    n = text.count("\n")
    print(f"{n:,} lines, {len(prog):,} moves: {best:.2f} CPU s, "
          f"{n / best:,.0f} lines per CPU-second")


if __name__ == "__main__":
    main()
