"""Which micro edges cut during one revolution at a cutter location.

``docs/method.md`` §3-4: a micro edge cuts at a rotation step if the point
of the cutting-edge envelope it occupies holds material that the previous
tooth left: inside the stock and outside every sweep up to one feed per
tooth before this location (T1). The membership test is exact for the swept
tool solids (``errpred/_kernels.py``); the stock answers through the depth
buffer of the current view (``errpred/raster``) or analytically for a box.

With the rotation divided into ``n`` steps, ``n`` a multiple of the number of
flutes ``N``, flute ``k`` at step ``i`` occupies the positions of flute 0 at
step ``i + k n / N``: one flute's engagement is computed and the others are
read from it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ._cluster_kernels import inside_any_sweep_clustered
from .constants import CLUSTER_CELL_MM, MEMBERSHIP_EPS_MM
from .tool import MicroEdges, Tool

__all__ = ["Engagement", "revolution_angles", "edge_points_tool", "engage", "expand_flutes"]


def revolution_angles(angle_step_rad: float, flutes: int) -> np.ndarray:
    """Rotation angles of one revolution, a multiple of ``flutes`` steps [rad].

    The step actually used is the largest one not above ``angle_step_rad``
    that divides the tooth pitch, and the count is even (for the FFT).
    """
    if not (math.isfinite(angle_step_rad) and 0 < angle_step_rad <= math.pi / 2):
        raise ValueError(f"angle_step_rad: expected 0 < step <= pi/2, got {angle_step_rad!r}")
    per_tooth = math.ceil((2 * math.pi / flutes) / angle_step_rad - 1e-9)
    n = per_tooth * flutes
    if n % 2:
        n *= 2
    return np.arange(n) * (2 * math.pi / n)


def edge_points_tool(edges: MicroEdges, theta: np.ndarray) -> np.ndarray:
    """Flute-0 micro-edge positions over a revolution, tool frame, (n, m, 3) [mm]."""
    phi = theta[:, None] - edges.psi[None, :]
    rho = edges.rho[None, :]
    return np.stack(np.broadcast_arrays(rho * np.sin(phi), rho * np.cos(phi),
                                        edges.z[None, :]), axis=-1)


@dataclass(frozen=True, eq=False)
class Engagement:
    """One revolution's engagement at a cutter location (flute 0 stored).

    Attributes
    ----------
    theta : ndarray, shape (n,) [rad]
        Rotation angles of flute 0's tip.
    cutting0 : ndarray, shape (n, m), bool
        Flute 0's micro edge j cuts at step i.
    step_length : ndarray, shape (n, m) [mm]
        Path of each micro edge through the workpiece during step i (rotation
        and feed), the increment of its actual cutting distance when cutting.
    """

    theta: np.ndarray
    cutting0: np.ndarray
    step_length: np.ndarray

    @property
    def any(self) -> bool:
        return bool(self.cutting0.any())

    def cutting_distance_per_rev(self) -> np.ndarray:
        """Actual cutting distance per revolution of each micro edge, (m,) [mm]."""
        return np.where(self.cutting0, self.step_length, 0.0).sum(axis=0)


def expand_flutes(theta: np.ndarray, cutting0: np.ndarray, edges: MicroEdges,
                  flutes: int) -> tuple[np.ndarray, np.ndarray]:
    """Angles and cutting masks of every flute, each (n, N, m).

    ``phi[i, k, j] = theta_i + 2 pi k / N - psi_j``; flute k at step i cuts
    where flute 0 cuts at step ``i + k n / N``.
    """
    n = theta.shape[0]
    if n % flutes:
        raise ValueError(f"{n} rotation steps are not a multiple of {flutes} flutes")
    shift = n // flutes
    idx = (np.arange(n)[:, None] + shift * np.arange(flutes)[None, :]) % n
    cutting = cutting0[idx]  # (n, N, m)
    phi = (theta[:, None, None] + (2 * math.pi / flutes) * np.arange(flutes)[None, :, None]
           - edges.psi[None, None, :])
    return phi, cutting


def engage(tool: Tool, edges: MicroEdges, frame: np.ndarray, tip: np.ndarray,
           feed_per_rev_world: np.ndarray, theta: np.ndarray,
           in_stock: Callable[[np.ndarray], np.ndarray],
           t1: tuple[np.ndarray, ...]) -> Engagement:
    """Engagement of flute 0 over one revolution at a cutter location.

    Parameters
    ----------
    tool : Tool
    edges : MicroEdges
    frame : ndarray, shape (3, 3)
        Tool frame rows x', y', z' (``errpred/frames.py``).
    tip : ndarray, shape (3,) [mm]
    feed_per_rev_world : ndarray, shape (3,) [mm]
        Tool displacement per revolution (feed direction x feed / speed).
    theta : ndarray, shape (n,) [rad]
        From :func:`revolution_angles`.
    in_stock : callable
        ``in_stock(points (k, 3)) -> bool (k,)``: material of the stock.
    t1 : tuple of ndarray
        ``(p0, d, w, lo, hi)`` of the sweeps before this location
        (:meth:`errpred.sweeps.Sweeps.clipped`), likeliest containers first.
    """
    pts_tool = edge_points_tool(edges, theta)  # (n, m, 3)
    n, m, _ = pts_tool.shape
    world = tip + pts_tool.reshape(-1, 3) @ frame
    cand = in_stock(world)
    p0, d, w, lo, hi = t1
    removed = inside_any_sweep_clustered(world, cand, p0, d, w, lo, hi, tool.core_radius_mm,
                               tool.corner_radius_mm, tool.flute_length_mm,
                               MEMBERSHIP_EPS_MM,
                                        CLUSTER_CELL_MM)
    cutting0 = (cand & ~removed).reshape(n, m)
    # path of each edge point through the workpiece per step: rotation + feed
    step = 2 * math.pi / n
    nxt = edge_points_tool(edges, theta + step)
    feed_tool = frame @ np.asarray(feed_per_rev_world, dtype=float)
    move = nxt - pts_tool + feed_tool * (step / (2 * math.pi))
    return Engagement(theta=theta, cutting0=cutting0,
                      step_length=np.linalg.norm(move, axis=-1))
