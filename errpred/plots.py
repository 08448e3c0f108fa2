"""Plots of a prediction (matplotlib, PNG, written atomically).

* error along the program (E, E_d, E_p per prediction point),
* force and deflection over one revolution at a chosen block, with the
  generation instant marked (the deflection lags the force),
* an error map over the part (generation points coloured by E),
* actual cutting distance per micro edge (wear along the cutting edge).

Angles are shown in degrees, errors in um; the data stay in the package's
units until they are drawn.
"""

from __future__ import annotations

import math
import os

import numpy as np

from nc.atomic import atomic_write

from .predict import Prediction

__all__ = ["plot_error_along_program", "plot_revolution", "plot_error_map", "plot_wear",
           "revolution_png", "revolution_series", "write_all"]


def _figure(width=9.0, height=4.5):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(width, height), dpi=110)
    return fig, ax


def _save(fig, path) -> None:
    import matplotlib.pyplot as plt

    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", bbox_inches="tight")
    plt.close(fig)


def plot_error_along_program(prediction: Prediction, path, title: str = "") -> None:
    """E, E_d and E_p [um] against the program's line number."""
    pred = prediction.predicted()
    fig, ax = _figure()
    if pred:
        line = np.array([p.line for p in pred])
        E = np.array([p.result.E_um for p in pred])
        Ed = np.array([p.result.E_d_um for p in pred])
        Ep = np.array([p.result.E_p_um for p in pred])
        ax.plot(line, E, ".", ms=2.5, color="C0", label="E = E_d + E_p")
        ax.plot(line, Ed, ".", ms=1.5, color="C1", alpha=0.6, label="E_d (deflection)")
        ax.plot(line, Ep, ".", ms=1.5, color="C2", alpha=0.6, label="E_p (tool shape, wear)")
        k = int(np.argmax(np.abs(E)))
        ax.annotate(f"max |E| = {abs(E[k]):.2f} um\nline {line[k]}", (line[k], E[k]),
                    xytext=(10, 10), textcoords="offset points", fontsize=8,
                    arrowprops=dict(arrowstyle="->", lw=0.6))
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("program line")
    ax.set_ylabel("error along the surface normal [um]\n(+ material left, - overcut)")
    ax.set_title(title or "Predicted machining error along the program")
    ax.legend(loc="best", fontsize=8, markerscale=4)
    ax.grid(alpha=0.3)
    _save(fig, path)


def revolution_png(theta: np.ndarray, force_N: np.ndarray, deflection_mm: np.ndarray,
                   theta_m: float, title: str = "") -> bytes:
    """Force and deflection over one revolution, world X and Y, generation instant marked,
    as PNG bytes (for a page; :func:`plot_revolution` writes them to a file).

    Parameters
    ----------
    theta : ndarray, shape (n,) [rad]
    force_N : ndarray, shape (n, 3) [N]
    deflection_mm : ndarray, shape (n, 3) [mm]
    theta_m : float [rad]
        Rotation at which the surface is generated.
    title : str
    """
    import io

    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6), dpi=110, sharex=True)
    deg = np.degrees(theta)
    for k, name in enumerate("XY"):
        a1.plot(deg, force_N[:, k], color=f"C{k}", label=f"F{name.lower()}")
        a2.plot(deg, deflection_mm[:, k] * 1e3, color=f"C{k}", label=f"D{name.lower()}")
    a1.plot(deg, force_N[:, 2], color="C2", lw=0.8, label="Fz")
    for ax in (a1, a2):
        ax.axvline(math.degrees(theta_m % (2 * math.pi)), color="k", ls="--", lw=0.8)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    # phase lag of the dominant deflection behind its force (first tooth harmonic)
    lag = _lag_deg(force_N[:, :2], deflection_mm[:, :2])
    a1.set_ylabel("force on the tool [N]")
    a2.set_ylabel("tool deflection [um]")
    a2.set_xlabel("rotation of flute 1 [deg]   (dashed: the instant the surface is generated)")
    a1.set_title((title or "Force and deflection over one revolution")
                 + (f"\ndeflection trails force by {lag:.0f} deg of rotation (cross-correlation)"
                    if lag is not None else ""))
    buf = io.BytesIO()
    fig.savefig(buf, format="png", bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def plot_revolution(theta: np.ndarray, force_N: np.ndarray, deflection_mm: np.ndarray,
                    theta_m: float, path, title: str = "") -> None:
    """:func:`revolution_png` written to ``path`` (atomically)."""
    png = revolution_png(theta, force_N, deflection_mm, theta_m, title)
    with atomic_write(path, "wb") as fh:
        fh.write(png)


def _lag_deg(force: np.ndarray, defl: np.ndarray) -> float | None:
    """Rotation by which the deflection trails the force [deg].

    The circular cross-correlation of the force and the deflection in the
    plane normal to the axis (components X, Y): the shift that best aligns
    the deflection with the force.
    """
    f = force[:, 0] + 1j * force[:, 1]
    d = defl[:, 0] + 1j * defl[:, 1]
    f = f - f.mean()
    d = d - d.mean()
    if not np.any(np.abs(f) > 0):
        return None
    corr = np.fft.ifft(np.fft.fft(d) * np.conj(np.fft.fft(f)))
    k = int(np.argmax(corr.real))
    return 360.0 * k / f.shape[0]


def plot_error_map(prediction: Prediction, path, title: str = "") -> None:
    """Generation points (X, Y) coloured by the error [um]."""
    pred = prediction.predicted()
    fig, ax = _figure(7.5, 6.0)
    if pred:
        pts = np.array([p.geometry.gen.point_world for p in pred])
        E = np.array([p.result.E_um for p in pred])
        lim = float(np.abs(E).max()) or 1.0
        sc = ax.scatter(pts[:, 0], pts[:, 1], c=E, s=4, cmap="coolwarm", vmin=-lim, vmax=lim)
        fig.colorbar(sc, ax=ax, label="error [um] (+ material left)")
        ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("X [mm]")
    ax.set_ylabel("Y [mm]")
    ax.set_title(title or "Predicted error over the part")
    _save(fig, path)


def plot_wear(prediction: Prediction, path, title: str = "") -> None:
    """Actual cutting distance of each micro edge, against its contact angle."""
    fig, ax = _figure()
    kap = np.degrees(prediction.edges_kappa_rad)
    z = prediction.edges_z_mm
    flank = kap >= 89.999
    x = np.where(flank, 90.0 + (z - z[flank].min() if flank.any() else 0.0), kap)
    ax.plot(x, prediction.wear_mm / 1e3, ".-", ms=3)
    ax.set_xlabel("contact angle kappa [deg]  (beyond 90: height up the flank [mm] + 90)")
    ax.set_ylabel("actual cutting distance [m]")
    ax.set_title(title or "Actual cutting distance per micro edge (wear along the edge)")
    ax.grid(alpha=0.3)
    _save(fig, path)


def revolution_series(prediction: Prediction) -> tuple | None:
    """The revolution kept for a plot: ``(line, theta [rad], force_N (n, 3), deflection_mm
    (n, 3), theta_m [rad])`` of the first line asked for (``series_lines``), else of the
    point with the largest |E|; None when none was kept."""
    if not prediction.series:
        return None
    key = next((k for k in prediction.series if k != -1), -1)
    item = prediction.series[key]
    line = key if key != -1 else item[4]
    return (line, item[3], item[0], item[1], item[2])


def write_all(prediction: Prediction, directory, revolution=None, name: str = "") -> list[str]:
    """Write every plot into ``directory``; returns the file paths.

    ``revolution``: ``(line, theta, force_N, deflection_mm, theta_m)`` for the
    per-revolution plot, or None to skip it.
    """
    os.makedirs(directory, exist_ok=True)
    out = []
    p = os.path.join(directory, "error_along_program.png")
    plot_error_along_program(prediction, p, f"{name}: predicted error along the program")
    out.append(p)
    p = os.path.join(directory, "error_map.png")
    plot_error_map(prediction, p, f"{name}: predicted error over the part")
    out.append(p)
    p = os.path.join(directory, "wear_per_micro_edge.png")
    plot_wear(prediction, p, f"{name}: actual cutting distance per micro edge")
    out.append(p)
    if revolution is not None:
        line, theta, force, defl, tm = revolution
        p = os.path.join(directory, f"revolution_line{line}.png")
        plot_revolution(theta, force, defl, tm, p, f"{name}: line {line}")
        out.append(p)
    return out
