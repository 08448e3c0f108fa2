"""Time-domain milling with regeneration (``docs/method.md`` §8).

The force model is errpred's micro-edge model, the engagement orient's
(:func:`orient.engagement.engagement`: which micro edges of which flute are in the
material at each rotation sample of a finishing cut, and their static chip ``h0``; taken
as flute 0's, ``flute_engagement``, and its cutting samples of every flute,
``FluteEngagement.entries``), with its trailing edges (``trailing=True``: in the
material the tooth before left, first-order chip 0 -- a ball's sliver
``-fz/2 < (p - c).f <= 0``, which errpred's rasterizer keeps too). Those rub: the law's zero-chip
force, no chip term (``F1 = 0``), their static chip the thickness the tooth before left
(second order, ``fz^2 / 2R`` at most). The surface is generated among them, so their
edge force is in the deflection the surface keeps: without them the simulated surface of
the bundled thin wall kept 1-2 um less than errpred's prediction on every tilted pass.
The dynamics orient's
:class:`~orient.dynamics.ModalSystem`
(tool modes turned with the axis, workpiece modes along their directions;
``q`` is the relative displacement, tool minus workpiece, in the workpiece
frame [m]).

At each step, each micro edge that the static engagement puts in the
material has the chip

    ``h = h0 + n . (q(t) - S)``

with ``n`` its outward envelope normal (the chip direction) and ``S`` the
relative displacement with which the previous flute left the surface at the
same place: regeneration from the surface, not from a fixed delay. ``S`` is
kept as a vector, so that when the posture changes (another chip direction
for the same place) the old surface is read along the new direction. If
``h > 0`` the edge cuts, its force is ``s (F0 + h F1)`` (chip widths scaled
by ``s``; ``F0, F1`` per entry from the force law, :mod:`errpred.laws`: the
tangent of ``F(h)`` at the static chip ``h0``, ``F1 = dF/dh(h0)``,
``F0 = F(h0) - h0 F1``; for the linear and Lee-Altintas laws the law itself,
``F0`` the edge force; for Kienzle's law exact at ``h0`` and to first order in
the vibration, as orient's stability analysis linearises it, while a
rubbing edge (``-EDGE_RUB_MM < h <= 0``) then gets the tangent's ``F0``,
not the law's zero-chip force) and it leaves ``S = q(t)``;
otherwise it leaves the material as it was (``S`` moves back by ``h0`` along
``n``: the next flute meets a thicker chip) -- the tool jumping out of the
cut is the model's nonlinearity. For small vibrations this is the
linear model that orient's stability analysis uses
(``F = s H(t) (q(t) - q(t - tau))``), which the tests check.

Each mode ``m eta'' + c eta' + k eta = d . F`` is advanced exactly for the
force held over the step (its 2x2 matrix exponential); the force is taken
with the displacement predicted at the middle of the step, so the hold is
centred (no half-step lag in the regenerative loop). The step only has to
sample the force finely: ``STEPS_PER_MODE_PERIOD`` steps per period of the
highest mode at least, and at least ``MIN_STEPS_PER_REV`` per revolution.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg

from errpred.engagement import revolution_angles
from errpred import laws
from errpred.coefficients import LawCoefficients
from errpred.force import to_tool_frame
from errpred.spindle import tooth_frequency, tooth_period
from errpred.tool import MicroEdges, Tool, core_distance
from nc.checks import real_number
from orient.dynamics import ModalSystem
from orient.engagement import LocalCut, flute_engagement

from . import _kernels as _k
from .constants import (
    BOUNDARY_RTOL,
    EDGE_RUB_MM,
    GROWTH_LINEAR_FRACTION,
    GROWTH_MIN_POINTS,
    GROWTH_SKIP_REVOLUTIONS,
    MAX_STEPS_PER_REV,
    MICRO_EDGES_ENVELOPE,
    MIN_STEPS_PER_REV,
    MM_PER_M,
    RAMP_REVOLUTIONS,
    STEP_MAP_UNDERDAMPED,
    STEPS_PER_MODE_PERIOD,
)
from .cutting_model import CuttingModel
from .forced import forced_response
from .generation import edge_spacing_rad, generating_weights, tooth_surface

__all__ = [
    "CuttingModel",
    "MillingRun",
    "forced_response",
    "generating_weights",
    "growth_rate",
    "prepare_cut",
    "simulate",
    "stability_boundary",
    "steps_per_rev_for",
    "with_system",
]



@dataclass(frozen=True, eq=False)
class MillingRun:
    """A simulated run.

    Attributes
    ----------
    time_s : ndarray, shape (n,) [s]
    force_N : ndarray, shape (n, 3) [N]
        Force on the tool, workpiece frame.
    displacement_m : ndarray, shape (n, 3) [m]
        Relative displacement, tool minus workpiece, workpiece frame (at the
        middle of each step).
    tool_acceleration_m_s2 : ndarray, shape (n, 3) [m/s^2]
        Acceleration of the tool alone (its modes), workpiece frame: what
        sensors on the spindle see.
    modal_state : ndarray, shape (n_teeth, nm, 2)
        ``(eta, eta')`` once per tooth period (the Poincare section) [m, m/s].
    chip_mean_mm : ndarray, shape (n,) [mm]
        Mean chip of the edges in contact at each step.
    contact_loss : ndarray, shape (n,) [-]
        Engaged micro edges whose chip fell to zero (the tool left the cut).
    surface_offset_mm : ndarray, shape (n_teeth,) [mm]
        Relative displacement along the surface normal once per tooth, at the
        phase where the lowest engaged edge generates the surface: the
        generated surface's deviation (positive: the tool stood off, material
        left), chatter marks show as its variation.
    scale : float [-]
        Chip-width scale of the run (nan when it was a function of time).
    """

    time_s: np.ndarray
    force_N: np.ndarray
    displacement_m: np.ndarray
    tool_acceleration_m_s2: np.ndarray
    modal_state: np.ndarray
    chip_mean_mm: np.ndarray
    contact_loss: np.ndarray
    surface_offset_mm: np.ndarray
    scale: float


def steps_per_rev_for(f_max_hz: float, spindle_rpm: float, flutes: int) -> int:
    """Default rotation steps per revolution for a highest mode of ``f_max_hz`` [Hz]:
    ``STEPS_PER_MODE_PERIOD`` per its period, at least ``MIN_STEPS_PER_REV``, a
    multiple of the flutes and even, as the engagement samples it
    (``errpred.engagement.revolution_angles``); refused above ``MAX_STEPS_PER_REV``."""
    n = _steps_per_rev_raw(f_max_hz, spindle_rpm)
    n = _checked(flutes * math.ceil(n / flutes), spindle_rpm)
    return int(revolution_angles(2.0 * math.pi / n, flutes).size)


def _steps_per_rev_raw(f_max_hz: float, spindle_rpm: float) -> int:
    return max(MIN_STEPS_PER_REV, math.ceil(STEPS_PER_MODE_PERIOD * f_max_hz
                                                  / tooth_frequency(spindle_rpm)))


def _checked(n: int, spindle_rpm: float) -> int:
    if n > MAX_STEPS_PER_REV:
        raise ValueError(f"steps_per_rev: {n} steps per revolution are needed for the highest "
                         f"mode at {spindle_rpm:g} rev/min, more than MAX_STEPS_PER_REV="
                         f"{MAX_STEPS_PER_REV}; drop modes far above the tooth frequency")
    return n


def _steps_per_rev(system: ModalSystem, spindle_rpm: float, flutes: int,
                   steps_per_rev: int | None) -> int:
    if steps_per_rev is None:
        f_max = float(system.natural_frequency_rad_s.max()) / (2.0 * math.pi)
        n = _steps_per_rev_raw(f_max, spindle_rpm)
    else:
        if isinstance(steps_per_rev, bool) or not isinstance(steps_per_rev, (int, np.integer)) \
                or steps_per_rev < 4 * flutes:
            raise ValueError(f"steps_per_rev: expected an integer >= {4 * flutes}, "
                             f"got {steps_per_rev!r}")
        n = int(steps_per_rev)
    return _checked(flutes * math.ceil(n / flutes), spindle_rpm)


def _step_map(system: ModalSystem, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretization of each mode ``m q'' + c q' + k q = F`` over
    ``dt`` [s]: ``phi`` (nm, 2, 2) maps ``(q, q')`` over a step, ``gam`` (nm, 2) is the
    response to a unit force held over it.

    Underdamped modes (all of the machine's) in closed form, with ``s = zeta w``,
    ``wd = w sqrt(1 - zeta^2)``, ``S = sin(wd dt) / wd``, ``C = cos(wd dt)``:
    ``phi = exp(-s dt) [[C + s S, S], [-w^2 S, C - s S]]`` and
    ``gam = [(1 - phi_11 - 2 s phi_01) / (m w^2), phi_01 / m]`` (``A^-1 (Phi - I) B``);
    modes damped near or above critical by the matrix exponential (Van Loan).
    """
    m = np.asarray(system.m_kg, dtype=float)
    c = np.asarray(system.c_Ns_m, dtype=float)
    k = np.asarray(system.k_N_m, dtype=float)
    w2 = k / m
    s = 0.5 * c / m
    wd2 = w2 - s * s
    under = wd2 > STEP_MAP_UNDERDAMPED * w2
    wd = np.sqrt(np.where(under, wd2, 1.0))
    e = np.exp(-s * dt)
    S = np.sin(wd * dt) / wd
    C = np.cos(wd * dt)
    phi = np.empty((m.size, 2, 2))
    phi[:, 0, 0] = e * (C + s * S)
    phi[:, 0, 1] = e * S
    phi[:, 1, 0] = -e * w2 * S
    phi[:, 1, 1] = e * (C - s * S)
    gam = np.empty((m.size, 2))
    gam[:, 0] = (1.0 - phi[:, 1, 1] - 2.0 * s * phi[:, 0, 1]) / k
    gam[:, 1] = phi[:, 0, 1] / m
    for j in np.flatnonzero(~under):
        # Van Loan: expm([[A, B], [0, 0]] dt) = [[Phi, Gamma B], [0, I]]
        big = np.zeros((3, 3))
        big[:2, :2] = [[0.0, 1.0], [-w2[j], -2.0 * s[j]]]
        big[1, 2] = 1.0 / m[j]
        ex = scipy.linalg.expm(big * dt)
        phi[j] = ex[:2, :2]
        gam[j] = ex[:2, 2]
    return phi, gam


def prepare_cut(tool: Tool, coeffs: LawCoefficients, posture_axis: Any, normal: Any,
                feed_dir: Any, cut: LocalCut, system: ModalSystem, spindle_rpm: float, *,
                edges: MicroEdges | None = None, steps_per_rev: int | None = None,
                cutting_distance_mm: float = 0.0) -> CuttingModel:
    """The engagement table and the modes' step map of one cut.

    Parameters
    ----------
    tool : errpred.tool.Tool
    coeffs : errpred.coefficients.LawCoefficients
        The force law's coefficients (:mod:`errpred.laws`).
    posture_axis, normal, feed_dir : array_like, shape (3,) [-]
        Tool axis, outward surface normal and feed direction at the contact
        (workpiece frame).
    cut : orient.engagement.LocalCut
        Depth, pick feed, previous pass, feed per tooth.
    system : orient.dynamics.ModalSystem
        Relative dynamics; its tool modes are carried to ``posture_axis``.
    spindle_rpm : float [rev/min]
    edges : MicroEdges, optional
        Micro edges of one flute (default ``MICRO_EDGES_ENVELOPE`` on the envelope).
    steps_per_rev : int, optional
        Rotation steps per revolution (default from the highest mode).
    cutting_distance_mm : float [mm]
        The tool's cutting distance so far (errpred's wear term of the edge force).

    Returns
    -------
    CuttingModel
    """
    rpm = real_number("spindle_rpm", spindle_rpm, ">0")
    cl = real_number("cutting_distance_mm", cutting_distance_mm, ">=0")
    if not isinstance(system, ModalSystem):
        raise TypeError(f"system: expected an orient.dynamics.ModalSystem, got "
                         f"{type(system).__name__}")
    u = np.asarray(posture_axis, dtype=float)
    system = system.with_tool_axis(u)
    if edges is None:
        edges = tool.micro_edges(MICRO_EDGES_ENVELOPE)
    spr = _steps_per_rev(system, rpm, tool.flutes, steps_per_rev)
    # the trailing edges (chip 0, in the material the tooth before left) rub: their edge
    # force acts where the surface is generated, as in errpred's engagement
    eng = flute_engagement(tool, edges, u, normal, feed_dir, cut, n_angles=spr, trailing=True)
    spr = eng.theta.size                       # rounded to the flutes and even
    spt = spr // tool.flutes
    i, f, j, phi, h0 = eng.entries()           # (angle sample, flute, edge), i sorted
    # within a sample by surface position, then edge: the kernel walks two tables' entries
    # at a sample side by side (sim._kernels._leave); the order in which a flute wraps
    # past the last position is the only change (two flutes cutting at one sample)
    order = np.lexsort((j, (i + f * spt) % spr, i))
    i, f, j, phi, h0 = (x[order] for x in (i, f, j, phi, h0))
    kappa = edges.kappa[j]
    db = edges.db[j]
    # the law's per-entry table: the tangent of F(h) at the static chip; a trailing edge
    # (first-order chip 0) rubs: the law's zero-chip force, no chip term, as errpred's
    fh = laws.force(coeffs, h0, kappa, cl)
    rub = h0 <= 0.0
    gh = tuple(np.where(rub, 0.0, gx) for gx in laws.slope(coeffs, h0, kappa))
    zero = to_tool_frame(*((fx - h0 * gx) * db for fx, gx in zip(fh, gh)), phi, kappa)
    frame = eng.frame
    f0 = zero @ frame
    f1 = to_tool_frame(*(gx * db for gx in gh), phi, kappa) @ frame
    if rub.any():       # its chip: what the tooth before left there (second order in fz)
        h0 = h0.copy()
        h0[rub] = _left_by_tooth_before(tool, edges, j[rub], phi[rub],
                                        frame @ eng.f_tooth_world)
    nrm = edges.take(j).normals(phi) @ frame * MM_PER_M
    ptr = np.searchsorted(i, np.arange(spr + 1)).astype(np.int64)
    pos = ((i + f * spt) % spr).astype(np.int64)
    table = (ptr, pos, j.astype(np.int64), np.ascontiguousarray(h0),
             np.ascontiguousarray(nrm), np.ascontiguousarray(f0), np.ascontiguousarray(f1))
    dt = tooth_period(rpm, spr)
    n = np.asarray(eng.normal, dtype=float)
    gen = generating_weights(table, spr, tool.flutes, n, eng.f_tooth_world / cut.fz_mm, cut,
                             tool.corner_radius_mm, edge_spacing_rad(edges))
    return CuttingModel(spindle_rpm=rpm, flutes=tool.flutes, steps_per_rev=spr, dt_s=dt,
                        system=system, normal=n, fz_mm=cut.fz_mm, table=table,
                        n_edges=len(edges), step_map=_step_map(system, dt), generating=gen)


def _left_by_tooth_before(tool: Tool, edges: MicroEdges, j: np.ndarray, phi: np.ndarray,
                          f_tooth_tool: np.ndarray) -> np.ndarray:
    """Thickness of the material the tooth before left outside micro edges ``j`` at angular
    positions ``phi`` [rad]: their distance outside the tool solid one feed per tooth back
    (``f_tooth_tool``, tool frame [mm]), at least 0 [mm]. Where the first-order chip
    ``f . n`` is 0 (a ball's trailing sliver) it is ``fz^2 / 2R`` at most. A positive static
    chip keeps the kernel's rule for an edge that misses its cut (the next flute meets
    the thicker chip) from leaving a rubbing edge out of contact for good."""
    rho, z = edges.rho[j], edges.z[j]
    x = rho * np.sin(phi) + f_tooth_tool[0]
    y = rho * np.cos(phi) + f_tooth_tool[1]
    d = core_distance(np.hypot(x, y), z + f_tooth_tool[2], tool.core_radius_mm,
                      tool.corner_radius_mm)
    return np.maximum(d - tool.corner_radius_mm, 0.0)


def with_system(model: CuttingModel, system: ModalSystem, posture_axis: Any) -> CuttingModel:
    """The same engagement with other dynamics (e.g. the wall's modes at the next
    cutter location); the tool modes are carried to ``posture_axis``."""
    system = system.with_tool_axis(np.asarray(posture_axis, dtype=float))
    return CuttingModel(spindle_rpm=model.spindle_rpm, flutes=model.flutes,
                        steps_per_rev=model.steps_per_rev, dt_s=model.dt_s, system=system,
                        normal=model.normal, fz_mm=model.fz_mm, table=model.table,
                        n_edges=model.n_edges, step_map=_step_map(system, model.dt_s),
                        generating=model.generating)


def empty_table(steps_per_rev: int) -> tuple:
    """An engagement table that cuts nothing (``CuttingModel.table`` layout)."""
    return (np.zeros(steps_per_rev + 1, dtype=np.int64), np.zeros(0, dtype=np.int64),
            np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)),
            np.zeros((0, 3)))


@functools.lru_cache(maxsize=4)
def _empty_table(steps_per_rev: int) -> tuple:
    """:func:`empty_table`, made once per ``steps_per_rev`` (the kernel only reads it; a
    run's ticks each made a new one). Not marked read-only: numba would compile the
    kernel a second time for read-only arrays."""
    return empty_table(steps_per_rev)


def _integrate(model: CuttingModel, step: int, scale: np.ndarray, linear: bool,
               surface: np.ndarray, state: np.ndarray, force: np.ndarray, disp: np.ndarray,
               acc: np.ndarray, chip: np.ndarray, lost: np.ndarray,
               previous: tuple | None = None, blend: np.ndarray | None = None) -> None:
    """The kernel over ``scale.size`` steps from step ``step`` (its rotation sample), with
    the model's table, modes and step map; ``surface`` and ``state`` carry in and out.
    ``previous`` (a table) is blended in with weight ``blend`` (per step)."""
    sysm = model.system
    phi_d, gam_d = model.step_map
    spr = model.steps_per_rev
    if previous is None:
        previous, blend = _empty_table(spr), np.zeros(scale.size)
    _k.integrate(step % spr, scale.size, spr, *model.table, *previous, blend,
                 phi_d, gam_d, np.ascontiguousarray(sysm.direction), scale, sysm.k_N_m,
                 sysm.c_Ns_m, sysm.m_kg, sysm.velocity_s, np.asarray(sysm.source == "tool"),
                 bool(linear), EDGE_RUB_MM, 0.5 * model.dt_s, surface, state, force, disp, acc,
                 chip, lost)


def simulate(model: CuttingModel, revolutions: float, *, scale: Any = 1.0,
             ramp_revolutions: float = RAMP_REVOLUTIONS, linear: bool = False) -> MillingRun:
    """Run the cut for a number of revolutions from rest.

    Parameters
    ----------
    model : CuttingModel
    revolutions : float [-]
        Duration in spindle revolutions, > 0.
    scale : float or callable [-]
        Chip-width scale (1: the cut as given; the stability margin is the
        scale at which the cut starts to chatter), or a function of the time
        array [s] returning it per step (a change of depth during the run).
    ramp_revolutions : float [-]
        The scale rises linearly from 0 over this many revolutions.
    linear : bool
        Keep every engaged edge cutting even where its chip falls below zero:
        the linearized model of the stability analysis. Default False: the
        tool leaves the cut where the chip vanishes.

    Returns
    -------
    MillingRun
    """
    rev = real_number("revolutions", revolutions, ">0")
    if callable(scale):
        s = math.nan
    else:
        s = real_number("scale", scale, ">=0")
    ramp = real_number("ramp_revolutions", ramp_revolutions, ">=0")
    spr, spt = model.steps_per_rev, model.steps_per_tooth
    n_teeth = max(1, math.ceil(rev * model.flutes))
    n = n_teeth * spt
    t = np.arange(n) * model.dt_s
    if callable(scale):
        sc = np.asarray(scale(t), dtype=float).reshape(-1)
        if sc.shape != (n,) or not np.all(np.isfinite(sc)) or np.any(sc < 0):
            raise ValueError("scale: the function must return one finite value >= 0 per step")
    else:
        sc = np.full(n, s)
    if ramp > 0:
        sc *= np.minimum(np.arange(n) / (ramp * spr), 1.0)
    nm = model.system.n_modes
    state = np.zeros((nm, 2))
    surface = np.zeros((spr, model.n_edges, 3))
    force = np.empty((n, 3))
    disp = np.empty((n, 3))
    acc = np.empty((n, 3))
    chip = np.empty(n)
    lost = np.empty(n, dtype=np.int64)
    poincare = np.empty((n_teeth, nm, 2))
    for k in range(n_teeth):                  # one kernel call per tooth: the Poincare state
        sl = slice(k * spt, (k + 1) * spt)
        _integrate(model, k * spt, sc[sl], linear, surface, state, force[sl], disp[sl],
                   acc[sl], chip[sl], lost[sl])
        poincare[k] = state
    surf = tooth_surface(disp, model, 0)
    return MillingRun(time_s=t, force_N=force, displacement_m=disp, tool_acceleration_m_s2=acc,
                      modal_state=poincare,
                      chip_mean_mm=chip, contact_loss=lost, surface_offset_mm=surf, scale=s)


def growth_rate(run: MillingRun, model: CuttingModel) -> float:
    """Growth of the deviation from the periodic (forced) motion per tooth period.

    The Poincare states (once per tooth) of a stable cut converge to a fixed
    point; their successive differences shrink by the critical Floquet
    multiplier per tooth. Returns the slope of ``log |difference|`` per tooth
    from ``GROWTH_SKIP_REVOLUTIONS`` after the ramp until the displacement
    (once per tooth) departs from its settled value by ``GROWTH_LINEAR_FRACTION``
    of the feed per tooth (where the tool starts to leave the cut and growth
    saturates): < 0 stable, > 0 chatter [1/tooth].
    """
    x = run.modal_state.reshape(run.modal_state.shape[0], -1)
    w = np.sqrt(np.maximum(model.system.k_N_m, 1e-300))       # energy-like weights
    wm = np.sqrt(np.maximum(model.system.m_kg, 1e-300))
    wts = np.stack([w, wm], axis=1).reshape(-1)
    d = np.linalg.norm(np.diff(x, axis=0) * wts, axis=1)       # (n,) per tooth
    n = d.size
    ramp_end = math.ceil(RAMP_REVOLUTIONS * model.flutes)
    first = ramp_end + math.ceil(GROWTH_SKIP_REVOLUTIONS * model.flutes)
    # deviation of the Poincare samples of the displacement from their settled value
    amp = run.displacement_m[::model.steps_per_tooth][1:n + 1] * MM_PER_M
    ref = np.median(amp[min(first, n - 1):], axis=0) if n else np.zeros(3)
    dev = np.linalg.norm(amp - ref, axis=1)
    over = np.flatnonzero(dev > GROWTH_LINEAR_FRACTION * model.fz_mm)
    over = over[over >= first]
    last = int(over[0]) if over.size else n
    if last - first < GROWTH_MIN_POINTS:        # left the linear range early: grew in the ramp
        first = max(1, last - max(GROWTH_MIN_POINTS, ramp_end))
    k = np.arange(first, last)
    k = k[d[k] > 0]
    if k.size < GROWTH_MIN_POINTS:
        raise ValueError("growth_rate: too few tooth periods to fit a growth rate; simulate "
                         "more revolutions")
    return float(np.polyfit(k, np.log(d[k]), 1)[0])


def stability_boundary(model: CuttingModel, lo: float, hi: float, *, revolutions: float = 60.0,
                       rtol: float = BOUNDARY_RTOL, linear: bool = False) -> float:
    """Chip-width scale where the simulated growth rate crosses zero (bisection).

    Parameters
    ----------
    model : CuttingModel
    lo, hi : float [-]
        A bracket: the cut is stable at ``lo`` and chatters at ``hi``
        (checked; a ValueError names the end that is not).
    revolutions : float [-]
        Length of each run.
    rtol : float [-]
        Relative width of the final bracket.
    linear : bool
        As in :func:`simulate`.

    Returns
    -------
    float
        The boundary scale (the bracket's midpoint) [-].
    """
    lo = real_number("lo", lo, ">0")
    hi = real_number("hi", hi, ">0")
    if hi <= lo:
        raise ValueError(f"hi: expected a scale above lo={lo:g}, got {hi:g}")

    def rate(s: float) -> float:
        return growth_rate(simulate(model, revolutions, scale=s, linear=linear), model)

    if rate(lo) >= 0:
        raise ValueError(f"lo: the cut already chatters at scale {lo:g}")
    if rate(hi) <= 0:
        raise ValueError(f"hi: the cut is still stable at scale {hi:g}")
    while hi - lo > rtol * hi:
        mid = math.sqrt(lo * hi)
        if rate(mid) < 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
