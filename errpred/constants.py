"""Defaults and tolerances of the ``errpred`` package, in one place.

Resolution defaults are the ones shown to converge by
``tests/errpred/test_convergence.py`` (the predicted error at the default is
within 0.5 um of the value at a 4x finer setting on the bundled scenarios).
"""

from __future__ import annotations

import math

# --- resolution (see docs/method.md §9) -----------------------------------
#: Pixel size of the depth buffer, as a fraction of the tool diameter [-].
PIXEL_PER_DIAMETER = 1.0 / 64.0
#: Micro edges along the lower envelope (bottom face + corner arc) [-].
MICRO_EDGES_ENVELOPE = 80
#: Rotation step of the engagement and force computation [rad].
ANGLE_STEP_RAD = math.radians(2.0)
#: Chord tolerance when arcs are expanded into lines [mm]. The chords cut
#: up to this much deeper than the arc between their ends, which shifts the
#: finished surface and the error by as much: well below the micrometre.
CHORD_TOL_MM = 2.5e-4

# --- geometry ---------------------------------------------------------------
#: A point closer than this to a sweep's or the stock's boundary counts as
#: on it (inside) [mm]. Keeps flat-floor contacts from flickering.
MEMBERSHIP_EPS_MM = 1.0e-6
#: Cell side of the sweeps' height map (errpred.zmap) [mm]: its bounds are off
#: the true boundary by about curvature x cell^2 / 8 (0.25 um for a 5 mm ball at
#: 0.1 mm), and samples that close to a boundary are left to the exact test;
#: a smaller cell answers more of them, at more cells to fill per sweep.
ZMAP_CELL_MM = 0.1
#: Cells a side of the height map's tiles, allocated where queries ask [-].
ZMAP_TILE_CELLS = 32
#: Tiles the height map keeps at most (least recently used dropped first, to
#: be filled again if asked for): 2,048 tiles of 32 x 32 cells of 18 values
#: hold 302 MB, a part of 92 x 92 mm at 0.1 mm; the state kept for going back
#: (errpred.zmap) doubles it [-].
ZMAP_MAX_TILES = 2048
#: A run uses the height map where the sweeps before its first block, not yet in
#: the map, are at most this many a block of the run [-]. The map saves about 1-5
#: ms a block (mold-ball raster, contour); its catch-up, each tile the run
#: touches filled with the earlier sweeps that reach it (ZMAP_JUMP_SWEEPS), took
#: 3.5-4.5 s for the 101-167 tiles along the 300-block bench slices (every tile,
#: as before, 14.5-16.2 s: about 1 ms a sweep), so such a slice still loses.
ZMAP_CATCHUP_PER_BLOCK = 2
#: A query this many sweeps or more after the height map's time is a jump [-]:
#: the sweeps skipped are not inserted into every tile they reach, but into each
#: tile a later query touches, when it does (a stage-1 worker's next chunk skips
#: the other workers' chunks; a run may start far into the program). Below it
#: every tile follows (eager insertion, the tests' reference). 1: every query is
#: a jump, so a new sweep goes only into the tiles a query touches, when it does:
#: at 32 (consecutive blocks inserted eagerly) inserting a block's sweep into the
#: ~20 tiles a D10 ball reaches was 10 % of stage 1 on the mold-ball contour slice
#: (1.3 ms a sweep), and the queries touch only the tiles on the stock's side.
#: bench_errpred.py, one core, the median of two repeats, two runs in turn (with
#: FEW_SWEEPS): contour 54.6 and 56.3 -> 59.2 and 61.5 blocks/s, raster 62.6 and
#: 64.6 -> 69.7 and 71.5; check_geometry_same.py --blocks 60 --dense: the same bytes.
ZMAP_JUMP_SWEEPS = 1
#: A tile filled with at most this many sweeps (caught up after a jump, or new at
#: a map time this small) tests each one's bounds; with more, the sweep index is
#: asked, whose grid gives every sweep of the program near the tile, the later
#: ones then dropped (on the mold-ball raster, with the index alone, the catch-ups'
#: look-ups took 4 % of a stage-1 worker's samples) [-]. The same sweeps either way.
ZMAP_SCAN_SWEEPS = 4096
#: The sweeps' height map is made where at least this share of the sweeps have one
#: axis (every one in a 3-axis program, a 3+2 program's tilted one, a 5-axis
#: program's most common posture): it holds those, in a frame whose z is that axis,
#: and the others are tested exactly. Where many sweeps are of other axes a point's
#: earlier sweeps are mostly those, and the map only adds its filling: the bundled thin
#: wall's most common axis has 61 % of its sweeps (all in its last pass), and with the
#: map its planned program's dense stage 1 took 24.3 s against 21.1 s without; the
#: mold core's planned program keeps the vertical axis in 59 % of its sweeps, and its
#: first 5,000 blocks took 53.4 s against 47.6 s. A 3+2 program (all of them) gains
#: x1.08-1.29 (benchmarks/bench_tilted.py). Shares between were not measured [-].
ZMAP_AXIS_SHARE = 0.75
#: Rounding allowance of the height map's decisions [mm]: far above the
#: closed forms' rounding (~1e-12 mm), far below a cell.
ZMAP_GUARD_MM = 1.0e-5
#: Side of the cubes into which points are binned before their membership
#: tests, so that each bin tests only the sweeps that can reach it [mm].
#: Smaller bins give shorter lists (a bin's list holds the sweeps within its
#: radius of its points) at more list-making; the answers are the same at any
#: size. CPU of a dense prediction, 0.2 -> 0.05 mm (one process, same statuses
#: and E): the planned 5-axis mold core's blocks 9000-9149 and 18000-18149
#: 4.95 -> 2.92 s, mold-ball contour and raster slices 6.14 -> 4.39 and
#: 4.93 -> 3.34 s, the planned thin wall 16.1 -> 15.0 s, wall-radius 4.07 ->
#: 3.79 s (0.1 and 0.03 mm: within noise of 0.05, neither better on all). Measured
#: again on 2026-11-28 (the recent sweeps' pass since; membership bins alone at 0.2
#: mm, the margins' kept at 0.05, two runs each): 3-6 % less on the slices and the
#: thin wall, 25-30 % more on the mold core's blocks (1.9 -> 2.4-2.5 s).
CLUSTER_CELL_MM = 0.05
#: Bins are grouped into cubes of this many bins a side; a bin's sweeps are
#: picked from its cube's, which are picked from all (two levels instead of
#: every bin against every sweep: a finishing raster has ~2,000 sweeps within
#: a tool's reach) [-].
CLUSTER_COARSE = 8
#: Coarse cubes are grouped into super cubes of this many a side, a level
#: between all the sweeps and a coarse cube's: without it each coarse cube
#: tested every sweep near the points (the wall-radius slice: ~2,100 sweeps,
#: ~30 coarse cubes a call, most of a membership call's time) [-].
CLUSTER_SUPER = 4
#: A bin's points go first against this many sweeps that held points of the
#: bins before (latest first); only a bin with a point none of them holds gets
#: its short list and the exact tests against it [-].
CLUSTER_RECENT = 8
#: A membership test against at most this many sweeps tests each point against
#: each of them, without binning (:func:`errpred._cluster_kernels.inside_any_sweep_clustered`):
#: on the mold-ball slices, the current move's sweeps past the height map (one
#: sweep, ~790 points a call) took 0.26 ms a call binned [-].
FEW_SWEEPS = 4
#: Before binning, points are tested against a few sweeps likely to hold many
#: of them (in finishing, the moves just behind the tool and the pass before),
#: picked in HOT_ROUNDS rounds: each round, of the first HOT_SEED_SWEEPS sweeps
#: (nearest first), the one holding the most of HOT_SEED_POINTS points spread
#: over those left (fewer where fewer are left) [-]. Only the points none of
#: them holds are binned. Ball end mills (a closed-form test) take more of each;
#: other tools' tests are searches, so fewer (wall-radius, a corner radius, took
#: x1.45 the time with the ball's figures). Measured on the calls recorded from stage 1 (the same answers; min of
#: six runs each, in turn with the former seed, the first of 16 sweeps to hold one
#: of the first 4 points): the thin wall's planned program (5-axis ball) x0.69-0.75,
#: mold-ball contour x0.87-0.93, raster x0.96, wall-radius x0.97.
HOT_SEED_SWEEPS = 16
HOT_SEED_POINTS = 16
HOT_ROUNDS = 1
HOT_SEED_SWEEPS_BALL = 64
HOT_SEED_POINTS_BALL = 48
HOT_ROUNDS_BALL = 3
#: The margins' first pass (errpred._cluster_kernels.sweep_margin_clustered): the
#: first of HOT_SEED_SWEEPS sweeps to hold one of this many points spread over the
#: candidates [-]. The rounds above do not pay there (recorded calls, min of six
#: runs in turn: three rounds x1.21 on the thin wall, x1.06 on the contour; one
#: round of 16 or 32 sweeps and points, two rounds, or 8 points x0.99-1.13): few
#: points lie deep enough inside one sweep for the pass to decide them.
MARGIN_SEED_POINTS = 4
#: Stock membership by vertical rays looks up the triangles over a point in a
#: grid of (x, y) columns: at most this many columns along the longer side
#: [-] ...
COLUMNS_PER_AXIS = 512
#: ... coarsened until no more than this many (triangle, column) entries are
#: listed (8 bytes each: 16 MB) [-]. A ray then tests the few triangles above
#: its column (mold-ball stock: 2.2 -> see bench; a coarse 3-d grid cell put
#: ~950 triangles in every column of the wall-radius stock).
COLUMN_ENTRIES = 2_000_000
#: A tooth's engagement should span at least this many rotation steps; a
#: shorter one (a light cut) is recomputed with a finer step ...
ENGAGEMENT_MIN_STEPS = 16
#: ... divided by at most this [-].
ENGAGEMENT_MAX_REFINE = 8
#: On the engagement's boundary each sample's cell is sub-sampled this many
#: times in rotation ...
ENGAGEMENT_SUBSTEPS = 8
#: ... and this many times along the micro edge [-].
ENGAGEMENT_SUBEDGES = 4
#: The stock's surface seen in a view is interpolated between pixel centres
#: where it is tilted less than this from the view plane; steeper surfaces
#: (walls) are decided by the mesh itself [rad].
STOCK_INTERPOLATION_SLOPE_RAD = math.radians(60.0)
#: Tool-axis change inside one sweep segment above which the segment is
#: split so that each piece has a nearly constant axis [rad].
SWEEP_AXIS_STEP_RAD = math.radians(1.0)
#: Two tool axes are taken as parallel where the sine of the angle between them is
#: below this [-] (``errpred.sweeps.slerp``: straight interpolation there, where the
#: turning formula divides by that sine).
PARALLEL_AXES_SIN = 1e-12
#: Cell of the uniform grid over the sweeps' bounds, in tool radii [-]. A query
#: (the tool near one point, ~2 radii wide) is answered by the cells it overlaps and
#: then by each sweep's bounds exactly, so the cell changes only the speed: a sweep's
#: bounds span ~2 radii across and up to the flute length high, and cells of 2.5
#: radii visit each near sweep in fewer cells than cells of one radius. Measured on
#: the mold-ball slices (10 mm ball, Sweeps.near per point): 1.28 -> 0.96 ms
#: (contour), 0.98 -> 0.62 ms (raster), index 13.9 -> 5.3 MB; 2 and 3 radii within
#: 10 % of it.
SWEEP_GRID_CELL_PER_RADIUS = 2.5

# --- prediction -------------------------------------------------------------
#: Blocks longer than this get a prediction point in each of equal parts
#: no longer than it (method.md section 3: long blocks, several points) [mm].
#: Default: one point per stretch of a block that cuts (one per block, as the seeds
#: do, where the whole block cuts). More points show how the
#: error varies along a long block, but a correction that moves only the
#: block's ends cannot follow that variation (the bundled wall, 44 mm lines
#: between corners: a third of the largest error removed when the
#: corner-affected ends of the lines count too), so the largest error then
#: mixes in what no rewrite of the block's end points can correct.
POINT_SPACING_MM = math.inf
#: Spacing of the dense verification's prediction points along every block (both
#: ends included) [mm]: a corrected program is re-predicted this densely before it
#: is written (the corrected path's vertices and everything between them).
VERIFY_SPACING_MM = 2.0
#: A block up to this share longer than a whole number of point spacings keeps that
#: number of parts (its points up to 1 % farther apart than the spacing) [-]. A CAM
#: program's moves are often exactly the spacing long (the bundled thin wall's 2 mm
#: moves), and a correction lengthens them by micrometres: at a slack of 1e-9 each
#: such move of a candidate got two points where the original's had one (the main
#: job's candidates: 2,588 cutting points against the planned program's 1,569, their
#: dense predictions that much slower), and the candidate was sampled elsewhere than
#: the original it is compared with.
POINT_SPACING_SLACK = 0.01
#: A feed move within this angle of the tool axis is a plunge (or a retract): the
#: dense points predict the corner at its end as the next move's start [rad].
PLUNGE_ANGLE_RAD = math.radians(45.0)
#: Whole-block pre-check: the tool is tested for material at stations this many
#: tool diameters apart along every block (a quarter diameter: an island of stock
#: that the tool's swept band crosses over more than a quarter of its diameter is
#: met at a station) [-].
PRECHECK_STEP_PER_DIAMETER = 0.25
#: A block's tool positions share one look-up of the sweeps near them (a box
#: holding every position's, each position then keeps those overlapping its own
#: box: the same sweeps) where the block's cutter locations span at most this
#: many tool diameters; a longer block's box would hold too many [-].
SHARED_LOOKUP_SPAN_PER_DIAMETER = 4.0
#: Padding of that box beyond the positions' boxes [mm]: far above the rounding
#: of a tool position between cutter locations (~1e-15 mm), so that every
#: position on a block with a constant axis lies inside it.
SHARED_LOOKUP_PAD_MM = 1.0e-6
#: That box grown by this many tool diameters on every side, so that the blocks after
#: it share it while their boxes lie inside (a finishing contour's or raster's short
#: blocks: replayed look-ups of the bench slices, 0.9 -> 0.17 ms a contour point and
#: 0.63 -> 0.20 ms a raster point with 3 mm on a 10 mm tool; 0.1 mm: most blocks
#: outside the box before; 0.5 mm: the box holds more sweeps than it saves) [-].
SHARED_LOOKUP_GROW_PER_DIAMETER = 0.3
#: A block's stage 1 is taken from the program before (errpred.repredict) only
#: where no changed sweep's bounds come within this of its look-up box [mm]: far
#: above the bounds' rounding (~1e-12 mm), so a sweep the look-up could have met
#: is never missed; reuses a little less than exactly possible.
REUSE_BOX_PAD_MM = 1.0e-3
#: ... and where a block's cutting stretch begins or ends, between a station that cuts
#: and one that does not, is found by this many halvings (to 1/8 of the step: the
#: stretch's length, which sets the wear it adds, within 0.6 mm for a D20 tool) [-].
PRECHECK_BISECTIONS = 3
#: The pre-check tests flute 0's micro-edge samples at every this-many rotation
#: steps (a coarse engagement: 4 deg at the default 2 deg step) [-].
PRECHECK_ROTATION_STRIDE = 2
#: Stage 2's carried state (wear, the largest error) is kept every this many blocks of
#: a prediction, so that the next program of a correction takes its points window by
#: window while its blocks are the same (errpred.repredict, predict.Follow): a state is
#: one wear array (a few kB); a window that differs runs stage 2 for all its blocks [-].
STAGE2_STATE_BLOCKS = 64
#: The pre-check tests the tool shrunk by this much (toward its axis and up) [mm]:
#: samples on an earlier sweep's boundary (a slot's walls and floor) are no cut
#: whatever the rounding of the membership tests (~1e-5 mm for non-ball tools).
PRECHECK_INSET_MM = 1.0e-3
#: A rapid move counts as "into material" only where the tool shrunk by this much
#: still meets the stock [mm]: positioning onto the stock's surface is no crash.
RAPID_TOUCH_MM = 0.01
#: Above the flutes (errpred.geometry.PointGeometry.above_flutes): the shank is
#: tested at this many angles on a ring a pixel above the flutes' end [-] (10 degrees
#: apart: a D10 shank's ring samples 0.87 mm apart, finer than any step-over that
#: leaves a wall the shank could rub) ...
ABOVE_FLUTES_SAMPLES = 36
#: ... the ring's radius smaller than the shank's (or the tool's, if smaller) by
#: this much [mm]: a shank running along a wall an earlier pass's flutes cut is
#: no contact whatever the rounding (as RAPID_TOUCH_MM for a rapid).
ABOVE_FLUTES_INSET_MM = 0.01
#: The pre-check's sample sets kept (one per set of micro edges under the stock's
#: top and inset, each ~10k x 3 floats at the default resolution) before the cache
#: is emptied [-]: a block's stations mostly share one set.
PRECHECK_SAMPLE_SETS = 8
#: A corrected program may be worse than the original by at most this much at any
#: point of the dense verification (larger |E|, or a deeper overcut) [um]: below the
#: prediction's own convergence (0.5 um at the default resolution) plus margin.
VERIFY_TOLERANCE_UM = 1.0
#: ... and a corrected program may cut deeper than the original and than the
#: nominal surface (E below min(E_original, 0)) by at most this much [um]: an
#: overcut cannot be mended, but iterating ends within the prediction's own noise
#: (0.5 um) on either side of zero, so a correction that takes 10 um of undercut to
#: 1.5 um of overcut is no harm; 2 um is the finish tolerance's order, not the
#: error's.
VERIFY_OVERCUT_UM = 2.0
#: Verification: an error of the corrected program is compared with the original's
#: interpolated along the path between its two nearest points, if they are at most
#: this many dense spacings apart (else the nearest within one spacing) [-].
VERIFY_BRACKET_SPACINGS = 2.5
#: ... and a point within this many spacings of one of the original's is at the same
#: place: compared with that one alone [-].
VERIFY_SAME_PLACE = 0.05
#: Sensitivities dE/dx beyond this are not trusted for the correction's size [-]
#: (a move of E / (1 - gain) cancels E to first order).
MAX_GAIN = 0.5
#: The correction's fit (errpred/offset.py): weight of the second-difference rows
#: against a point's equation [-]. A uniform or linearly varying error is followed
#: exactly whatever the weight; an error alternating from one point to the next (noise,
#: or a zigzag) is followed to 1 / (1 + 16 x 0.5) = 11 % per pass; a step (a wall's
#: end) is spread over about two point spacings.
OFFSET_SMOOTH = 0.5
#: ... made edge-preserving: a second difference of the moves of this size gets half
#: the weight (squared), a larger one less: a real step of the error (a wall's end, the
#: tool leaving the material: 36 -> 0 um over 2 mm on the bundled thin wall) is
#: followed instead of dragging the exit's vertex 4.5 um into the wall, while noise of
#: a micrometre or so is still damped [um] ...
OFFSET_EDGE_UM = 4.0
#: ... by this many reweighted solves (Cauchy weights) [-].
OFFSET_EDGE_ITERATIONS = 2
#: ... and of the rows holding each vertex's move along its surface normal [-] (a
#: component across it changes no error: without them the few points whose normals
#: tilt would buy tiny improvements with large slides along the wall).
OFFSET_NORMAL = 1.0
#: ... and of a held point's equation (no move there: the fallback's last resort where a
#: candidate was worse; the smoothing would otherwise carry the neighbours' moves
#: across a point that asks for none) [-].
OFFSET_HOLD = 100.0
#: ... and of the ridge on every move [-] (no component that no equation asks for).
OFFSET_RIDGE = 1.0e-6
#: ... and of the rows holding a full circle's start on the moved circle [-].
OFFSET_STIFF = 1.0e3
#: A vertex on which the points weigh less than this many points (a point at share t of
#: a segment weighs 1 - t on its start and t on its end) is interpolated from its
#: neighbours along the chain (first differences on both its segments) instead of
#: being fitted: its only equation would be a point barely on a segment, whose move
#: m = residual / t runs away (on the whole mold core, a point at t = 0.045 of a
#: chain's last segment asking 6.4 um moved the chain's end 143.9 um); or nothing at
#: all would tie it to one side (the last vertex of a stretch without points before a
#: point at the far end of the next segment: on the mold core such vertices kept a
#: neighbouring stretch's 18.9 um beside points asking 8 um, and the candidate cut
#: 9.6 um too deep where the pass began to finish the surface) [-].
OFFSET_PIN = 0.5
#: A line block is split (points inserted) where the moves its points ask for depart
#: from a straight line in the path length by more than this [mm]: two end points
#: cannot follow an error that changes inside the block (a wall's end).
SPLIT_TOL_MM = 1.0e-3
#: Decimals of the corrected program's changed words, per unit mode (G21 mm, G20 inch)
#: [-]: a tenth of a micrometre in mm (4), a quarter in inch (5: 0.00001 in = 0.254 um).
#: Four in an inch program, the correction moved in steps of 2.54 um (tried as a new
#: user on a public inch raster program: a +2.00 um error was corrected to -1.81 um).
CORRECTION_DECIMALS = {21: 4, 20: 5}
#: Iteration of the correction: each pass adds this share of the new fit's moves
#: (under-relaxation: halved after a pass that did not improve, doubled after one that
#: did, up to 1) [-]. Below 1 at first: the first pass knows the error's response to a
#: move only from the model's first-order gain, which overshoots where passes share a
#: surface (a full circle's two levels: a move of the error took 24 um of undercut to
#: 5 um of overcut); from the second pass on the measured slope guides the step.
RELAXATION = 0.7
#: The secant dE/dshift between two candidates is measured only where the path moved
#: at least this much along the normal [um] ...
SECANT_MIN_SHIFT_UM = 0.3
#: ... and clipped to this range [-] (1 - gain of the model: 1 where the error
#: follows the path exactly; 0.5 where deeper cutting bends the tool back half, the
#: model's own bound, 1 - MAX_GAIN). A smaller measured slope is mostly a point the path
#: hardly governs (another pass finishes it, a slot's full-width end), where 1 / slope
#: multiplies the error: with 0.25 the next pass asked for four times it (a public slot
#: program: 242 um for a 77 um error, each such candidate rejected), and on the bundled
#: thin wall the second pass moved 27.3 um against 18.7 um with 0.5, which ended better
#: (predicted RMS 0.653 -> 0.589 um, simulated ratio 0.234 -> 0.230, 8 -> 7 dense
#: predictions).
SECANT_SLOPE_RANGE = (0.5, 2.0)
#: Where a candidate is worse than the original, the moves wanted by the points near
#: there are scaled down this many times, then those points held (verified each time)
#: [-]. The share kept is the one that would bring the worse point half a tolerance
#: inside its band were the error linear in the move ...
FALLBACK_SCALINGS = 1
#: ... at most this [-]: a step the linear estimate calls nearly harmless is still cut
#: by a tenth (the response is not linear near a wall's end).
FALLBACK_SCALE_MAX = 0.9
#: A fallback refits the moves near the worse points only: a vertex more than this many
#: vertices along its chain from a unit whose points' weights changed keeps the rejected
#: candidate's move exactly, and the vertices between are fitted to it (so the path
#: changes near the worse points only, and its dense prediction recomputes there only:
#: errpred.repredict). A whole refit moved every vertex of the chains a little (on the
#: whole mold core the first fallback recomputed 22,297 of 28,219 blocks). The fit's
#: smoothing (OFFSET_SMOOTH) couples a vertex to its neighbours: a change of the wanted
#: moves decays along the chain by about a factor 0.45 a vertex (measured on a raster
#: chain of 0.25 mm units, 3 points each: 5 % of the change 2 vertices on, 1e-4 after
#: 8), so the whole refit would have moved the vertices held by less than a ten-thousandth
#: of the change (0.01 um for a 100 um move); the local and the whole refit agree within
#: a thousandth of the change (tests/errpred/test_offset.py) [-].
FALLBACK_FREE_VERTICES = 8
#: ... "near": within this many tool radii of a worse point (at least one dense
#: spacing; the pass beside or below can finish the same surface) [-].
FALLBACK_REACH_RADII = 0.25
#: Extra stock thickness along the normal with which the error's sensitivity
#: to the correction is evaluated (a finite difference) [mm].
SENSITIVITY_STEP_MM = 2.0e-3
#: A 5-axis path's prediction points are placed on the path by the nearest
#: cutter location in tip and axis together: one radian of axis counts as this
#: many mm of tip (errpred/correct_path.py; about a ball's diameter, so a
#: point's own pass wins over another pass whose tilted tips run nearby) [mm].
LOCATE_AXIS_MM = 10.0
#: ... the path sampled at most this far apart for that search [mm] (a long block is
#: found from its middle, not only from its ends).
LOCATE_SAMPLE_MM = 0.5
#: Below this angle between tool axis and surface normal the cutting speed
#: at the generation point is too small for the force model (flat floors cut
#: by the ball's tip); no prediction is made there [rad].
MIN_AXIS_NORMAL_ANGLE_RAD = math.radians(5.0)
#: View correction: contact angle above which the bottom view is replaced by
#: a view toward the cutting region's normal [rad] (seeds: 60 deg).
VIEW_CORRECTION_KAPPA_RAD = math.radians(60.0)
#: Zoom factor of the corrected view [-].
VIEW_ZOOM = 8.0
#: The side view, which needs only its finished pixels, tests its in-stock pixels
#: first against this many sweeps of T2, those starting nearest the tip (the tool's
#: own path ahead, which holds nearly all of the cutting region: the front of the
#: tool), then against T1, then against the rest of T2: the same pixels, but the
#: cutting region is not refuted against every sweep of T1 first [-] (1, 3, 8
#: measured on the planned 5-axis mold-core program's side views: T1 and T2 took
#: about half the time at 3, a little more at 1 and 8).
SIDE_T2_FIRST_SWEEPS = 3
#: How far the side view's kernels' hits may lie from their numpy twins'
#: (``errpred/_side_kernels.py``; the same arithmetic, numpy's BLAS sums in another
#: order) [mm]: a few ulps of world coordinates up to ~1 m (ulp 1.1e-13 mm; measured
#: 5.9e-13 mm on the mold-core program's views), far below any pixel ...
SIDE_HITS_TOL_MM = 1e-11
#: ... and their angles [rad]: ``arctan2``/``arccos`` of arguments that differ by
#: that rounding divided by a radius of at least ~1 mm (1e-11 rad), away from the
#: ball's pole: there ``arccos`` of (r - z) / r turns a rounding dz of z into
#: sqrt(2 dz / r) (3.7e-7 rad for dz 1e-13 mm, r 1.5 mm), so the tests compare the
#: contact angle's cosine within ``SIDE_HITS_TOL_MM`` per mm of radius there.
SIDE_HITS_TOL_RAD = 1e-7

# --- the local Dask cluster (errpred/cluster.py) ---------------------------------
#: glibc malloc settings of the local cluster's workers [bytes]: trim threshold and mmap
#: threshold (mallopt M_TRIM_THRESHOLD, M_MMAP_THRESHOLD). Dask's default,
#: MALLOC_TRIM_THRESHOLD_=65536, hands freed memory back at once and pins the mmap
#: threshold at 128 kB, so every array above it is mapped and unmapped again (page
#: faults): the bundled error prediction of 1,200 blocks took 30 s with it against 17 s
#: with these, at the same peak memory (260 MB).
WORKER_MALLOC_TRIM_BYTES = 128 << 20
WORKER_MALLOC_MMAP_BYTES = 32 << 20
#: How long the main job waits for a local worker it starts again to drop numba's
#: compiler memory (``errpred.cluster.restart_compiled_workers``) [s]: one takes
#: 0.6-2.7 s here; past this the work goes on without it (Dask's default: 120 s).
WORKER_RESTART_TIMEOUT_S = 30.0

# --- tool wear (errpred/tool_state.py) -----------------------------------------
#: A tool-state file matches the scenario's tool when its diameter, corner
#: radius and micro-edge positions agree within this [mm]: the file stores
#: them with every digit, so only another tool or another resolution differs
#: by more (the micro edges of neighbouring ``resolution.micro_edges``
#: settings are hundredths of a millimetre apart).
TOOL_STATE_MATCH_MM = 1.0e-6

#: Chunks of blocks a Dask worker may have submitted ahead of the one being
#: taken [-]: enough to keep it busy while the client takes results in order,
#: few enough that the workers hold a few chunks' results, not a pass's
#: (every chunk's future used to be held until the pass ended: 2.1-2.6 GB a
#: worker in the main job).
DASK_CHUNKS_IN_FLIGHT = 3
#: Stage 1 on worker processes or a Dask cluster (``errpred.predict``): consecutive
#: blocks go to a worker as one task, the tasks shrinking toward the end of the run
#: (guided: the blocks left over ``WORKER_CHUNK_SHARE`` times the workers, between
#: ``WORKER_CHUNK_MIN_BLOCKS`` and ``WORKER_CHUNK_MAX_BLOCKS``) [blocks, -]. Equal chunks
#: of a quarter of a worker's share (38 blocks on the 300-block bench slices) left a
#: worker idle for up to a chunk at the end and the parent's stage 2 of the last chunk
#: after both (together 7 % of the run's wall time with 2 workers on the raster slice);
#: the first and largest chunks keep a worker on consecutive blocks (its sweep look-up
#: and the sweeps' height map go forward), the last ones are a block or two.
WORKER_CHUNK_MAX_BLOCKS = 64
WORKER_CHUNK_MIN_BLOCKS = 2
WORKER_CHUNK_SHARE = 4
#: Chunks a worker process may have submitted ahead of the one the parent takes [-]
#: (``concurrent.futures`` pool; the Dask cluster's is ``DASK_CHUNKS_IN_FLIGHT``): the
#: results wait in order for the parent's stage 2, so memory stays flat in program length.
POOL_CHUNKS_IN_FLIGHT = 3

# --- limits of a scenario's values (errpred/limits.py; checked when it is loaded) --------
# Each bounds a value that would otherwise run for hours or exhaust memory before any
# answer, or that no real end mill has: a scenario beyond one is refused at once.
#: Memory one prediction process may plan for the arrays that a resolution implies
#: (one point's bottom and side views and its micro-edge samples over a revolution,
#: estimated at their worst: the side view over the whole flute length) [bytes]. The
#: machine has 24 GiB for two worker processes and the parent; the convergence test's
#: setting (every discretization 4x finer) estimates 2.9 GB on mold-ball and fits.
MEMORY_BUDGET_BYTES = 4 << 30
#: What one pixel of a view costs [bytes]: the bottom template's per-pixel arrays
#: (measured: 89 bytes a pixel, mold-ball's tool at D/64 and D/256) plus a view's four
#: float64 intervals and the rasterizer's depth buffers, rounded up.
BYTES_PER_PIXEL = 256
#: What one micro-edge sample of a revolution costs [bytes]: the template's (measured:
#: about 100 bytes a sample) and a point's per-revolution arrays (cutting, weights,
#: shifts, the T1 memo, forces), rounded up.
BYTES_PER_SAMPLE = 1024
#: Most flutes an end mill in a scenario may have [-] (solid end mills have 2-8,
#: large high-feed ones up to about 12).
MAX_FLUTES = 24
#: Largest tool diameter [mm] (end mills beyond 100 mm are face mills, not modelled).
MAX_TOOL_DIAMETER_MM = 200.0
#: Longest tool length (flute length, overhang, holder) [mm].
MAX_TOOL_LENGTH_MM = 2000.0
#: Most micro edges along the envelope [-] (the default is 80; the convergence test
#: shows 4x finer changes the error by less than 0.5 um).
MAX_MICRO_EDGES = 2000
#: Largest rotation step [deg]: the engagement needs several steps per tooth pitch
#: (errpred.engagement.revolution_angles refuses more than 90).
MAX_ANGLE_STEP_DEG = 90.0
#: Finest chord tolerance for arcs [mm]: 10 nm, 25 times below the default; finer
#: only multiplies the chords of every arc.
MIN_CHORD_TOL_MM = 1.0e-5
#: Closest spacing of prediction points along a block [mm]: every point costs a full
#: engagement; 0.01 mm is a fifth of the dense verification's spacing.
MIN_POINT_SPACING_MM = 1.0e-2
#: Most predict-correct passes of an iterated correction [-].
MAX_CORRECTION_ITERATIONS = 100
#: Largest mesh file read [bytes]: 1 GiB of STL is 20 million triangles, beyond what
#: the triangle grid and the interference check can hold in the memory budget.
MAX_MESH_FILE_BYTES = 1 << 30
#: Largest cutting coefficient in magnitude [N/mm^2 for chip, N/mm for edge, N/mm^2
#: per m for wear growth]: hardened steels and titanium have chip coefficients of
#: 2,000-6,000 N/mm^2; 1e5 is beyond any metal, and near 1e300 the forces overflow.
MAX_CUTTING_COEFFICIENT = 1.0e5
#: Highest natural frequency of a tool or workpiece mode [Hz]: tool-tip modes are
#: 0.5-10 kHz; a mode far above the tooth frequencies only adds static compliance.
MAX_MODE_FREQUENCY_HZ = 1.0e5
#: Largest modal damping ratio [-]: structural modes are under-damped (0.5-10 %); a
#: ratio above 1 has no resonance left.
MAX_DAMPING_RATIO = 1.0
#: Stiffest mode [N/m]: a tool tip is 1e6-1e8 N/m; 1e12 is rigid for any cut.
MAX_STIFFNESS_N_M = 1.0e12
#: Largest modal mass [kg] and damping [N s/m] (a machine column: hundreds of kg).
MAX_MODE_MASS_KG = 1.0e4
MAX_MODE_DAMPING_NS_M = 1.0e7
#: Largest static compliance [m/N] (1e-3 m/N: a millimetre per newton, rubber).
MAX_STATIC_COMPLIANCE_M_N = 1.0e-3
#: Fastest wear, radius lost per metre of actual cutting distance [um/m]: 1 mm/m
#: wears a tool out within a metre (representative rates are 0.01-1 um/m).
MAX_WEAR_RATE_UM_PER_M = 1.0e3
#: Longest cutting distance a used tool may have behind it [m] (100 km).
MAX_CUTTING_DISTANCE_M = 1.0e5
#: Coarsest chord tolerance for arcs [mm]: a chord cuts up to this deeper than its arc,
#: which shifts the predicted surface by as much; 10 um drowns the errors predicted.
MAX_CHORD_TOL_MM = 1.0e-2
#: The bottom view spans at least this many pixels across the tool [-]: fewer cannot
#: place the micro edges' samples (the default is 64).
MIN_PIXELS_PER_DIAMETER = 8.0
#: Largest shape-error deviation of the effective radius [um] (1 mm: a broken tool).
MAX_RADIUS_DEVIATION_UM = 1.0e3

# --- cutting conditions of a program (errpred/conditions.py; checked before predicting) --
#: Largest feed per tooth the prediction accepts, as a share of the tool's radius [-].
#: The chip thickness fz sin(phi) (docs/method.md §4) is the first term of the
#: trochoidal tooth path's; the next, about fz^2 cos^2(phi) / (2 R), is a quarter of fz
#: at fz = R / 2, beyond which the force model is no longer the cut's. Real programs
#: stay far below (finishing a mold with a D10 ball: 0.05-0.2 mm a tooth, 0.01-0.04 R;
#: a high-feed mill roughing: about 0.1 R); a program beyond is refused at its first such
#: block (a feed scaled by mistake: LinuxCNC's 3D_Chips.ngc as installed feeds 10,000
#: times its intended feed, 312 mm a tooth on a D10 ball, and was predicted at 1.6 m).
MAX_FEED_PER_TOOTH_RADII = 0.5

# --- tool libraries (errpred/toollib.py) ------------------------------------------
#: Millimetres per inch (exact, by the 1959 definition) [mm/in]: inch tool
#: libraries are converted at the reader, nothing beyond it sees inches.
INCH_MM = 25.4
#: A library's corner radius below this counts as a sharp corner, so a "flat end
#: mill" may carry it [mm]. Libraries store inch values to 6 decimals (0.025 um);
#: a corner radius of 1 um changes the predicted error by well under 1 um, the
#: prediction's own resolution (docs/method.md §9). A flat end mill with a larger
#: corner radius is refused: it is a bull-nose end mill and must be modelled as one.
LIBRARY_SHARP_CORNER_MM = 1.0e-3
#: A ball end mill's corner radius in a library may differ from D/2 by this
#: much and still be the ball [mm] (inch values to 6 decimals; see above). A
#: larger difference is a contradiction in the library and is refused.
LIBRARY_BALL_RADIUS_TOL_MM = 1.0e-3

# --- force laws (errpred.laws) ---------------------------------------------------
#: Smallest chip at which Kienzle's law is evaluated as a power law [mm]. The law
#: F = k_c1.1 b h^(1-m_c) has the slope (1-m_c) k_c1.1 b h^(-m_c), infinite at h -> 0,
#: where the regenerative gain and the linearised force table need it finite; below
#: this chip the force is the chord from 0 to its value here (finite slope, continuous
#: force). 1 um is below the chips that tables are measured at (5-10 um and up) and
#: about the edge radius of a sharp carbide edge, under which the edge ploughs rather
#: than shears anyway.
KIENZLE_MIN_CHIP_MM = 1.0e-3
#: Largest exponent m_c of Kienzle's law [-]: tabulated values are 0.1-0.45; at 1 the
#: force no longer grows with the chip, which no metal shows.
KIENZLE_MAX_MC = 0.95
#: Highest degree of a Lee-Altintas coefficient polynomial in kappa [-]: the published
#: fits use up to 4; more only follows the noise of a calibration.
LEE_ALTINTAS_MAX_DEGREE = 6

# --- identification of a force law from mean forces (errpred.fit) ------------------
#: Gauss-Legendre nodes of the mean-force integral on each smooth piece of the engaged
#: arc [-] (pieces split where a law kinks, e.g. Kienzle's floor); the nodes are
#: clustered at both ends (phi = a + L (1 - cos(pi s)) / 2), where Kienzle's h^(1-m)
#: has its root singularity: 128 give side-milling and slot means of the power law to
#: 1e-9 relative of scipy's adaptive quadrature (tests/errpred/test_laws.py).
FIT_QUADRATURE_NODES = 128
#: Tests in one fit file at most [-]: a sanity bound against a wrong file (a
#: force time series, not means); a calibration uses 5-50.
FIT_MAX_TESTS = 10_000

# --- pages of predict and compensate (errpred/run_page.py) -------------------------
#: A surface whose generation points have a normal within this of horizontal (|n_z|
#: below it, at the median) is a wall and is drawn unrolled (arc length along the
#: contour x Z); steeper normals, a free-form surface, are drawn from above (X x Y)
#: [-]. sin 20 deg: the bundled wall's 3 deg draft (|n_z| 0.05) is a wall, the
#: mold core's flanks of 60 deg and less (|n_z| 0.5 and more) are not.
PAGE_WALL_NORMAL_Z = 0.342
#: Tool tips closer than this in Z belong to one waterline level [mm]: finishing Z
#: steps are 0.1 mm and more, and a correction moves a drafted wall's tips in Z by
#: micrometres.
PAGE_LEVEL_GAP_MM = 0.02
#: Rows of the per-level (per-pass) table at most [-]: a whole program has hundreds of
#: levels; the plot above the table shows them all, the table the worst ones.
PAGE_TABLE_ROWS = 40
#: Half the Z span of an unrolled wall's plot at least [mm]: a single waterline level
#: keeps a readable axis instead of one zoomed to micrometres.
PAGE_MIN_HALF_SPAN_MM = 0.5

# --- feed scheduling (errpred/schedule.py) ------------------------------------------
#: Largest change of the schedule's factor on the programmed feed from one feed block
#: to the next, as a share of the earlier block's factor, up or down [-] (the CAM's
#: own feed steps, a plunge at a quarter feed then the cut, are kept as they are).
#: Per block, not per mm: the controller holds
#: one programmed feed per block and blends between blocks in its look-ahead, so a
#: block is the unit the chip load changes in; 20 % keeps the chip thickness, the
#: force and the surface's mark from stepping visibly between neighbouring blocks
#: (a 20 % step in feed per tooth changes the cutting force by at most 20 %), while
#: a schedule still reaches double the feed within 4 blocks.
MAX_FEED_STEP = 0.20
#: The schedule aims this share below the error tolerance and the force limit [-]:
#: each block's feed is solved on a line through two predictions (the error and the
#: force grow nearly linearly with the feed per tooth under the linear law, less
#: than linearly under Kienzle's), and 5 % absorbs that line's error so that the
#: dense verification rarely has to lower a block again.
SCHEDULE_MARGIN = 0.05
#: Verified rounds at most: after each dense re-prediction the blocks over a limit
#: get a lower feed and the program is predicted again [-].
SCHEDULE_ROUNDS = 4
#: Scheduled feeds are whole multiples of this [mm/min] (rounded down): a
#: controller's feed resolution is far finer, and whole numbers read well.
FEED_QUANTUM_MM_MIN = 1.0
#: Without --min-feed / --max-feed (no machine file gives feed limits), the allowed
#: range is this share of the smallest and this multiple of the largest programmed
#: cutting feed in scope [-]: a bounded change around the CAM's own feed, which is
#: within a cutter maker's recommended range.
DEFAULT_MIN_FEED_FACTOR = 0.25
DEFAULT_MAX_FEED_FACTOR = 2.0
