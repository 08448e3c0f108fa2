"""Tolerances and defaults of the ``nc`` package, in one place.

Every number a kernel compares against lives here, with its unit in the name
and the reason beside it. Change a default here, not in the middle of a
function.
"""

from __future__ import annotations

import math

#: Millimetres per inch (exact, by definition).
MM_PER_INCH = 25.4

# --- reader -----------------------------------------------------------------

#: Start and end radius of an IJK arc may differ by this much before the block
#: is refused, whatever the radius [mm]. LinuxCNC's rule, kept so that a
#: program LinuxCNC accepts is accepted here too.
ARC_RADIUS_TOL_ABS_MM = 0.005
#: ... or by this fraction of the radius, if that is larger [-].
ARC_RADIUS_TOL_REL = 1.0e-3
#: ... but never by more than this [mm].
ARC_RADIUS_TOL_MAX_MM = 0.5
#: An R-form arc whose chord exceeds 2|R| by less than this is taken as a
#: half circle (rounding in the programmed digits) [mm]; beyond it the arc is
#: impossible and refused.
ARC_R_CHORD_TOL_MM = 1.0e-3
#: Largest absolute coordinate or feed accepted from a program, in program
#: units. Anything beyond is a typo or an overflow, not a machine [-].
MAX_ABS_WORD_VALUE = 1.0e7

#: Most moves one canned-cycle block may expand into (L repeats times the
#: pecks of Q): a typo such as Q0.0001 on a deep hole is refused before any
#: work, not expanded into millions of rows [-].
MAX_CYCLE_MOVES = 100_000
#: ... and all cycle blocks of one program together: a short program of modal
#: repeats of such a block must not fill the memory (a real program drilling
#: ten thousand holes makes some 50 000) [-].
MAX_CYCLE_MOVES_PROGRAM = 1_000_000
#: Chords the reader may make of arcs in tilted planes (G68.2, 3-D G68) in one
#: program, all arcs together: rows the reader holds as Python lists, so the
#: same bound as the cycles' [-].
MAX_TILTED_ARC_CHORDS = 1_000_000
#: G68.2 P2: the three points must span a plane; below this sine of the angle
#: at the first point (about 0.06 deg) the plane's normal would be set by the
#: points' rounding rather than by the programmer [-].
TILT_POINTS_MIN_SIN = 1.0e-3
#: G68.2 P3: how far from perpendicular the X and Z directions may be. Posts
#: write unit vectors with 3-6 decimals, which leaves up to about 0.09 deg; the
#: reader keeps Z and takes X's part perpendicular to it. Fanuc accepts up to
#: 5 deg, but which vector it keeps was not found in its text, so a larger
#: deviation is refused [deg].
TILT_VECTORS_ANGLE_TOL_DEG = 0.1
#: G73/G83: how far above the last depth the tool rapids back before the
#: next peck, LinuxCNC's G83_RAPID_DELTA (0.010 in), in mm [mm].
CYCLE_PECK_RETRACT_MM = 0.254

#: Error messages are one line; a run of more digits than this (a 400-digit
#: word quoted back) is shown as its first digits and its length [digits] ...
ERROR_MAX_DIGITS = 20
#: ... and a message longer than this is cut [characters].
ERROR_MAX_CHARS = 400
#: Characters of the source line shown around the column by
#: ``NCParseError.excerpt`` [characters].
ERROR_EXCERPT_CHARS = 100

#: Smallest F word other than 0 [program units per minute, deg/min, or 1/min
#: under G93]. A block of 1 mm at this feed takes 10^6 min (two years): a
#: typo, and a time worked out from a feed ~1e-310 overflows to infinity.
MIN_FEED = 1.0e-6

#: Most turns ``P`` of one G2/G3 block (LinuxCNC's helical turns) [turns].
#: Helical entries and bores take a few to a few hundred turns; every turn is
#: expanded into chords downstream (``CHORD_TOL_MM``), so a P of millions is a
#: typo that would fill the memory, refused where it is read.
MAX_ARC_TURNS = 1000

#: Codes the reader understands and treats as asserting the state it assumes
#: (cutter compensation off, no canned cycle, program end/stop). They need no
#: ``allow`` option.
IMPLIED_DEFAULT_CODES = frozenset({"G40", "G80", "M0", "M1", "M2", "M30"})

#: Heidenhain reader: most blocks executed in one read, counting every pass
#: through a label repeat or subprogram, before the read stops with an error
#: (a loop that does not end, or repeats nested too deep) [-].
TNC_MAX_EXECUTED_BLOCKS = 20_000_000
#: ... and deepest nesting of subprogram calls (CALL LBL without REP) [-].
TNC_MAX_CALL_DEPTH = 19

#: Siemens reader: most blocks executed in one read, counting every pass through
#: a GOTOB loop, before the read stops with an error (a loop that does not end) [-].
SIEMENS_MAX_EXECUTED_BLOCKS = 20_000_000
#: ... most passes of one loop (WHILE FOR LOOP REPEAT/UNTIL counted from its
#: last entry; a jump back, the times in a row it is taken) and most repetitions
#: one REPEAT/REPEATB may ask for (P=): more than a loop in an NC program makes
#: (10^6 passes of a one-line body is already 10^6 moves), few enough that a
#: loop whose condition never changes is refused in seconds (1-10 s on two
#: shared cores; longer if it moves the tool) rather than after
#: SIEMENS_MAX_EXECUTED_BLOCKS [passes].
SIEMENS_MAX_LOOP_PASSES = 1_000_000
#: ... deepest nesting of running section repeats (REPEAT/REPEATB inside a
#: repeated section); it stops a section that repeats itself through a second
#: REPEAT long before memory runs out [-].
SIEMENS_MAX_REPEAT_DEPTH = 16

#: LinuxCNC O-word programs (nc.owords): most lines executed in one read,
#: counting every pass through a loop and every line of a called subroutine,
#: before the read stops with an error (a loop that does not end). LinuxCNC's
#: largest sample (flowsnake.ngc) runs some 37 000 lines and a roughing loop
#: of 100 000 moves some 500 000; a runaway loop with an expression per line
#: reaches this in about 18 s here (measured 3.7 s per million) [lines].
LINUXCNC_MAX_EXECUTED_LINES = 5_000_000
#: ... deepest nesting of O-word subroutine calls: LinuxCNC's
#: INTERP_SUB_ROUTINE_LEVELS (10 levels with the main program; rs274 refuses
#: the 10th nested call) [calls].
LINUXCNC_MAX_CALL_DEPTH = 9
#: ... arguments of one call, #1-#30 (LinuxCNC's INTERP_SUB_PARAMS) [-].
LINUXCNC_SUB_ARGS = 30

# --- paths ------------------------------------------------------------------

#: Chord tolerance when arcs are expanded into lines [mm].
CHORD_TOL_MM = 1.0e-3
#: Most chords one arc block may be expanded into [chords]. The count is
#: |sweep| / (2 acos(1 - tol / r)), ~ turns x pi sqrt(2 r / tol): 1000 turns of
#: radius 40 mm at 1 um give 0.44 million; more is a radius or turn count
#: nobody cuts, refused (file, line) before any point is made.
MAX_ARC_CHORDS = 1_000_000
#: Most points of a whole program's expansion [points]. A point takes about
#: 170 bytes while it is made on a straight block, 210 on an arc (measured:
#: tracemalloc peak of expand_arcs and summarize), so at most 3.4 to 4.2 GB;
#: a program of 10^6 blocks may average 20 points per block. Beyond: refused
#: (file, line) before any point is made.
MAX_PATH_POINTS = 20_000_000
#: Tool-axis vectors from a file must have unit length within this [-].
UNIT_VECTOR_TOL = 1.0e-6

# --- kinematics -------------------------------------------------------------

#: Half-angle of the cone around the free rotary axis inside which the free
#: axis is held instead of solved [rad] (0.001 rad = 0.057 deg).
SINGULAR_CONE_RAD = 1.0e-3
#: Largest deviation of the tool tip from the programmed straight line while
#: the machine axes move linearly between two points [mm].
LINEARIZE_TOL_MM = 2.0e-3
#: Largest number of bisections of one segment during linearization [-].
LINEARIZE_MAX_DEPTH = 12

# --- writer -----------------------------------------------------------------

#: Decimals written for linear axes (mm) and rotary axes (deg) and vectors.
LINEAR_DECIMALS = 4
ANGLE_DECIMALS = 4
VECTOR_DECIMALS = 6
#: Feed used for moves that only turn rotary axes, in G94 [deg/min].
ROTARY_ONLY_FEED_DEG_MIN = 3600.0
#: Rotary motion below this counts as "no rotary motion" when the writer
#: decides between G93 and G94 [rad].
ROTARY_STILL_RAD = math.radians(1.0e-6)
#: Decimals of the unit vectors (LN NX..TZ) in written Heidenhain programs:
#: the TNC's input allows 7 [-].
TNC_VECTOR_DECIMALS = 7
#: Largest coordinate a TNC accepts (its input format, 5 digits and 4
#: decimals) [mm] ...
TNC_MAX_COORDINATE_MM = 99_999.9999
#: ... and largest feed [mm/min] or spindle speed [rev/min] (5 digits, 3 decimals).
TNC_MAX_FEED = 99_999.999

#: Decimals of the A3= B3= C3= tool vector in written Sinumerik programs: as the
#: TNC's, 7 keep the read-back angle within 1e-5 deg [-].
SIEMENS_VECTOR_DECIMALS = 7
#: Largest coordinate [mm], feed [mm/min] or speed [rev/min] the Sinumerik
#: writer puts in a word: below the reader's MAX_ABS_WORD_VALUE, so that every
#: written program reads back [-].
SIEMENS_MAX_WORD = 9_999_999.0

# --- kinematics (nc.kinematics, nc.machines) --------------------------------

#: A joint may pass its limit by this much before it counts as outside
#: (rounding in the inverse kinematics) [rad] ...
LIMIT_TOL_RAD = 1.0e-9
#: ... and a linear axis by this much [mm].
LIMIT_TOL_MM = 1.0e-9
#: The squared sine that decides whether a tool axis is reachable by the two
#: rotary axes may be this negative (rounding) before the orientation counts
#: as unreachable [-].
REACH_TOL = 1.0e-12
#: Tilt and rotary axes of a machine, and the tilt axis and the tool axis,
#: must be at least this far from parallel [rad].
MIN_AXIS_ANGLE_RAD = 1.0e-3
#: Interior fractions of each segment (k / (N + 1), k = 1..N) at which
#: linearization checks the tip deviation [-] ...
LINEARIZE_CHECKS = 7
#: ... and of each half made by bisection, short enough for its deviation
#: to be a smooth bump [-].
LINEARIZE_CHECKS_BISECTED = 3
#: Singular points tried (closest to the free axis first) when the path solver
#: looks for a place to flip to the other solution [-].
SINGULAR_FLIP_TRIES = 64
#: A singular point whose rotary joints are farther than this from the ones
#: holding the rotary axis at its neighbour's value is reached by a flip;
#: linearization then turns the rotary axis at that point [rad].
FLIP_TOL_RAD = 1.0e-9
#: Linearization bisects a segment when its estimated deviation exceeds
#: (1 - this) x the tolerance: the sampled estimate (parabola through the
#: largest samples) can fall short of the true peak by ~0.2 % [-].
LINEARIZE_MARGIN = 0.02
#: Linearization may grow a path to this many points per input point ...
LINEARIZE_MAX_POINTS_PER_POINT = 16
#: ... plus this many, before it gives up with a clear error [-].
LINEARIZE_MAX_POINTS_EXTRA = 10_000

#: LinuxCNC's EQ and NE compare within this (its TOLERANCE_EQUAL; rs274 gives
#: [1 EQ 1.00001] = 1) [same units as the operands]
MACRO_EQ_TOL = 1.0e-4

#: Fanuc macro B expansion (nc.macro_b): most blocks executed in one read,
#: counting every pass through a WHILE loop, GOTO and subprogram repeat, before
#: the read stops with an error (a loop that does not end). At ~2-5 us a block
#: in Python this bounds a runaway program to tens of seconds, while a real
#: macro program (a bolt circle, a pocket of a few thousand passes) executes
#: far fewer [blocks].
MACRO_B_MAX_EXECUTED_BLOCKS = 5_000_000
#: ... and deepest nesting of M98/M97 subprogram and G65 macro calls together:
#: Fanuc controls nest at most 10 subprogram levels and 5 macro levels, so a
#: deeper chain is a call that recurses without end [calls].
MACRO_B_MAX_CALL_DEPTH = 15
