"""Plots of a simulated run (matplotlib, Agg): acceleration spectra before and after."""

from __future__ import annotations

import numpy as np

from nc.atomic import atomic_path

from .report import spectrum

__all__ = ["plot_spectra"]


def plot_spectra(path: str, panels: list[tuple[str, np.ndarray, np.ndarray]], fs_hz: float,
                 tooth_hz: float, *, max_hz: float | None = None) -> None:
    """Amplitude spectra of accelerometer stretches, one panel each, written atomically.

    Parameters
    ----------
    path : str
        PNG file.
    panels : list of (title, before (k, 2) [m/s^2], after (k, 2) [m/s^2])
        Each panel overlays a "before" and an "after" stretch.
    fs_hz : float [Hz]
        Sample rate.
    tooth_hz : float [Hz]
        Tooth-passing frequency (its multiples are marked).
    max_hz : float [Hz], optional
        Upper end of the axis (default Nyquist).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 3.2 * len(panels)), squeeze=False)
    for ax, (title, before, after) in zip(axes[:, 0], panels, strict=True):
        for label, x, style in (("before", before, "-"), ("after", after, "-")):
            if x.shape[0] < 16:
                continue
            f, a = spectrum(x, fs_hz)
            ax.semilogy(f, np.maximum(a, 1e-3), style, lw=0.8, label=label)
        top = max_hz or fs_hz / 2
        for k in np.arange(tooth_hz, top, tooth_hz):
            ax.axvline(k, color="0.85", lw=0.5, zorder=0)
        ax.set_xlim(0, top)
        ax.set_title(title, fontsize=10)
        ax.set_ylabel("acceleration [m/s²]")
        ax.legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel(f"frequency [Hz]  (grey: tooth-passing multiples, {tooth_hz:.0f} Hz)")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
