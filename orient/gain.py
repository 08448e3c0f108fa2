"""Directional matrices and the average process gain of a cut (contract of orient).

Regenerative force on the tool, workpiece frame (``docs/method.md`` §7 and the
shared contract of ``orient.stability``)::

    F(t) = s H(t) (q(t) - q(t - tau))          [N], q in m, H in N/m
    H(t) = sum over cutting micro edges of db_j (Ktc t_j + Krc r_j + Kac a_j) n_j^T

``n_j`` is the micro edge's outward envelope normal (the chip-thickness
direction, ``h = f_tooth . n``), ``t_j, r_j, a_j`` the unit vectors of the force
on the tool of ``errpred.force.to_tool_frame`` (tangential opposing the edge
velocity, radial ``-n``, axial), mapped to the workpiece frame with the tool
frame's rows. Chip widths in mm times coefficients in N/mm^2 give N/mm,
times 1000 N/m. With this sign ``H`` is "negative": a thicker chip pushes
the tool back. Only the chip coefficients enter (the edge forces do not
depend on the chip thickness, so they do not regenerate). ``Kxc`` is the
force law's slope ``dF/dh`` at the micro edge (:mod:`errpred.laws`): the
linear law's constants, the Lee-Altintas polynomials at the edge's kappa,
Kienzle's ``(1-m) k h^-m`` at the edge's chip of the sample (the
linearisation about the static chip).

``P``, the average process gain matrix, is the mean of ``H`` over one tooth
period ``tau = 60 / (spindle_rpm flutes)``. Its restriction to directions
``E`` (3 x d, orthonormal columns) is ``E^T P E`` (:func:`restricted`); the
scalar gain along a unit direction ``e`` is ``e^T P e``
(:func:`directional_gain`).

Up-cut/down-cut degree (``cut_sense``): chip-weighted mean of ``v . n_w`` over
the cutting edge samples, ``v`` the unit edge velocity and ``n_w`` the
workpiece's outward normal at the contact, divided by the chip-weighted mean
of ``|v . n_w|``: in ``[-1, 1]``, positive = up-cut (the edge leaves the
material through the generated surface), negative = down-cut, 0 when the
velocity is tangent to the surface everywhere (an axis along the normal).
The chip weight is ``h db`` per unit rotation (the chip cross-section).

Two sources:

* :func:`process_gain` / :func:`process_gain_batch`: the fast analytic path
  (``orient/_kernels.py``): exact entry/exit angles per micro edge, the
  integrand integrated in closed form, so ``P`` is exact in time; micro
  edges either given (``edges``) or placed along the cutting profile
  adaptively (Gauss-Legendre on the smooth pieces between the kinks of the
  integrand, :class:`GainResolution`). ``H`` is the average over each of
  ``k`` equal steps of the tooth period (the semi-discretization's step
  average), whose mean is ``P`` to round-off. With adaptive micro edges the
  engaged fraction is that of the edges used (a few 0.01 at most below the
  limit).
  This path needs a slope constant along the rotation (linear and
  Lee-Altintas laws). For a law whose slope depends on the chip (Kienzle),
  :func:`process_gain` and :func:`process_gain_batch` integrate per micro
  edge numerically instead: the sampled engagement (``default_edges``,
  ``GAIN_ANGLES_PER_REV`` samples per revolution at least) through
  :func:`gain_from_engagement` (tests compare both paths for the linear law).
* :func:`gain_from_engagement`: any sampled engagement
  (:func:`orient.engagement.engagement`, or errpred's through
  :func:`orient.engagement.from_errpred`); ``H`` at the samples via
  :func:`directional_matrices`, ``P`` its mean.
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from errpred import laws
from errpred.coefficients import LawCoefficients
from errpred.force import to_tool_frame
from errpred.spindle import tooth_period
from errpred.tool import MicroEdges, Tool

from . import _kernels as KN
from .constants import (
    AXIS_NORMAL_MIN_COS,
    DIRECTION_MIN_NORM,
    GAIN_ANGLES_PER_REV,
    GAIN_BISECTIONS,
    GAIN_MICRO_EDGES_ENVELOPE,
    GAIN_PIECE_EDGES,
    GAIN_ROOT_STEP_RAD,
    GAIN_SCAN_POINTS,
    N_PER_M_PER_N_PER_MM,
    ORTHONORMAL_TOL,
    ROUND_SLACK,
)
from .engagement import (
    LocalCut,
    SampledEngagement,
    _edge_arrays,
    engagement,
    geometry_vector,
    kernel_settings,
    place,
)

__all__ = [
    "GainBatch",
    "GainResolution",
    "ProcessGain",
    "default_edges",
    "directional_gain",
    "directional_matrices",
    "gain_from_engagement",
    "process_gain",
    "process_gain_batch",
    "restricted",
]


@dataclass(frozen=True, eq=False)
class ProcessGain:
    """Directional matrices of one cut over a tooth period, and their average.

    Attributes
    ----------
    H : ndarray, shape (k, 3, 3) [N/m]
        ``H`` over one tooth period in ``k`` equal steps, workpiece frame
        (step ``i`` starts at flute 0's rotation ``2 pi i / (N k)``).
    P : ndarray, shape (3, 3) [N/m]
        Mean of ``H`` over the tooth period.
    cut_sense : float [-]
        Up/down-cut degree in [-1, 1] (module docstring): > 0 up-cut.
    engaged_fraction : float [-]
        Share of the tooth period during which some micro edge cuts.
    mean_chip_mm : float [mm]
        Mean uncut chip thickness over the cutting edge-time (chip-width
        weighted); 0 when nothing cuts.
    flutes : int
    tooth_period_s : float or None [s]
        ``60 / (spindle_rpm flutes)`` when the speed was given.
    """

    H: np.ndarray
    P: np.ndarray
    cut_sense: float
    engaged_fraction: float
    mean_chip_mm: float
    flutes: int
    tooth_period_s: float | None = None


@dataclass(frozen=True, eq=False)
class GainBatch:
    """Process gains of many postures (:func:`process_gain_batch`).

    Attributes
    ----------
    P : ndarray, shape (..., 3, 3) [N/m]
    cut_sense : ndarray, shape (...) [-]
    engaged_fraction : ndarray, shape (...) [-]
    mean_chip_mm : ndarray, shape (...) [mm]
    """

    P: np.ndarray
    cut_sense: np.ndarray
    engaged_fraction: np.ndarray
    mean_chip_mm: np.ndarray


@dataclass(frozen=True)
class GainResolution:
    """Discretization of the exact-interval gain (``orient/_kernels.py``).

    Attributes
    ----------
    scan_points : int
        Points along the band of the cutting profile that can reach the stock
        at which the structure of the cutting intervals is tested.
    bisections : int
        Bisections locating each change of that structure (a kink).
    piece_edges : int
        Gauss-Legendre micro edges per smooth piece between kinks.
    root_step_rad : float [rad]
        Sampling step along an edge circle before sign changes of the
        non-circular material conditions are refined to roots.
    """

    scan_points: int = GAIN_SCAN_POINTS
    bisections: int = GAIN_BISECTIONS
    piece_edges: int = GAIN_PIECE_EDGES
    root_step_rad: float = GAIN_ROOT_STEP_RAD

    def __post_init__(self) -> None:
        for name in ("scan_points", "piece_edges"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
                raise ValueError(f"resolution.{name}: expected an integer >= 1, got {v!r}")
        v = self.bisections
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise ValueError(f"resolution.bisections: expected an integer >= 0, got {v!r}")
        v = self.root_step_rad
        if not (isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v)
                and 0 < v <= math.pi):
            raise ValueError(f"resolution.root_step_rad: expected 0 < step <= pi, got {v!r}")

    def finer(self, factor: int) -> GainResolution:
        """Every discretization refined by an integer ``factor`` (bisections: + log2)."""
        if isinstance(factor, bool) or not isinstance(factor, (int, np.integer)) or factor < 1:
            raise ValueError(f"factor: expected an integer >= 1, got {factor!r}")
        return GainResolution(self.scan_points * factor,
                              self.bisections + math.ceil(math.log2(factor)),
                              self.piece_edges * factor, self.root_step_rad / factor)

    def settings(self) -> np.ndarray:
        """The kernels' ``set_par`` (:func:`orient.engagement.kernel_settings`)."""
        return kernel_settings(self.root_step_rad)

    def rule(self) -> tuple[np.ndarray, np.ndarray]:
        """Gauss-Legendre nodes and weights on [0, 1], ``piece_edges`` of them."""
        return _gauss_legendre(int(self.piece_edges))


def _gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = _leggauss(n)
    return x.copy(), w.copy()     # writeable: one compiled signature of the kernels


@functools.lru_cache(maxsize=16)
def _leggauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def _check_tool(tool: Any, coeffs: Any) -> None:
    if not isinstance(tool, Tool):
        raise ValueError(f"tool: expected an errpred.tool.Tool, got {type(tool).__name__}")
    laws.law_of(coeffs)


@functools.lru_cache(maxsize=32)
def default_edges(tool: Tool) -> MicroEdges:
    """Fixed micro edges for sampled engagements (``GAIN_MICRO_EDGES_ENVELOPE``)."""
    return tool.micro_edges(GAIN_MICRO_EDGES_ENVELOPE)


def _tooth_period(spindle_rpm: float | None, flutes: int) -> float | None:
    if spindle_rpm is None:
        return None
    if isinstance(spindle_rpm, bool) or not (isinstance(spindle_rpm, (int, float, np.integer,
                                                                      np.floating))
                                             and math.isfinite(spindle_rpm) and spindle_rpm > 0):
        raise ValueError(f"spindle_rpm: expected a finite value > 0, got {spindle_rpm!r}")
    return tooth_period(float(spindle_rpm), flutes)


def directional_matrices(tool: Tool, edges: MicroEdges, coeffs: LawCoefficients,
                         frame: Any, phi: Any, cutting: Any, weight: Any = None,
                         h: Any = None) -> np.ndarray:
    """``H`` at sampled rotation angles, folded into one tooth period.

    Parameters
    ----------
    tool : Tool
    edges : MicroEdges
        ``m`` micro edges (``kappa`` and ``db`` used).
    coeffs : LawCoefficients
        The force law's coefficients; its slope ``dF/dh`` [N/mm^2] enters
        (edge terms do not).
    frame : array_like, shape (3, 3) [-]
        Tool frame rows ``x', y', z'`` (``errpred.frames``).
    phi : array_like, shape (n_ang, n_fl, m) [rad]
        Angular positions, one revolution in ``n_ang`` equal steps
        (``n_ang`` a multiple of ``n_fl = tool.flutes``).
    cutting : array_like of bool, shape (n_ang, n_fl, m)
    weight : array_like, shape (n_ang, n_fl, m), optional [-]
        Share of each step spent cutting (default 1).
    h : array_like, shape (n_ang, n_fl, m), optional [mm]
        Chip thickness; needed by a law whose slope depends on it (Kienzle).

    Returns
    -------
    ndarray, shape (n_ang / n_fl, 3, 3) [N/m]
        ``H`` over one tooth period, workpiece frame (the mean of the
        ``n_fl`` tooth periods of the revolution, identical when the flutes
        are alike).
    """
    _check_tool(tool, coeffs)
    phi = np.asarray(phi, dtype=float)
    cutting = np.asarray(cutting, dtype=bool)
    frame = np.asarray(frame, dtype=float)
    if phi.ndim != 3 or phi.shape[1] != tool.flutes or phi.shape[2] != len(edges):
        raise ValueError(f"phi: expected shape (n_ang, {tool.flutes}, {len(edges)}), got "
                         f"{phi.shape}")
    if cutting.shape != phi.shape:
        raise ValueError(f"cutting: shape {cutting.shape} differs from phi's {phi.shape}")
    if frame.shape != (3, 3) or not np.all(np.isfinite(frame)):
        raise ValueError(f"frame: expected a finite (3, 3) array, got shape {frame.shape}")
    n_ang = phi.shape[0]
    if n_ang % tool.flutes:
        raise ValueError(f"phi: {n_ang} rotation samples are not a multiple of "
                         f"{tool.flutes} flutes")
    i, _, j = np.nonzero(cutting)
    db = np.asarray(edges.db, dtype=float)[j]
    if weight is not None:
        weight = np.asarray(weight, dtype=float)
        if weight.shape != phi.shape:
            raise ValueError(f"weight: shape {weight.shape} differs from phi's {phi.shape}")
        db = db * weight[cutting]
    p = phi[cutting]
    kappa = np.asarray(edges.kappa, dtype=float)[j]
    if h is None:
        if laws.slope_in_kappa(coeffs) is None:
            raise ValueError(f"h: the {coeffs.law} law's slope depends on the chip; give the "
                             f"chip thickness")
        hc = np.zeros(p.shape)
    else:
        h = np.asarray(h, dtype=float)
        if h.shape != phi.shape:
            raise ValueError(f"h: shape {h.shape} differs from phi's {phi.shape}")
        hc = h[cutting]
    # force per unit chip thickness: the law's slope dF/dh at each entry
    gt, gr, ga = laws.slope(coeffs, hc, kappa)
    v = to_tool_frame(gt * db, gr * db, ga * db, p, kappa)
    nrm = edges.take(j).normals(p)                           # (k, 3) tool frame
    vw, nw = v @ frame, nrm @ frame
    H = np.zeros((n_ang, 9))
    outer = (vw[:, :, None] * nw[:, None, :]).reshape(-1, 9)
    for c in range(9):
        H[:, c] = np.bincount(i, outer[:, c], minlength=n_ang)
    H = H.reshape(tool.flutes, n_ang // tool.flutes, 3, 3).mean(axis=0)
    return H * N_PER_M_PER_N_PER_MM


def gain_from_engagement(tool: Tool, edges: MicroEdges, coeffs: LawCoefficients,
                         eng: SampledEngagement, spindle_rpm: float | None = None
                         ) -> ProcessGain:
    """Process gain from a sampled engagement (any chip-thickness source).

    Parameters
    ----------
    tool : Tool
    edges : MicroEdges
    coeffs : LawCoefficients
    eng : SampledEngagement
        From :func:`orient.engagement.engagement` or
        :func:`orient.engagement.from_errpred`.
    spindle_rpm : float, optional [rev/min]

    Returns
    -------
    ProcessGain
        ``H`` at the samples of one tooth period, ``P`` their mean; the
        statistics are sums over the cutting samples.
    """
    if not isinstance(eng, SampledEngagement):
        raise ValueError(f"eng: expected a SampledEngagement, got {type(eng).__name__}")
    tau = _tooth_period(spindle_rpm, tool.flutes)
    H = directional_matrices(tool, edges, coeffs, eng.frame, eng.phi, eng.cutting, eng.weight,
                             eng.h)
    w = np.broadcast_to(np.asarray(edges.db, dtype=float), eng.phi.shape)
    if eng.weight is not None:
        w = w * eng.weight
    w = np.where(eng.cutting, w, 0.0)
    # unit edge velocity (cos phi, -sin phi, 0) in the tool frame, its normal component
    al, be = eng.frame[0] @ eng.normal, eng.frame[1] @ eng.normal
    vn = al * np.cos(eng.phi) - be * np.sin(eng.phi)
    hw = w * eng.h
    den = float(np.sum(hw * np.abs(vn)))
    sense = float(np.sum(hw * vn)) / den if den > 0 else 0.0
    wsum = float(w.sum())
    mean_h = float(hw.sum()) / wsum if wsum > 0 else 0.0
    engaged = float(eng.cutting.any(axis=(1, 2)).mean())
    return ProcessGain(H=H, P=H.mean(axis=0), cut_sense=sense, engaged_fraction=engaged,
                       mean_chip_mm=mean_h, flutes=tool.flutes, tooth_period_s=tau)


def _tool_params(tool: Tool) -> np.ndarray:
    """``tp`` of the kernels: rotation, R - r, r, flute length, R, tan(helix), flutes."""
    return np.array([float(tool.rotation_sign), tool.core_radius_mm, tool.corner_radius_mm,
                     tool.flute_length_mm, tool.radius_mm, tool.tan_helix, float(tool.flutes)])


def _edge_table(edges: MicroEdges) -> tuple[np.ndarray, int]:
    """(5, m) rho, z, kappa, psi, db, and the index of the first flank edge.

    Flank edges ordered by height at the end let the kernel stop at the
    first one above the stock; otherwise it tests them all.
    """
    tab = np.ascontiguousarray(np.vstack(_edge_arrays(edges)))
    seg = np.asarray(edges.segment)
    flank = np.flatnonzero(seg == 2)
    fs = int(flank[0]) if flank.size else len(edges)
    if flank.size and (np.any(seg[fs:] != 2) or np.any(np.diff(tab[1, fs:]) < 0)):
        fs = len(edges)
    return tab, fs


def _resolution(resolution: GainResolution | None) -> GainResolution:
    if resolution is None:
        return GainResolution()
    if not isinstance(resolution, GainResolution):
        raise ValueError(f"resolution: expected a GainResolution, got "
                         f"{type(resolution).__name__}")
    return resolution


def process_gain(tool: Tool, coeffs: LawCoefficients, posture_axis: Any, normal: Any,
                 feed_dir: Any, cut: LocalCut, spindle_rpm: float | None = None,
                 n_angles: int = GAIN_ANGLES_PER_REV, edges: MicroEdges | None = None,
                 resolution: GainResolution | None = None) -> ProcessGain:
    """Process gain of a posture in a local cut (the exact-interval path).

    Parameters
    ----------
    tool : Tool
    coeffs : LawCoefficients
        A law whose slope depends on the chip (Kienzle) is integrated over
        the sampled engagement (:func:`_sampled_gain`), the others in closed form.
    posture_axis : array_like, shape (3,) [-]
        Tool axis (:func:`orient.geometry.posture_axis`); ``u . n > 0``.
    normal, feed_dir : array_like, shape (3,) [-]
        Outward surface normal and feed direction at the contact.
    cut : LocalCut
    spindle_rpm : float, optional [rev/min]
        Only sets ``tooth_period_s``.
    n_angles : int
        Steps of ``H`` per revolution (``H`` has ``ceil(n_angles / flutes)``
        per tooth period). ``P`` does not depend on it.
    edges : MicroEdges, optional
        Fixed micro edges (e.g. ``tool.micro_edges(n)``). Default: micro
        edges placed along the profile adaptively (``resolution``).
    resolution : GainResolution, optional
        Default ``GainResolution()``.

    Returns
    -------
    ProcessGain
        All zero (and ``engaged_fraction`` 0) when nothing cuts (zero depth,
        the tool misses the material).
    """
    _check_tool(tool, coeffs)
    if not isinstance(cut, LocalCut):
        raise ValueError(f"cut: expected a LocalCut, got {type(cut).__name__}")
    if isinstance(n_angles, bool) or not (isinstance(n_angles, (int, np.integer))
                                          and n_angles >= 1):
        raise ValueError(f"n_angles: expected an integer >= 1, got {n_angles!r}")
    res = _resolution(resolution)
    cut.check_tool(tool)
    tau = _tooth_period(spindle_rpm, tool.flutes)
    k = max(1, math.ceil(n_angles / tool.flutes - ROUND_SLACK))
    kc = laws.slope_in_kappa(coeffs)
    if kc is None:
        return _sampled_gain(tool, coeffs, posture_axis, normal, feed_dir, cut, k, edges, tau)
    pl = place(tool, posture_axis, normal, feed_dir)
    geo = geometry_vector(tool, posture_axis, normal, feed_dir, cut)
    Ht = np.zeros((k, 3, 3))
    st = np.zeros(5)
    tp, kc = _tool_params(tool), np.ascontiguousarray(kc, dtype=float)
    buf = np.zeros((KN.BUF_ROWS, 2))
    kinds = np.zeros((KN.BUF_ROWS, 2), dtype=np.int64)
    if edges is None:
        x, w = res.rule()
        union = np.zeros((KN.union_rows(0, res.scan_points, x.size), 2))
        KN.gain_adaptive(geo, tp, res.settings(), kc, k, res.scan_points, res.bisections, x, w,
                         Ht, st, buf, kinds, union)
    else:
        tab, fs = _edge_table(edges)
        union = np.zeros((KN.union_rows(len(edges), 0, 0), 2))
        KN.gain_fixed(geo, tab, fs, tp, res.settings(), kc, k, Ht, st, buf, kinds, union)
    F = pl.frame
    H = np.einsum("ap,kab,bq->kpq", F, Ht, F) * N_PER_M_PER_N_PER_MM
    sense = st[0] / st[1] if st[1] > 0 else 0.0
    mean_h = cut.fz_mm * st[2] / st[3] if st[3] > 0 else 0.0
    return ProcessGain(H=H, P=H.mean(axis=0), cut_sense=float(sense),
                       engaged_fraction=float(st[4]), mean_chip_mm=float(mean_h),
                       flutes=tool.flutes, tooth_period_s=tau)


def _sampled_gain(tool: Tool, coeffs: LawCoefficients, posture_axis: Any, normal: Any,
                  feed_dir: Any, cut: LocalCut, k: int, edges: MicroEdges | None,
                  tau: float | None) -> ProcessGain:
    """:func:`process_gain` integrated per micro edge over the sampled engagement.

    For a law whose slope depends on the chip. At least ``GAIN_ANGLES_PER_REV``
    samples per revolution, a multiple of ``2 k`` per tooth so that ``H``'s
    ``k`` steps are each the mean of whole samples; micro edges ``edges`` or
    :func:`default_edges`.
    """
    e = default_edges(tool) if edges is None else edges
    per_tooth = 2 * k * math.ceil(GAIN_ANGLES_PER_REV / (tool.flutes * 2 * k))
    eng = engagement(tool, e, posture_axis, normal, feed_dir, cut,
                     n_angles=per_tooth * tool.flutes)
    g = gain_from_engagement(tool, e, coeffs, eng)
    H = g.H.reshape(k, -1, 3, 3).mean(axis=1)
    return ProcessGain(H=H, P=g.P, cut_sense=g.cut_sense, engaged_fraction=g.engaged_fraction,
                       mean_chip_mm=g.mean_chip_mm, flutes=tool.flutes, tooth_period_s=tau)


def _cut_rows(cut: Any, shape: tuple[int, ...]) -> np.ndarray:
    """(n, 6) kernel rows of one LocalCut or a sequence/array of them."""
    if isinstance(cut, LocalCut):
        rows = cut.row()
    elif isinstance(cut, np.ndarray) and cut.dtype == object:
        rows = _rows_of(cut.ravel()).reshape(cut.shape + (6,))
    elif isinstance(cut, Sequence):
        flat = np.empty(len(cut), dtype=object)
        flat[:] = list(cut)
        rows = _rows_of(flat).reshape(len(cut), 6)
    else:
        raise ValueError(f"cut: expected a LocalCut or a sequence of them, got "
                         f"{type(cut).__name__}")
    try:
        return np.ascontiguousarray(np.broadcast_to(rows, shape + (6,)).reshape(-1, 6))
    except ValueError:
        raise ValueError(f"cut: {rows.shape[:-1]} cuts do not broadcast with the postures' "
                         f"shape {shape}") from None


def _rows_of(flat: np.ndarray) -> np.ndarray:
    """(n, 6) rows of a 1-D object array of cuts; each distinct object is converted
    once (a planner passes the same cut for every posture at a cutter location)."""
    if flat.size == 0:
        return np.zeros((0, 6))
    ids = np.fromiter(map(id, flat), dtype=np.int64, count=flat.size)
    _, first, inverse = np.unique(ids, return_index=True, return_inverse=True)
    uniq = np.array([flat[i].row() if isinstance(flat[i], LocalCut) else _bad_cut(flat[i])
                     for i in first]).reshape(-1, 6)
    return uniq[inverse.reshape(-1)]


def _bad_cut(c: Any) -> np.ndarray:
    raise ValueError(f"cut: expected LocalCut entries, got {type(c).__name__}")


def process_gain_batch(tool: Tool, coeffs: LawCoefficients, posture_axis: Any,
                       normal: Any, feed_dir: Any, cut: Any, edges: MicroEdges | None = None,
                       resolution: GainResolution | None = None, parallel: bool = False,
                       threads: int | None = None) -> GainBatch:
    """``P``, up/down-cut degree and engaged fraction of many postures at once.

    Parameters
    ----------
    tool : Tool
    coeffs : LawCoefficients
        A law whose slope depends on the chip (Kienzle) is integrated over
        each posture's sampled engagement (:func:`process_gain`, one posture
        at a time: much slower than the closed form).
    posture_axis : array_like, shape (..., 3) [-]
        Tool axes; ``u . n > 0`` everywhere.
    normal, feed_dir : array_like, shape (..., 3) [-]
        Broadcast with ``posture_axis`` (e.g. (L, 1, 3) against axes of
        shape (L, K, 3): K postures at each of L cutter locations).
    cut : LocalCut or sequence of LocalCut
        One cut for all, or cuts broadcasting with the postures' leading
        shape (e.g. a (L, 1) object array, or a length-L sequence against
        postures of shape (L,)).
    edges : MicroEdges, optional
        Fixed micro edges; default: placed along the profile adaptively.
    resolution : GainResolution, optional
    parallel : bool
        Spread the postures over numba's threads.
    threads : int, optional
        Chunks for the parallel run (default: ``os.cpu_count()`` x 4).

    Returns
    -------
    GainBatch
        Arrays of the postures' leading shape; ``P`` equals
        :func:`process_gain`'s ``P`` (same intervals, summed over the whole
        tooth period at once).
    """
    _check_tool(tool, coeffs)
    u = np.asarray(posture_axis, dtype=float)
    n = np.asarray(normal, dtype=float)
    fd = np.asarray(feed_dir, dtype=float)
    for name, a in (("posture_axis", u), ("normal", n), ("feed_dir", fd)):
        if a.ndim == 0 or a.shape[-1] != 3:
            raise ValueError(f"{name}: expected vectors of 3 components, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name}: expected finite values, got nan or inf")
    u, n, fd = np.broadcast_arrays(u, n, fd)
    shape = u.shape[:-1]
    U, N, Fd = (np.ascontiguousarray(a.reshape(-1, 3)) for a in (u, n, fd))
    un_norm = np.linalg.norm(U, axis=1) * np.linalg.norm(N, axis=1)
    if np.any(un_norm == 0):
        raise ValueError("posture_axis, normal: expected non-zero vectors")
    cosn = np.sum(U * N, axis=1) / un_norm
    if np.any(cosn < AXIS_NORMAL_MIN_COS):
        k = int(np.argmin(cosn))
        raise ValueError(f"posture_axis: the tool axis must point away from the workpiece "
                         f"(u . n > 0); posture {k} has u . n = {cosn[k]:.3g}")
    fn = Fd - np.sum(Fd * N, axis=1, keepdims=True) * N / np.sum(N * N, axis=1, keepdims=True)
    if np.any(np.linalg.norm(fn, axis=1) <= DIRECTION_MIN_NORM * np.linalg.norm(Fd, axis=1)):
        raise ValueError("feed_dir: a feed direction is parallel to its surface normal (or zero)")
    rows = _cut_rows(cut, shape)
    r = tool.corner_radius_mm
    if r > 0 and np.any(rows[:, 4:6] * r <= -1.0):
        raise ValueError(f"cut: a concave curvature is tighter than the tool's corner radius "
                         f"{r:g} mm (the tool would gouge)")
    res = _resolution(resolution)
    px, pw = res.rule()
    if edges is None:
        tab, fs = np.zeros((5, 0)), 0
    else:
        tab, fs = _edge_table(edges)
    m = U.shape[0]
    P = np.zeros((m, 3, 3))
    stats = np.zeros((m, 3))
    kc = laws.slope_in_kappa(coeffs)
    if kc is None:
        for i in range(m):
            r = rows[i]
            g = process_gain(tool, coeffs, U[i], N[i], Fd[i],
                             LocalCut(r[0], r[1], int(r[2]), r[3], r[4], r[5]), edges=edges)
            P[i] = g.P
            stats[i] = g.cut_sense, g.engaged_fraction, g.mean_chip_mm
        return GainBatch(P=P.reshape(shape + (3, 3)), cut_sense=stats[:, 0].reshape(shape),
                         engaged_fraction=stats[:, 1].reshape(shape),
                         mean_chip_mm=stats[:, 2].reshape(shape))
    kc = np.ascontiguousarray(kc, dtype=float)
    args = (U, N, Fd, rows, _tool_params(tool), res.settings(), kc, tab, fs, res.scan_points,
            res.bisections, px, pw, N_PER_M_PER_N_PER_MM, P, stats)
    if parallel and m > 1:
        chunks = threads if threads is not None else 4 * (os.cpu_count() or 1)
        KN.gain_batch_parallel(*args, max(1, min(int(chunks), m)))
    else:
        KN.gain_batch(*args)
    return GainBatch(P=P.reshape(shape + (3, 3)), cut_sense=stats[:, 0].reshape(shape),
                     engaged_fraction=stats[:, 1].reshape(shape),
                     mean_chip_mm=stats[:, 2].reshape(shape))


def directional_gain(P: Any, direction: Any) -> np.ndarray:
    """Scalar gain ``e^T P e`` along unit directions [N/m].

    Parameters
    ----------
    P : array_like, shape (..., 3, 3) [N/m]
    direction : array_like, shape (..., 3) [-]
        Normalized here (must be non-zero); broadcast with ``P``.

    Returns
    -------
    ndarray, shape (broadcast,) [N/m]
    """
    P = np.asarray(P, dtype=float)
    e = np.asarray(direction, dtype=float)
    if P.ndim < 2 or P.shape[-2:] != (3, 3):
        raise ValueError(f"P: expected shape (..., 3, 3), got {P.shape}")
    if e.ndim == 0 or e.shape[-1] != 3:
        raise ValueError(f"direction: expected vectors of 3 components, got shape {e.shape}")
    norm = np.linalg.norm(e, axis=-1, keepdims=True)
    if not np.all(np.isfinite(e)) or np.any(norm == 0):
        raise ValueError("direction: expected finite non-zero vectors")
    e = e / norm
    return np.einsum("...i,...ij,...j->...", e, P, e)


def restricted(P: Any, E: Any) -> np.ndarray:
    """``E^T P E``: the gain restricted to the directions of E's columns [N/m].

    Parameters
    ----------
    P : array_like, shape (..., 3, 3) [N/m]
    E : array_like, shape (3, d) [-]
        Orthonormal columns (checked to 1e-9).

    Returns
    -------
    ndarray, shape (..., d, d) [N/m]
    """
    P = np.asarray(P, dtype=float)
    E = np.asarray(E, dtype=float)
    if P.ndim < 2 or P.shape[-2:] != (3, 3):
        raise ValueError(f"P: expected shape (..., 3, 3), got {P.shape}")
    if E.ndim != 2 or E.shape[0] != 3 or not 1 <= E.shape[1] <= 3:
        raise ValueError(f"E: expected shape (3, d) with 1 <= d <= 3, got {E.shape}")
    if not np.all(np.isfinite(E)) or not np.allclose(E.T @ E, np.eye(E.shape[1]),
                                                      atol=ORTHONORMAL_TOL):
        raise ValueError("E: expected orthonormal columns")
    return np.einsum("ip,...ij,jq->...pq", E, P, E)
