"""Defaults and tolerances of the ``sim`` package, in one place (``docs/method.md`` §8)."""

from __future__ import annotations

# --- time-domain cutting (sim/cutting.py) -----------------------------------
#: The integrator takes at least this many steps per period of the highest
#: mode (the modes are integrated exactly for a force held over a step, so
#: this bounds the force's sampling, not a stability limit) [-].
STEPS_PER_MODE_PERIOD = 24
#: Least rotation steps per revolution (engagement sampling) [-].
MIN_STEPS_PER_REV = 360
#: Most rotation steps per revolution (refused above: choose fewer modes) [-].
MAX_STEPS_PER_REV = 20_000
#: Micro edges on the lower envelope of the simulated tool [-].
MICRO_EDGES_ENVELOPE = 60
#: The chip widths are ramped from 0 to full over this many revolutions when a
#: run starts (the tool entering the cut), so the start does not kick the
#: structure out of the linear range [-].
RAMP_REVOLUTIONS = 3.0

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
#: Window and hop [samples] at the accelerometers' rate: 2048 at 25.6 kHz is
#: 80 ms (12.5 Hz bins), a verdict every 10 ms.
DETECTOR_WINDOW_SAMPLES = 2048
DETECTOR_HOP_SAMPLES = 256
#: Harmonics excluded: the simulated tools have no runout, so only the
#: tooth-passing multiples are forced lines (period-doubling chatter at odd
#: multiples of half the tooth frequency stays visible).
DETECTOR_HARMONIC_BASE = "tooth"
