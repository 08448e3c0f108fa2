"""The finished surface a cutter location leaves, and where it is generated.

``docs/method.md`` §3: in a view of the tool, each pixel's ray meets the
rotating tool's envelope at one point. That point is in the **cutting
region** if it holds material this revolution removes (inside the stock,
outside every sweep before this location, T1), and on the **finished
surface** if, in addition, no later sweep (T2) removes it again. The finished
pixels' mean rotation and contact angle give the generation point: the
rotation angle ``theta_m`` at which flute 0 passes it, the contact angle
``kappa_m``, the point and the surface normal (from the point toward the
envelope's centre of curvature). Per-pixel attributes are analytic, nothing
is read back from colours.

Views: the bottom view along the tool axis (rays parallel to ``z'``), and the
side view (rays perpendicular to ``z'``) for steep walls.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ._cluster_kernels import inside_any_sweep_clustered, read_only
from ._side_kernels import side_stock_hits
from .constants import CLUSTER_CELL_MM, MEMBERSHIP_EPS_MM, SIDE_T2_FIRST_SWEEPS
from .tool import Tool

__all__ = ["EnvelopeHits", "Region", "GenerationPoint", "envelope_hits", "regions",
           "side_regions", "generation_point", "strip_samples"]

_PARALLEL_TOL = 1e-9
#: Finished pixels kept per point for averaging the error over the strip.
MAX_STRIP_SAMPLES = 256


@dataclass(frozen=True, eq=False)
class EnvelopeHits:
    """Where each pixel ray meets the tool envelope (flat arrays over pixels).

    Attributes
    ----------
    valid : ndarray, shape (p,), bool
    tool_xyz : ndarray, shape (p, 3) [mm]
        Hit point in the tool frame.
    world : ndarray, shape (p, 3) [mm]
    phi, kappa : ndarray, shape (p,) [rad]
        Angular position and contact angle of the envelope at the hit.
    shape : tuple
        (ny, nx) of the view.
    index : ndarray, shape (p,), int, or None
        Where only some of the view's pixels are kept (:func:`side_regions`): the flat
        pixel index (``i * nx + j``) of each; None: every pixel, in order.
    """

    valid: np.ndarray
    tool_xyz: np.ndarray
    world: np.ndarray
    phi: np.ndarray
    kappa: np.ndarray
    shape: tuple[int, int]
    index: np.ndarray | None = None


def _pixel_rays(view) -> tuple[np.ndarray, np.ndarray]:
    j, i = np.meshgrid(np.arange(view.nx) + 0.5, np.arange(view.ny) + 0.5)
    o = (np.asarray(view.origin)[None, :]
         + (j.reshape(-1, 1) * view.pixel_mm) * view.basis[0][None, :]
         + (i.reshape(-1, 1) * view.pixel_mm) * view.basis[1][None, :])
    return o, np.asarray(view.basis[2], dtype=float)


def _side_kappa(z: np.ndarray, r: float) -> np.ndarray:
    """Contact angle [rad] of the envelope at tool-frame heights ``z`` [mm] seen from the
    side: pi/2 on the cylinder (``z >= r``), the corner's angle below it."""
    with np.errstate(invalid="ignore"):
        return np.where(z >= r, math.pi / 2,
                        np.arccos(np.clip((r - z) / r if r > 0 else 0.0, -1, 1)))


def envelope_hits(tool: Tool, view, frame: np.ndarray, tip: np.ndarray) -> EnvelopeHits:
    """First hits of the view's pixel rays on the tool's cutting envelope.

    The view must look along the tool axis (bottom view, ``+z'``) or across
    it (side view); other directions raise ``ValueError``. Over a whole view, in
    numpy: the twin of the side view's kernel (:func:`side_regions`,
    :func:`errpred._side_kernels.side_stock_hits`: the same hits within
    ``constants.SIDE_HITS_TOL_MM`` / ``SIDE_HITS_TOL_RAD``).
    """
    o, v = _pixel_rays(view)
    o_t = (o - tip) @ frame.T
    v_t = frame @ v
    R, r, c = tool.radius_mm, tool.corner_radius_mm, tool.core_radius_mm
    p = o_t.shape[0]
    xyz = np.full((p, 3), np.nan)
    if abs(abs(v_t[2]) - 1.0) < _PARALLEL_TOL:
        if v_t[2] < 0:
            raise ValueError("the bottom view must look up the tool axis (+z')")
        rho = np.hypot(o_t[:, 0], o_t[:, 1])
        valid = rho <= R
        xyz[:, :2] = o_t[:, :2]
        xyz[:, 2] = tool.envelope_z(rho)
        kappa = tool.kappa_at_rho(rho)
    elif abs(v_t[2]) < _PARALLEL_TOL:
        z = o_t[:, 2]
        with np.errstate(invalid="ignore"):
            rad = np.where(z >= r, R, c + np.sqrt(np.maximum(r * r - (r - z) ** 2, 0.0)))
        rad = np.where((z >= 0) & (z <= tool.flute_length_mm), rad, np.nan)
        v2 = v_t[:2] / np.linalg.norm(v_t[:2])
        b = o_t[:, :2] @ v2
        cc = np.sum(o_t[:, :2] ** 2, axis=1) - rad ** 2
        disc = b * b - cc
        valid = np.isfinite(disc) & (disc >= 0)
        t = -b - np.sqrt(np.where(valid, disc, 0.0))
        xyz[:, :2] = o_t[:, :2] + t[:, None] * v2[None, :]
        xyz[:, 2] = z
        kappa = _side_kappa(z, r)
    else:
        raise ValueError("views must look along or across the tool axis")
    phi = np.arctan2(xyz[:, 0], xyz[:, 1])
    world = tip + np.where(valid[:, None], xyz, 0.0) @ frame
    return EnvelopeHits(valid=valid, tool_xyz=xyz, world=world, phi=phi, kappa=kappa,
                        shape=(view.ny, view.nx))


@dataclass(frozen=True, eq=False)
class Region:
    """Cutting and finished pixels of a view (flat boolean arrays; ``cutting`` None where
    only the finished pixels were asked for, :func:`side_regions`)."""

    hits: EnvelopeHits
    cutting: np.ndarray | None
    finished: np.ndarray
    pixel_mm: float


def _outside(tool: Tool, pts: np.ndarray, cand: np.ndarray, sweeps) -> np.ndarray:
    p0, d, w, lo, hi = sweeps
    if p0.shape[0] == 0:
        return cand.copy()
    inside = inside_any_sweep_clustered(pts, cand, p0, d, w, lo, hi, tool.core_radius_mm,
                              tool.corner_radius_mm, tool.flute_length_mm, MEMBERSHIP_EPS_MM,
                                        CLUSTER_CELL_MM)
    return cand & ~inside


def regions(tool: Tool, hits: EnvelopeHits, pixel_mm: float,
            in_stock: Callable[[np.ndarray], np.ndarray], t1, t2) -> Region:
    """Cutting region (material before, T1) and finished surface (also after, T2)."""
    cand = hits.valid.copy()
    if cand.any():
        cand[cand] = in_stock(hits.world[cand])
    cutting = _outside(tool, hits.world, cand, t1)
    finished = _outside(tool, hits.world, cutting, t2)
    return Region(hits=hits, cutting=cutting, finished=finished, pixel_mm=pixel_mm)


def _nearest_sweeps(sweeps, point: np.ndarray, k: int):
    """The ``k`` sweeps (``(p0, d, w, lo, hi)``) whose start lies nearest ``point``."""
    p0 = sweeps[0]
    if p0.shape[0] <= k:
        return sweeps
    pick = np.sort(np.argpartition(((p0 - point) ** 2).sum(axis=1), k - 1)[:k])
    return read_only(*(np.ascontiguousarray(a[pick]) for a in sweeps))


def side_regions(tool: Tool, view, frame: np.ndarray, tip: np.ndarray, probe, t1, t2,
                 cutting: bool = True) -> Region:
    """:func:`regions` of a side view's :func:`envelope_hits`, kept to the pixels whose
    hit lies in the stock (``probe``, a :class:`errpred.probe.StockProbe` of ``view``):
    the cutting and finished regions are made of those alone, so they are the same
    pixels; the others' arrays are never made (``EnvelopeHits.index`` says which
    pixels these are). One numba pass finds them and their hits
    (:func:`errpred._side_kernels.side_stock_hits`); ``phi`` and ``kappa`` as
    :func:`envelope_hits` forms them.

    With ``cutting=False`` only the finished pixels are wanted (``Region.cutting`` is
    None): the same pixels, found in a cheaper order. A finished pixel is in the
    stock and in no sweep of T1 or T2, whichever is asked first, and each answer is
    exact; so the pixels go first against the ``SIDE_T2_FIRST_SWEEPS`` sweeps of T2
    that start nearest the tip (the tool's own path ahead, which holds the front of
    the tool), then T1, then all of T2, instead of refuting the whole cutting region
    against every sweep of T1 first.
    """
    frame = np.ascontiguousarray(frame, dtype=float)
    v_t = frame @ np.asarray(view.basis[2], dtype=float)
    if not abs(v_t[2]) < _PARALLEL_TOL:
        raise ValueError("side_regions: the view must look across the tool axis")
    R, r, c = tool.radius_mm, tool.corner_radius_mm, tool.core_radius_mm
    box, lo, hi, bottom, top = probe.kernel_args()
    index, xyz, world = side_stock_hits(
        np.ascontiguousarray(view.origin, dtype=float),
        np.ascontiguousarray(view.basis, dtype=float), float(view.pixel_mm), int(view.nx),
        int(view.ny), np.ascontiguousarray(tip, dtype=float), frame, float(R), float(r),
        float(c), float(tool.flute_length_mm), bool(box), lo, hi, bottom, top,
        MEMBERSHIP_EPS_MM)
    stock = np.ones(index.shape[0], dtype=bool)
    hits = EnvelopeHits(valid=stock, tool_xyz=xyz, world=world,
                        phi=np.arctan2(xyz[:, 0], xyz[:, 1]), kappa=_side_kappa(xyz[:, 2], r),
                        shape=(view.ny, view.nx), index=index)
    if cutting:
        cut = _outside(tool, world, stock, t1)
        finished = _outside(tool, world, cut, t2)
    else:
        cut = None
        first = _nearest_sweeps(t2, tip, SIDE_T2_FIRST_SWEEPS)
        finished = _outside(tool, world, _outside(tool, world, stock, first), t1)
        if first is not t2:             # T2 has more sweeps than those asked first
            finished = _outside(tool, world, finished, t2)
    return Region(hits=hits, cutting=cut, finished=finished, pixel_mm=view.pixel_mm)


@dataclass(frozen=True)
class GenerationPoint:
    """Where and when a cutter location generates the finished surface.

    Attributes
    ----------
    theta_rad : float [rad]
        Rotation of flute 0 (its tip) when its edge passes the point.
    phi_rad, kappa_rad : float [rad]
        Angular position and contact angle of the point on the envelope.
    point_tool, point_world : ndarray, shape (3,) [mm]
    normal_world : ndarray, shape (3,)
        Outward normal of the finished surface (from the point toward the
        envelope's centre of curvature).
    pixels : int
        Finished pixels it was computed from.
    samples_theta, samples_kappa, samples_z : ndarray, shape (k,)
        Rotation [rad], contact angle [rad] and height [mm] of (up to
        ``MAX_STRIP_SAMPLES``, evenly chosen) finished pixels: the strip the
        surface is generated over, for averaging the error across it.
    samples_normal : ndarray, shape (k, 3)
    """

    theta_rad: float
    phi_rad: float
    kappa_rad: float
    point_tool: np.ndarray
    point_world: np.ndarray
    normal_world: np.ndarray
    pixels: int
    samples_theta: np.ndarray | None = None
    samples_kappa: np.ndarray | None = None
    samples_z: np.ndarray | None = None
    samples_normal: np.ndarray | None = None


def strip_samples(tool: Tool, phi: np.ndarray, kappa: np.ndarray, z: np.ndarray,
                  frame: np.ndarray) -> dict:
    """Per-pixel rotation, contact angle, height and world normal of a strip."""
    k = phi.shape[0]
    if k > MAX_STRIP_SAMPLES:
        pick = np.linspace(0, k - 1, MAX_STRIP_SAMPLES).round().astype(int)
        phi, kappa, z = phi[pick], kappa[pick], z[pick]
    sk, ck = np.sin(kappa), np.cos(kappa)
    n_tool = np.column_stack([-sk * np.sin(phi), -sk * np.cos(phi), ck])
    theta = (phi + tool.helix_lag(z)) % (2 * math.pi)
    # contiguous (a column of the caller's array otherwise): a point pickles to the same
    # bytes before and after a round trip (errpred.repredict compares them)
    return dict(samples_theta=theta, samples_kappa=np.ascontiguousarray(kappa),
                samples_z=np.ascontiguousarray(z), samples_normal=n_tool @ frame)


def generation_point(tool: Tool, region: Region, frame: np.ndarray,
                     tip: np.ndarray) -> GenerationPoint | None:
    """Mean of the finished pixels' attributes; None if there are none."""
    sel = region.finished
    k = int(sel.sum())
    if k == 0:
        return None
    phi = region.hits.phi[sel]
    phi_m = math.atan2(float(np.sin(phi).mean()), float(np.cos(phi).mean()))
    kappa_m = float(region.hits.kappa[sel].mean())
    if kappa_m < math.pi / 2 - 1e-9:
        rho, z = tool.profile_point(kappa_m)
        rho, z = float(rho), float(z)
    else:
        rho, z = tool.radius_mm, float(region.hits.tool_xyz[sel, 2].mean())
    pt = np.array([rho * math.sin(phi_m), rho * math.cos(phi_m), z])
    sk, ck = math.sin(kappa_m), math.cos(kappa_m)
    n_tool = np.array([-sk * math.sin(phi_m), -sk * math.cos(phi_m), ck])
    theta = (phi_m + float(tool.helix_lag(z))) % (2 * math.pi)
    strip = strip_samples(tool, phi, region.hits.kappa[sel], region.hits.tool_xyz[sel, 2],
                          frame)
    return GenerationPoint(theta_rad=theta, phi_rad=phi_m, kappa_rad=kappa_m,
                           point_tool=pt, point_world=tip + pt @ frame,
                           normal_world=n_tool @ frame, pixels=k, **strip)
