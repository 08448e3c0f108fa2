"""Stage 2 of the prediction: forces with wear, deflection, and the error.

Per prediction point, in program order (``docs/method.md`` §4-6): the
actual cutting distance of each micro edge so far (carried from the
previous points), the cutting force over one revolution, the tool's
deflection by FFT with its compliance, the deflection at the instant the
surface is generated, and the error ``E = E_d + E_p`` along the surface
normal (positive: material left). The wear that makes this sequential is a
running sum; everything else was computed in stage 1 (:mod:`errpred.geometry`).

Bending directions: the compliance's ``x`` and ``y`` are world X and Y
projected onto the plane normal to the tool axis (exactly X and Y for a
vertical tool); ``z`` is the tool axis.

A flexible workpiece (a thin wall) adds its own compliance at the cutting
point: with ``workpiece(point_mm) -> [(Mode, direction)]`` the deflection is
the relative one, tool minus workpiece. The workpiece carries the reaction
``-F``, so its modes add to the tool's: ``q = (G_tool + sum_m d_m G_m d_m^T) F``
(the same sum as orient's stability analysis and sim's time-domain model).

**The wear part of the error** (what a tool change removes). At a prediction
point the error is ``E(cl) = E_d(cl) + E_p(cl)``, ``cl`` the actual cutting
distances of the micro edges (mid-block, as the force uses them). Its wear
part is::

    W = E(cl) - E(0)          (same point, same engagement, a fresh tool)
      = [E_d(cl) - E_d(0)]  +  [E_p(cl) - E_p(0)]
      =  W_d (edge forces)  +  W_p (radius loss)

``W_p`` is the shape model's wear term: the radius lost by the micro edges
that generate the surface, ``wear_rate * cl`` averaged over the generation
strip. ``W_d`` is the deflection the edge forces' growth ``Kxe1 cl db``
adds: force is linear in the coefficients and in each ``cl_j``, deflection
is linear in force (FFT with the compliance, workpiece modes included), and
``E_d`` is linear in the deflection, so ``W_d`` is exactly the ``E_d`` of
the wear-grown edge forces alone: ``W_d = sum_j a_j cl_j``, ``a_j`` the
``E_d`` of micro edge ``j``'s growth per mm of its cutting distance
(:func:`wear_influence`, one batched evaluation per point; the tests check
the sum against a second prediction with the wear models off). Without a
wear coefficient (``Kxe1 = 0``) it is 0 and not computed.

Why this and not ``|E|``: the rest of ``E``, ``E(0)``, is what a fresh tool
leaves at the same point (its deflection and its form error); a new tool
leaves it again, and the path correction, not a tool change, is what takes
it out. ``W`` is what the same cut would not have with a new tool. Both
terms are linear in the ``cl_j`` and 0 at ``cl = 0``: ``W = w . cl`` with
per-point weights ``w`` (:attr:`PointResult.wear_influence_um_mm`), which is
what lets the report say what the point's wear part would be with the tool
as it is at the end, and how far the tool can cut before it reaches a
tolerance (:func:`errpred.report.tool_change`).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from .coefficients import WEAR_NAMES, CuttingCoefficients
from .dynamics import Compliance, receptance
from .force import _chip, entry_forces
from .geometry import PointGeometry
from .spindle import tooth_frequency
from .tool import MicroEdges, Tool

__all__ = ["PointResult", "ShapeErrorModel", "WearState", "bending_basis", "evaluate",
           "revolution", "wear_influence", "workpiece_deflection"]


def bending_basis(axis: np.ndarray) -> dict[str, np.ndarray]:
    """Unit vectors of the compliance directions 'x', 'y', 'z' for a tool axis."""
    # np.linalg.norm's and np.cross's own arithmetic for three components (the norm is
    # ``sqrt(x . x)``, the cross product's terms in its order: the same numbers), without
    # their general machinery: 45 -> 5 us a call, twice a point in stage 2
    u = np.asarray(axis, dtype=float)
    x = np.array([1.0, 0.0, 0.0]) - u[0] * u
    if math.sqrt(x.dot(x)) < 1e-6:  # tool along X: take Y as the first direction
        x = np.array([0.0, 1.0, 0.0]) - u[1] * u
    x /= math.sqrt(x.dot(x))
    (u0, u1, u2), (x0, x1, x2) = u.tolist(), x.tolist()
    y = np.array([u1 * x2 - u2 * x1, u2 * x0 - u0 * x2, u0 * x1 - u1 * x0])
    return {"x": x, "y": y, "z": u}


class ShapeErrorModel:
    """The tool's effective-radius error and its growth with wear.

    Parameters
    ----------
    deviation : callable or None
        ``deviation(kappa_rad, z_mm) -> mm``: effective cutting radius minus
        nominal, measured on the spinning tool (form error, runout).
    wear_rate : float [mm radius loss per mm of actual cutting distance]
    """

    def __init__(self, deviation=None, wear_rate: float = 0.0) -> None:
        self.deviation = deviation
        self.wear_rate = float(wear_rate)

    def error_mm(self, kappa, z, cl_mm):
        """``E_p`` [mm]: a smaller effective radius leaves material (positive).

        Scalars or arrays (broadcast together).
        """
        dev = self.deviation(kappa, z) if self.deviation is not None else 0.0
        return -np.asarray(dev, dtype=float) + self.wear_rate * np.asarray(cl_mm, dtype=float)


@dataclass
class WearState:
    """Actual cutting distance of every micro edge so far (same for every flute) [mm]."""

    cl_mm: np.ndarray

    @classmethod
    def new(cls, edges: MicroEdges) -> "WearState":
        """A fresh tool: every micro edge at 0."""
        return cls(np.zeros(len(edges)))

    @classmethod
    def start(cls, edges: MicroEdges, cl_mm=None) -> "WearState":
        """A used tool's state.

        Parameters
        ----------
        edges : MicroEdges
        cl_mm : None, float or ndarray of shape (m,) [mm]
            None: a fresh tool; a number: every micro edge has cut this far;
            an array: each micro edge's actual cutting distance.

        Raises
        ------
        ValueError
            Wrong length, a non-finite or negative distance.
        """
        if cl_mm is None:
            return cls.new(edges)
        cl = np.asarray(cl_mm, dtype=float)
        if cl.ndim == 0:
            cl = np.full(len(edges), float(cl))
        if cl.shape != (len(edges),):
            raise ValueError(f"initial wear: {cl.shape[0] if cl.ndim == 1 else cl.shape} "
                             f"cutting distances for {len(edges)} micro edges (a tool state "
                             "made for another tool or resolution.micro_edges)")
        if not (np.all(np.isfinite(cl)) and np.all(cl >= 0)):
            raise ValueError("initial wear: cutting distances must be finite and >= 0")
        return cls(cl.copy())


@dataclass(frozen=True)
class PointResult:
    """Stage-2 result of one prediction point (all physics in report units).

    Attributes
    ----------
    peak_force_N : float
        Largest magnitude of the force on the tool over the revolution.
    mean_force_N : ndarray, shape (3,)
        Revolution-mean force on the tool, world frame.
    deflection_um : ndarray, shape (3,)
        Tool deflection at the generation instant, world frame.
    E_d_um, E_p_um, E_um : float
        Error from deflection, from tool shape (with wear), total.
    cl_max_mm, cl_gen_mm : float
        Largest actual cutting distance of any micro edge, and that of the
        micro edge generating the surface, at this point (wear so far).
    gain : float
        ``dE/dx``: how much the error grows per unit the tool cuts deeper
        along the normal (from the stock-thickened engagement); 0 if unknown.
    E_wear_d_um, E_wear_p_um : float
        The wear part of the error (:func:`evaluate`, module docstring), from
        the edge forces' growth (deflection) and from the radius loss: ``E``
        with the tool's wear minus ``E`` of a fresh tool at the same point.
        NaN where ``E`` is.
    cl_wear_mm : float
        Actual cutting distance of the most-worn micro edge among those that
        cut at this point or generate its surface [mm].
    wear_edge : int
        Index of that micro edge (-1 if none).
    wear_edges : ndarray of int, shape (k,), or None
        The micro edges whose wear moves this point's surface (those that cut
        or generate it).
    E_wall_um : float [um]
        The error of the wall a flat or radius end mill's flank finishes beside the
        floor ``E_um`` is for (:attr:`errpred.geometry.PointGeometry.wall`: deflection
        and shape error there, as ``E_um``); NaN where there is none. Reported, not
        corrected.
    wear_influence_um_mm : ndarray, shape (k,), or None [um per mm]
        The wear part is linear in their cutting distances:
        ``W = wear_influence_um_mm @ cl[wear_edges]`` (:meth:`wear_part_um`),
        for the tool's state at this point or any other.
    """

    peak_force_N: float
    mean_force_N: np.ndarray
    deflection_um: np.ndarray
    E_d_um: float
    E_p_um: float
    E_um: float
    cl_max_mm: float
    cl_gen_mm: float
    gain: float = 0.0
    E_wear_d_um: float = math.nan
    E_wear_p_um: float = math.nan
    cl_wear_mm: float = math.nan
    wear_edge: int = -1
    wear_edges: np.ndarray | None = None
    wear_influence_um_mm: np.ndarray | None = None
    E_wall_um: float = math.nan

    @property
    def E_wear_um(self) -> float:
        """The wear part of the error, ``E_wear_d_um + E_wear_p_um`` [um]."""
        return self.E_wear_d_um + self.E_wear_p_um

    def wear_part_um(self, cl_mm: np.ndarray) -> float:
        """The wear part this point would have with the tool in state ``cl_mm`` [um].

        ``cl_mm``: every micro edge's actual cutting distance [mm], shape (m,).
        NaN for a point without an error.
        """
        if self.wear_edges is None:
            return math.nan
        return float(self.wear_influence_um_mm @ np.asarray(cl_mm, float)[self.wear_edges])


def workpiece_deflection(modes, force_N: np.ndarray, spindle_rpm: float) -> np.ndarray:
    """Workpiece's share of the relative deflection over a revolution [mm].

    Parameters
    ----------
    modes : list of (Mode, ndarray shape (3,))
        Workpiece modes at the cutting point, each along a unit direction.
    force_N : ndarray, shape (..., n, 3) [N]
        Force on the tool over a revolution, world frame.
    spindle_rpm : float [rev/min]

    Returns
    -------
    ndarray, shape (..., n, 3) [mm]
        ``sum_m d_m (G_m * (F . d_m))`` per harmonic, as :meth:`Compliance.deflection`.
    """
    out = np.zeros_like(force_N, dtype=float)
    for mode, d in modes:
        d = np.asarray(d, dtype=float)
        part = Compliance.from_modes({"x": (mode,)}).deflection((force_N @ d)[..., None],
                                                                spindle_rpm)
        out += part[..., :1] * d
    return out


@functools.lru_cache(maxsize=16)
def _harmonics(spindle_rpm: float, n: int) -> np.ndarray:
    """``omega_m`` [rad/s] of harmonics ``m = 0 .. n/2`` of the spindle frequency, read
    only (as :meth:`Compliance.deflection` takes them)."""
    omega = 2.0 * math.pi * tooth_frequency(spindle_rpm) * np.arange(n // 2 + 1)
    omega.flags.writeable = False
    return omega


@functools.lru_cache(maxsize=16)
def _harmonic_response(compliance: Compliance, spindle_rpm: float, n: int) -> np.ndarray:
    """The tool's ``G(omega_m)`` [m/N] at :func:`_harmonics`, (n/2 + 1, ndir), read
    only: the same for every point at one speed."""
    out = compliance.response(_harmonics(spindle_rpm, n))
    out.flags.writeable = False
    return out


def _point_modes(workpiece, g: PointGeometry) -> list:
    """The workpiece's modes at the point's generation point (none: rigid, or no
    generation point)."""
    if workpiece is None or g.gen is None:
        return []
    return list(workpiece(g.gen.point_world))


def _engagement(tool: Tool, edges: MicroEdges, g: PointGeometry) -> tuple:
    """The micro edges that cut at a point over one revolution of every flute, as a list
    of cutting entries (sample, flute, micro edge), read from flute 0's engagement
    without making the whole (n, flutes, c) block: flute ``k`` at step ``i`` is flute 0
    at step ``i + k n / flutes`` (:func:`errpred.engagement.expand_flutes`, whose angles
    and masks these entries are, in ``np.nonzero``'s order of its block).

    Returns
    -------
    theta : ndarray, shape (n,) [rad]
    cols : ndarray of int, shape (c,)
        Indices of the micro edges that cut.
    edges : MicroEdges
        Those micro edges.
    i, k, j : ndarray of int, shape (e,)
        Each cutting entry's rotation step, flute and micro edge (of ``edges``), sorted.
    phi : ndarray, shape (e,) [rad]
        Their angular positions (within-step shifts applied).
    weight : ndarray, shape (e,), or None
        Share of each step spent cutting.
    """
    n = g.cutting0.shape[0]
    flutes = tool.flutes
    if n % flutes:
        raise ValueError(f"{n} rotation steps are not a multiple of {flutes} flutes")
    theta = np.arange(n) * (2 * math.pi / n)
    cols = np.flatnonzero(g.cutting0.any(axis=0))  # only the micro edges that cut
    edges = edges.take(cols)
    i0, j0 = np.nonzero(g.cutting0[:, cols])        # flute 0's entries, row by row
    i, k, src = _flute_entries(i0, n, flutes)
    j = j0[src]
    # as expand_flutes adds them: (theta + the flute's offset) - psi (+ the shift)
    phi = (theta[i] + (2 * math.pi / flutes) * k) - edges.psi[j]
    weight = None
    if g.weight0 is not None:
        weight = g.weight0[i0, cols[j0]].astype(float)[src]
    if g.shift0 is not None:
        phi = phi + g.shift0[i0, cols[j0]].astype(float)[src]
    return theta, cols, edges, i, k, j, phi, weight


def _flute_entries(i0: np.ndarray, n: int, flutes: int
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every flute's cutting entries from flute 0's, sorted by (step, flute, edge).

    Flute ``k`` cuts at step ``i`` what flute 0 cuts at step ``(i + k n / flutes) mod
    n``. ``i0``: the row indices of ``np.nonzero`` of flute 0's (n, m) block
    (non-decreasing, each in [0, n)). Returns each entry's step ``i``, flute ``k`` and
    flute-0 entry ``src``: for each step, each flute in turn, the flute-0 row's entries
    in their order. With ``np.nonzero``'s edges (ascending within a row, so distinct)
    that is the order ``np.lexsort((j, k, i))`` gives all flutes' entries, without the
    sort: stage 2 did that sort at every point's every revolution."""
    shift = n // flutes
    counts = np.bincount(i0, minlength=n)
    first = np.cumsum(counts) - counts                  # each row's first entry
    rows = (np.arange(n)[:, None] + shift * np.arange(flutes)[None, :]) % n   # (i, k)
    lens = counts[rows].ravel()
    total = int(lens.sum())
    # the rows' entries end to end: each run starts at its row's first entry
    ends = np.cumsum(lens)
    src = np.arange(total) + np.repeat(first[rows].ravel() - (ends - lens), lens)
    i = np.repeat(np.arange(n), lens.reshape(n, flutes).sum(axis=1))
    k = np.repeat(np.tile(np.arange(flutes), n), lens)
    return i, k, src


def _deflection(compliance: Compliance, g: PointGeometry, force: np.ndarray,
                modes: list) -> np.ndarray:
    """Deflection over a revolution from forces on the tool, world frame [mm].

    ``force`` has shape (..., n, 3) [N]; the result the same shape [mm]. With the
    workpiece's ``modes`` at the point (:func:`_point_modes`) it is tool minus
    workpiece. One transform of the force for both: ``D = irfft(sum of the
    compliances' responses to rfft(F)) * 1000``, the tool's in its bending directions
    (:func:`bending_basis`, :meth:`Compliance.deflection`), each workpiece mode's along
    its direction (:func:`workpiece_deflection`); the same sums as those, once.
    """
    basis = bending_basis(g.axis)
    B = np.stack([basis[d] for d in compliance.directions])            # (ndir, 3)
    n = force.shape[-2]
    spec = np.fft.rfft(force, axis=-2)                                  # (..., n/2+1, 3)
    rpm = float(g.spindle_rpm)
    out = ((spec @ B.T) * _harmonic_response(compliance, rpm, n)) @ B
    if modes:
        omega = _harmonics(rpm, n)
        for mode, d in modes:
            d = np.asarray(d, dtype=float)
            G = receptance(mode.k_N_m, mode.m_kg, mode.c_Ns_m, omega)
            out = out + ((spec @ d) * G)[..., None] * d
    return np.fft.irfft(out, n=n, axis=-2) * 1000.0


def revolution(tool: Tool, edges: MicroEdges, coeffs: CuttingCoefficients,
               compliance: Compliance, g: PointGeometry,
               cl_mm: np.ndarray, workpiece=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Force on the tool and its deflection over one revolution, world frame.

    With ``workpiece`` (``workpiece(point_mm) -> [(Mode, direction)]``) and a
    generation point, the deflection is relative: tool minus workpiece.

    Returns
    -------
    theta : ndarray, shape (n,) [rad]
        The point's own rotation steps (finer for light cuts).
    force_N : ndarray, shape (n, 3)
    deflection_mm : ndarray, shape (n, 3)
    """
    return _revolution(tool, edges, coeffs, compliance, g, cl_mm,
                       _point_modes(workpiece, g))[:3]


def _revolution(tool, edges, coeffs, compliance, g, cl_mm, modes) -> tuple:
    """:func:`revolution` with the workpiece's modes at the point given, and the
    engagement it used (:func:`_engagement`) last."""
    eng = _engagement(tool, edges, g)
    theta, cols, edges, i, k, j, phi, weight = eng
    cl_mm = np.asarray(cl_mm)[..., cols]
    f_tool = g.frame @ g.feed_per_tooth_world
    # chip_thickness per entry
    h = _chip(f_tool, np.sin(edges.kappa)[j], np.cos(edges.kappa)[j], np.sin(phi),
              np.cos(phi))
    f_tool_frame = entry_forces(edges, coeffs, theta.shape[0], i, k, j, phi, h, cl_mm,
                                weight=weight)
    force = f_tool_frame @ g.frame  # rows: tool frame -> world
    return theta, force, _deflection(compliance, g, force, modes), eng


def wear_influence(tool: Tool, edges: MicroEdges, coeffs: CuttingCoefficients,
                   compliance: Compliance, g: PointGeometry, workpiece=None,
                   engagement: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
    """How the deflection error grows with each micro edge's cutting distance.

    The edge forces grow by ``Kxe1 cl_j db_j`` (method.md §4), linearly in
    each micro edge's ``cl_j``, and the deflection and ``E_d`` are linear in
    the force, so ``E_d(cl) - E_d(0) = sum_j a_j cl_j`` exactly. This returns
    the ``a_j``: the deflection error along the normal, averaged over the
    generation strip as ``E_d`` is, caused by the edge-force growth of one
    micro edge (on every flute) per mm of its cutting distance. The forces
    are those of :func:`errpred.force.tool_forces` with only the ``Kxe1``
    terms, kept per micro edge instead of summed; their deflections are one
    batched FFT.

    Parameters
    ----------
    tool, edges, coeffs, compliance, g, workpiece
        As :func:`revolution`; ``g`` needs a generation point.
    engagement : tuple, optional
        The point's cutting entries if already listed (``_engagement``).

    Returns
    -------
    cols : ndarray of int, shape (c,)
        The micro edges that cut at the point.
    a : ndarray, shape (c,) [mm per mm]
        ``dE_d / dcl_j``.
    """
    return _wear_influence(tool, edges, coeffs, compliance, g, _point_modes(workpiece, g),
                           engagement)


def _wear_influence(tool, edges, coeffs, compliance, g, modes, engagement=None) -> tuple:
    """:func:`wear_influence` with the workpiece's modes at the point given."""
    theta, cols, e, i, k, j, p, weight = engagement or _engagement(tool, edges, g)
    n, c = theta.shape[0], cols.shape[0]
    w = e.db[j] * (weight if weight is not None else 1.0)            # [mm]
    sp, cp = np.sin(p), np.cos(p)
    sk, ck = np.sin(e.kappa)[j], np.cos(e.kappa)[j]
    kt, kr, ka = coeffs.Kte1_N_mm2, coeffs.Kre1_N_mm2, coeffs.Kae1_N_mm2
    a_in = kr * sk + ka * ck   # in-plane part of the radial and axial growth (to_tool_frame)
    parts = (-w * (kt * cp + a_in * sp), w * (kt * sp - a_in * cp), w * (kr * ck - ka * sk))
    at = j * n + i
    f = np.stack([np.bincount(at, v, minlength=c * n) for v in parts], axis=-1)
    force = f.reshape(c, n, 3) @ g.frame                              # (c, n, 3) world [N/mm]
    defl = _deflection(compliance, g, force, modes)                   # (c, n, 3) [mm/mm]
    gen = g.gen
    series = np.moveaxis(defl, 1, 0)                                  # (n, c, 3)
    if gen.samples_theta is None or not gen.samples_theta.size:
        return cols, _at_angles(series, theta, np.array([gen.theta_rad]))[0] @ gen.normal_world
    d_s = _at_angles(series, theta, gen.samples_theta)                # (k, c, 3)
    return cols, np.mean(np.sum(d_s * gen.samples_normal[:, None, :], axis=2), axis=0)


def _strip_error(gen, defl: np.ndarray, theta: np.ndarray) -> float:
    """Deflection along the normal, averaged over the generation strip [mm]."""
    if gen.samples_theta is None or not gen.samples_theta.size:
        return float(_at_angle(defl, theta, gen.theta_rad) @ gen.normal_world)
    d_s = _at_angles(defl, theta, gen.samples_theta)
    return float(np.mean(np.sum(d_s * gen.samples_normal, axis=1)))


def _nearest_edges(edges: MicroEdges, kappa: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Micro edge nearest each (kappa, z): by contact angle, on the flank by height."""
    dk = np.abs(edges.kappa[None, :] - kappa[:, None])
    dz = np.abs(edges.z[None, :] - z[:, None])
    return np.argmin(dk + 1e-3 * dz, axis=1)


def _at_angles(series: np.ndarray, theta: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """:func:`_at_angle` for many angles: shape (k,) + series.shape[1:]."""
    n = theta.shape[0]
    x = (np.asarray(angles) % (2 * math.pi)) / (2 * math.pi) * n
    i = np.floor(x).astype(int) % n
    t = (x - np.floor(x)).reshape((-1,) + (1,) * (series.ndim - 1))
    return (1 - t) * series[i] + t * series[(i + 1) % n]


def _at_angle(series: np.ndarray, theta: np.ndarray, angle: float) -> np.ndarray:
    """Periodic linear interpolation of a (n, 3) series at ``angle`` [rad]."""
    n = theta.shape[0]
    x = (angle % (2 * math.pi)) / (2 * math.pi) * n
    i = int(math.floor(x)) % n
    t = x - math.floor(x)
    return (1 - t) * series[i] + t * series[(i + 1) % n]


def evaluate(tool: Tool, edges: MicroEdges, coeffs: CuttingCoefficients,
             compliance: Compliance, shape: ShapeErrorModel, theta: np.ndarray,
             g: PointGeometry, wear: WearState, series: list | None = None,
             workpiece=None) -> PointResult | None:
    """Stage 2 for one point; advances ``wear`` by the revolutions it cuts.

    Returns None for points that do not cut (the wear does not advance).
    Points that cut but have no generation point (or none to trust) get
    their forces and wear, and NaN errors. If ``series`` is a list,
    ``(theta, force_N, deflection_mm)`` over the revolution (world frame) is
    appended to it for points with an error. ``workpiece``: see :func:`revolution`.

    The wear part of the error (module docstring) is ``E`` minus ``E`` of
    the same point with every micro edge at zero cutting distance: the
    radius loss from the shape model at ``cl = 0``, and, when a wear
    coefficient ``Kxe1`` is not zero, the deflection of the edge forces'
    growth, from each cutting micro edge's influence (:func:`wear_influence`:
    its forces per unit ``cl`` over the revolution and their FFT deflection,
    one batch). The influences are kept (``PointResult.wear_influence_um_mm``)
    so that the wear part for any other state of the tool is a dot product.
    """
    if g.cutting0 is None:
        return None
    revs = g.spindle_rpm * g.cut_length_mm / g.feed_mm_min if g.feed_mm_min > 0 else 0.0
    increment = g.cl_per_rev * revs
    cl_mid = wear.cl_mm + 0.5 * increment
    modes = _point_modes(workpiece, g)      # once for the point's three revolutions
    theta, force, defl, eng = _revolution(tool, edges, coeffs, compliance, g, cl_mid, modes)
    gen = g.gen
    nan = math.nan
    E_d = E_p = nan
    d_gen = np.full(3, nan)
    gain = 0.0
    j = int(np.argmax(cl_mid)) if cl_mid.size else 0
    W_d = W_p = cl_w = E_wall = nan
    j_w = -1
    infl = (None, None)
    if gen is not None and g.status in ("predicted", "axis-normal"):
        if series is not None:
            series.append((theta, force, defl))
        d_gen = _at_angle(defl, theta, gen.theta_rad)
        E_d = _strip_error(gen, defl, theta)
        E_p, E_p0, js = _shape_part(gen, edges, shape, cl_mid)
        if g.wall is not None:
            E_wall = _strip_error(g.wall, defl, theta) + _shape_part(g.wall, edges, shape,
                                                                     cl_mid)[0]
        j = _nearest_edges(edges, np.array([gen.kappa_rad]), np.array([gen.point_tool[2]]))[0]
        # the wear part: E minus E of a fresh tool at the same point, linear in cl
        cols = np.flatnonzero(g.cutting0.any(axis=0))
        wear_edges = np.union1d(cols, js)
        influence = np.zeros(wear_edges.shape)  # [mm of error per mm of cl]
        W_p = E_p - E_p0
        idx, count = np.unique(js, return_counts=True)
        influence[np.searchsorted(wear_edges, idx)] += shape.wear_rate * count / js.size
        W_d = 0.0
        if _edge_wear(coeffs):
            cols, a_d = _wear_influence(tool, edges, coeffs, compliance, g, modes,
                                        engagement=eng)
            W_d = float(a_d @ cl_mid[cols])
            influence[np.searchsorted(wear_edges, cols)] += a_d
        j_w = int(wear_edges[np.argmax(cl_mid[wear_edges])])
        cl_w = float(cl_mid[j_w])
        infl = (wear_edges.astype(np.int32), influence * 1e3)
        if g.sensitivity is not None:
            delta, c_b, w_b, s_b = g.sensitivity
            g_b = dataclasses.replace(g, cutting0=c_b, weight0=w_b, shift0=s_b)
            th_b, _, defl_b, _ = _revolution(tool, edges, coeffs, compliance, g_b, cl_mid,
                                             modes)
            gain = (_strip_error(gen, defl_b, th_b) - E_d) / delta
    result = PointResult(
        peak_force_N=float(np.linalg.norm(force, axis=1).max()),
        mean_force_N=force.mean(axis=0),
        deflection_um=d_gen * 1e3,
        E_d_um=E_d * 1e3, E_p_um=E_p * 1e3, E_um=(E_d + E_p) * 1e3,
        cl_max_mm=float(cl_mid.max()), cl_gen_mm=float(cl_mid[j]), gain=gain,
        E_wear_d_um=W_d * 1e3, E_wear_p_um=W_p * 1e3, cl_wear_mm=cl_w, wear_edge=j_w,
        wear_edges=infl[0], wear_influence_um_mm=infl[1], E_wall_um=E_wall * 1e3)
    wear.cl_mm = wear.cl_mm + increment
    return result


def _shape_part(gen, edges: MicroEdges, shape: ShapeErrorModel, cl_mid: np.ndarray
                ) -> tuple[float, float, np.ndarray]:
    """The shape error at a generation point [mm] (over its strip's samples where it has
    them), the same for a fresh tool, and the micro edges it is read from."""
    if gen.samples_theta is not None and gen.samples_theta.size:
        js = _nearest_edges(edges, gen.samples_kappa, gen.samples_z)
        return (float(np.mean(shape.error_mm(gen.samples_kappa, gen.samples_z, cl_mid[js]))),
                float(np.mean(shape.error_mm(gen.samples_kappa, gen.samples_z, 0.0))), js)
    js = _nearest_edges(edges, np.array([gen.kappa_rad]), np.array([gen.point_tool[2]]))
    return (float(shape.error_mm(gen.kappa_rad, float(gen.point_tool[2]),
                                 float(cl_mid[js[0]]))),
            float(shape.error_mm(gen.kappa_rad, float(gen.point_tool[2]), 0.0)), js)


def _edge_wear(coeffs: CuttingCoefficients) -> bool:
    """True if the edge forces grow with the cutting distance (a ``Kxe1`` is not 0)."""
    return any(getattr(coeffs, n) != 0.0 for n in WEAR_NAMES)
