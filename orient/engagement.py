"""Engagement of an end mill in a local finishing cut: the fast path for planning.

A :class:`LocalCut` describes the material around one cutter contact point
in the local frame ``(f, b, n)`` (:mod:`orient.geometry`), contact at the
origin:

* the finished surface through the contact, ``n . x = 0`` or the quadric
  ``n . x = -(kf (f . x)^2 + kb (b . x)^2) / 2`` (positive curvature =
  convex); the tool touches it at the contact;
* the stock top, the surface offset by ``depth_mm`` along ``n`` (locally the
  quadric with curvatures ``k / (1 + k depth)``): material is below it;
* the previous pass removed the tool solid swept along its own line, the
  current pass's line translated by ``previous_side * pick_mm * b`` with the
  same tool axis. The swept solid is errpred's (``errpred/_kernels.py``:
  points within the corner radius of the swept core, up to the flute
  length): for a ball end mill a cylinder of radius ``R`` around the line of
  the previous ball centres, plus the flank swept above it;
* the previous tooth: a micro edge cuts only where its chip thickness
  ``h = f_tooth . n_edge`` is positive (``errpred.force.chip_thickness``),
  i.e. outside the envelope's position one tooth earlier.

The tool touches the finished surface at the contact: the envelope point
whose outward normal is ``-n`` is the origin, so the tip is
``r (n - u) + (R - r) n_perp / |n_perp|`` (``n_perp`` the part of ``n``
normal to ``u``); for a ball ``tip = R n - R u`` (ball centre ``R n``). With
``u`` along ``n`` a flat or radius end mill sits with its tip on the contact.

A micro edge (``errpred.tool.Tool.micro_edges``) of flute ``k`` at rotation
sample ``i`` cuts when its midpoint lies in the material and ``h > 0``.
:func:`engagement` samples that on a rotation grid (any tool), and
:func:`from_errpred` wraps errpred's own engagement (the rasterizer's) in
the same :class:`SampledEngagement`, so that either source feeds
:func:`orient.gain.gain_from_engagement`. :func:`cutting_intervals` gives
the exact entry/exit angles of each micro edge (``orient/_engagement_kernels.py``),
from which :func:`orient.gain.process_gain` integrates the gain.

Limits of the local model: the previous pass is the current line shifted
along ``b`` with the same axis (on a curved surface its true position also
drops by ``k pick^2 / 2`` and turns, which is ignored); the current pass's
earlier motion only enters through ``h > 0`` (errpred's exact sweeps also
keep a sliver ``-fz/2 < (p - c).f <= 0`` of a ball where material is left
but ``h`` is clamped to 0: :func:`from_errpred` drops it by default;
:func:`engagement` keeps it with ``trailing=True``, as the simulated machine
does: its edges rub there, and that is where the surface is generated). For a
flat or radius end mill the contact point jumps from the tip to the rim as
soon as ``u`` leaves ``n`` (the bottom face touches the surface only when
they are parallel).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from errpred.engagement import expand_flutes, revolution_angles
from errpred.force import chip_thickness
from errpred.frames import tool_frame
from errpred.sweeps import read_only
from errpred.tool import MicroEdges, Tool

from . import _kernels as KN
from . import _sampled_kernels as SK
from .constants import (
    ANGLE_GRIDS_KEPT,
    AXIS_NORMAL_MIN_COS,
    CHIP_EPS,
    DIRECTION_MIN_NORM,
    GAIN_ANGLES_PER_REV,
    GAIN_BAND_BISECTIONS,
    GAIN_BAND_PROBES,
    GAIN_MIN_ARC_SAMPLES,
    GAIN_ROOT_MAX_ITER,
    GAIN_ROOT_STEP_RAD,
    GAIN_ROOT_TOL_RAD,
    MEMBERSHIP_EPS_MM,
)
from .geometry import local_frame

__all__ = [
    "FluteEngagement",
    "LocalCut",
    "Placement",
    "SampledEngagement",
    "cutting_intervals",
    "engagement",
    "flute_engagement",
    "from_errpred",
    "geometry_vector",
    "kernel_settings",
    "place",
]


def _number(name: str, v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name}: expected a number, got {v!r}")
    if not math.isfinite(v):
        raise ValueError(f"{name}: expected a finite value, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class LocalCut:
    """A finishing cut at one cutter location, in the local frame (f, b, n).

    Attributes
    ----------
    depth_mm : float [mm]
        Stock above the finished surface along ``n`` (>= 0; 0 cuts nothing).
    pick_mm : float [mm]
        Step-over along ``b`` between adjacent passes (>= 0).
    previous_side : int
        +1 if the previous pass lies at ``+pick b``, -1 at ``-pick b``, 0 for
        a single groove or first pass (nothing removed beside the tool).
    fz_mm : float [mm]
        Feed per tooth (> 0).
    curvature_f_1_mm, curvature_b_1_mm : float [1/mm]
        Normal curvatures of the finished surface along ``f`` and ``b``;
        0 flat, positive convex. ``1 + curvature depth`` must stay > 0.
    """

    depth_mm: float
    pick_mm: float
    previous_side: int
    fz_mm: float
    curvature_f_1_mm: float = 0.0
    curvature_b_1_mm: float = 0.0

    def __post_init__(self) -> None:
        for name in ("depth_mm", "pick_mm", "fz_mm", "curvature_f_1_mm", "curvature_b_1_mm"):
            object.__setattr__(self, name, _number(f"cut.{name}", getattr(self, name)))
        if self.depth_mm < 0:
            raise ValueError(f"cut.depth_mm: expected a value >= 0, got {self.depth_mm!r}")
        if self.pick_mm < 0:
            raise ValueError(f"cut.pick_mm: expected a value >= 0, got {self.pick_mm!r}")
        if not self.fz_mm > 0:
            raise ValueError(f"cut.fz_mm: expected a value > 0, got {self.fz_mm!r}")
        side = self.previous_side
        if isinstance(side, bool) or side not in (-1, 0, 1):
            raise ValueError(f"cut.previous_side: expected -1, 0 or +1, got {side!r}")
        object.__setattr__(self, "previous_side", int(side))
        for name in ("curvature_f_1_mm", "curvature_b_1_mm"):
            k = getattr(self, name)
            if not 1.0 + k * self.depth_mm > 0:
                raise ValueError(f"cut.{name}: {k!r} 1/mm with depth {self.depth_mm:g} mm "
                                 f"folds the stock top (1 + k depth <= 0)")

    def row(self) -> np.ndarray:
        """``[depth, pick, side, fz, kf, kb]`` as the kernels take it, shape (6,)."""
        return np.array([self.depth_mm, self.pick_mm, float(self.previous_side), self.fz_mm,
                         self.curvature_f_1_mm, self.curvature_b_1_mm])

    def check_tool(self, tool: Tool) -> None:
        """Refuse a concave surface tighter than the tool's corner (it would gouge)."""
        r = tool.corner_radius_mm
        for name in ("curvature_f_1_mm", "curvature_b_1_mm"):
            k = getattr(self, name)
            if k < 0 and r > 0 and -k * r >= 1.0:
                raise ValueError(f"cut.{name}: concave curvature {k:g} 1/mm is tighter than "
                                 f"the tool's corner radius {r:g} mm (the tool would gouge)")


@dataclass(frozen=True, eq=False)
class Placement:
    """The tool at a cutter contact point (contact at the origin).

    Attributes
    ----------
    axis : ndarray, shape (3,) [-]
        Unit tool axis ``u``.
    f, b, n : ndarray, shape (3,) [-]
        Local frame (:func:`orient.geometry.local_frame`).
    frame : ndarray, shape (3, 3) [-]
        Tool frame rows ``x', y', z'`` (``errpred.frames.tool_frame``,
        mirrored for a counter-clockwise spindle).
    tip : ndarray, shape (3,) [mm]
        Tool tip relative to the contact point.
    """

    axis: np.ndarray
    f: np.ndarray
    b: np.ndarray
    n: np.ndarray
    frame: np.ndarray
    tip: np.ndarray


def place(tool: Tool, posture_axis: Any, normal: Any, feed_dir: Any) -> Placement:
    """Tool frame and tip of a posture at a contact point (module docstring).

    Parameters
    ----------
    tool : Tool
    posture_axis : array_like, shape (3,) [-]
        Tool axis (normalized here); must point away from the workpiece
        (``u . n > 0``).
    normal, feed_dir : array_like, shape (3,) [-]
        Outward surface normal and feed direction.

    Returns
    -------
    Placement
    """
    u = np.asarray(posture_axis, dtype=float)
    if u.shape != (3,) or not np.all(np.isfinite(u)) or not np.linalg.norm(u) > 0:
        raise ValueError(f"posture_axis: expected a finite non-zero 3-vector, got {u!r}")
    if np.asarray(normal).shape != (3,) or np.asarray(feed_dir).shape != (3,):
        raise ValueError("normal, feed_dir: expected 3-vectors")
    u = u / np.linalg.norm(u)
    f, b, n = local_frame(normal, feed_dir)
    un = float(u @ n)
    if not un >= AXIS_NORMAL_MIN_COS:
        raise ValueError(f"posture_axis: the tool axis must point away from the workpiece "
                         f"(u . n > 0), got u . n = {un:.3g}")
    frame = tool_frame(u, f, tool.rotation_sign)
    r, c0 = tool.corner_radius_mm, tool.core_radius_mm
    n_perp = n - un * u
    norm = float(np.linalg.norm(n_perp))
    tip = r * (n - u) + (c0 / norm * n_perp if norm > DIRECTION_MIN_NORM else 0.0)
    return Placement(axis=u, f=f, b=b, n=n, frame=frame, tip=np.asarray(tip, dtype=float))


def _pass_half_length(tool: Tool, pick: float) -> float:
    """Half length of the finite sweep that stands for the infinite previous pass [mm]."""
    return 4.0 * tool.radius_mm + 2.0 * tool.flute_length_mm + pick


def geometry_vector(tool: Tool, posture_axis: Any, normal: Any, feed_dir: Any,
                    cut: LocalCut) -> np.ndarray:
    """The kernels' per-posture vector (``orient._kernels.posture_geometry``).

    Built from the vectors as given (the batch kernel normalizes them itself:
    the same rounding in both paths); validate them with :func:`place` first.
    """
    geo = np.empty(KN.GEO_SIZE)
    # a copy: a read-only axis (a frozen array) compiled a version of the kernel of its own
    ok = KN.posture_geometry(np.array(posture_axis, dtype=float),
                             np.asarray(normal, dtype=float), np.asarray(feed_dir, dtype=float),
                             cut.depth_mm, cut.pick_mm,
                             float(cut.previous_side), cut.curvature_f_1_mm,
                             cut.curvature_b_1_mm, float(tool.rotation_sign),
                             tool.core_radius_mm, tool.corner_radius_mm, tool.flute_length_mm,
                             geo)
    if not ok:
        raise ValueError("posture_axis: no tool frame (the axis is along the feed)")
    return geo


@dataclass(frozen=True, eq=False)
class SampledEngagement:
    """Engagement sampled over one revolution, every flute (any chip-thickness source).

    Attributes
    ----------
    theta : ndarray, shape (n_ang,) [rad]
        Rotation angles of flute 0 (a multiple of the flutes, equal steps).
    phi : ndarray, shape (n_ang, n_fl, m) [rad]
        Angular position of each micro edge (``errpred.engagement.expand_flutes``).
    cutting : ndarray of bool, shape (n_ang, n_fl, m)
    h : ndarray, shape (n_ang, n_fl, m) [mm]
        Uncut chip thickness (``errpred.force.chip_thickness``).
    weight : ndarray, shape (n_ang, n_fl, m) or None [-]
        Share of each sample's rotation step spent cutting (errpred's
        boundary refinement); None = 1 where cutting.
    frame : ndarray, shape (3, 3) [-]
        Tool frame rows.
    normal : ndarray, shape (3,) [-]
        Outward surface normal at the contact (for the up/down-cut degree).
    f_tooth_world : ndarray, shape (3,) [mm]
        Feed per tooth vector.
    """

    theta: np.ndarray
    phi: np.ndarray
    cutting: np.ndarray
    h: np.ndarray
    weight: np.ndarray | None
    frame: np.ndarray
    normal: np.ndarray
    f_tooth_world: np.ndarray


@functools.lru_cache(maxsize=ANGLE_GRIDS_KEPT)
def _angle_grid(n_angles: int, flutes: int, psi: bytes) -> tuple[np.ndarray, ...]:
    """``theta`` (n,) and ``sin``, ``cos`` of flute 0's ``phi = theta - psi`` (n, m): the
    same for every cutter location of a tool and angle count (numpy's, read-only)."""
    theta = revolution_angles(2 * math.pi / n_angles, flutes)
    phi0 = theta[:, None] - np.frombuffer(psi)[None, :]
    out = (theta, np.sin(phi0), np.cos(phi0))
    for a in out:
        a.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class FluteEngagement:
    """Flute 0's engagement over one revolution (:func:`flute_engagement`); the other
    flutes are flute 0 a tooth later (``errpred.engagement.expand_flutes``).

    Attributes
    ----------
    theta : ndarray, shape (n,) [rad]
    cutting0 : ndarray of bool, shape (n, m)
    h0 : ndarray, shape (n, m) [mm]
        Chip thickness (clamped at 0).
    rows, cols : ndarray of int64, shape (c,)
        The cutting samples of flute 0, ``np.nonzero(cutting0)``.
    psi : ndarray, shape (m,) [rad]
        The micro edges' helix lag.
    flutes : int
    frame, normal, f_tooth_world
        As in :class:`SampledEngagement`.
    """

    theta: np.ndarray
    cutting0: np.ndarray
    h0: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    psi: np.ndarray
    flutes: int
    frame: np.ndarray
    normal: np.ndarray
    f_tooth_world: np.ndarray

    def entries(self) -> tuple[np.ndarray, ...]:
        """The cutting samples of every flute, ``(i, k, j, phi, h)``: angle sample, flute,
        micro edge (int64, in ``np.nonzero``'s order of the (n, flutes, m) mask),
        angular position [rad] and chip [mm] -- :meth:`expand`'s ``phi``, ``h`` at the
        nonzeros of its ``cutting``, the same numbers, without its (n, flutes, m) arrays."""
        n = self.theta.size
        shift = n // self.flutes
        i0, j0 = self.rows, self.cols
        k = np.repeat(np.arange(self.flutes, dtype=np.int64), i0.size)
        j = np.tile(j0, self.flutes)
        i = (np.tile(i0, self.flutes) - shift * k) % n      # flute k at i is flute 0 at i0
        order = np.lexsort((j, k, i))
        i, k, j = i[order], k[order], j[order]
        h = np.tile(self.h0[i0, j0], self.flutes)[order]
        phi = self.theta[i] + (2 * math.pi / self.flutes) * k - self.psi[j]
        return i, k, j, phi, h

    def expand(self, edges: MicroEdges) -> SampledEngagement:
        """Every flute's ``phi``, ``cutting``, ``h``, shape (n, flutes, m)."""
        phi, cutting = expand_flutes(self.theta, self.cutting0, edges, self.flutes)
        # flute k at step i is flute 0 at step i + k n / N (expand_flutes): same chip
        h = expand_flutes(self.theta, self.h0, edges, self.flutes)[1]
        return SampledEngagement(theta=self.theta, phi=phi, cutting=cutting, h=h,
                                 weight=None, frame=self.frame, normal=self.normal,
                                 f_tooth_world=self.f_tooth_world)


def flute_engagement(tool: Tool, edges: MicroEdges, posture_axis: Any, normal: Any,
                     feed_dir: Any, cut: LocalCut, n_angles: int = GAIN_ANGLES_PER_REV, *,
                     trailing: bool = False) -> FluteEngagement:
    """:func:`engagement` of flute 0 alone (same arguments, same samples): one numba
    kernel over the rotation samples x micro edges (``orient/_sampled_kernels.py``)."""
    if not isinstance(cut, LocalCut):
        raise ValueError(f"cut: expected a LocalCut, got {type(cut).__name__}")
    if not (isinstance(n_angles, (int, np.integer)) and n_angles >= 4):
        raise ValueError(f"n_angles: expected an integer >= 4, got {n_angles!r}")
    cut.check_tool(tool)
    pl = place(tool, posture_axis, normal, feed_dir)
    psi = np.ascontiguousarray(edges.psi, dtype=float)
    theta, sin0, cos0 = _angle_grid(int(n_angles), tool.flutes, psi.tobytes())
    # the projections of the edge points on n, f, b: tip . v + p . (frame v)
    proj = np.array([[float(pl.tip @ v), *(pl.frame @ v)] for v in (pl.n, pl.f, pl.b)])
    kf = cut.curvature_f_1_mm / (1.0 + cut.curvature_f_1_mm * cut.depth_mm)
    kb = cut.curvature_b_1_mm / (1.0 + cut.curvature_b_1_mm * cut.depth_mm)
    half = _pass_half_length(tool, cut.pick_mm)
    if cut.previous_side != 0:
        prev_p0 = (pl.tip + cut.previous_side * cut.pick_mm * pl.b - half * pl.f)[None, :]
        prev_d = (2.0 * half * pl.f)[None, :]
    else:
        prev_p0 = prev_d = np.zeros((0, 3))
    cur_p0 = (pl.tip - half * pl.f)[None, :]
    cur_d = ((half - cut.fz_mm) * pl.f)[None, :]
    f_tool = pl.frame @ (cut.fz_mm * pl.f)
    # read-only, as errpred's sweeps: the membership test's callees compiled once for
    # both (numba types read-only arrays apart)
    sweeps = read_only(*(np.ascontiguousarray(a) for a in (prev_p0, prev_d, cur_p0, cur_d,
                                                           pl.axis[None, :].copy())))
    rho, z, kappa = (np.ascontiguousarray(getattr(edges, a), dtype=float)
                     for a in ("rho", "z", "kappa"))
    shape = sin0.shape
    cutting0, h0 = np.empty(shape, bool), np.empty(shape)
    rows, cols = SK.flute0_engagement(
        sin0, cos0, rho, z, np.sin(kappa), np.cos(kappa), np.ascontiguousarray(pl.frame),
        np.ascontiguousarray(pl.tip), proj, cut.depth_mm, kf, kb, *sweeps,
        tool.core_radius_mm, tool.corner_radius_mm, tool.flute_length_mm, MEMBERSHIP_EPS_MM,
        f_tool, CHIP_EPS * cut.fz_mm, bool(trailing), cutting0, h0)
    return FluteEngagement(theta=theta, cutting0=cutting0, h0=h0, rows=rows, cols=cols,
                           psi=psi, flutes=tool.flutes, frame=pl.frame, normal=pl.n,
                           f_tooth_world=cut.fz_mm * pl.f)


def engagement(tool: Tool, edges: MicroEdges, posture_axis: Any, normal: Any, feed_dir: Any,
               cut: LocalCut, n_angles: int = GAIN_ANGLES_PER_REV, *,
               trailing: bool = False) -> SampledEngagement:
    """Which micro edges cut, sampled over one revolution (module docstring).

    Parameters
    ----------
    tool : Tool
    edges : MicroEdges
        ``m`` micro edges of one flute (``tool.micro_edges(...)``).
    posture_axis, normal, feed_dir : array_like, shape (3,) [-]
        Tool axis, outward surface normal and feed direction at the contact.
    cut : LocalCut
    n_angles : int
        Rotation samples per revolution (rounded up to a multiple of the
        flutes, and even: ``errpred.engagement.revolution_angles``).
    trailing : bool
        Also the micro edges in the material whose chip ``h`` is 0 but which lie
        outside the envelope one tooth earlier (the current pass swept up to one
        feed per tooth back): the trailing sliver ``-fz/2 < (p - c).f <= 0`` of a
        ball, the material the first-order chip misses and errpred's rasterizer
        keeps (:func:`from_errpred`). Their edges rub (the edge force, no chip);
        the finished surface is generated among them. Off for the planner: they
        add nothing to the process gain.

    Returns
    -------
    SampledEngagement
        ``phi``, ``cutting``, ``h`` of shape (n_ang, n_fl, m); with ``trailing``
        the trailing edges are those cutting with ``h == 0``.
    """
    return flute_engagement(tool, edges, posture_axis, normal, feed_dir, cut, n_angles,
                            trailing=trailing).expand(edges)


def from_errpred(eng: Any, tool: Tool, edges: MicroEdges, normal: Any, frame: Any = None,
                 f_tooth_world: Any = None, positive_chip_only: bool = True
                 ) -> SampledEngagement:
    """Wrap errpred's engagement (rasterizer and sweeps) as a :class:`SampledEngagement`.

    Parameters
    ----------
    eng : errpred.engagement.Engagement or errpred.geometry.PointGeometry
        Anything with ``cutting0`` (n, m) for flute 0; ``theta`` (default:
        ``n`` equal steps from 0) and ``weight0`` (fractional boundary
        samples) are used when present.
    tool : Tool
    edges : MicroEdges
        The micro edges ``eng`` was computed with.
    normal : array_like, shape (3,) [-]
        Outward surface normal at the contact (for the up/down-cut degree).
    frame : array_like, shape (3, 3), optional [-]
        Tool frame rows; default ``eng.frame``.
    f_tooth_world : array_like, shape (3,), optional [mm]
        Feed per tooth; default ``eng.feed_per_tooth_world``.
    positive_chip_only : bool
        Keep only the samples with a positive chip thickness (the fast
        model's rule). errpred's sweeps leave a sliver, ``-fz/2 < (p - c).f
        <= 0`` for a ball, where material is present but ``h`` is clamped
        to 0: its edges rub without a chip.

    Returns
    -------
    SampledEngagement
    """
    cutting0 = np.asarray(getattr(eng, "cutting0", None))
    if cutting0.ndim != 2 or cutting0.shape[1] != len(edges):
        raise ValueError(f"eng.cutting0: expected shape (n, {len(edges)}), got "
                         f"{cutting0.shape}")
    n = cutting0.shape[0]
    theta = getattr(eng, "theta", None)
    theta = np.arange(n) * (2 * math.pi / n) if theta is None else np.asarray(theta, float)
    frame = np.asarray(eng.frame if frame is None else frame, dtype=float)
    f_tooth = np.asarray(eng.feed_per_tooth_world if f_tooth_world is None else f_tooth_world,
                         dtype=float)
    if frame.shape != (3, 3) or f_tooth.shape != (3,):
        raise ValueError("frame, f_tooth_world: expected shapes (3, 3) and (3,)")
    nrm = np.asarray(normal, dtype=float)
    if nrm.shape != (3,) or not np.all(np.isfinite(nrm)) or not np.linalg.norm(nrm) > 0:
        raise ValueError(f"normal: expected a finite non-zero 3-vector, got {nrm!r}")
    phi, cutting = expand_flutes(theta, cutting0.astype(bool), edges, tool.flutes)
    weight = getattr(eng, "weight0", None)
    if weight is not None:
        weight = expand_flutes(theta, np.asarray(weight, dtype=float), edges, tool.flutes)[1]
    h = chip_thickness(edges, phi, frame @ f_tooth)
    if positive_chip_only:
        cutting = cutting & (h > CHIP_EPS * float(np.linalg.norm(f_tooth)))
    return SampledEngagement(theta=theta, phi=phi, cutting=cutting, h=h, weight=weight,
                             frame=frame, normal=nrm / np.linalg.norm(nrm),
                             f_tooth_world=f_tooth)


def cutting_intervals(tool: Tool, edges: MicroEdges, posture_axis: Any, normal: Any,
                      feed_dir: Any, cut: LocalCut,
                      root_step_rad: float = GAIN_ROOT_STEP_RAD) -> list[np.ndarray]:
    """Exact entry and exit angles of each micro edge of flute 0.

    Parameters
    ----------
    tool, edges, posture_axis, normal, feed_dir, cut
        As in :func:`engagement`.
    root_step_rad : float [rad]
        Sampling step of the non-circular material conditions before their
        roots are refined (``orient/_engagement_kernels.py``).

    Returns
    -------
    list of ndarray, each shape (k_j, 2) [rad]
        Per micro edge, the intervals ``[phi_in, phi_out]`` of its angular
        position ``phi`` (``phi_out > phi_in``; not wrapped into one turn)
        during which it cuts.
    """
    if not isinstance(cut, LocalCut):
        raise ValueError(f"cut: expected a LocalCut, got {type(cut).__name__}")
    if not (math.isfinite(root_step_rad) and 0 < root_step_rad <= math.pi):
        raise ValueError(f"root_step_rad: expected 0 < step <= pi, got {root_step_rad!r}")
    cut.check_tool(tool)
    place(tool, posture_axis, normal, feed_dir)            # validates the vectors
    geo = geometry_vector(tool, posture_axis, normal, feed_dir, cut)
    set_par = kernel_settings(root_step_rad)
    counts, iv, _kinds = KN.edge_intervals(geo, *_edge_arrays(edges)[:3], tool.core_radius_mm,
                                           tool.corner_radius_mm, tool.flute_length_mm, set_par)
    return [iv[j, :counts[j]].copy() for j in range(len(edges))]


def kernel_settings(root_step_rad: float = GAIN_ROOT_STEP_RAD) -> np.ndarray:
    """The kernels' ``set_par``, shape (8,).

    Chip eps, membership eps [mm], root step [rad], root tolerance [rad],
    iterations, band probes, band bisections, least samples per arc (passed
    as values, not read as numba globals: a changed constant would not
    invalidate numba's on-disk cache).
    """
    return np.array([CHIP_EPS, MEMBERSHIP_EPS_MM, float(root_step_rad), GAIN_ROOT_TOL_RAD,
                     float(GAIN_ROOT_MAX_ITER), float(GAIN_BAND_PROBES),
                     float(GAIN_BAND_BISECTIONS), float(GAIN_MIN_ARC_SAMPLES)])


def _edge_arrays(edges: MicroEdges) -> tuple[np.ndarray, ...]:
    """rho, z, kappa, psi, db as contiguous float arrays."""
    return tuple(np.ascontiguousarray(getattr(edges, k), dtype=float)
                 for k in ("rho", "z", "kappa", "psi", "db"))
