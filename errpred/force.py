"""Cutting force of an end mill over one revolution (``docs/method.md`` §4).

Conventions (``docs/method.md`` §1, ``errpred/frames.py``): tool frame with the origin at the
tip, ``z'`` up the tool axis, feed along ``x'``; a flute's angle ``phi`` is
measured from ``+y'`` toward ``+x'`` (clockwise seen from the spindle), an edge
point at ``phi`` sits at ``(rho sin phi, rho cos phi, z)`` and moves along
``(cos phi, -sin phi, 0)``. The outward envelope normal at ``(phi, kappa)``
is ``n = (sin k sin phi, sin k cos phi, -cos k)``.

Per micro edge, while it cuts (units: ``h``, ``db`` [mm], forces [N])::

    dFt = Ft(h, kappa, cl) db     opposes the edge velocity
    dFr = Fr(h, kappa, cl) db     toward the centre of curvature (-n)
    dFa = Fa(h, kappa, cl) db     the third direction, a = r x t

with ``F`` the force per unit chip width of the scenario's force law
(:mod:`errpred.laws`; the linear law: ``Fx = Kxe0 + Kxe1 cl + Kxc h``). The
law is evaluated here, per cutting entry (sample, flute, micro edge); the compiled sum
(``errpred._force_kernels``) only turns the local forces to the tool frame.

and the force **on the tool**, tool frame::

    Fx' = -dFt cos phi - dFr sin k sin phi - dFa cos k sin phi
    Fy' = +dFt sin phi - dFr sin k cos phi - dFa cos k cos phi
    Fz' = +dFr cos k - dFa sin k

The unit vectors of the force on the tool are ``t = (-cos phi, sin phi, 0)``,
``r = -n`` and ``a = r x t = (-cos k sin phi, -cos k cos phi, -sin k)``. On the
flank (``k = 90 deg``) a positive ``dFa`` pushes the tool toward its tip
(``-z'``). This is the ball-end transformation of Lee & Altintas (1996); for
a flat end mill it reads ``Fz' = -Fa``, where Altintas' flat-end-mill section
(Manufacturing Automation, 2nd ed., §2.3) writes ``Fz = +Fa``: the contract's
sign is the one used, so a fitted ``Kac``/``Kae`` of a flat end mill has the
opposite sign of a value quoted in that convention.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import laws
from ._force_kernels import entry_forces_kernel
from .coefficients import LawCoefficients
from .tool import MicroEdges

__all__ = ["chip_thickness", "entry_forces", "local_components", "to_tool_frame",
           "tool_forces"]


def chip_thickness(edges: MicroEdges, phi: Any, f_tooth_tool: Any,
                   sin_cos: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Uncut chip thickness ``h = max(f_tooth . n, 0)``.

    Parameters
    ----------
    edges : MicroEdges
        ``m`` micro edges; their ``kappa`` is used.
    phi : ndarray, shape (..., m) [rad]
        Angular positions of the micro edges (helix lag included), e.g.
        (n_ang, n_fl, m).
    f_tooth_tool : ndarray, shape (3,) or broadcastable to phi.shape + (3,) [mm]
        Feed per tooth vector in the tool frame (``(fz, 0, 0)`` for feed along
        ``+x'``; an axial component for plunges and ramps). A per-sample feed
        has shape e.g. (n_ang, 1, 1, 3).
    sin_cos : tuple of ndarray, optional
        ``(sin(phi), cos(phi))`` when the caller has them already.

    Returns
    -------
    ndarray, shape of ``phi`` (broadcast with the feed) [mm]
        ``fz sin phi sin k`` for feed ``(fz, 0, 0)``, clamped at 0.
    """
    phi = np.asarray(phi, dtype=float)
    f = np.asarray(f_tooth_tool, dtype=float)
    if f.ndim == 0 or f.shape[-1] != 3:
        raise ValueError(f"f_tooth_tool: expected a vector of 3 components (last axis), got "
                         f"shape {f.shape}")
    m = len(edges)
    if phi.ndim == 0 or phi.shape[-1] != m:
        raise ValueError(f"phi: last axis must hold the {m} micro edges, got shape {phi.shape}")
    sin_phi, cos_phi = (np.sin(phi), np.cos(phi)) if sin_cos is None else sin_cos
    return _chip(f, np.sin(edges.kappa), np.cos(edges.kappa), sin_phi, cos_phi)


def _chip(f: np.ndarray, sk: np.ndarray, ck: np.ndarray, sin_phi: np.ndarray,
          cos_phi: np.ndarray) -> np.ndarray:
    """:func:`chip_thickness`' ``max(f . n, 0)`` from the sines and cosines of the micro
    edges' immersion (``sk``, ``ck``) and angular positions, broadcast (stage 2 passes
    them per cutting entry, ``errpred.physics``)."""
    return np.maximum((f[..., 0] * sk) * sin_phi + (f[..., 1] * sk) * cos_phi
                      - f[..., 2] * ck, 0.0)


def local_components(coeffs: LawCoefficients, h: Any, cl: Any, db: Any, kappa: Any
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tangential, radial and axial force of micro edges (as if all cut).

    Parameters
    ----------
    coeffs : LawCoefficients
        The force law's coefficients (:mod:`errpred.laws`).
    h : ndarray, any shape broadcasting with ``cl``, ``db`` and ``kappa`` [mm]
        Uncut chip thickness.
    cl : ndarray, broadcasting [mm]
        Actual cutting distance of the micro edge.
    db : ndarray, broadcasting [mm]
        Chip width of the micro edge.
    kappa : ndarray, broadcasting [rad]
        Axial immersion angle of the micro edge.

    Returns
    -------
    dFt, dFr, dFa : ndarray, broadcast shape [N]
        ``F(h, kappa, cl) db`` (linear law: ``(Kxe0 + Kxe1 cl + Kxc h) db``). No
        cutting mask is applied here.
    """
    db = np.asarray(db, dtype=float)
    ft, fr, fa = laws.force(coeffs, h, kappa, cl)
    return ft * db, fr * db, fa * db


def to_tool_frame(dFt: Any, dFr: Any, dFa: Any, phi: Any, kappa: Any) -> np.ndarray:
    """Local force components to the force on the tool in the tool frame.

    Parameters
    ----------
    dFt, dFr, dFa : ndarray, broadcasting [N]
        Tangential (opposing the edge velocity), radial (toward the centre
        of curvature) and axial components.
    phi : ndarray, broadcasting [rad]
        Angular position.
    kappa : ndarray, broadcasting [rad]
        Axial immersion angle.

    Returns
    -------
    ndarray, shape broadcast + (3,) [N]
        ``(Fx', Fy', Fz')`` per element; see the module docstring.
    """
    sp, cp = np.sin(phi), np.cos(phi)
    sk, ck = np.sin(kappa), np.cos(kappa)
    a = dFr * sk + dFa * ck          # in-plane part of the radial and axial forces
    fx = -dFt * cp - a * sp
    fy = dFt * sp - a * cp
    fz = dFr * ck - dFa * sk
    return np.stack(np.broadcast_arrays(fx, fy, fz), axis=-1)


def _check_inputs(edges: MicroEdges, phi: Any, h: Any, cutting: Any, cl_mm: Any
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    phi = np.asarray(phi, dtype=float)
    h = np.asarray(h, dtype=float)
    cutting = np.asarray(cutting, dtype=bool)
    if phi.ndim != 3:
        raise ValueError(f"phi: expected shape (n_angles, n_flutes, m), got {phi.shape}")
    _, n_fl, m = phi.shape
    if m != len(edges):
        raise ValueError(f"phi: last axis has {m} entries, the tool has {len(edges)} micro edges")
    if h.shape != phi.shape:
        raise ValueError(f"h: shape {h.shape} differs from phi's {phi.shape}")
    if cutting.shape != phi.shape:
        raise ValueError(f"cutting: shape {cutting.shape} differs from phi's {phi.shape}")
    cl = np.asarray(cl_mm, dtype=float)
    if cl.shape not in ((m,), (n_fl, m), (1, m), ()):
        raise ValueError(f"cl_mm: expected shape ({m},) or ({n_fl}, {m}), got {cl.shape}")
    return phi, h, cutting, np.broadcast_to(cl, (n_fl, m))


def tool_forces(edges: MicroEdges, coeffs: LawCoefficients, phi: Any, h: Any,
                cutting: Any, cl_mm: Any, weight: Any = None) -> np.ndarray:
    """Force on the tool over the sampled rotation, tool frame.

    Sums the micro-edge forces (:func:`local_components`,
    :func:`to_tool_frame`) over flutes and micro edges at each angle sample.

    Parameters
    ----------
    edges : MicroEdges
        ``m`` micro edges of one flute (all flutes alike); ``kappa`` and
        ``db`` are used.
    coeffs : LawCoefficients
        The force law's coefficients (:mod:`errpred.laws`).
    phi : ndarray, shape (n_ang, n_fl, m) [rad]
        Angular position of each micro edge of each flute at each sample.
    h : ndarray, shape (n_ang, n_fl, m) [mm]
        Uncut chip thickness (ignored where not cutting; may be NaN there).
    cutting : ndarray of bool, shape (n_ang, n_fl, m)
        Whether the micro edge cuts; non-cutting entries contribute exactly 0.
    cl_mm : ndarray, shape (m,) or (n_fl, m) [mm]
        Actual cutting distance: (m,) the same wear on every flute,
        (n_fl, m) per flute.
    weight : ndarray, shape (n_ang, n_fl, m), optional
        Fraction of each sample's rotation step spent cutting (default 1):
        the engagement's boundary resolved within a step.

    Returns
    -------
    ndarray, shape (n_ang, 3) [N]
        ``(Fx', Fy', Fz')`` on the tool at each sample.
    """
    phi, h, cutting, cl = _check_inputs(edges, phi, h, cutting, cl_mm)
    if weight is None:
        weight = np.ones(phi.shape)
    else:
        weight = np.asarray(weight, dtype=float)
        if weight.shape != phi.shape:
            raise ValueError(f"weight: shape {weight.shape} differs from phi's {phi.shape}")
    return _block_forces(edges, coeffs, phi, h, cutting, cl, weight,
                         compiled=entry_forces_kernel is not None)


def entry_forces(edges: MicroEdges, coeffs: LawCoefficients, n_ang: int, i: Any, k: Any,
                 j: Any, phi: Any, h: Any, cl_mm: Any, weight: Any = None) -> np.ndarray:
    """:func:`tool_forces` from the cutting entries alone, listed one by one (a point's
    engagement is a few per cent of its revolution's (sample, flute, micro edge) block;
    the block itself need not be made).

    Parameters
    ----------
    edges : MicroEdges
        ``m`` micro edges of one flute.
    coeffs : LawCoefficients
    n_ang : int
        Angle samples of the revolution.
    i, k, j : ndarray of int, shape (e,)
        Each entry's angle sample, flute and micro edge; in the order of ``np.nonzero``
        of the block's mask (samples, then flutes, then micro edges), the sums are
        :func:`tool_forces`' own, in its order: the same numbers.
    phi, h : ndarray, shape (e,) [rad], [mm]
        Angular position and uncut chip thickness of each entry.
    cl_mm : float or ndarray, shape (m,), (1, m) or (n_fl, m) [mm]
        Actual cutting distance, as :func:`tool_forces` takes it: one for every flute, or
        per flute (row ``k`` for the entries of flute ``k``).
    weight : ndarray, shape (e,), optional
        Each entry's share of its rotation step spent cutting (default 1).

    Returns
    -------
    ndarray, shape (n_ang, 3) [N]
        ``(Fx', Fy', Fz')`` on the tool at each sample.

    Raises
    ------
    ValueError
        Entries that do not fit: lengths that differ, non-integer indices, a sample, flute
        or micro edge out of range, ``cl_mm`` or ``weight`` of another shape.
    """
    if isinstance(n_ang, (bool, np.bool_)) or not isinstance(n_ang, (int, np.integer)) \
            or n_ang < 0:
        raise ValueError(f"n_ang: expected an integer >= 0 (angle samples), got {n_ang!r}")
    idx = []
    for name, a in (("i", i), ("k", k), ("j", j)):
        a = np.asarray(a).reshape(-1)
        if a.size and a.dtype.kind not in "iu":
            raise ValueError(f"{name}: expected integer indices, got dtype {a.dtype}")
        idx.append(a.astype(np.int64))
    i, k, j = idx
    phi = np.asarray(phi, dtype=float).reshape(-1)
    h = np.asarray(h, dtype=float).reshape(-1)
    n = i.shape[0]
    if not (k.shape[0] == j.shape[0] == phi.shape[0] == h.shape[0] == n):
        raise ValueError(f"i, k, j, phi, h: expected one value per entry each, got "
                         f"{[a.shape[0] for a in (i, k, j, phi, h)]}")
    m = len(edges)
    cl = np.asarray(cl_mm, dtype=float)
    if cl.ndim == 0 or (cl.ndim == 2 and cl.shape[0] == 1):
        cl = np.broadcast_to(cl, (m,)) if cl.ndim == 0 else cl[0]  # one wear for all flutes
    if cl.ndim not in (1, 2) or cl.shape[-1] != m:
        raise ValueError(f"cl_mm: expected shape ({m},) or (n_fl, {m}), got {cl.shape}")
    n_fl = cl.shape[0] if cl.ndim == 2 else None
    if n and (i.min() < 0 or i.max() >= n_ang or j.min() < 0 or j.max() >= m
              or k.min() < 0 or (n_fl is not None and k.max() >= n_fl)):
        raise ValueError(f"i, k, j: expected samples in [0, {n_ang}), flutes >= 0"
                         + (f" and < {n_fl} (cl_mm's rows)" if n_fl is not None else "")
                         + f" and micro edges in [0, {m})")
    cl_e = cl[j] if cl.ndim == 1 else cl[k, j]
    w = np.ones(n) if weight is None else np.asarray(weight, dtype=float).reshape(-1)
    if w.shape[0] != n:
        raise ValueError(f"weight: expected {n} values, got {w.shape[0]}")
    return _entry_forces(edges, coeffs, int(n_ang), i, j, phi, h, cl_e, w,
                         compiled=entry_forces_kernel is not None)


def _entry_forces(edges: MicroEdges, coeffs: LawCoefficients, n_ang: int, i: np.ndarray,
                  j: np.ndarray, phi: np.ndarray, h: np.ndarray, cl: np.ndarray,
                  weight: np.ndarray, compiled: bool) -> np.ndarray:
    """The law at each entry, then the sum per sample: the compiled loop
    (``errpred._force_kernels``) or its numpy twin (``compiled`` False)."""
    kappa = np.asarray(edges.kappa, dtype=float)
    ft, fr, fa = (np.ascontiguousarray(np.broadcast_to(f, phi.shape), dtype=float)
                  for f in laws.force(coeffs, h, kappa[j], cl))
    sk, ck = np.sin(kappa), np.cos(kappa)
    db = np.ascontiguousarray(edges.db, dtype=float)
    if compiled:
        return entry_forces_kernel(n_ang, i, j, phi, db, sk, ck, ft, fr, fa,
                                   np.ascontiguousarray(weight, dtype=float))
    w = db[j] * weight
    dft, dfr, dfa = ft * w, fr * w, fa * w
    sp, cp = np.sin(phi), np.cos(phi)
    a = dfr * sk[j] + dfa * ck[j]   # as in to_tool_frame, without the (n, 3) stack
    out = np.empty((n_ang, 3))
    out[:, 0] = np.bincount(i, -(dft * cp + a * sp), minlength=n_ang)
    out[:, 1] = np.bincount(i, dft * sp - a * cp, minlength=n_ang)
    out[:, 2] = np.bincount(i, dfr * ck[j] - dfa * sk[j], minlength=n_ang)
    return out


def _block_forces(edges: MicroEdges, coeffs: LawCoefficients, phi: np.ndarray,
                  h: np.ndarray, cutting: np.ndarray, cl: np.ndarray, weight: np.ndarray,
                  compiled: bool) -> np.ndarray:
    """:func:`tool_forces`' sum over the block's cutting entries (``np.nonzero`` order):
    the compiled loop, or its numpy twin (``compiled`` False); ``cl`` already (n_fl, m)."""
    i, k, j = np.nonzero(cutting)
    return _entry_forces(edges, coeffs, phi.shape[0], i, j, phi[i, k, j], h[i, k, j],
                         cl[k, j], weight[i, k, j], compiled=compiled)
