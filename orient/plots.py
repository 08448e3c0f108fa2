"""Plots of a plan (matplotlib, PNG): margin over the lead/tilt grid, margin along the path.

Computation is in radians; degrees only on the axes. Files are written
atomically (``nc.atomic.atomic_path``).
"""

from __future__ import annotations

import os

import numpy as np

from nc.atomic import atomic_path
from .constants import MARGIN_CLIP

__all__ = ["plot_margin_along_path", "plot_margin_grid"]



def _figure(**kw):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt, plt.subplots(**kw)


def plot_margin_grid(lead_rad: np.ndarray, tilt_rad: np.ndarray, margin: np.ndarray,
                     feasible: np.ndarray, path: str | os.PathLike, *,
                     chosen: tuple[float, float] | None = None,
                     cam: tuple[float, float] | None = None, title: str = "",
                     clip: float = MARGIN_CLIP) -> None:
    """Stability margin over the lead/tilt grid at one cutter location.

    Parameters
    ----------
    lead_rad : ndarray, shape (nl,) [rad]
    tilt_rad : ndarray, shape (nt,) [rad]
    margin : ndarray, shape (nl, nt) [-]
    feasible : ndarray of bool, shape (nl, nt)
        False where the posture collides, leaves the axis limits or the cone
        (hatched).
    path : path-like
        PNG file.
    chosen, cam : (lead_rad, tilt_rad), optional
        The planned and the CAM posture, marked.
    clip : float [-]
        Top of the colour scale (the planner's margins are exact only below its
        ``margin_target``: pass that).
    """
    plt, (fig, ax) = _figure(figsize=(6.8, 6.0))
    try:
        bad = ~np.asarray(feasible, bool)
        m = np.minimum(np.asarray(margin, float), clip)
        m = np.where(bad, np.nan, m)              # infeasible: not evaluated, left blank
        ax.set_facecolor("0.85")
        L, T = np.degrees(lead_rad), np.degrees(tilt_rad)
        mesh = ax.pcolormesh(T, L, m, shading="nearest", cmap="RdYlGn", vmin=0.0,
                             vmax=clip)
        cb = fig.colorbar(mesh, ax=ax)
        cb.set_label(f"stability margin (clipped at {clip:g}; > 1 stable)")
        if np.isfinite(m).any() and np.nanmin(m) < 1 < np.nanmax(m):
            ax.contour(T, L, m, levels=[1.0], colors="k", linewidths=1.5)
        if bad.any():
            tt, ll = np.meshgrid(T, L)
            ax.scatter(tt[bad], ll[bad], marker="x", color="0.2", s=18,
                       label="infeasible (collision, axis limit, cone)")
        if cam is not None:
            ax.plot(np.degrees(cam[1]), np.degrees(cam[0]), "s", ms=10, mfc="none", mec="b",
                    mew=2, label="CAM posture")
        if chosen is not None:
            ax.plot(np.degrees(chosen[1]), np.degrees(chosen[0]), "*", ms=16, color="k",
                    label="planned posture")
        ax.set_xlabel("tilt [deg]")
        ax.set_ylabel("lead [deg]")
        ax.set_title(title or "stability margin over lead and tilt")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=3, fontsize=8)
        fig.tight_layout()
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
    finally:
        plt.close(fig)


def plot_margin_along_path(distance_mm: np.ndarray, margin_before: np.ndarray,
                           margin_after: np.ndarray, path: str | os.PathLike, *,
                           cutting: np.ndarray | None = None, title: str = "") -> None:
    """Stability margin along the path, CAM posture and planned posture.

    Parameters
    ----------
    distance_mm : ndarray, shape (n,) [mm]
        Tip travel along the path.
    margin_before, margin_after : ndarray, shape (n,) [-]
        Margin of the CAM's and of the planned posture (inf where not cutting).
    path : path-like
        PNG file.
    cutting : ndarray of bool, shape (n,), optional
        Points that cut (others are not drawn).
    """
    plt, (fig, ax) = _figure(figsize=(9.0, 4.2))
    try:
        x = np.asarray(distance_mm, float)
        keep = np.ones(len(x), bool) if cutting is None else np.asarray(cutting, bool)
        for m, style, label in ((margin_before, "-", "CAM posture"),
                                (margin_after, "-", "planned posture")):
            y = np.minimum(np.asarray(m, float), MARGIN_CLIP)
            y = np.where(keep, y, np.nan)
            ax.plot(x, y, style, lw=1.0, label=label)
        ax.axhline(1.0, color="k", lw=1.0, ls="--", label="stability boundary")
        ax.set_xlabel("distance along the path [mm]")
        ax.set_ylabel(f"stability margin (clipped at {MARGIN_CLIP:g})")
        ax.set_ylim(0.0, MARGIN_CLIP * 1.05)
        ax.set_title(title or "stability margin along the path")
        ax.legend(loc="upper right", fontsize=8)
        ax.grid(alpha=0.3)
        fig.tight_layout()
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=110, format="png")
    finally:
        plt.close(fig)
