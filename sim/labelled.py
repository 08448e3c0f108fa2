"""Labelled accelerometer runs for measuring a chatter detector (issue: sensors and detection).

Each case is a side-milling cut (straight-fluted flat end mill, half
immersion, down-milling) simulated by :mod:`sim.cutting` and measured by
:mod:`sim.sensors`, of one of three kinds:

``'stable'``
    flexible tool, chip width at ``STABLE_FRACTION`` of the boundary all along;
``'tool'``
    flexible tool (two equal bending modes: the tool whirls), chip width stepped
    from ``STABLE_FRACTION`` to ``CHATTER_FRACTION`` times the boundary at the
    onset (a deeper cut);
``'workpiece'``
    stiff tool, flexible workpiece (one mode along the wall normal ``+y``),
    the same step.

The boundary is orient's full-discretization margin of the case, and the
*label* of a chatter run (the side that chatters) comes from orient's
zero-order analysis: the source (tool or workpiece modes) that dominates the
compliance at the predicted chatter frequency -- not from the simulation it
labels, and not from the case's name (a stiff tool still chatters first at some
speeds). Times are in seconds, speeds in rev/min.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from errpred.dynamics import Mode
from errpred.coefficients import CuttingCoefficients
from errpred.spindle import tooth_frequency, tooth_period
from errpred.tool import Tool
from orient.detect import ChatterDetector
from orient.dynamics import ModalSystem
from orient.engagement import LocalCut
from orient.gain import process_gain
from orient.stability import sdm_margin
from orient.stability.zoa import zoa_margin_detail

from .cutting import prepare_cut, simulate
from .sensors import Accelerometers, SensorSignals, sample_accelerometers

__all__ = ["KINDS", "DetectorScore", "LabelledCase", "LabelledRun", "labelled_run", "score_detector"]

KINDS = ("stable", "tool", "workpiece")
#: Chip-width scale before the onset (and all along in stable runs), and after
#: it, as fractions of the boundary [-].
STABLE_FRACTION = 0.5
CHATTER_FRACTION = 2.5
#: The cut of every case: depth [mm], radial width [mm], feed per tooth [mm].
DEPTH_MM, WIDTH_MM, FZ_MM = 1.0, 5.0, 0.05
COEFFICIENTS = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                                   Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0)
TOOL = Tool("flat", 10.0, flutes=2, helix_deg=0.0, flute_length_mm=6.0)
#: Flexible tool: two equal bending modes [Hz, -, N/m] (Ding et al. 2010's 2-DOF tool).
TOOL_MODE = (922.0, 0.011, 1.34e6)
#: Stiff tool and flexible workpiece (a thin wall along +y) [Hz, -, N/m].
STIFF_TOOL_MODE = (2400.0, 0.03, 4.0e7)
WALL_MODE = (1300.0, 0.01, 3.0e6)


@dataclass(frozen=True)
class LabelledCase:
    """One labelled run.

    Attributes
    ----------
    kind : str
        ``'stable'``, ``'tool'`` or ``'workpiece'``.
    spindle_rpm : float [rev/min]
    noise_rms_m_s2 : float [m/s^2]
        Sensor noise per channel.
    seed : int
        Noise seed.
    revolutions : float [-]
        Length of the run.
    onset_revolution : float [-]
        Where the chip width steps up (chatter runs).
    """

    kind: str
    spindle_rpm: float
    noise_rms_m_s2: float
    seed: int = 0
    revolutions: float = 60.0
    onset_revolution: float = 25.0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"kind: expected one of {KINDS}, got {self.kind!r}")


@dataclass(frozen=True, eq=False)
class LabelledRun:
    """Signals of a case and their label.

    Attributes
    ----------
    case : LabelledCase
    signals : SensorSignals
    onset_s : float [s]
        Time of the step (nan for stable runs).
    boundary : float [-]
        The case's full-discretization margin (chip-width scale at the boundary).
    label : str
        ``'stable'``, or the side that chatters after the onset: ``'tool'`` or
        ``'workpiece'`` (from the zero-order analysis, see the module doc).
    chatter_hz : float [Hz]
        The zero-order analysis's chatter frequency (nan for stable runs).
    """

    case: LabelledCase
    signals: SensorSignals
    onset_s: float
    boundary: float
    label: str
    chatter_hz: float


def _system(kind: str) -> ModalSystem:
    if kind == "workpiece":
        t = Mode.from_frequency(*STIFF_TOOL_MODE)
        w = Mode.from_frequency(*WALL_MODE)
        tool = ModalSystem.from_modes([(t, (1, 0, 0)), (t, (0, 1, 0))], source="tool")
        return ModalSystem.combine(tool, ModalSystem.from_modes([(w, (0, 1, 0))]))
    m = Mode.from_frequency(*TOOL_MODE)
    return ModalSystem.from_modes([(m, (1, 0, 0)), (m, (0, 1, 0))], source="tool")


def labelled_run(case: LabelledCase, sensors: Accelerometers | None = None) -> LabelledRun:
    """Simulate a case and sample its accelerometers.

    Parameters
    ----------
    case : LabelledCase
    sensors : Accelerometers, optional
        Default ``Accelerometers(noise_rms_m_s2=case.noise_rms_m_s2)``.

    Returns
    -------
    LabelledRun
    """
    z, x = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    cut = LocalCut(DEPTH_MM, WIDTH_MM, 1, FZ_MM)
    edges = TOOL.micro_edges(40, flank_height_mm=DEPTH_MM)
    system = _system(case.kind)
    rpm = float(case.spindle_rpm)
    g = process_gain(TOOL, COEFFICIENTS, z, z, x, cut, spindle_rpm=rpm, edges=edges,
                     n_angles=360)
    boundary = sdm_margin(g.H, system, rpm, TOOL.flutes).margin
    label, chatter_hz = "stable", math.nan
    if case.kind != "stable":
        wc = zoa_margin_detail(g.P, system, rpm, TOOL.flutes).omega_rad_s
        rec = np.abs(system.modal_receptance(np.array([wc]))[0])
        tool_part = rec[system.source == "tool"].sum()
        label = "tool" if tool_part >= rec.sum() - tool_part else "workpiece"
        chatter_hz = wc / (2 * math.pi)
    model = prepare_cut(TOOL, COEFFICIENTS, z, z, x, cut, system, rpm, edges=edges)
    rev_s = tooth_period(rpm)
    onset = math.nan if case.kind == "stable" else case.onset_revolution * rev_s
    lo, hi = STABLE_FRACTION * boundary, CHATTER_FRACTION * boundary

    def scale(t: np.ndarray) -> np.ndarray:
        return np.where(t >= onset, hi, lo) if math.isfinite(onset) else np.full(t.size, lo)

    run = simulate(model, case.revolutions, scale=scale)
    if sensors is None:
        sensors = Accelerometers(noise_rms_m_s2=case.noise_rms_m_s2)
    sig = sample_accelerometers(run.time_s, run.tool_acceleration_m_s2, sensors,
                                seed=case.seed)
    return LabelledRun(case=case, signals=sig, onset_s=onset, boundary=boundary, label=label,
                       chatter_hz=chatter_hz)


@dataclass(frozen=True)
class DetectorScore:
    """A detector's verdicts on one labelled run.

    Attributes
    ----------
    label : str
        The run's label.
    detected : str or None
        Cause of the first chatter verdict at or after the onset (None: none).
    latency_rev : float [rev]
        Revolutions from the onset to that verdict's window end (nan if none).
    false_alarms, quiet_windows : int
        Chatter verdicts among the windows that end before the onset (all
        windows of a stable run), and the number of such windows.
    """

    label: str
    detected: str | None
    latency_rev: float
    false_alarms: int
    quiet_windows: int


def score_detector(run: LabelledRun, detector: ChatterDetector) -> DetectorScore:
    """Stream a run's samples through ``detector`` (reset first) and score its verdicts."""
    detector.reset()
    a = run.signals.acceleration_m_s2
    rpm = run.case.spindle_rpm
    verdicts = detector.feed(a[:, 0], a[:, 1], rpm, TOOL.flutes)
    fs = detector.settings.sample_rate_hz
    end_s = run.signals.time_s[0] + np.array([d.sample_index for d in verdicts]) / fs
    chatter = np.array([d.chatter for d in verdicts], dtype=bool)
    onset = run.onset_s if math.isfinite(run.onset_s) else math.inf
    quiet = end_s < onset
    after = np.flatnonzero(chatter & ~quiet)
    if math.isfinite(onset) and after.size:
        first = int(after[0])
        detected, latency = verdicts[first].cause, (end_s[first] - onset) * tooth_frequency(rpm)
    else:
        detected, latency = None, math.nan
    return DetectorScore(label=run.label, detected=detected, latency_rev=float(latency),
                         false_alarms=int(np.sum(chatter & quiet)),
                         quiet_windows=int(np.sum(quiet)))
