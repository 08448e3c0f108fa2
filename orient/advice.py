"""Advice at one cutter location: a spindle speed, and the largest stable depth and pick
feed at it (the patent's 8th embodiment), for the CAM posture and the planned one.

``python -m orient lobes`` draws on it. The steps:

1. :func:`planned_posture` -- the posture the planner would choose at this point alone:
   the planner's candidates (lead x tilt grid plus the CAM's), those inside the
   inclination range and the machine's axis limits, scored by the zero-order margin
   capped at ``margin_target`` (ties to the posture nearest the CAM's); the best one
   whose shank, holder and flank clear the stock and the design. Without smoothness
   along the path: ``python -m orient plan`` may choose differently where the axis may
   not turn that fast.
2. Lobes of both postures over the speed range (zero-order by default).
3. :func:`suggest_speed` -- the speed of the range whose stable depth at the planned
   posture, *lowest within +-* ``LOBES_SPEED_MARGIN`` *of it*, is largest: a lobe
   pocket, with room on both sides for a lobe that sits off by that much.
4. :func:`largest_stable` -- the patent's 8th embodiment: the largest stable axial depth
   (the scenario's pick feed kept) and the largest stable pick feed (the depth kept) at
   the planned posture and the suggested speed, each divided by a safety factor.

A ball-end cut's process gain is not proportional to its depth or pick feed (the
engaged part of the ball changes), so the limits are roots of ``margin(x) = 1`` with
the gain recomputed at each trial cut, not ``depth x margin``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import brentq

from .constants import (
    GAIN_ANGLES_PER_REV,
    LOBES_LIMIT_FACTOR,
    LOBES_LIMIT_RTOL,
    LOBES_SAFETY_FACTOR,
    LOBES_SPEED_MARGIN,
)
from .engagement import LocalCut
from .gain import process_gain, process_gain_batch
from .geometry import inclination, lead_tilt_of, posture_axis
from .pointwise import PointSetup
from .scenario import PlanScenario
from .stability import recommended_samples, sdm_margin, zoa_margin, zoa_margin_batch

__all__ = ["POSTURE_CHECKS", "PlannedPosture", "StableLimit", "largest_stable", "margin_at",
           "planned_posture", "sdm_gain", "suggest_speed", "window_minimum", "with_axis"]

#: Most candidates checked for interference, best first, before the point is called
#: one without a feasible posture [-] (each check: one FCL query).
POSTURE_CHECKS = 40


@dataclass(frozen=True)
class PlannedPosture:
    """The planner's choice at one point (:func:`planned_posture`).

    ``axis`` (3,) unit; ``lead_deg``, ``tilt_deg`` [deg]; ``margin`` [-] its zero-order
    margin at ``rpm`` [rev/min]; ``feasible`` False when no candidate is (then the CAM
    posture is returned).
    """

    axis: np.ndarray
    lead_deg: float
    tilt_deg: float
    margin: float
    rpm: float
    feasible: bool


@dataclass(frozen=True)
class StableLimit:
    """Largest stable value of a cut parameter (:func:`largest_stable`).

    ``value`` [mm] the limit (``margin(value) = 1``); ``capped`` True when the cut is
    still stable at the largest value tried (``value`` is then that cap: "at least").
    """

    value: float
    capped: bool


def window_minimum(rpm: np.ndarray, values: np.ndarray, margin: float) -> np.ndarray:
    """Per speed, the lowest of ``values`` over the speeds within ``+-margin`` (a
    fraction) of it [same unit as ``values``].

    Parameters
    ----------
    rpm : ndarray, shape (r,) [rev/min]
        Spindle speeds, increasing.
    values : ndarray, shape (r,)
    margin : float [-]
        Relative half-width of the window, >= 0.
    """
    r = np.asarray(rpm, dtype=float)
    v = np.asarray(values, dtype=float)
    lo = np.searchsorted(r, r * (1.0 - margin), side="left")
    hi = np.searchsorted(r, r * (1.0 + margin), side="right")
    return np.array([v[a:b].min() for a, b in zip(lo, hi, strict=True)])


def suggest_speed(rpm: np.ndarray, depth_limit_mm: np.ndarray,
                  margin: float = LOBES_SPEED_MARGIN) -> tuple[float, float]:
    """The speed whose stable depth, lowest within ``+-margin`` of it, is largest.

    Parameters
    ----------
    rpm : ndarray, shape (r,) [rev/min]
        Spindle speeds, increasing (the range allowed).
    depth_limit_mm : ndarray, shape (r,) [mm]
        Limiting depth (or margin) at each speed (inf where no boundary).
    margin : float [-]
        Relative distance kept from the lobe boundary in speed.

    Returns
    -------
    (float, float)
        The speed [rev/min] and its window's lowest limit [mm]; ties go to the middle
        of the plateau (farthest from both of its ends).
    """
    r = np.asarray(rpm, dtype=float)
    if r.ndim != 1 or r.size == 0 or np.any(np.diff(r) <= 0):
        raise ValueError("rpm: expected increasing spindle speeds")
    w = window_minimum(r, depth_limit_mm, margin)
    best = np.flatnonzero(w >= w.max() * (1.0 - 1e-9)) if np.isfinite(w.max()) \
        else np.flatnonzero(np.isinf(w))
    # the plateau containing the first best point; its middle
    run = best[: 1 + int(np.argmax(np.diff(best) > 1)) if np.any(np.diff(best) > 1)
               else len(best)]
    i = int(run[len(run) // 2])
    return float(r[i]), float(w[i])


def largest_stable(margin_of: Callable[[float], float], start: float, x_max: float, *,
                   factor: float = LOBES_LIMIT_FACTOR, rtol: float = LOBES_LIMIT_RTOL
                   ) -> StableLimit:
    """Largest ``x`` in ``(0, x_max]`` with ``margin_of(x) >= 1``: the root of
    ``margin_of(x) = 1`` found by scanning from ``start`` by ``factor`` (down while
    unstable, up while stable) and Brent's method on ``log margin`` in the bracket.

    Parameters
    ----------
    margin_of : callable
        ``x [mm] -> margin [-]`` (inf when nothing cuts).
    start : float [mm]
        First trial value, > 0.
    x_max : float [mm]
        Largest value considered.
    factor : float [-]
        Scan step, > 1.
    rtol : float [-]
        Relative tolerance of the root; its lower end is returned.
    """
    if not (0 < start and math.isfinite(start) and factor > 1 and x_max > 0):
        raise ValueError("largest_stable: expected 0 < start, x_max and factor > 1")
    x = min(start, x_max)
    m = margin_of(x)
    if m >= 1.0:
        while True:
            if x >= x_max:
                return StableLimit(float(x_max), True)
            lo, x = x, min(x * factor, x_max)
            m = margin_of(x)
            if m < 1.0:
                hi = x
                break
    else:
        while True:
            hi, x = x, x / factor
            if x < start * 1e-6:
                return StableLimit(0.0, False)
            m = margin_of(x)
            if m >= 1.0:
                lo = x
                break

    def f(t: float) -> float:
        mt = margin_of(t)
        return math.log(mt) if mt > 0 else -1e3

    if not math.isfinite(margin_of(lo)):     # nothing cuts at lo: no log there
        return StableLimit(_bisect(margin_of, lo, hi, rtol), False)
    root = brentq(f, lo, hi, rtol=rtol, xtol=1e-12)
    return StableLimit(float(root) * (1.0 - rtol), False)


def _bisect(margin_of: Callable[[float], float], lo: float, hi: float, rtol: float) -> float:
    """Bisection on ``margin >= 1`` (where ``log margin`` is not finite at ``lo``)."""
    while hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        if margin_of(mid) >= 1.0:
            lo = mid
        else:
            hi = mid
    return lo


def margin_at(scn: PlanScenario, setup: PointSetup, axis: np.ndarray, cut: LocalCut,
              rpm, method: str = "zoa") -> float:
    """Margin [-] of the cut ``cut`` at ``setup``'s point with tool ``axis``: the lowest
    over the speeds ``rpm`` [rev/min] (a float or an array), by ``'zoa'`` or ``'sdm'``
    (H sampled as fine as the time-periodic analysis recommends)."""
    from .stability import zoa_lobes

    tool = scn.base.tool
    i = setup.index
    c = setup.contacts
    speeds = np.atleast_1d(np.asarray(rpm, dtype=float))
    system = setup.system.with_tool_axis(axis)
    g = process_gain(tool, scn.base.coefficients, axis, c.normal[i], c.feed[i], cut,
                     spindle_rpm=float(speeds[0]))
    if method == "zoa":
        return float(np.min(zoa_lobes(g.P, system, tool.flutes, speeds)))
    if g.engaged_fraction <= 0.0:
        return math.inf
    g = sdm_gain(scn, setup, axis, cut, float(speeds[0]), g.engaged_fraction)
    return min(sdm_margin(g.H, system, float(r), tool.flutes).margin for r in speeds)


def sdm_gain(scn: PlanScenario, setup: PointSetup, axis: np.ndarray, cut: LocalCut,
             rpm: float, engaged_fraction: float):
    """Process gain with ``H`` in as many steps as :func:`recommended_samples` asks for
    (as the planner's time-periodic check)."""
    tool = scn.base.tool
    i = setup.index
    c = setup.contacts
    n = max(GAIN_ANGLES_PER_REV,
            recommended_samples(min(1.0, max(engaged_fraction, 1e-3))) * tool.flutes)
    return process_gain(tool, scn.base.coefficients, axis, c.normal[i], c.feed[i], cut,
                        spindle_rpm=rpm, n_angles=n)


def planned_posture(scn: PlanScenario, setup: PointSetup, rpm: float) -> PlannedPosture:
    """The posture the planner would choose at ``setup``'s point alone at ``rpm``.

    The planner's candidate grid and limits (:mod:`orient.plan` steps 2, 3 and 5 at one
    point; no smoothness along the path), scored by the zero-order margin capped at
    ``margin_target`` less a small preference for the CAM posture; the best of at most
    ``POSTURE_CHECKS`` candidates whose shank, holder and flank clear stock and design.
    """
    from .plan import CAM_PREFERENCE_PER_RAD, _reachable, candidate_grid

    opt = scn.options
    tool = scn.base.tool
    i = setup.index
    c = setup.contacts
    n, f = c.normal[i], c.feed[i]
    lead, tilt = candidate_grid(opt)
    L, T = np.meshgrid(lead, tilt, indexing="ij")
    cam_axis = np.asarray(setup.axis, dtype=float)
    axes = np.vstack([posture_axis(n[None], f[None], L.ravel(), T.ravel()), cam_axis[None]])
    incl = inclination(axes, n[None])
    tips = c.centre[i][None] - tool.radius_mm * axes
    ok = (incl >= opt.min_inclination_rad - 1e-9) & (incl <= opt.max_inclination_rad + 1e-9)
    ok &= _reachable(scn.machine(), tips, axes)
    margin = np.full(len(axes), -np.inf)
    sel = np.flatnonzero(ok)
    if len(sel):
        cuts = np.empty(len(sel), dtype=object)
        cuts[:] = [setup.cut] * len(sel)
        g = process_gain_batch(tool, scn.base.coefficients, axes[sel], np.tile(n, (len(sel), 1)),
                               np.tile(f, (len(sel), 1)), cuts)
        dirs = setup.system.directions_for_axes(axes[sel])
        margin[sel] = zoa_margin_batch(g.P, setup.system, rpm, tool.flutes,
                                       mode_directions=dirs)
    pref = CAM_PREFERENCE_PER_RAD * np.arccos(np.clip(axes @ cam_axis, -1.0, 1.0))
    score = np.where(ok, np.minimum(margin, opt.margin_target) - pref, -np.inf)
    order = [int(k) for k in np.argsort(-score, kind="stable") if np.isfinite(score[k])]
    chosen = None
    if order:
        checker = scn.interference_checker()
        for a in range(0, min(len(order), POSTURE_CHECKS), 8):
            batch = order[a:a + 8]
            res = checker.check(tips[batch], axes[batch])
            free = ~res.collides & ~res.gouges
            if free.any():
                chosen = batch[int(np.argmax(free))]
                break
    feasible = chosen is not None
    k = chosen if feasible else len(axes) - 1
    if not feasible:
        margin[k] = zoa_margin(_gain_p(scn, setup, cam_axis), setup.system.with_tool_axis(
            cam_axis), rpm, tool.flutes)
    ld, td = lead_tilt_of(axes[k], n, f)
    return PlannedPosture(axes[k], math.degrees(float(ld)), math.degrees(float(td)),
                          float(margin[k]), float(rpm), feasible)


def _gain_p(scn: PlanScenario, setup: PointSetup, axis: np.ndarray) -> np.ndarray:
    i = setup.index
    return process_gain(scn.base.tool, scn.base.coefficients, axis, setup.contacts.normal[i],
                        setup.contacts.feed[i], setup.cut, spindle_rpm=setup.spindle_rpm).P


def with_axis(setup: PointSetup, axis: np.ndarray) -> PointSetup:
    """``setup`` with the tool at ``axis`` (tool modes carried with it)."""
    u = np.asarray(axis, dtype=float)
    return replace(setup, system=setup.system.with_tool_axis(u), axis=u)


@dataclass(frozen=True, eq=False)
class Advice:
    """What ``python -m orient lobes`` shows (:func:`advise`).

    Attributes
    ----------
    setup : PointSetup
        The point, with the CAM posture.
    planned : PlannedPosture
        The planner's posture at the point, at the suggested speed.
    lobes : list of (str, Lobes)
        ``(label, lobes)`` per curve: CAM and planned posture, each by the method(s) run;
        the time-periodic check's few speeds among them.
    suggested_rpm : float [rev/min]
        :func:`suggest_speed` on the planned posture's lobes.
    window_depth_mm : float [mm]
        The lowest limiting depth (gain-scaled) within the speed margin of it.
    depth_limit, pick_limit : StableLimit [mm]
        Largest stable depth (the pick feed kept) and pick feed (the depth kept) at the
        planned posture and the suggested speed, before the safety factor.
    safety_factor : float [-]
    limit_method : str
        The method of the limits (``'sdm'`` where the check disagreed with ``'zoa'``).
    sdm_disagrees : bool
        The time-periodic check found the window's limit lower than the zero-order
        method by more than ``LOBES_SDM_DISAGREE``.
    seconds : dict
        Time per stage [s].
    """

    setup: PointSetup
    planned: PlannedPosture
    lobes: list
    suggested_rpm: float
    window_depth_mm: float
    depth_limit: StableLimit
    pick_limit: StableLimit
    safety_factor: float
    limit_method: str
    sdm_disagrees: bool
    engaged_fraction: float
    seconds: dict


def _posture_label(name: str, lead_deg: float, tilt_deg: float) -> str:
    return f"{name} posture (lead {lead_deg:.0f}, tilt {tilt_deg:.0f} deg)"


_METHOD_LABEL = {"zoa": "zero-order", "sdm": "time-periodic"}


def advise(scn: PlanScenario, setup: PointSetup, rpm: np.ndarray, *, method: str = "auto",
           safety_factor: float = LOBES_SAFETY_FACTOR,
           progress: Callable[[str, int, int], None] | None = None) -> Advice:
    """Lobes of the CAM and the planned posture, a suggested speed and the largest
    stable depth and pick feed there (module docstring).

    Parameters
    ----------
    scn : PlanScenario
    setup : PointSetup
        The point with the CAM posture (:func:`orient.pointwise.point_setup`).
    rpm : ndarray, shape (r,) [rev/min]
        Spindle speeds of the diagram, increasing: the range a speed is suggested from.
    method : str
        ``'auto'``: zero-order lobes, checked by the time-periodic method at
        ``LOBES_SDM_SPEEDS`` speeds across the suggested speed's window (planned
        posture), and the limits by the time-periodic method where it disagrees;
        ``'zoa'``: zero-order only; ``'sdm'``: time-periodic lobes and limits.
    safety_factor : float [-]
        The limits are divided by it (>= 1).
    progress : callable, optional
        ``progress(stage, done, total)``.
    """
    import time

    from .constants import LOBES_SDM_DISAGREE, LOBES_SDM_SPEEDS
    from .stability import Lobes, stability_lobes

    if method not in ("auto", "zoa", "sdm"):
        raise ValueError(f"method: expected 'auto', 'zoa' or 'sdm', got {method!r}")
    if not (math.isfinite(safety_factor) and safety_factor >= 1.0):
        raise ValueError(f"safety_factor: expected a finite value >= 1, got {safety_factor!r}")
    say = progress or (lambda stage, done, total: None)
    tool = scn.base.tool
    i = setup.index
    c = setup.contacts
    cut = setup.cut
    seconds: dict[str, float] = {}
    t = time.perf_counter()

    def lap(name: str) -> None:
        nonlocal t
        now = time.perf_counter()
        seconds[name] = seconds.get(name, 0.0) + now - t
        t = now

    def gain(axis: np.ndarray, r: float, c_: LocalCut = cut):
        return process_gain(tool, scn.base.coefficients, axis, c.normal[i], c.feed[i], c_,
                            spindle_rpm=r)

    def lobes_of(axis: np.ndarray, m: str, speeds: np.ndarray, stage: str):
        system = setup.system.with_tool_axis(axis)
        g = gain(axis, float(speeds[0]))
        if m == "zoa":
            return stability_lobes(g.H, system, tool.flutes, speeds, "zoa", cut.depth_mm)
        if g.engaged_fraction > 0:
            g = sdm_gain(scn, setup, axis, cut, float(speeds[0]), g.engaged_fraction)
        out = []
        for k, r in enumerate(speeds):
            out.append(stability_lobes(g.H, system, tool.flutes, [r], "sdm", cut.depth_mm))
            say(stage, k + 1, len(speeds))
        return Lobes(np.asarray(speeds, float), np.concatenate([x.margin for x in out]), "sdm",
                     cut.depth_mm, tuple(k for x in out for k in x.kind))

    base = "sdm" if method == "sdm" else "zoa"
    cam_axis = np.asarray(setup.axis, dtype=float)
    say("planned posture", 0, 1)
    planned = planned_posture(scn, setup, setup.spindle_rpm)
    lap("posture")
    # the planned posture's lobes give the speed; the posture is chosen again at it
    first = lobes_of(planned.axis, "zoa", rpm, "lobes")
    s_rpm, _ = suggest_speed(rpm, first.depth_limit_mm)
    lap("lobes")
    if s_rpm != planned.rpm:
        planned = planned_posture(scn, setup, s_rpm)
        lap("posture")
    pl = lobes_of(planned.axis, base, rpm, "planned posture, time-periodic lobes")
    cm = lobes_of(cam_axis, base, rpm, "CAM posture, time-periodic lobes")
    s_rpm, w_depth = suggest_speed(rpm, pl.depth_limit_mm)
    lap("lobes")
    cl_lead, cl_tilt = lead_tilt_of(cam_axis, c.normal[i], c.feed[i])
    cam_label = _posture_label("CAM", math.degrees(float(cl_lead)), math.degrees(float(cl_tilt)))
    curves = [(f"{cam_label}, {_METHOD_LABEL[base]}", cm),
              (f"{_posture_label('planned', planned.lead_deg, planned.tilt_deg)}, "
               f"{_METHOD_LABEL[base]}", pl)]
    g_plan = gain(planned.axis, s_rpm)
    disagrees = False
    limit_method = base
    if method == "auto" and g_plan.engaged_fraction > 0:
        from .constants import LOBES_SPEED_MARGIN as M

        win = s_rpm * (1.0 + M * np.linspace(-1.0, 1.0, LOBES_SDM_SPEEDS))
        chk = lobes_of(planned.axis, "sdm", win, "time-periodic check")
        curves.append(("planned posture, time-periodic check", chk))
        w_sdm = float(np.min(chk.depth_limit_mm))
        if w_sdm < w_depth * (1.0 - LOBES_SDM_DISAGREE):
            disagrees = True
            limit_method = "sdm"
        w_depth = min(w_depth, w_sdm)
        lap("time-periodic check")
    # the patent's 8th embodiment: the largest stable depth and pick feed, the lowest
    # over the suggested speed's window (zero-order on the diagram's speeds in it; and
    # the time-periodic method at the check's lowest speed where it disagreed)
    from .constants import LOBES_SPEED_MARGIN as M

    inside = (rpm >= s_rpm * (1.0 - M)) & (rpm <= s_rpm * (1.0 + M))
    window = rpm[inside] if inside.any() else np.array([s_rpm])
    sdm_rpm = float(chk.rpm[int(np.argmin(chk.margin))]) if limit_method == "sdm" \
        and method == "auto" else s_rpm
    cap = tool.radius_mm

    def cut_margin(c_: LocalCut) -> float:
        if base == "sdm":
            return margin_at(scn, setup, planned.axis, c_, s_rpm, "sdm")
        m = margin_at(scn, setup, planned.axis, c_, window, "zoa")
        if limit_method == "sdm":
            m = min(m, margin_at(scn, setup, planned.axis, c_, sdm_rpm, "sdm"))
        return m

    def depth_margin(d: float) -> float:
        say("largest stable depth", 0, 1)
        return cut_margin(replace(cut, depth_mm=d))

    def pick_margin(p: float) -> float:
        say("largest stable pick feed", 0, 1)
        return cut_margin(replace(cut, pick_mm=p))

    m0 = cut_margin(cut)
    start_d = cut.depth_mm * (m0 if math.isfinite(m0) and m0 > 0 else 1.0)
    d_lim = largest_stable(depth_margin, max(start_d, 1e-3), cap)
    p_lim = largest_stable(pick_margin, max(cut.pick_mm, 1e-3), cap) \
        if cut.previous_side != 0 else StableLimit(float("nan"), False)
    lap("limits")
    return Advice(setup, planned, curves, s_rpm, w_depth, d_lim, p_lim, float(safety_factor),
                  limit_method, disagrees, float(g_plan.engaged_fraction), seconds)
