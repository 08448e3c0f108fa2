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
    """One frame, shape (3, 3); see :func:`tool_frames`."""
    return tool_frames(np.asarray(axis)[None, :], np.asarray(feed)[None, :], rotation_sign)[0]
