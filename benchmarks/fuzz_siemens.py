"""Seeded fuzzer of the Siemens Sinumerik reader and of what follows it.

Mutates a Sinumerik program written here (header, R parameters and DEF
variables, arcs with I J K / CR= / TURN=, SUPA, TRAORI with A3= B3= C3=,
CYCLE800 axis by axis, projection and solid angle, TRANS/AROT, ROTS, DC() on a
rotary axis, an IF ... GOTOB loop, IF/ELSE/ENDIF, WHILE, FOR, REPEAT/UNTIL, LOOP,
REPEAT label P=, REPEATB, ENDLABEL, GOTOC) by deleting, inserting and
replacing characters, and runs each mutant through
:func:`nc.siemens.parse_siemens`, :func:`nc.summary.summarize` and
:func:`nc.path.cutter_locations` (on a table-table B/C machine).

Every program ends one of three ways: **refused** (an
:class:`nc.errors.InputError` whose message is one line starting
``f.mpf:``; a refusal that is not is counted as *unclear*), **read**, or
**crashed** (any other exception; the first few are printed).

Usage: nice -n 10 python benchmarks/fuzz_siemens.py [-n 10000] [--seed 7]
"""

from __future__ import annotations

import argparse
import random
import time
import traceback

import nc.constants as K
from nc.errors import InputError
from nc.kinematics import get_machine
from nc.path import cutter_locations
from nc.siemens import parse_siemens
from nc.summary import summarize

BASE = """%_N_FUZZ_MPF
;$PATH=/_N_MPF_DIR
N10 G17 G90 G71 G94 G642
N20 T="BALL6" M6
N30 D1 S12000 M3
N40 DEF REAL DEPTH=2, STEP
N50 DEF INT NN=3
N60 R1=5 R2=R1*2+1 STEP=DEPTH/2
N70 G1 X10 Y0 Z0 F500
N80 G3 X0 Y10 I-10 J0
N90 G1 X=R1 Y=R2 Z=-DEPTH F=R2*10
N100 G2 X=IC(0) Y=IC(0) I=AC(0) J=AC(0) Z=IC(-STEP) TURN=1
N110 CYCLE800(1,"TC1",0,57,0,0,0,0,30,0,0,0,0,-1,100,1)
N120 G1 X5 Y5 Z0
N130 G2 X10 Y5 CR=2.5
N140 CYCLE800()
N150 SUPA G0 Z100 D0
N160 TRAORI
N170 G1 X1 Y2 Z3 A3=0 B3=0.6 C3=0.8 F800
N180 X2 A3=0.1 C3=1
N190 TRAFOOF
N200 TRANS X5 Y5
N210 AROT Z30
N220 G1 X=10*COS(60) Y=ATAN2(1,1) Z=ROUND(2.5)
N230 TRANS
N240 G1 C=DC(20)
N250 NN=NN DIV 2 MSG("done; ok")
N252 R3=0
N254 AGAIN: R3=R3+1 G1 X=R3
N256 IF (R3<4) AND NOT (R3==9) GOTOB AGAIN
N258 GOTOF N260
N259 G1 X99
N260 CYCLE800(1,"TC1",0,185,0,0,0,20,-15,30,0,0,0,-1,100,1)
N262 G1 X2 Y2 Z0
N264 CYCLE800(1,"TC1",1,64,0,0,0,45,10,0,0,0,0,-1,100,1)
N266 G1 X1
N268 CYCLE800()
N270 ROTS X10 Y20
N272 G1 X3 Y1
N274 ROTS
N276 R4=0
N278 WHILE R4<3
N280 R4=R4+1
N282 IF R4==2
N284 G1 Y=R4
N286 ELSE
N288 G1 Y=-R4
N290 ENDIF
N292 ENDWHILE
N294 FOR R5=1 TO 3
N296 G1 Z=-R5
N298 ENDFOR
N300 REPEAT
N302 R4=R4-1
N304 UNTIL R4<=0
N306 LOOP
N308 R4=R4+1 G1 X=R4
N310 IF R4>2 GOTOF OUT
N312 ENDLOOP
N314 OUT: G91 X1
N316 ENDLABEL: Y1
N318 REPEAT OUT P=2
N320 REPEATB OUT P=1
N321 G90
N322 GOTOC NOWHERE
N324 M30
"""
ALPHABET = "GXYZABCIJKRFMNTDS+-.=()\"',;:/$*[] 0123456789\n"


def fuzz(n: int, seed: int, show: int = 3, max_blocks: int = 100_000,
         max_passes: int = 10_000) -> dict:
    """Mutate ``BASE`` ``n`` times; tallies of refused, read, unclear, crashed.

    ``max_blocks`` replaces ``SIEMENS_MAX_EXECUTED_BLOCKS`` while fuzzing: a mutant
    whose loop never ends is refused after that many blocks, not 2*10^7; ``max_passes``
    replaces ``SIEMENS_MAX_LOOP_PASSES`` the same way.
    """
    K.SIEMENS_MAX_EXECUTED_BLOCKS = max_blocks
    K.SIEMENS_MAX_LOOP_PASSES = max_passes
    rng = random.Random(seed)
    machine = get_machine("xyzbc-trt")
    tally = dict(refused=0, read=0, unclear=0, crashed=0)
    for _ in range(n):
        s = list(BASE)
        for _ in range(rng.randint(1, 6)):
            k = rng.randrange(len(s))
            op = rng.random()
            if op < 0.4:
                del s[k]
            elif op < 0.8:
                s.insert(k, rng.choice(ALPHABET))
            else:
                s[k] = rng.choice(ALPHABET)
        text = "".join(s)
        try:
            prog = parse_siemens(text, file="f.mpf")
            summarize(prog)
            if len(prog):
                cutter_locations(prog, machine)
            tally["read"] += 1
        except InputError as exc:
            msg = str(exc)
            ok = "\n" not in msg and msg.startswith("f.mpf")
            tally["refused" if ok else "unclear"] += 1
        except Exception:  # noqa: BLE001 - a crash is what the fuzzer counts
            tally["crashed"] += 1
            if tally["crashed"] <= show:
                print("crash on:\n" + text)
                traceback.print_exc()
    return tally


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("-n", type=int, default=10_000)
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args()
    t0 = time.perf_counter()
    tally = fuzz(a.n, a.seed)
    print(f"{a.n:,} programs (seed {a.seed}): {tally['refused']:,} refused, "
          f"{tally['read']:,} read, {tally['unclear']:,} unclear, {tally['crashed']:,} "
          f"crashed; {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
