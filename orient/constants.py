"""Defaults and tolerances of the ``orient`` package, in one place, each with its unit
and reason.

Resolution defaults are the ones shown to converge by the tests named next to
them (``docs/method.md`` §9).
"""

from __future__ import annotations

import math

# --- units ------------------------------------------------------------------
#: Chip coefficients [N/mm^2] times chip widths [mm] give N/mm; this turns
#: them into the N/m of the stability analysis.
N_PER_M_PER_N_PER_MM = 1000.0

# --- geometry ---------------------------------------------------------------
#: Vectors shorter than this (relative, for directions) are refused as
#: having no direction [-].
DIRECTION_MIN_NORM = 1.0e-12
#: Rotations and orthonormal bases are accepted when ``R R^T`` is the identity
#: within this [-] (what a rotation built in floating point keeps; a wrong one is
#: off by far more).
ORTHONORMAL_TOL = 1.0e-9
#: Counts from ratios are ``ceil(x - this)`` (``floor(x + this)``) [-]: a ratio that
#: is whole but for rounding (12.000000000000002) does not add one.
ROUND_SLACK = 1.0e-9
#: A tool axis must make at least this cosine with the surface normal (the
#: tool axis points away from the workpiece) [-].
AXIS_NORMAL_MIN_COS = 1.0e-6

# --- engagement and process gain (orient.engagement, orient.gain) -----------
#: The band of the cutting profile that can reach the stock (below the stock
#: top, positive chip thickness, away from the previous pass) is probed at
#: this many points for those necessary conditions ...
GAIN_BAND_PROBES = 10
#: ... and its ends located by this many bisections.
GAIN_BAND_BISECTIONS = 4
#: Along the cutting profile, the band that can reach the stock is scanned
#: at this many points for changes of the cutting intervals' structure
#: (kinks of the integrand along the profile) ...
GAIN_SCAN_POINTS = 6
#: ... each change located by this many bisections ...
GAIN_BISECTIONS = 4
#: ... and each smooth piece between changes integrated with this many
#: Gauss-Legendre micro edges. At these defaults P is within 2 % of P with
#: 4x as many points and micro edges
#: (``tests/orient/test_gain.py::test_default_resolution_converges``).
GAIN_PIECE_EDGES = 4
#: Micro edges on the lower envelope of :func:`orient.gain.default_edges`
#: (fixed micro edges for sampled engagements).
GAIN_MICRO_EDGES_ENVELOPE = 80
#: Rotation samples per revolution of the sampled engagement and of the
#: time-varying directional matrix H(t) (made a multiple of the flutes).
GAIN_ANGLES_PER_REV = 180
#: Along a micro edge's circle, the material test is sampled at most this
#: far apart before its sign changes are refined to roots [rad] ...
GAIN_ROOT_STEP_RAD = math.radians(10.0)
#: ... and at least this many times on each arc where the closed-form
#: conditions hold (narrow cutting intervals near the band's ends).
GAIN_MIN_ARC_SAMPLES = 6
#: The roots (entry and exit angles) are refined to this [rad] (an angle
#: error e changes P by about e relative to the engaged angle) ...
GAIN_ROOT_TOL_RAD = 1.0e-6
#: ... with at most this many iterations [-].
GAIN_ROOT_MAX_ITER = 60
#: A micro edge cuts only where its chip thickness exceeds this fraction of
#: the feed per tooth (a bottom face edge with the feed normal to the axis
#: has h = 0 up to round-off and does not cut) [-].
CHIP_EPS = 1.0e-12

#: Angle grids (the rotation samples' sin and cos for one tool and angle count,
#: ``orient.engagement.flute_engagement``) kept: a run uses one or two [-].
ANGLE_GRIDS_KEPT = 4
#: A point this close to the previous pass's swept volume counts as removed
#: [mm] (as ``errpred.constants.MEMBERSHIP_EPS_MM``).
MEMBERSHIP_EPS_MM = 1.0e-6

# --- planning (orient/plan.py, orient/scenario.py) ------------------------------
#: Default half-range of the lead and tilt search around the surface normal [deg].
LEAD_TILT_RANGE_DEG = 40.0
#: Default lead and tilt steps of the search grid [-] (15 x 15 postures).
GRID_STEPS = 15
#: Below this inclination between tool axis and surface normal the ball cuts
#: with its tip, where the cutting speed is zero (method.md §7) [deg].
MIN_INCLINATION_DEG = 5.0
#: Largest inclination considered [deg].
MAX_INCLINATION_DEG = 60.0
#: Largest change of the tool axis per mm of path, so that the rotary axes
#: are not whipped [deg/mm].
MAX_RATE_DEG_PER_MM = 2.0
#: Smallest angle kept between the tool axis and the machine's rotary (free) axis,
#: e.g. |B| on a B/C head-table machine [deg]; 0: no floor (the default). At the pole
#: (B = 0) the rotary axis is undefined: nc's writer holds it there and turns it when
#: the axis leaves, so a path through the pole turns the table while the tip stands (a
#: dwell mark; on a slice of the mold core's raster C turned 30 deg at one point). A
#: floor of 5 deg ([orient] pole_floor_deg) removes that, but it is not the default:
#: with the CAM's vertical posture refused, passes end tilted, and the retract (then a
#: G0 to the CAM's vertical clearance point) turned B while the ball was still at the
#: surface (on raster.nc 5283-6500 a rapid into material, which the job refuses). The
#: links now keep the last cut's posture up to the clearance height (orient.choice);
#: with them raster.nc 5283-5586 ran with every check on rapids, collisions and coverage
#: holding, but 5283-6500 still has one rapid into material (the retract after raster.nc
#: line 6281, whatever its direction: the tool at that pass's last planned posture meets
#: the stock; README, the mold core), so the floor stays off.
POLE_FLOOR_DEG = 0.0
#: A rapid of a link between passes whose CAM ball centre is within this of straight
#: above the end of the pass it takes its posture from keeps the CAM's ball centre
#: (orient.choice._Inherited: a 3-axis program's retract and approach, straight up and
#: down) [mm]: the program's modal X Y are repeated to the digit, so any tolerance
#: above rounding (1e-6 mm) and far below a pick feed (0.35 mm on the mold core) will do.
LINK_VERTICAL_TOL_MM = 1.0e-6
#: Margin above which postures count as equally good; the planner then
#: prefers the posture nearest the CAM's [-].
MARGIN_TARGET = 1.5

# --- interference (orient/interference.py; the planner's [orient] defaults) ---------
#: Clearance kept between shank/holder and the workpiece [mm]: the default of
#: ``[orient] clearance_mm``, of :class:`orient.interference.ToolAssembly` and of
#: :class:`orient.interference.InterferenceChecker` (one value: the check the
#: planner makes is the one every other caller makes). 1 mm, the usual CAM holder
#: clearance for finishing, and what the bundled scenarios state.
CLEARANCE_MM = 1.0
#: Penetration of the flute part above the ball into the design surface tolerated
#: as a touch [mm] (on a steep wall the flank is tangent to the surface by design).
#: It must exceed the design mesh's deviation from the true surface: the chord
#: tolerance of CAM meshes (1-10 um; 4 um in errpred's bundled mold) plus the
#: float32 rounding of binary STL coordinates (up to 4 um at 60-120 mm).
GOUGE_TOL_MM = 0.01
#: Points without a feasible posture named (CAM program lines, indices) in the
#: one-line refusal or warning of ``python -m orient plan -o`` (a line, not a
#: listing: the plan report has them all when written) [-].
INFEASIBLE_LISTED = 5
#: Spindle speeds tried when the spindle speed is chosen from the lobes [-].
SPINDLE_STEPS = 120
#: Default damping ratio of a thin wall's modes (monolithic steel, clamped) [-].
WALL_DAMPING_RATIO = 0.01
#: Modes of the thin wall's finite-element model used [-].
WALL_MODES = 6

# --- limits of a planning scenario's values (orient/scenario.py; checked when loaded) ---
#: Most spindle speeds tried when the speed is chosen from the lobes [-]: each costs
#: every contact point's margins once more (the bundled wall: 71).
MAX_SPINDLE_STEPS = 1000
#: Highest spindle speed of a range to choose from [rev/min] (fastest HSC spindles).
MAX_SPINDLE_RPM = 100_000.0
#: Most thin-wall modes kept [-]: each is a lowest eigenpair of the finite-element
#: model, and the planner's margins take them all at every contact point.
MAX_WALL_MODES = 50
#: Most modes of a workpiece given mode by mode, and of the tool's dynamics [-].
MAX_WORKPIECE_MODES = 50
#: Highest stability margin aimed at [-] (critical over actual depth: 1.5 is the
#: default; a target beyond 10 leaves every posture infeasible, found only after the
#: whole search).
MAX_MARGIN_TARGET = 10.0
#: Largest clearance of shank and holder to the stock [mm] (the default is 1 mm; more
#: than this refuses every posture of a finishing cut after the whole search).
MAX_CLEARANCE_MM = 50.0
#: Largest gouge tolerance [mm] (the default is 0.01 mm; a millimetre is no check).
MAX_GOUGE_TOL_MM = 1.0
#: Fastest lead/tilt change allowed along the path [deg/mm] (the default is 2; 180
#: deg/mm is no limit at all).
MAX_RATE_LIMIT_DEG_PER_MM = 180.0
#: Largest thin wall [mm] (length, height, thicknesses): a part on a machine table.
MAX_WALL_MM = 10_000.0
#: Stiffest wall material [GPa] (diamond: about 1,050) ...
MAX_YOUNG_GPA = 1.2e3
#: ... and densest [kg/m^3] (osmium: 22,600).
MAX_DENSITY_KG_M3 = 2.5e4

# --- linear algebra (orient/blas.py) -------------------------------------------
#: BLAS threads (numpy's and scipy's OpenBLAS, through threadpoolctl) in the
#: time-periodic stability's eigenvalues and the thin-wall FEM's solves [-]:
#: one, as the job's main process and Dask's workers. With OpenBLAS's default
#: (a thread a core) on cores kept busy by other processes, eigvals of the
#: monodromy matrices ran 10 to 100 times slower; the matrices here (a few
#: hundred rows) gain nothing from more threads.
BLAS_THREADS = 1

# --- the zero-order stability analysis (orient/stability/zoa.py) --------------
#: ZOA's default chatter-frequency grid, built from the modes: a dense band around
#: each natural frequency, +- this many ``zeta wn`` [-] (the receptance's peak is
#: about ``2 zeta wn`` wide) ...
ZOA_NEAR_HALF_WIDTH = 8.0
#: ... with this many points (step 0.4 zeta wn) [-].
ZOA_NEAR_POINTS = 25
#: Wider band around each natural frequency: +- this fraction of ``wn`` [-] ...
ZOA_BAND_HALF_WIDTH = 0.5
#: ... with this many points [-].
ZOA_BAND_POINTS = 16
#: Global log-spaced grid from ``lo * wn_min`` to ``hi * wn_max`` [-] (chatter
#: away from every mode, for the far lobes) ...
ZOA_GLOBAL_RANGE = (0.2, 3.0)
#: ... with this many points [-].
ZOA_GLOBAL_POINTS = 32
#: Damping ratios below this are taken as this for the grid's width [-].
ZOA_MIN_ZETA = 1e-3
#: Where the bands of several modes overlap, a point closer than this fraction
#: of the finest step any band asks for there to the previous kept point is
#: dropped (the union of the bands would otherwise be denser than any band) [-].
ZOA_THIN_FRACTION = 0.5
#: ZOA margins of fewer postures than this in one call are computed in the calling
#: thread, more over numba's threads [-]. A thread launch cost about 6 ms of CPU (20 ms
#: wall) a call on the shared 2-core machine, a capped margin 7-8 us and an exact one
#: about 15 us a posture in one thread: the planner's calls (a cutter location's 226
#: postures) spent nearly all their time launching threads.
ZOA_PARALLEL_MIN_POSTURES = 4096
#: Mode directions with |d_a . d_b| above this share a group (add their receptances) [-].
GROUP_PARALLEL_TOL = 1.0 - 1e-9

# --- full discretization (orient/stability/sdm.py) ----------------------------
#: Steps per tooth period: at least this many [-] ...
SDM_DEFAULT_STEPS = 40
#: ... and at least this many per period of the highest natural frequency [-]
#: (the step's error scales with ``(f_max dt)^2``: on the 1-DOF benchmark grid
#: 24 leave up to +6 %, 32 up to +4 % at lobe crossings and high-depth flip
#: lobes, 64 about +1 %; the error control of :func:`sdm_margin` does the rest) ...
SDM_STEPS_PER_MODE_PERIOD = 32
#: ... but not beyond this [-] (cost: the monodromy matrix has ``(k + 2) m``
#: rows; its eigenvalues cost ``k^3``).
SDM_MAX_STEPS = 200
#: Sub-steps per step on which ``H`` is integrated exactly against the
#: Duhamel kernel: at least this many [-] ...
SDM_SUBSTEPS = 4
#: ... and up to this many to put every sample interval's edge on a sub-step
#: edge (else the samples are averaged onto the sub-steps) [-].
SDM_MAX_SUBSTEPS = 64
#: Samples of ``H`` per tooth period recommended at least [-] ...
SDM_MIN_SAMPLES = 320
#: ... and that the engaged part of the tooth period should span
#: (:func:`recommended_samples`): the samples are ``H``'s step averages, and
#: their count bounds how well its shape inside the cut is known [-].
SDM_MIN_SAMPLES_IN_CUT = 48
#: Default steps: the margin at half the steps estimates the error ``D``;
#: where ``D`` exceeds this fraction of the margin, the steps are doubled once
#: [-] ...
SDM_REFINE_TOL = 0.005
#: ... if the monodromy matrix then has at most this many rows [-] (its
#: eigenvalues cost ``rows^3``: about 30 ms at 400 rows on one thread) ...
SDM_REFINE_MAX_ROWS = 400
#: ... and the margin returned is the finest one less this multiple of ``D``
#: [-] (1/3 would be Richardson's estimate of the error of a second-order
#: method; more keeps the result below the converged limit where the
#: refinement is not yet asymptotic: calibration on the 1-DOF benchmark grid).
SDM_ERROR_WEIGHT = 0.5
#: The scan in ``s`` starts at this fraction of the ZOA critical margin [-] ...
SDM_SCAN_START = 0.25
#: (without a finite ZOA margin, at that fraction of the stiffest mode's
#: ``k zeta`` over the gain, the damping ratio taken at least this [-], so that an
#: undamped mode does not start the scan at 0) ...
SDM_SCAN_MIN_ZETA = 1.0e-3
#: ... and multiplies ``s`` by this per step [-] ...
SDM_SCAN_FACTOR = 1.3
#: ... up to this many times the start (then the margin is taken as inf) [-].
SDM_SCAN_MAX = 1e4
#: The last coarse interval (stable to unstable) is scanned again by this
#: factor [-]: the radius can cross 1 and come back within it (an unstable
#: window 7 % wide below the boundary on the 1-DOF benchmark, up-milling
#: a/D = 0.5 at 13,000 rev/min, which the coarse scan alone stepped over).
SDM_SCAN_FINE_FACTOR = 1.04
#: Relative tolerance of the margin [-] (the lower end of the root's
#: interval is returned).
SDM_RTOL = 5e-4
#: A critical multiplier within this angle [rad] of the real axis is a fold (+1)
#: or a flip (-1); otherwise a Hopf pair (rounding of the eigenvalues).
KIND_ANGLE_TOL = 1e-6

# --- one point's lobes (orient/pointwise.py) ----------------------------------
#: Spindle speeds of a lobe diagram [-].
LOBE_SPEEDS = 200
#: Default speed range of a lobe diagram, as factors of the programmed speed [-].
LOBE_RANGE = (0.5, 1.6)

# --- the posture rules (orient/strategies.py, orient/strategy_types.py) -------
#: Default step of the rules [rad]; the patent's example trial step ([0094]).
DEFAULT_STEP_RAD = math.radians(10.0)
#: Directions on a ring of candidate moves [-].
RING_DIRECTIONS = 36
#: Radii of the rings, as fractions of the step [-], largest first.
STEP_FRACTIONS = (1.0, 0.75, 0.5, 0.25)
#: Smallest change of inclination [rad] or cut sense [-] that counts as one.
CHANGE_TOL = 1e-9
#: Smallest relative improvement of gain or margin worth a posture change [-].
MIN_REL_IMPROVEMENT = 1e-3
#: Postures closer than this in lead and tilt are the same [rad].
SAME_POSTURE_RAD = 1e-6
#: MemoryRule: matches farther than this are not similar [-] (see orient/memory.py).
DEFAULT_MEMORY_MAX_DISTANCE = 2.0
#: MemoryRule does not learn a posture already stored this near [-] (among the
#: nearest LEARN_DEDUPE_K entries) ...
LEARN_DEDUPE_DISTANCE = 0.05
#: ... entries looked at for that [-] (the memory stays bounded by what it holds).
LEARN_DEDUPE_K = 32
#: Default candidate grid of the analytical rules: +-20 deg [rad] ...
DEFAULT_GRID_HALF_WIDTH_RAD = math.radians(20.0)
#: ... in 5 deg steps [rad] (81 postures, each one process gain).
DEFAULT_GRID_STEP_RAD = math.radians(5.0)

# --- the posture memory (orient/memory.py) ------------------------------------
#: From this many entries of one tool on, queries use a k-d tree [-].
KDTREE_MIN_ENTRIES = 64
#: A normal or feed vector must have a norm at least this to be normalized [-].
MIN_VECTOR_NORM = 1e-9
#: The feed must make at least this sine with the normal [-].
MIN_FEED_SINE = 1e-6
#: Default distance scales of the memory's nearest recall (see orient/memory.py's
#: docstring): one unit of distance is 10 % of spindle speed [-] ...
DEFAULT_SPEED_REL = 0.10
#: ... 0.1 mm of depth [mm] ...
DEFAULT_DEPTH_MM = 0.1
#: ... 0.1 mm of pick feed [mm] ...
DEFAULT_PICK_MM = 0.1
#: ... or 10 degrees of surface normal or feed direction [rad].
DEFAULT_ANGLE_RAD = math.radians(10.0)

# --- the chatter detector (orient/detect.py) ----------------------------------
#: Default window length [samples] (0.1 s at 10 kHz: 17 revolutions at 10000 rev/min).
DEFAULT_WINDOW_SAMPLES = 1024
#: Default hop between windows [samples].
DEFAULT_HOP_SAMPLES = 256
#: Default harmonic exclusion half-width, in frequency bins of the window [-].
DEFAULT_BAND_BINS = 3.0
#: Default phase threshold between whirling (tool) and one-directional
#: (workpiece) vibration [rad]: 45 degrees.
DEFAULT_PHASE_THRESHOLD_RAD = math.pi / 4.0
#: Windows accepted, with the half-width of their main lobe [bins]; the
#: harmonic band must be at least that wide or a harmonic's own main lobe
#: would leak into the candidate bins.
WINDOW_MAINLOBE_BINS = {"hann": 2.0, "hamming": 2.0, "blackman": 3.0,
                        "blackmanharris": 4.0, "boxcar": 1.0}
#: Shortest window accepted [samples].
MIN_WINDOW_SAMPLES = 16
#: Lines of a window's DFT kept for its response at fractional bins
#: (:func:`orient.detect.window_response`): those above this fraction of the largest
#: [-]. The windows accepted are cosine sums, with 1 to 7 lines; the others are
#: rounding (about 1e-16 of the largest), far below this.
WINDOW_LINE_REL = 1e-12
#: Floor added to the power spectrum before taking its logarithm [-], relative
#: to the largest power of the window (avoids log(0) on synthetic silence).
LOG_FLOOR_REL = 1e-30

# --- modal systems (orient/dynamics.py) ---------------------------------------
#: Mode directions must have unit length within this (they are then renormalized) [-].
DIRECTION_TOL = 1e-6
#: Tool axes closer than this to -Z (cos of the angle + 1) have no minimal rotation [-].
ANTIPODAL_TOL = 1e-9
#: Peaks of |Im G| below this fraction of the largest are not taken as modes [-].
FIT_PEAK_FRACTION = 0.05
#: At most this many modes are fitted per FRF [-].
FIT_MAX_MODES = 6
#: A peak's half-power damping estimate (the fit's start) is at least this [-]
#: (a peak one frequency bin wide would give zero).
FIT_MIN_ZETA = 1.0e-4

# --- smoothing and choice (orient/smoothing.py, orient/choice.py, orient/contacts.py) ---
#: Slack on the allowed axis change: numerical noise of the frames [rad].
ANGLE_SLACK_RAD = 1e-6
#: Score of the CAM posture where no candidate is feasible (below any margin, so it
#: is only taken where nothing else is left) [-].
FALLBACK_SCORE = -1.0e6
#: The ball touches the design where its centre is within R + this of it [mm].
CONTACT_TOL_MM = 0.01
#: Radius of the sphere that stands for a point in FCL's distance query of the ball
#: centre against the design (``orient.contacts.closest_points``; FCL has no point shape,
#: the distance is corrected by it) [mm]: far below any tolerance here.
CONTACT_PROBE_RADIUS_MM = 1e-9
#: An FCL answer whose nearest point is not at its distance from the query point within
#: this is asked again of trimesh's exact query [mm] (a safeguard; none seen).
CONTACT_NEAREST_CHECK_MM = 1e-6

# --- the workpiece's modes (orient/workpiece.py, orient/workpiece_fem.py, orient/fem/) ---
#: In-process cut levels at which the thin wall's modes are solved [-].
WALL_LEVELS = 3
#: Threads that solve the levels side by side [-]: one. Two threads held two SuperLU
#: factorizations at once: the bundled thin wall's model peaked at 717 MB against
#: 491 MB one level after another (three levels, 50 contact heights), for no gain on a
#: loaded 2-core machine (8.6 s against 7.7 s). With a Dask client the levels but the
#: first are offered to its workers instead (orient.workpiece._solve_shared).
WALL_LEVEL_THREADS = 1
#: A contact point this far outside the wall's material is taken at the
#: nearest material point (the contact lies on the finished face) [mm].
WALL_POINT_TOL_MM = 2.0
#: Default number of the thin wall's modes solved for [-].
DEFAULT_N_MODES = 6
#: Refuse meshes with more free DOFs than this [-] (memory of the sparse LU).
MAX_DOFS = 400_000
#: A query point may lie this far outside the wall's material [mm].
POINT_TOLERANCE_MM = 1.0
#: modes_at skips modes whose static compliance at the point (along the
#: direction) is below this fraction of the largest mode's [-].
NEGLIGIBLE_MODE_FRACTION = 1e-6
#: Elements assembled per batch [-] (bounds the dense (batch, 81, 81) work array).
ASSEMBLY_BATCH = 512
#: Relative tolerance of the Lanczos (ARPACK) eigen solve [-].
EIGEN_TOL = 1e-10
#: Seed of the Lanczos start vector [-] (deterministic modes, run to run).
EIGEN_SEED = 0
#: Parts of at most this many elements end the nested dissection that orders the
#: stiffness's DOFs for its sparse LU (orient.fem.q2hex.nested_dissection) [-]. The
#: bundled thin wall's largest level (24,108 DOFs): SuperLU's own minimum degree
#: ordering 2.7 s and 22.8 M entries in L and U; nested dissection with parts of 8
#: elements 1.4-1.5 s and 18.6 M, a solve 31.5 -> 24.2 ms (leaves of 4: 1.4 s, of 16:
#: 1.5 s, of 32: 1.8 s and 22.3 M).
ND_LEAF_ELEMENTS = 8
#: Default modal damping ratio of a wall [-] (measure it when it matters).
DEFAULT_DAMPING_RATIO = 0.01
#: Default mesh: element size = min(length, height) / this (one Q2 element per
#: thickness layer for a thin wall) [-]; shown to be within 1 % of a finer mesh.
DEFAULT_ELEMENTS_SHORT_SIDE = 12
#: Default mesh: at most this many elements along the length or the height [-].
DEFAULT_MAX_ELEMENTS_PER_DIRECTION = 48
#: Face positions closer than this are merged when meshing [mm].
MERGE_MM = 1e-6
#: Largest |cosine| between the frame directions accepted as orthogonal [-].
ORTHO_TOL = 1e-6

# --- plots (orient/plots.py) --------------------------------------------------
#: Margins above this are drawn at this value (the colour scale's top) [-].
MARGIN_CLIP = 4.0
# --- advice at one point (orient/advice.py, python -m orient lobes) ---------------
#: The largest stable depth and pick feed are divided by this before they are offered
#: (the patent's 8th embodiment: "the stability limit times a safety factor") [-]. At
#: the lobes' floor the limiting depth is proportional to the modal stiffness times
#: the damping ratio over the cutting coefficient; an impact test gives the damping to
#: about +-30 % and a table's coefficients are good to about +-20 %, so the limit is
#: known to about a third: 1.5 keeps a cut at the offered depth stable when the
#: predicted limit is up to a third too high. The planner's margin target
#: (``MARGIN_TARGET``) is the same factor on the process gain.
LOBES_SAFETY_FACTOR = 1.5
#: A suggested spindle speed keeps this relative distance from the lobe boundary: its
#: stable depth is the lowest within +-3 % of it [-]. Natural frequencies shift by a
#: few per cent between the impact test and the cut (spindle speed, temperature, the
#: part losing mass), and the lobes shift with them in speed.
LOBES_SPEED_MARGIN = 0.03
#: Speeds of that window at which ``python -m orient lobes`` checks the zero-order
#: lobes with the time-periodic method by default [-] (each costs about as much as
#: the zero-order lobes of the whole diagram times a hundred).
LOBES_SDM_SPEEDS = 5
#: The time-periodic check disagrees when its window minimum is this much below the
#: zero-order one [-] (the default steps leave the time-periodic margin within 1 % of
#: its converged value: orient.stability.sdm_margin's Notes).
LOBES_SDM_DISAGREE = 0.05
#: The largest stable depth and pick feed: the scan steps by this factor [-] ...
LOBES_LIMIT_FACTOR = 1.25
#: ... and the root is refined to this relative tolerance [-].
LOBES_LIMIT_RTOL = 2e-3

# --- the local cut from the part (orient/part_cuts.py) -----------------------------
#: Columns across the ball's cross-section (along b, over [-R, R]) at whose foot (just
#: above the ball's profile) the material before the pass is probed: is there any in
#: the ball's reach at the centre's section [-] (R/8 apart: 0.625 mm for a D10 ball).
PART_CUT_COLUMNS = 17
#: Halvings of one tool radius that find the stock's top up a column (R / 2^13: 0.6 um
#: for a D10 ball) [-].
PART_CUT_BISECTIONS = 13
#: The stock's curvature is measured from its top this far either side of the contact,
#: along f and along b, in tool radii [-]: 1 mm for a D10 ball, about the half width a
#: finishing cut engages (sqrt(2 R depth): 1.2 mm at 0.15 mm depth).
PART_CUT_CURVATURE_SPAN_RADII = 0.2
#: The moves of the current pass within this many tool radii of path behind a cutter
#: location are its own trail, not an earlier pass [-]: farther back they cannot
#: reach the ball (radius R) nor its cross-section.
PART_CUT_OWN_TRAIL_RADII = 3.0
#: A pass ends where the path turns by more than this between two moves [deg]: a
#: zig-zag's step-over (90 deg) ends one pass and starts the next; an earlier move
#: counts as a previous pass when it runs within this of the feed (either way).
PART_CUT_PASS_TURN_DEG = 45.0
#: Less material than this above the finished surface in the ball's reach is air [mm]
#: (the stock meshes' own deviation is a few um).
PART_CUT_MIN_DEPTH_MM = 1.0e-3
#: An earlier pass whose ball centre lies closer than this to the current line (along
#: b) runs along the same line (a recut), not beside it [mm].
PART_CUT_MIN_PICK_MM = 0.01
#: Directions on the ball's front-lower quarter sphere sampled for "does the ball meet
#: material at all" (per angle, polar x azimuth) [-].
PART_CUT_SHELL_STEPS = 6
#: The stock's convex curvature is kept below this over the tool radius [-] (a ridge
#: of radius R/2; a fit over +-1 mm is not trusted beyond).
PART_CUT_MAX_CURVATURE_RADII = 2.0
#: The stock's concave curvature is kept below this over the tool radius [-] (a hollow
#: of radius 2 R: a ball in a tighter hollow would touch it away from its contact,
#: which the local model does not hold; a hollow of radius R would gouge).
PART_CUT_MAX_CONCAVE_RADII = 0.5
#: Consecutive cutter locations whose earlier moves are looked up together [-]: the
#: lookup (errpred's Sweeps.near) costs about 7 ms on mold-ball's flanks, whatever the
#: box; each location then keeps the moves before its own trail near its ball.
PART_CUT_CHUNK = 16
#: Engaged cutter locations whose stock top is found in one bisection [-]
#: (``_Section.stock_tops``: 17 calls of the mesh's test for them all instead of 17 a
#: location); bounded so that a long program's arrays stay small (about 2 MB at 4,096:
#: five columns of three coordinates a location, a few arrays at once).
PART_CUT_TOP_CHUNK = 4096
