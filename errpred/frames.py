"""Tool frames at cutter locations (``docs/method.md`` §1).

Tool frame: origin at the tip, ``z'`` = tool axis ``u``, ``x'`` = the feed
direction projected onto the plane normal to ``u``, ``y' = z' x x'``. For a
counter-clockwise (M4) spindle the frame is mirrored (``x'`` reversed), so
that every kernel computes as for a clockwise tool: the mirror image of a
counter-clockwise cut is a clockwise cut.

A frame is a (3, 3) matrix whose rows are ``x'``, ``y'``, ``z'`` in world
coordinates: ``p_tool = F @ (p_world - tip)``, ``p_world = tip + F.T @ p_tool``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["tool_frames", "tool_frame"]


def tool_frames(axis: np.ndarray, feed: np.ndarray, rotation_sign: int = 1) -> np.ndarray:
    """Frames for n cutter locations, shape (n, 3, 3).

    Parameters
    ----------
    axis : ndarray, shape (n, 3)
        Unit tool axes.
    feed : ndarray, shape (n, 3)
        Feed directions (any length). Where the feed is along the axis (a
        plunge) or zero, ``x'`` is world X projected (world Y if X is along
        the axis).
    rotation_sign : int
        +1 clockwise spindle, -1 counter-clockwise (mirrored frame).
    """
    u = np.asarray(axis, dtype=float).reshape(-1, 3)
    f = np.asarray(feed, dtype=float).reshape(-1, 3)
    x = f - np.sum(f * u, axis=1, keepdims=True) * u
    nx = np.linalg.norm(x, axis=1)
    bad = nx < 1e-9 * np.maximum(np.linalg.norm(f, axis=1), 1e-300)
    bad |= nx == 0
    if np.any(bad):
        ref = np.where(np.abs(u[bad, 0:1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        xb = ref - np.sum(ref * u[bad], axis=1, keepdims=True) * u[bad]
        x[bad] = xb
        nx = np.linalg.norm(x, axis=1)
    x /= nx[:, None]
    y = np.cross(u, x)
    if rotation_sign < 0:
        x = -x
    return np.stack([x, y, u], axis=1)


def tool_frame(axis, feed, rotation_sign: int = 1) -> np.ndarray:
    """One frame, shape (3, 3); see :func:`tool_frames`.

    The same arithmetic as :func:`tool_frames` on one row, in scalars (numpy's
    per-call overhead on a 3-vector is most of the cost): the dot products and
    squared norms summed left to right as numpy's row sums do, the cross product
    as ``np.cross`` forms it, so the frame is the same to the bit.
    """
    u0, u1, u2 = np.asarray(axis, dtype=float).reshape(3).tolist()
    f0, f1, f2 = np.asarray(feed, dtype=float).reshape(3).tolist()
    fu = f0 * u0 + f1 * u1 + f2 * u2
    x0, x1, x2 = f0 - fu * u0, f1 - fu * u1, f2 - fu * u2
    nx = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    nf = math.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
    if nx < 1e-9 * max(nf, 1e-300) or nx == 0:
        r0, r1, r2 = (1.0, 0.0, 0.0) if abs(u0) < 0.9 else (0.0, 1.0, 0.0)
        ru = r0 * u0 + r1 * u1 + r2 * u2
        x0, x1, x2 = r0 - ru * u0, r1 - ru * u1, r2 - ru * u2
        nx = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    x0, x1, x2 = x0 / nx, x1 / nx, x2 / nx
    y0, y1, y2 = u1 * x2 - u2 * x1, u2 * x0 - u0 * x2, u0 * x1 - u1 * x0
    if rotation_sign < 0:
        x0, x1, x2 = -x0, -x1, -x2
    return np.array([[x0, x1, x2], [y0, y1, y2], [u0, u1, u2]])
