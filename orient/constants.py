"""Defaults and tolerances of the ``orient`` package, in one place.

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
