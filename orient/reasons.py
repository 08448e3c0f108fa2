"""Why each planned point has its posture (``orient.plan``'s ``PlanResult.reason``)."""

from __future__ import annotations

import math

import numpy as np

from nc.path import CutterLocations

from .choice import _APPROACH, _FEASIBLE, _IN_PASS, _RETRACT, _Inherited

__all__: list[str] = []


def _reasons(cam: CutterLocations, idx: np.ndarray, inh: _Inherited, choice: np.ndarray,
             S1: int, none: np.ndarray, cause: np.ndarray, final_cause: np.ndarray,
             labels: list[str], margin: np.ndarray, sense: np.ndarray, lead: np.ndarray,
             tilt: np.ndarray, cam_lead: np.ndarray, cam_tilt: np.ndarray, target: float,
             cam_margin: np.ndarray, cam_rpm: float | None) -> list[str]:
    """Why each point has its posture (one line each, true to the checks made).

    ``cause`` (t, S1): rejection codes of the candidates (``labels``);
    ``final_cause`` (n,): code of the planned posture in the final check of the path
    (0 free or not checked). The reasons of infeasible points (touching points without
    a feasible candidate, points whose planned posture collides) start with
    ``"infeasible: "``. ``margin`` is at the planned speed; ``cam_margin`` (t,) the CAM
    posture's at the program's speed ``cam_rpm`` [rev/min] (None: the same speed).
    """
    n = len(cam)
    row_of = np.full(n, -1)
    row_of[inh.point] = inh.row
    kind_of = np.full(n, _IN_PASS)
    if inh.kind is not None:
        kind_of[inh.point] = inh.kind
    out = []
    for i in range(n):
        r = row_of[i]
        if r < 0:
            txt = ("rapid move" if cam.rapid[i] else "not touching the design") + \
                ": CAM posture (no cutting point in the pass)"
        elif none[r]:
            txt = ("rapid move" if cam.rapid[i] else "not touching the design") + \
                (f": CAM posture, as at point {idx[r]} of the pass, which has no feasible "
                 f"posture")
        elif kind_of[i] == _RETRACT:
            txt = (f"rapid move (retract): posture of the last cutting point of the pass "
                   f"it leaves ({idx[r]})")
        elif kind_of[i] == _APPROACH:
            txt = (f"rapid move (approach): posture of the first cutting point of the pass "
                   f"it enters ({idx[r]})")
        else:
            txt = ("rapid move" if cam.rapid[i] else "not touching the design") + \
                f": posture of the nearest cutting point of the pass ({idx[r]})"
        out.append(txt)
    for r, i in enumerate(idx):
        j = choice[r]
        m, mc = margin[r, j], cam_margin[r]
        where = (f"lead {math.degrees(lead[i]):+.1f} tilt {math.degrees(tilt[i]):+.1f} deg, "
                 f"{'up' if sense[r, j] > 0 else 'down'}-cut {sense[r, j]:+.2f}")
        cam_txt = (f"CAM posture (lead {math.degrees(cam_lead[i]):+.1f} tilt "
                   f"{math.degrees(cam_tilt[i]):+.1f}) margin {mc:.2f}"
                   + ("" if cam_rpm is None else f" at {cam_rpm:g} rev/min")
                   + ("" if cause[r, -1] == _FEASIBLE else
                      f", infeasible: {labels[cause[r, -1]]}"))
        if none[r]:
            codes, counts = np.unique(cause[r], return_counts=True)
            why = ", ".join(f"{c} {labels[k]}" for k, c in
                            sorted(zip(codes, counts), key=lambda kc: -kc[1]))
            cam_state = ("" if final_cause[i] == 0 else
                         f", which collides ({labels[final_cause[i]]})")
            out[i] = (f"no feasible posture: all {S1} candidates rejected ({why}); CAM "
                      f"posture kept{cam_state}, margin {m:.2f}")
        elif j == S1 - 1:
            out[i] = f"CAM posture kept: margin {m:.2f} ({where})"
        elif m >= target:
            out[i] = f"margin {m:.2f} >= target {target:g} at {where}; {cam_txt}"
        else:
            out[i] = (f"margin {m:.2f} below target {target:g}, the best of a smooth path, "
                      f"at {where}; {cam_txt}")
    for i in np.flatnonzero(final_cause):
        if not out[i].startswith("no feasible posture"):
            out[i] = f"planned posture collides ({labels[final_cause[i]]}); {out[i]}"
    for i in np.flatnonzero(final_cause != 0):
        out[i] = "infeasible: " + out[i]
    for i in idx[none]:
        if not out[i].startswith("infeasible: "):
            out[i] = "infeasible: " + out[i]
    return out
