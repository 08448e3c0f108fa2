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
#: Side of the cubes into which points are binned before their membership
#: tests, so that each bin tests only the sweeps that can reach it [mm].
CLUSTER_CELL_MM = 0.2
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

# --- prediction -------------------------------------------------------------
#: Blocks longer than this get a prediction point in each of equal parts
#: no longer than it (method.md section 3: long blocks, several points) [mm].
#: Default: one point per block, as the seeds do. More points show how the
#: error varies along a long block, but a correction that moves only the
#: block's ends cannot follow that variation (the bundled wall, 44 mm lines
#: between corners: a third of the largest error removed when the
#: corner-affected ends of the lines count too), so the largest error then
#: mixes in what no rewrite of the block's end points can correct.
POINT_SPACING_MM = math.inf
#: Extra stock thickness along the normal with which the error's sensitivity
#: to the correction is evaluated (a finite difference) [mm].
SENSITIVITY_STEP_MM = 2.0e-3
#: A 5-axis path's prediction points are placed on the path by the nearest
#: cutter location in tip and axis together: one radian of axis counts as this
#: many mm of tip (errpred/correct_path.py; about a ball's diameter, so a
#: point's own pass wins over another pass whose tilted tips run nearby) [mm].
LOCATE_AXIS_MM = 10.0
#: Below this angle between tool axis and surface normal the cutting speed
#: at the generation point is too small for the force model (flat floors cut
#: by the ball's tip); no prediction is made there [rad].
MIN_AXIS_NORMAL_ANGLE_RAD = math.radians(5.0)
#: View correction: contact angle above which the bottom view is replaced by
#: a view toward the cutting region's normal [rad] (seeds: 60 deg).
VIEW_CORRECTION_KAPPA_RAD = math.radians(60.0)
#: Zoom factor of the corrected view [-].
VIEW_ZOOM = 8.0

# --- the local Dask cluster (errpred/cluster.py) ---------------------------------
#: glibc malloc settings of the local cluster's workers [bytes]: trim threshold and mmap
#: threshold (mallopt M_TRIM_THRESHOLD, M_MMAP_THRESHOLD). Dask's default,
#: MALLOC_TRIM_THRESHOLD_=65536, hands freed memory back at once and pins the mmap
#: threshold at 128 kB, so every array above it is mapped and unmapped again (page
#: faults): the bundled error prediction of 1,200 blocks took 30 s with it against 17 s
#: with these, at the same peak memory (260 MB).
WORKER_MALLOC_TRIM_BYTES = 128 << 20
WORKER_MALLOC_MMAP_BYTES = 32 << 20

# --- tool wear (errpred/tool_state.py) -----------------------------------------
#: A tool-state file matches the scenario's tool when its diameter, corner
#: radius and micro-edge positions agree within this [mm]: the file stores
#: them with every digit, so only another tool or another resolution differs
#: by more (the micro edges of neighbouring ``resolution.micro_edges``
#: settings are hundredths of a millimetre apart).
TOOL_STATE_MATCH_MM = 1.0e-6
