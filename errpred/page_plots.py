"""Figures of the predict and compensate pages (PNG bytes; no files written here).

* the error on the part: a wall unrolled (arc length along its contour x Z), a
  free-form surface seen from above (X x Y), one panel per program (before and
  after correction) on one colour scale;
* the error per waterline level or per pass: its smallest and largest value.

Errors in um, lengths in mm; positive error: material left.
"""

from __future__ import annotations

import io
import math

import numpy as np

from .constants import PAGE_MIN_HALF_SPAN_MM

__all__ = ["error_on_part_png", "levels_png", "png_bytes"]

#: Figure resolution [dpi].
DPI = 110


def _figure(**kw):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt.subplots(**kw)


def png_bytes(fig) -> bytes:
    """The figure as PNG bytes (and closed)."""
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI)
    plt.close(fig)
    return buf.getvalue()


def error_on_part_png(panels: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]],
                      wall: bool) -> bytes:
    """The error over the part, one panel per ``(title, x [mm], y [mm], E [um])``.

    Parameters
    ----------
    panels : list of tuple
        ``x``, ``y``: arc length along the contour and Z for a wall (``wall``), X and Y
        of the generation points otherwise; ``E``: the error there.
    wall : bool
        Label the axes as the unrolled wall (True) or the top view (False).
    """
    vals = [np.asarray(e, float) for *_, e in panels if np.size(e)]
    lim = max((float(np.max(np.abs(v))) for v in vals), default=1.0)
    lim = max(lim, 1e-3)
    n = max(len(panels), 1)
    if wall:
        fig, axes = _figure(nrows=n, ncols=1, figsize=(9.0, 1.2 + 2.4 * n),
                            layout="constrained", squeeze=False, sharex=True)
    else:
        fig, axes = _figure(nrows=1, ncols=n, figsize=(4.8 * n + 1.2, 4.8),
                            layout="constrained", squeeze=False, sharey=True)
    sc = None
    for ax, (title, x, y, e) in zip(axes.flat, panels, strict=False):
        e = np.asarray(e, float)
        if e.size:
            sc = ax.scatter(x, y, c=e, s=7, cmap="RdBu_r", vmin=-lim, vmax=lim)
            rms = math.sqrt(float(np.mean(e ** 2)))
            title = (f"{title}\n{e.size} points, RMS {rms:.2f} um, "
                     f"{float(e.min()):+.2f} .. {float(e.max()):+.2f} um")
        ax.set_title(title, fontsize=9)
        ax.grid(alpha=0.3)
        if wall:
            ax.set_ylabel("Z [mm]")
        else:
            ax.set_xlabel("X [mm]")
            ax.set_aspect("equal", adjustable="datalim")
    if wall:
        axes.flat[-1].set_xlabel("arc length along the contour of each level [mm]")
        ys = np.concatenate([np.asarray(y, float) for _, _, y, e in panels if np.size(e)]
                            or [np.zeros(1)])
        mid, half = 0.5 * (ys.min() + ys.max()), 0.5 * (ys.max() - ys.min())
        half = max(1.08 * half, PAGE_MIN_HALF_SPAN_MM)    # one level is a line, not a band
        for ax in axes.flat:
            ax.set_ylim(mid - half, mid + half)
    else:
        axes.flat[0].set_ylabel("Y [mm]")
    if sc is not None:
        fig.colorbar(sc, ax=axes, label="error [um] (+ material left)", shrink=0.85)
    return png_bytes(fig)


def levels_png(series: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]],
               wall: bool) -> bytes:
    """Smallest and largest error per level or pass: ``(label, where, min [um], max [um])``
    per program; ``where``: the level's Z [mm] (``wall``) or the pass number."""
    fig, ax = _figure(figsize=(9.0, 3.4), layout="constrained")
    for k, (label, where, lo, hi) in enumerate(series):
        c = f"C{k}"
        ax.plot(where, hi, "^-", color=c, ms=4, lw=0.9, label=f"{label}: largest")
        ax.plot(where, lo, "v--", color=c, ms=4, lw=0.9, label=f"{label}: smallest")
        ax.fill_between(where, lo, hi, color=c, alpha=0.12)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("Z of the waterline level [mm]" if wall else "pass (runs between rapids)")
    if not wall:
        from matplotlib.ticker import MaxNLocator

        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_ylabel("error [um] (+ material left)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    return png_bytes(fig)
