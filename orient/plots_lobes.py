"""Plot stability lobes (PNG, written atomically)."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from nc.atomic import atomic_path
from orient.stability.lobes import Lobes

__all__ = ["plot_lobes"]

_STYLE = {"zoa": {"color": "tab:blue", "lw": 1.4, "label": "zero-order (ZOA)"},
          "sdm": {"color": "tab:red", "lw": 1.4, "ls": "--", "label": "time-periodic (FDM)"}}
#: Figure size [in] and resolution [dpi].
FIGSIZE_IN = (8.0, 4.5)
DPI = 120


#: Curves with fewer speeds than this are drawn as markers (spot checks) [-].
MARKER_BELOW = 12
#: Colours of the curves given ``labels``, in turn.
COLOURS = ("tab:gray", "tab:blue", "tab:red", "tab:green", "tab:purple")


def plot_lobes(lobes_list: Sequence[Lobes] | Lobes, operating_point: Any,
               path: str | os.PathLike, *, labels: Sequence[str] | None = None,
               suggested: Any = None) -> None:
    """Draw lobes of one or both methods on one plot and write a PNG.

    Parameters
    ----------
    lobes_list : Lobes or sequence of Lobes
        Curves to draw (e.g. the ZOA and the time-periodic lobes of one cut).
    operating_point : (float, float) or None
        ``(spindle_rpm [rev/min], depth_mm [mm])`` marked on the plot (its
        second value is read as a margin when the lobes have no depth).
    path : path-like
        PNG file; written to a temporary file in the same directory, then
        renamed onto ``path``.
    labels : sequence of str, optional
        One legend label per curve (e.g. posture and method); then each curve has
        its own colour (``COLOURS``) and the method sets the line style. Default: the
        method's name and colour.
    suggested : (float, float), optional
        ``(spindle_rpm [rev/min], depth_mm [mm])`` of a suggested speed, marked.

    Notes
    -----
    x axis: spindle speed [rev/min]; y axis: limiting depth of cut [mm] when
    every curve has a depth, else the margin [-]. Points with an infinite
    margin are left out. Uses matplotlib's Agg canvas (no display needed).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    items = [lobes_list] if isinstance(lobes_list, Lobes) else list(lobes_list)
    if not items or not all(isinstance(x, Lobes) for x in items):
        raise ValueError("lobes_list: expected one or more Lobes")
    if operating_point is not None:
        op = np.asarray(operating_point, dtype=float)
        if op.shape != (2,) or not np.all(np.isfinite(op)):
            raise ValueError(f"operating_point: expected (rpm, depth_mm) finite, got "
                             f"{operating_point!r}")
    if labels is not None and len(labels) != len(items):
        raise ValueError(f"labels: expected {len(items)}, got {len(labels)}")
    use_depth = all(x.depth_mm is not None for x in items)
    fig = Figure(figsize=FIGSIZE_IN)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ymax = 0.0
    for n, lob in enumerate(items):
        y = lob.depth_limit_mm if use_depth else lob.margin
        y = np.where(np.isfinite(y), y, np.nan)
        style = dict(_STYLE.get(lob.method, {}))
        if labels is not None:
            style["label"] = labels[n]
            style["color"] = COLOURS[n % len(COLOURS)]
        if len(lob.rpm) < MARKER_BELOW:
            style = {"color": style.get("color", "k"), "label": style.get("label"),
                     "marker": "s", "ls": "none", "ms": 5, "mfc": "none"}
        ax.plot(lob.rpm, y, **style)
        if np.any(np.isfinite(y)):
            ymax = max(ymax, float(np.nanmin(y)) * 6.0)
        if lob.kind is not None:
            flip = np.array([k == "flip" for k in lob.kind])
            if flip.any():
                ax.plot(lob.rpm[flip], y[flip], "x", color=style.get("color", "k"), ms=4,
                        label="flip (period doubling)")
    if operating_point is not None:
        ax.plot([op[0]], [op[1]], "ko", ms=6, label="operating point")
        ymax = max(ymax, 1.5 * float(op[1]))
    if suggested is not None:
        sg = np.asarray(suggested, dtype=float)
        if sg.shape != (2,) or not np.all(np.isfinite(sg)):
            raise ValueError(f"suggested: expected (rpm, depth_mm) finite, got {suggested!r}")
        ax.axvline(sg[0], color="tab:green", lw=1.0, ls=":",
                   label=f"suggested {sg[0]:.0f} rev/min")
        ymax = max(ymax, 1.5 * float(sg[1]))
    ax.set_xlabel("spindle speed [rev/min]")
    ax.set_ylabel("limiting depth of cut [mm] (depth x margin)" if use_depth
                  else "stability margin [-]")
    if ymax > 0 and math.isfinite(ymax):
        ax.set_ylim(0.0, ymax)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=DPI)
