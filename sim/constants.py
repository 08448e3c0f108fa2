"""Defaults and tolerances of the ``sim`` package, in one place (``docs/method.md`` §8)."""

from __future__ import annotations

#: The cutting model's chips are in mm, its displacements in m [mm/m].
MM_PER_M = 1e3

# --- time-domain cutting (sim/cutting.py) -----------------------------------
#: The integrator takes at least this many steps per period of the highest
#: mode (the modes are integrated exactly for a force held over a step, so
#: this bounds the force's sampling, not a stability limit) [-].
STEPS_PER_MODE_PERIOD = 24
#: Modes with a damped natural frequency squared above this share of the undamped one
#: (damping ratio below about 0.99) are discretized in closed form, the rest by the
#: matrix exponential [-].
STEP_MAP_UNDERDAMPED = 0.02
#: Least rotation steps per revolution (engagement sampling) [-].
MIN_STEPS_PER_REV = 360
#: Most rotation steps per revolution (refused above: choose fewer modes) [-].
MAX_STEPS_PER_REV = 20_000
#: Micro edges on the lower envelope of the simulated tool [-].
MICRO_EDGES_ENVELOPE = 60
#: An edge whose chip the vibration takes to zero still rubs the surface (edge force,
#: no chip force) until it stands off by more than this, the rounded cutting edge's
#: radius (ground carbide ball end mills: 3-10 um) [mm]. Without it, an edge at the
#: engagement's boundary, whose static chip is a few nanometres, switches its whole edge
#: force on and off with sub-micrometre vibration: a relay that keeps a linearly stable
#: cut in a limit cycle, an artefact of the micro edges' discretization.
EDGE_RUB_MM = 0.005
#: The time-domain kernels (sim/_kernels.py) set a state variable (a mode's
#: displacement or velocity, an accelerometer filter's delay) whose magnitude falls
#: below this to zero: the smallest normal float64 [m, m/s or m/s^2]. A mode that rings
#: down over a long air move reaches subnormal numbers, and rounding then keeps it
#: there (a limit cycle of a few ulps that never decays to zero); every operation on a
#: subnormal costs the processor about 20 times a normal one (the kernel's step:
#: 0.3 us -> 7.2 us), and the accelerometers' filters fed with them as much. Nothing
#: the simulation reports can see a difference below 2.2e-308 (a displacement in m,
#: against micrometres and sensor noise of 0.5 m/s^2).
SUBNORMAL_FLUSH = 2.2250738585072014e-308
#: Chip-to-chip scatter of the cutting force: the chip widths of each tooth pass are
#: multiplied by 1 + this times a standard normal draw (the work material's hardness and
#: the edges' micro-geometry are never uniform) [-]. It seeds a regenerative instability
#: as a real cut's unevenness does; without it the only seed is the discretization (the
#: switches between cutter locations), whose size depends on the steps, so an unstable
#: cut could stay near its periodic motion for a whole pass. 0.2 %: its own vibration
#: on a stable cut stays far below the detector's threshold.
MATERIAL_SCATTER = 0.002
#: Stream of the scatter's random generator beside the sensors' (same run seed) [-].
MATERIAL_SCATTER_STREAM = 1
#: The chip widths are ramped from 0 to full over this many revolutions when a
#: run starts (the tool entering the cut), so the start does not kick the
#: structure out of the linear range [-].
RAMP_REVOLUTIONS = 3.0

#: The finished patch of a cutter location (feed per tooth by pick feed) is
#: sampled with this many points a side to find the rotation samples that
#: generate it (sim/cutting.py: generating_weights) [-] ...
STRIP_GRID = 9
#: ... a patch point counts as generated when an engaged micro edge's normal lies
#: within this many of the table's angular steps (rotation step or micro-edge
#: step, the larger) of the point's normal [-].
STRIP_REACH = 1.0

# --- stability from simulation (sim/cutting.py: growth_rate, boundary) -------
#: The per-tooth (Poincare) differences are fitted from this many revolutions
#: after the ramp (the start's transient decays first) [-] ...
GROWTH_SKIP_REVOLUTIONS = 2.0
#: ... over at least this many tooth periods [-].
GROWTH_MIN_POINTS = 6
#: The growth fit stops where the vibration reaches this fraction of the
#: static chip (beyond it the tool leaves the cut and growth saturates) [-].
GROWTH_LINEAR_FRACTION = 0.3
#: Relative tolerance of the bisection on the chip-width scale [-].
BOUNDARY_RTOL = 0.01

# --- chatter detection on the simulated machine (orient.detect settings) -----
#: Threshold on the chatter component's vector amplitude [m/s^2]: well above
#: the noise of a bin (2 sigma sqrt(1.5 / N) = 0.16 m/s^2 for 3 m/s^2 rms noise
#: and N = 2048) and below a starting chatter's first windows.
DETECTOR_THRESHOLD_M_S2 = 5.0
#: ... and at least this share of the strongest tooth-passing line [-]. A posture that
#: changes along the path modulates the forced vibration: lines a few percent of the
#: tooth-passing line's stand beside it (the bundled plan's top pass: 3 %, 11 of 355
#: m/s^2), and the entry into the cut rings the modes once; chatter grows past the
#: forced lines within a few windows (the CAM pass: 7, 30, 111, 296 ... 650 m/s^2).
DETECTOR_RELATIVE_THRESHOLD = 0.05
#: Window and hop [samples] at the accelerometers' rate: 2048 at 25.6 kHz is
#: 80 ms (12.5 Hz bins), a verdict every 10 ms.
DETECTOR_WINDOW_SAMPLES = 2048
DETECTOR_HOP_SAMPLES = 256
#: Harmonics excluded: the simulated tools have no runout, so only the
#: tooth-passing multiples are forced lines (period-doubling chatter at odd
#: multiples of half the tooth frequency stays visible).
DETECTOR_HARMONIC_BASE = "tooth"
#: Windows judged per call of the detector when a recorded run is judged offline
#: (sim/report.py: chatter_timeline) [-]. The detector holds each window of a call and
#: its spectra at once (about 0.2 MB a window of 2048 samples): 256 windows bound that
#: to about 50 MB whatever the run's length (a whole 141 s run at once, 14,117 windows,
#: was a 2.2 GB transient); the verdicts do not depend on it (each window is judged
#: from its own samples).
DETECTOR_CHUNK_WINDOWS = 256

# --- the simulated NC (sim/machine.py) ----------------------------------------
#: Rapid traverse rate [mm/min].
RAPID_MM_MIN = 10_000.0
#: An orientation command is checked at the current and this many following
#: cutter locations (axis limits, interference) [-].
LOOKAHEAD_POINTS = 10
#: Cutting models kept (cutter location x posture) [-].
MODEL_CACHE = 64

# --- the Modbus server (sim/server.py) ------------------------------------------
#: Default TCP port (502 needs root).
DEFAULT_PORT = 5020
#: The NC's interpolation period: the path advances, commands are taken and the
#: state is published once per period; the cutting simulation inside it runs at
#: its own step (24 per period of the highest mode) [s].
TICK_S = 0.005
#: Default watchdog [ms]: silence of the controller's heartbeat after which the
#: orientation offset returns to the program's posture.
DEFAULT_WATCHDOG_MS = 1000
#: The watchdog's check period in the Modbus server's process [s]: a trip comes at most
#: this late (plus the event loop's latency), well inside the 50 ms its timing allows.
WATCHDOG_POLL_S = 0.005
#: Real-time priority (SCHED_FIFO, 1 the lowest) the Modbus server's process asks for
#: where it is permitted (root or CAP_SYS_NICE; elsewhere it stays time-shared) [-]. On
#: a loaded 2-core machine (load 9) a time-shared server with no simulation at all
#: waited 4.8 s on the run queue for 0.8 s on the CPU over a 3 s read test, and its
#: 125-register reads took p99 5.2-5.5 ms with one client; in the real-time class it
#: waited 1 ms and the p99 was 0.6-1.3 ms. The process sleeps in its event loop
#: between requests (66-106 us of CPU a read), so it takes little from the rest.
SERVER_RT_PRIORITY = 1
#: How long the Modbus server's process may take to listen [s].
SERVER_START_S = 10.0

# --- the controller side (sim/controller.py) -----------------------------------
#: Registers per Modbus read (the protocol's limit).
MAX_READ_REGISTERS = 125
#: Poll period of the controller [s] (wall clock).
CONTROLLER_POLL_S = 0.01
#: The detector-driven rule's posture step [deg] (the patent's trial step).
CONTROLLER_STEP_DEG = 10.0
#: After a command, the controller waits this many spindle revolutions (a fresh
#: detector window) before it acts again [rev].
CONTROLLER_HOLDOFF_REV = 15.0

# --- the run report (sim/report.py) ---------------------------------------------
#: Chatter counts as stopped from a quiet window after which, over this long
#: [s], at most this share of the windows call chatter [-].
STOP_WINDOW_S = 0.5
STOP_FRACTION = 0.1
#: Share of the cut (its end) over which the "after" surface figures are taken [-].
TAIL_FRACTION = 0.5
#: Default stretch of the bundled program the simulated machine runs (cutter
#: location indices): the second and third passes along the thin wall's top, where
#: the CAM's posture chatters (the first pass, which cuts on both sides of the ball,
#: is the planner's job: no inclination alone keeps it stable at 9000 min^-1).
DEFAULT_POINTS = (41, 114)
#: The controller acts on a chatter verdict only when this many verdicts in a
#: row agree on the cause [-].
CONTROLLER_CONFIRM = 2
#: Samples per segment of the averaged acceleration spectrum of a verification run
#: (0.32 s at 25.6 kHz: 3 Hz resolution) [-].
SPECTRUM_SEGMENT = 8192
#: Segments whose spectra are computed at once for that average [-]: scipy.signal.welch
#: holds every segment detrended, windowed and transformed at once (231 MB over the
#: 58 MB acceleration of a 141 s simulated run, the peak of a verification run), 64
#: at a time hold 4 MB beside the segments' spectra (79 MB in all); the same bits.
SPECTRUM_CHUNK_SEGMENTS = 64
#: Correction passes of the main job (predict, correct, predict again...) [-]. The
#: first is under-relaxed (errpred.constants.RELAXATION, 0.7), each is verified on the
#: dense points: on the job's light copy of the thin wall the dense RMS goes 5.25 ->
#: 1.69 -> 0.33 um in two (the second after three fallbacks), and the third finds
#: nothing left above the 1 um move tolerance. A scenario's ``[correction]
#: max_iterations`` below this is honoured (one pass: its fit applied whole). Passes
#: stop earlier once a verified candidate's dense RMS is within ``[correction]
#: verify_tolerance_um`` (sim/job.py).
JOB_CORRECTION_PASSES = 3
#: The Dask job's warm-up (``sim.warmup.run_part``): blocks of the CAM program
#: predicted and cutter locations simulated while the planner chooses the speed [-].
JOB_WARM_BLOCKS = 40
JOB_WARM_POINTS = 30
#: BLAS threads of the job's main process (threadpoolctl: numpy's and scipy's OpenBLAS) [-]: one, as Dask gives each of its
#: workers. With OpenBLAS's default (one a core) on the 2 cores kept busy by other
#: processes (as a cluster's workers keep them), the planner's time-periodic margins took
#: 188 of its 323 s (eigenvalues 6.1 s a matrix against 0.07 s on one thread); and
#: OpenBLAS's results change with its thread count (last bits: an SDM margin
#: 0.18029627247115548 against 0.1802962724711461), which one process and a cluster
#: must not.
JOB_BLAS_THREADS = 1
#: Spindle speeds of the job's lobe diagrams (0.5 to 1.5 times the planned speed) [-].
JOB_LOBE_SPEEDS = 300
#: The job's check: RMS simulated surface error of the corrected program at most this
#: share of the uncorrected one's [-].
JOB_SURFACE_RATIO = 0.25
#: The simulated machine cuts at a feed move whose ball is within this of the design
#: (a corrected program stands up to tens of micrometres off it) [mm], or deeper in it:
#: a gouge cuts whatever its depth (``sim.program.PartProgram``). Issue 16: with
#: ``|gap| <= 0.1 mm`` a bump up to 455 um into the flexible wall's three top passes
#: (tests/sim/flexible_wall.py) left 18 of their 93 cutting cutter locations cut.
CUTTING_GAP_MM = 0.1
#: Servo ticks of an offline verification (sim/verify.py) handed to the accelerometers
#: at once (``AccelerometerStream.push_many``: the same samples as tick by tick) [-]:
#: 200 ticks are 1 s simulated, about 25,600 samples (0.8 MB) in hand; tick by tick,
#: scipy's filter wrapper took 15.5 s of a 141 s simulated run's 28,243 pushes.
VERIFY_TICKS_PER_PUSH = 200
#: Stretches the main job's simulated run of each whole program is split into, at air
#: moves of about equal cutting time (``sim.verify.split_at_air``), run apart and judged
#: as one run [-]: the corrected program's run was the verification's critical path on
#: one worker (51 s) while the other ran the planned program's (35 s) and the CAM pass
#: (1.6 s); in halves the two workers share the 87 s. Each stretch starts at rest, after
#: an air move of about 1.3 s on the bundled thin wall, where one run's vibration has
#: rung down by more than 60 orders of magnitude.
VERIFY_STRETCHES = 2
#: Shortest air gap a simulated run is split in (``sim.verify.split_at_air``), from the
#: last move in the material to the next [s]: a stretch starts at rest, where one run's
#: vibration rings down over the gap; 0.25 s is eight decay times (1 / (zeta omega))
#: of a 500 Hz mode with 1 % damping, below a thousandth of its amplitude (the bundled
#: thin wall's gaps between passes: about 1.3 s).
SPLIT_AIR_MIN_S = 0.25
#: A verification's reason for an incomplete run lists at most this many cutter
#: locations (and program lines) of a kind, then their count [-].
COVERAGE_LISTED = 8
#: Upper end of the job page's spectrum plot (above the tool and wall modes) [Hz].
SPECTRUM_MAX_HZ = 8000.0
#: The main job's SIGINT or SIGTERM whose exception C swallowed (the handler ran in a
#: callback from C, as numba's compiler makes while it compiles a kernel) is sent
#: again this much later (sim.staging.terminate_as_interrupt) [s]: the callback has
#: returned by then (its calls take micro- to milliseconds), and a user waits no longer.
SIGNAL_REDELIVER_S = 0.05
