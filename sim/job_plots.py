"""Plots of the main job (PNG bytes, for the self-contained page; no files written here)."""

from __future__ import annotations

import math

import numpy as np

from errpred.page_plots import png_bytes
from errpred.spindle import tooth_frequency

__all__ = ["error_map_png", "lobes_png", "margin_png", "posture_png", "spectra_png"]


def _figure(**kw):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(**kw)


def margin_png(distance_mm: np.ndarray, cam: np.ndarray, planned: np.ndarray,
               cutting: np.ndarray, target: float, cam_rpm: float, planned_rpm: float
               ) -> bytes:
    """Stability margin along the path [-] over tip travel [mm]: the CAM posture at the CAM
    program's spindle speed ``cam_rpm`` and the planned one at ``planned_rpm`` [min^-1]
    (each curve labelled with its speed)."""
    fig, ax = _figure(figsize=(9.0, 3.6), layout="constrained")
    d = np.where(cutting, distance_mm, np.nan)
    ax.plot(d, np.where(cutting, cam, np.nan), ".", ms=2.5, color="tab:red",
            label=f"CAM posture at {cam_rpm:.0f} min^-1")
    ax.plot(d, np.where(cutting, planned, np.nan), ".", ms=2.5, color="tab:blue",
            label=f"planned posture at {planned_rpm:.0f} min^-1")
    ax.axhline(1.0, color="k", lw=1.0, label="stability limit (margin 1)")
    ax.axhline(target, color="tab:green", lw=0.8, ls="--", label=f"target {target:g}")
    ax.set_yscale("log")
    ax.set_xlabel("tip travel along the program [mm]")
    ax.set_ylabel("stability margin [-]")
    fig.legend(loc="outside lower center", fontsize=8, ncol=4)   # off the curves
    ax.grid(True, which="both", alpha=0.3)
    return png_bytes(fig)


def posture_png(distance_mm: np.ndarray, cutting: np.ndarray,
                lead_tilt: dict[str, tuple[np.ndarray, np.ndarray]],
                rotary: dict[str, tuple[np.ndarray, np.ndarray]],
                rotary_names: tuple[str, str]) -> bytes:
    """Lead, tilt and the two rotary axes along the path [deg] over tip travel [mm], the CAM
    posture against the planned one.

    Parameters
    ----------
    distance_mm : ndarray, shape (n,) [mm]
        Tip travel of each cutter location.
    cutting : ndarray of bool, shape (n,)
        Cutter locations in the material (lead and tilt are drawn there only).
    lead_tilt : dict
        ``"CAM"`` and ``"planned"`` -> (lead (n,), tilt (n,)) [rad].
    rotary : dict
        ``"CAM"`` and ``"planned"`` -> (tip travel (m,) [mm], joints (m, 2) [rad]): the two
        rotary axes along the path (any number of points each).
    rotary_names : (str, str)
        Letters of the tilt and the rotary axis.
    """
    fig, axes = _figure(nrows=2, ncols=2, figsize=(9.0, 5.4), layout="constrained",
                        sharex=True, squeeze=False)
    colors = {"CAM": "tab:red", "planned": "tab:blue"}
    d = np.where(cutting, distance_mm, np.nan)
    for k, what in enumerate(("lead", "tilt")):
        ax = axes[0, k]
        for name, pair in lead_tilt.items():
            ax.plot(d, np.where(cutting, np.degrees(pair[k]), np.nan), ".", ms=2.5,
                    color=colors[name], label=f"{name} posture")
        ax.set_ylabel(f"{what} angle [deg]")
        ax.set_title(f"{what} (where the tool cuts)", fontsize=9)
    for k in range(2):
        ax = axes[1, k]
        for name, (dist, joints) in rotary.items():
            ax.plot(dist, np.degrees(joints[:, k]), "-", lw=1.0, color=colors[name],
                    label=f"{name} posture")
        ax.set_ylabel(f"{rotary_names[k]} axis [deg]")
        ax.set_title(f"rotary axis {rotary_names[k]} (whole path)", fontsize=9)
        ax.set_xlabel("tip travel along the program [mm]")
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    return png_bytes(fig)


def error_map_png(panels: list[tuple[str, np.ndarray, np.ndarray]], along: int = 0,
                  up: int = 2) -> bytes:
    """Error maps over the part: one panel per (title, contact points (m, 3) [mm],
    error (m,) [um]), coloured on one symmetric scale (red: material left); the
    points' coordinates ``along`` (0, 1, 2: X, Y, Z) and ``up`` are the axes (a wall
    seen from the side, X and Z; a free-form part from above, X and Y)."""
    vals = [np.asarray(e, dtype=float) for _, _, e in panels]
    lim = max((float(np.nanpercentile(np.abs(v), 99)) for v in vals if v.size), default=1.0)
    lim = max(lim, 1e-3)
    cols = 2
    rows = math.ceil(len(panels) / cols)
    fig, axes = _figure(nrows=rows, ncols=cols, figsize=(9.0, 2.9 * rows),
                        layout="constrained", squeeze=False)
    sc = None
    for ax, (title, pts, err) in zip(axes.flat, panels, strict=False):
        pts = np.asarray(pts, dtype=float).reshape(-1, 3)
        e = np.asarray(err, dtype=float)
        rms = float(np.sqrt(np.nanmean(e ** 2))) if e.size else math.nan
        sc = ax.scatter(pts[:, along], pts[:, up], c=e, s=9, cmap="RdBu_r", vmin=-lim,
                        vmax=lim)
        ax.set_title(f"{title}\nRMS {rms:.2f} um, largest |E| {np.nanmax(np.abs(e)):.1f} um",
                     fontsize=9)
        ax.set_xlabel(f"{'XYZ'[along]} [mm]")
        ax.set_ylabel(f"{'XYZ'[up]} [mm]")
        if up != 2:
            ax.set_aspect("equal", adjustable="datalim")
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    if sc is not None:
        fig.colorbar(sc, ax=axes, label="surface error [um] (+ material left)", shrink=0.8)
    return png_bytes(fig)


def lobes_png(items: list[dict], cam_rpm: float | None = None) -> bytes:
    """Zero-order lobes (limiting depth [mm] over speed [rev/min]) at each representative
    point, CAM posture and planned posture, with the operating point (and the CAM
    program's at ``cam_rpm`` [rev/min] when it differs)."""
    fig, axes = _figure(nrows=1, ncols=len(items), figsize=(4.6 * len(items), 3.6),
                        layout="constrained", squeeze=False)
    for ax, it in zip(axes.flat, items, strict=True):
        for key, color, label in (("cam", "tab:red", "CAM posture"),
                                  ("planned", "tab:blue", "planned posture")):
            lb = it[key]
            ax.plot(lb.rpm, lb.depth_limit_mm, color=color, lw=1.3, label=label)
        rpm, depth = it["operating_point"]
        ax.plot([rpm], [depth], "k*", ms=11, label=f"operating point, {rpm:.0f} min^-1")
        if cam_rpm is not None and abs(cam_rpm - rpm) > 0.5:
            ax.plot([cam_rpm], [depth], "x", color="tab:red", ms=9, mew=2,
                    label=f"CAM program's speed, {cam_rpm:.0f} min^-1")
        top = max(float(np.nanmax(np.where(np.isfinite(it[k].depth_limit_mm),
                                           it[k].depth_limit_mm, np.nan)))
                  for k in ("cam", "planned"))
        ax.set_ylim(0.0, min(top * 1.05, 6 * depth))
        ax.set_title(f"point {it['point']}: {it['why']}", fontsize=9)
        ax.set_xlabel("spindle speed [rev/min]")
        ax.set_ylabel("limiting depth of cut [mm]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    return png_bytes(fig)


def spectra_png(panels: list[tuple[str, np.ndarray, np.ndarray, float]], teeth: int,
                max_hz: float) -> bytes:
    """Averaged acceleration spectra: (title, f [Hz], amplitude [m/s^2], rpm) per panel,
    tooth-passing harmonics marked."""
    fig, axes = _figure(nrows=len(panels), ncols=1, figsize=(9.0, 2.3 * len(panels)),
                        layout="constrained", squeeze=False, sharex=True)
    for ax, (title, f, a, rpm) in zip(axes.flat, panels, strict=True):
        tooth = tooth_frequency(rpm, teeth)
        for k in range(1, int(max_hz / tooth) + 1):
            ax.axvline(k * tooth, color="0.85", lw=0.8, zorder=0)
        m = f <= max_hz
        ax.semilogy(f[m], np.maximum(a[m], 1e-6), lw=0.8, color="tab:blue")
        ax.set_title(title, fontsize=9)
        ax.set_ylabel("[m/s^2]")
        ax.grid(True, which="major", alpha=0.3)
    axes.flat[-1].set_xlabel("frequency [Hz] (grey: tooth-passing harmonics)")
    return png_bytes(fig)
