"""Stage 1 of the prediction: the geometry of each prediction point.

Per block (``docs/method.md`` §3): place the prediction point, set up the
tool frame and the bottom view, find the sweeps near the tool (T1 before,
T2 after, one feed per tooth either side of the point), find which micro
edges cut during one revolution (:mod:`errpred.point_engagement`), and the
finished surface with its
generation point (correcting the view when the finished region is below a
pixel or the contact angle is steep). Nothing here depends on earlier
predictions, so blocks can be processed in any order and on any worker;
the wear that links them is stage 2 (:mod:`errpred.physics`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from nc.path import CutterLocations

from . import constants as K
from ._cluster_kernels import inside_any_sweep_clustered, read_only
from .bottomview import BottomTemplate, StockView, stock_view
from .engagement import revolution_angles
from .frames import tool_frame
from .geometry_pack import pack_engagement, pack_sparse, unpack_engagement, unpack_sparse
from .point_engagement import PointEngagement
from .probe import StockProbe
from .raster.camera import View
from .surface import GenerationPoint, generation_point, side_regions, strip_samples
from .sweeps import BlockLookup, Sweeps, build_sweeps, slerp
from .tool import MicroEdges, Tool
from .t1memo import RemovedMemo as _RemovedMemo
from .zmap import SweepMap, sweep_map

__all__ = ["Resolution", "PointGeometry", "GeometryModel", "STATUS", "ERROR_STATUSES"]

#: Status of a prediction point, and what it means.
STATUS = {
    "predicted": "error predicted",
    "rapid": "rapid move: not a cut",
    "no-cut": "the tool removes no material here",
    "axis-normal": ("generation point at the tool's centre: the tool axis is nearly "
                    "normal to the surface, cutting speed ~0, the force model does not hold"),
    "no-finished-surface": "cuts, but later moves remove everything it leaves",
    "spindle-stopped": "cutting move with the spindle stopped",
    "rapid-into-material": ("rapid move (G0) through material: a crash, not a cut; the "
                            "program must not be run as it is"),
}
#: Statuses that are errors in the program itself (``predict``, ``compensate`` and the
#: main job refuse the program: exit status 1).
ERROR_STATUSES = ("rapid-into-material",)


@dataclass(frozen=True)
class Resolution:
    """Discretization (``docs/method.md`` §9).

    Attributes
    ----------
    pixel_mm : float [mm]
    micro_edges : int
        Micro edges on the lower envelope (flank edges get the same spacing).
    angle_step_rad : float [rad]
    chord_tol_mm : float [mm]
    point_spacing_mm : float [mm]
        Blocks longer than this get several prediction points
        (``errpred.constants.POINT_SPACING_MM``: one per stretch of a block that
        cuts).
    point_ends : bool
        With a finite ``point_spacing_mm``: points at both ends of every block and
        at most ``point_spacing_mm`` apart between them (1 % more allowed:
        ``errpred.constants.POINT_SPACING_SLACK``; a block's start is left
        out where the block before it ends there, so each corner is predicted
        once). The dense verification of a correction uses this
        (:func:`Resolution.dense`).
    """

    pixel_mm: float
    micro_edges: int = K.MICRO_EDGES_ENVELOPE
    angle_step_rad: float = K.ANGLE_STEP_RAD
    chord_tol_mm: float = K.CHORD_TOL_MM
    point_spacing_mm: float = K.POINT_SPACING_MM
    point_ends: bool = False

    def dense(self, spacing_mm: float = K.VERIFY_SPACING_MM) -> "Resolution":
        """This resolution with points at most ``spacing_mm`` apart on every block
        (``POINT_SPACING_SLACK`` more), both ends included [mm]."""
        return dataclasses.replace(self, point_spacing_mm=float(spacing_mm), point_ends=True)

    @classmethod
    def default(cls, tool: Tool) -> "Resolution":
        return cls(pixel_mm=tool.diameter_mm * K.PIXEL_PER_DIAMETER)

    def finer(self, factor: float) -> "Resolution":
        """Every discretization refined by ``factor``."""
        return Resolution(self.pixel_mm / factor, int(round(self.micro_edges * factor)),
                          self.angle_step_rad / factor, self.chord_tol_mm / factor,
                          self.point_spacing_mm, self.point_ends)


@dataclass(frozen=True, eq=False)
class PointGeometry:
    """Stage-1 result for one prediction point (small: safe to ship between processes).

    Attributes
    ----------
    block : int
        Program block index.
    status : str
        A key of :data:`STATUS`.
    path_mm : float [mm]
        Cumulative tip path length of the point.
    tip, axis : ndarray, shape (3,)
    frame : ndarray, shape (3, 3)
    feed_mm_min, spindle_rpm : float
    feed_per_tooth_world : ndarray, shape (3,) [mm]
    cut_length_mm : float [mm]
        Length of the block this point stands for (for the revolutions spent
        cutting, which advance the wear).
    cutting0 : ndarray, shape (n, m), bool, or None
        Flute 0's engagement over one revolution.
    weight0 : ndarray, shape (n, m), float32, or None
        Share of each rotation step flute 0's micro edges spend cutting.
    sensitivity : tuple or None
        ``(delta_mm, cutting0, weight0, shift0)``: the engagement with the
        stock ``delta_mm`` thicker along the surface normal (the tool cutting
        that much deeper), for the error's sensitivity to a correction.
    shift0 : ndarray, shape (n, m), float32, or None [rad]
        Where within its step that share lies (centroid offset of the rotation
        angle): boundary samples are evaluated there.
    cl_per_rev : ndarray, shape (m,), or None [mm]
        Actual cutting distance per revolution of each micro edge.
    gen : GenerationPoint or None
    view : str
        ``"bottom"``, ``"bottom-zoom"`` or ``"side"``: the view that gave ``gen``.
    cutting_pixels, finished_pixels : int
    lookup_box : ndarray, shape (2, 3), or None [mm]
        A box holding every box in which the block's stage 1 looked up sweeps (the
        same for each point of the block; None: it looked up none). Sweeps whose
        bounds miss it cannot change the block's stage 1 (:mod:`errpred.repredict`).
    wall : GenerationPoint or None
        A flat or radius end mill whose ``gen`` lies on a floor (the bottom view,
        ``kappa`` up to ``VIEW_CORRECTION_KAPPA_RAD``) while its flank cuts: the wall
        the flank finishes at the same time, seen from the side (None: no such wall).
        Its error is predicted (``PointResult.E_wall_um``) and reported, not
        corrected: the correction fits ``gen``.
    above_flutes : bool
        The shank meets material: the moves before (to one feed per tooth behind the
        point) left material inside the shank (its radius, or the tool's where smaller),
        a pixel above the sweeps' tool solid (the flutes and the corner radius's cap
        on them; shallower contact is not seen), at the point or at any pre-check
        station of its block (an error in the program,
        :func:`errpred.findings.error_findings`). Tested only where the stock under the
        tool reaches that high; the holder is not tested.
    """

    block: int
    status: str
    path_mm: float
    tip: np.ndarray
    axis: np.ndarray
    frame: np.ndarray
    feed_mm_min: float
    spindle_rpm: float
    feed_per_tooth_world: np.ndarray
    cut_length_mm: float = 0.0
    cutting0: np.ndarray | None = None
    weight0: np.ndarray | None = None
    shift0: np.ndarray | None = None
    sensitivity: tuple | None = None
    cl_per_rev: np.ndarray | None = None
    gen: GenerationPoint | None = None
    view: str = "bottom"
    cutting_pixels: int = 0
    finished_pixels: int = 0
    notes: tuple[str, ...] = field(default_factory=tuple)
    lookup_box: np.ndarray | None = None
    above_flutes: bool = False
    wall: GenerationPoint | None = None

    def __getstate__(self) -> dict:
        # the per-revolution arrays are almost all zero: shipped packed, exactly
        # (errpred.geometry_pack; workers -> stage 2); a point that came packed (from a
        # worker) goes on packed as it came (the results' store, errpred.repredict):
        # its arrays are read only, so the packing still holds
        state = dict(self.__dict__)
        packed = state.pop("_packed", None)
        cutting0, weight0, shift0 = (state.pop(k) for k in ("cutting0", "weight0", "shift0"))
        sens = state.pop("sensitivity")
        clpr = state.pop("cl_per_rev")
        if packed is not None:
            state.update(packed)
            return state
        state["engagement"] = pack_engagement(cutting0, weight0, shift0)
        if sens is not None:
            state["sensitivity_packed"] = (sens[0], pack_engagement(*sens[1:]))
        else:
            state["sensitivity"] = None
        state["cl_per_rev"] = pack_sparse(clpr)
        return state

    def __setstate__(self, state: dict) -> None:
        packed = {k: state[k] for k in ("engagement", "sensitivity_packed", "sensitivity",
                                        "cl_per_rev") if k in state}
        state["cutting0"], state["weight0"], state["shift0"] = unpack_engagement(
            state.pop("engagement"))
        if "sensitivity_packed" in state:
            delta, pk = state.pop("sensitivity_packed")
            state["sensitivity"] = (delta, *unpack_engagement(pk))
        state["cl_per_rev"] = unpack_sparse(state["cl_per_rev"])
        arrays = [state["cutting0"], state["weight0"], state["shift0"], state["cl_per_rev"]]
        if state["sensitivity"] is not None:
            arrays += list(state["sensitivity"][1:])
        for a in arrays:
            if isinstance(a, np.ndarray):
                a.flags.writeable = False
        state["_packed"] = packed
        self.__dict__.update(state)

    @property
    def cuts(self) -> bool:
        """Whether the point removes material (known after stage 1)."""
        return self.status not in ("rapid", "no-cut", "spindle-stopped")

    def light(self) -> "PointGeometry":
        """This point without the per-revolution arrays (kept in results)."""
        gen, wall = (_without_samples(x) for x in (self.gen, self.wall))
        return dataclasses.replace(self, cutting0=None, weight0=None, shift0=None,
                                   sensitivity=None, cl_per_rev=None, gen=gen, wall=wall)


class GeometryModel:
    """Everything stage 1 needs: tool, stock, path, sweeps, discretization.

    Parameters
    ----------
    tool : Tool
    stock : errpred.raster.meshes.Stock
    cl : CutterLocations
        The program's path (arcs expanded), ``cl.block`` the program block.
    resolution : Resolution
    sensitivity : bool
        Also the engagement with the stock slightly thicker (the error's
        sensitivity to a correction, :attr:`PointGeometry.sensitivity`): what a
        correction needs, not a prediction alone.
    """

    def __init__(self, tool: Tool, stock, cl: CutterLocations, resolution: Resolution,
                 sensitivity: bool = True) -> None:
        self.tool = tool
        self.sensitivity = bool(sensitivity)
        self.stock = stock
        self.cl = cl
        self.res = resolution
        self.sweeps: Sweeps = build_sweeps(cl, tool)
        #: answer most T1 tests from a height map of the sweeps (3-axis ball end
        #: milling; identical answers, :mod:`errpred.zmap`): True, False, or None
        #: to decide per run (:meth:`plan_sweep_map`)
        self.use_sweep_map: bool | None = None
        self._zmap_on = True
        self._zmap: SweepMap | bool | None = None
        self.edges: MicroEdges = tool.micro_edges(resolution.micro_edges)
        self.theta = revolution_angles(resolution.angle_step_rad, tool.flutes)
        self.bottom = BottomTemplate(tool, self.edges, self.theta, resolution.pixel_mm)
        #: flute 0's engagement at a point (sample grids, step weights)
        self.engager = PointEngagement(tool, self.edges, self.theta, self.bottom, stock,
                                       resolution.pixel_mm)
        self._last_interval = self._last_near = None
        self._lookup_box: np.ndarray | None = None
        #: the shank met material at a pre-check station of the block being placed
        self._shank_hit = False
        #: the block :meth:`geometry` works on (CL range) and its shared sweep look-up
        self._block_span = self._block_near = None
        #: the last block's look-up, shared by the blocks after it inside its box
        self._kept_near: BlockLookup | None = None
        seg = np.zeros(len(cl))
        if len(cl) > 1:
            seg[1:] = np.linalg.norm(np.diff(cl.tip, axis=0), axis=1)
        self.path = np.cumsum(seg)
        # CL point range of each block
        blocks = cl.block
        order = np.argsort(blocks, kind="stable")
        self._block_ids, first = np.unique(blocks[order], return_index=True)
        self._first = order[first]
        last = np.r_[first[1:], blocks.size] - 1
        self._last = order[last]

    # --- placing points ----------------------------------------------------
    def block_points(self, block: int) -> tuple[int, int] | None:
        """First and last CL index of a block, or None if it has none."""
        k = np.searchsorted(self._block_ids, block)
        if k >= self._block_ids.size or self._block_ids[k] != block:
            return None
        return int(self._first[k]), int(self._last[k])

    def _at(self, L: float, block: int | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """Tip, axis, feed direction and ending CL index at path length L (on ``block``'s
        own segments where given: at a block's start, its first segment, not the end of
        the move before)."""
        s = int(np.searchsorted(self.path, L, side="left"))
        if block is not None:
            rng = self.block_points(block)
            if rng is not None:
                s = min(max(s, rng[0]), rng[1])
        s = min(max(s, 1), len(self.cl) - 1)
        L0, L1 = self.path[s - 1], self.path[s]
        t = 0.0 if L1 <= L0 else (L - L0) / (L1 - L0)
        a, b = self.cl.tip[s - 1], self.cl.tip[s]
        tip = a + t * (b - a)
        ua, ub = self.cl.axis[s - 1], self.cl.axis[s]
        om = math.acos(min(max(float(ua @ ub), -1.0), 1.0))
        if om > 0.0:
            # turning at a constant rate, as the sweeps do (errpred.sweeps.slerp)
            u = slerp(ua, ub, om, t)
        else:
            u = (1 - t) * ua + t * ub
            u /= np.linalg.norm(u)
        feed = b - a
        if t >= 1.0 and s + 1 < len(self.cl) and not self.cl.rapid[s + 1] \
                and self.cl.block[s + 1] == self.cl.block[s]:
            # at a chord end inside a block (an arc): the tangent is the bisector
            nxt = self.cl.tip[s + 1] - b
            la, lb = np.linalg.norm(feed), np.linalg.norm(nxt)
            if la > 0 and lb > 0:
                feed = feed / la + nxt / lb
        return tip, u, feed, s

    def geometry(self, block: int) -> list[PointGeometry]:
        """Prediction point(s) of one block, with their stage-1 geometry
        (:meth:`_geometry`), each with the block's :attr:`PointGeometry.lookup_box`;
        where the shank meets material at any of the block's pre-check stations, every
        point of the block says so (:attr:`PointGeometry.above_flutes`)."""
        self._lookup_box = None
        self._shank_hit = False
        out = self._geometry(block)
        if self._shank_hit:
            out = [dataclasses.replace(g, above_flutes=True) for g in out]
        box = self._lookup_box
        if box is None:
            return out
        box.flags.writeable = False
        return [dataclasses.replace(g, lookup_box=box) for g in out]

    def _geometry(self, block: int) -> list[PointGeometry]:
        """Prediction point(s) of one block, with their stage-1 geometry.

        The whole block is checked first (the seeds' pre-check: the block's sweep
        against the stock minus the earlier sweeps), at stations no more than
        ``PRECHECK_STEP_PER_DIAMETER`` tool diameters apart: prediction points go
        where it cuts, one in the middle of each stretch that cuts, standing for
        that stretch's length (its wear; the stretch's ends found between stations
        by bisection); with a finite ``point_spacing_mm``,
        points every so often along the block (and at its ends with
        ``point_ends``), each standing for its share of the block. A rapid move
        is checked the same way: one through material is ``rapid-into-material``.
        A block that leaves the tool where it was (no length, the same axis) is
        ``no-cut``.
        """
        rng = self.block_points(block)
        if rng is None:
            return []
        i0, i1 = rng
        self._block_span, self._block_near = (i0, i1), None
        cl = self.cl
        start = self.path[i0 - 1] if i0 > 0 else 0.0
        end = self.path[i1]
        length = end - start
        if bool(np.all(cl.rapid[i0:i1 + 1])):
            tip = cl.tip[i1]
            status = "rapid"
            for L in self._stations(start, end, ends=True):
                if self._material_at(L, start, rapid=True):
                    status = "rapid-into-material"
                    tip = self._at(L)[0]
                    break
            return [PointGeometry(block, status, float(self.path[i1]), tip, cl.axis[i1],
                                  np.eye(3), math.nan, float(cl.spindle_rpm[i1]), np.zeros(3))]
        k0 = max(i0 - 1, 0)
        if length <= 0.0 and not np.any(cl.axis[k0:i1 + 1] != cl.axis[i1]):
            # the tool stays where it is (a block repeating the position): no cut
            return [PointGeometry(block, "no-cut", float(end), cl.tip[i1], cl.axis[i1],
                                  np.eye(3), float(cl.feed_mm_min[i1]),
                                  float(cl.spindle_rpm[i1]), np.zeros(3))]
        spacing = self.res.point_spacing_mm
        if math.isfinite(spacing):
            return self._spaced_points(block, i0, start, length, spacing)
        stations = self._stations(start, end)
        if len(stations) == 1:
            # a short block: the midpoint first; the quarters if the midpoint does not cut
            last = None
            for frac in (0.5, 0.25, 0.75):
                g = self.point(block, start + frac * length, length)
                if g.status != "no-cut":
                    return [g]
                last = g
            return [last]
        step = length / len(stations)
        counts = np.array([self._material_at(L, start) for L in stations])
        out: list[PointGeometry] = []
        for a, b in _runs(counts > 0):
            # where the cut begins and ends between stations, to a fraction of a step
            lo = self._edge(start, stations[a - 1], stations[a]) if a > 0 else start
            hi = self._edge(start, stations[b], stations[b - 1]) if b < len(stations) \
                else start + length
            mid = 0.5 * (lo + hi)
            # the stretch's wear: the point's engagement times a length that makes its
            # coarse sample count integrate like the stations' counts over the stretch
            at = np.flatnonzero(stations[a:b] == mid)   # a station there already
            c_mid = int(counts[a + at[0]]) if at.size else self._material_at(mid, start)
            share = (float(counts[a:b].sum()) * step / c_mid) if c_mid else hi - lo
            tries = [mid] + sorted(stations[a:b].tolist(), key=lambda x: abs(x - mid))
            for L in tries:
                g = self.point(block, float(L), share)
                if g.status != "no-cut":
                    out.append(g)
                    break
        if not out:
            return [self.point(block, start + 0.5 * length, length)]
        return out

    def _spaced_points(self, block: int, i0: int, start: float, length: float,
                       spacing: float) -> list[PointGeometry]:
        """Points at most ``spacing`` apart along the block (``POINT_SPACING_SLACK``
        more), each standing for its share."""
        n = max(1, math.ceil(length / spacing - K.POINT_SPACING_SLACK))
        if not self.res.point_ends:
            # a point in the middle of each of n equal parts
            return [self.point(block, start + (k + 0.5) / n * length, length / n)
                    for k in range(n)]
        frac = np.arange(n + 1) / n
        # a corner between two feed moves is predicted once: as the end of the move
        # before it, unless that move runs along the tool axis (a plunge: the surface
        # at the corner is the next move's), or as the start of the move after it when
        # this one is a plunge
        cl = self.cl
        i1 = i0 + int(np.searchsorted(cl.block[i0:], block, side="right")) - 1
        before = i0 > 1 and not cl.rapid[i0 - 1] and cl.block[i0 - 1] != block
        after = i1 + 1 < len(cl) and not cl.rapid[i1 + 1]
        # (the move before predicts the corner only if it moves: a block that leaves
        # the tool where it was is no-cut and predicts nothing)
        if before and self.path[i0 - 1] > self.path[i0 - 2] and not self._plunge(i0 - 1):
            frac = frac[1:]
        if after and self._plunge(i1) and frac.size > 1:
            frac = frac[:-1]
        edges = np.concatenate([[0.0], 0.5 * (frac[1:] + frac[:-1]), [1.0]])
        return [self.point(block, start + float(t) * length, float(hi - lo) * length)
                for t, lo, hi in zip(frac, edges[:-1], edges[1:], strict=True)]

    def _edge(self, block_start: float, outside: float, inside: float) -> float:
        """Where between a station that does not cut (``outside``) and one that does
        (``inside``) the cut begins [mm path length], by ``PRECHECK_BISECTIONS``
        halvings."""
        for _ in range(K.PRECHECK_BISECTIONS):
            mid = 0.5 * (outside + inside)
            if self._material_at(mid, block_start):
                inside = mid
            else:
                outside = mid
        return 0.5 * (outside + inside)

    def _plunge(self, k: int) -> bool:
        """Does the segment ending at cutter location ``k`` run within ``PLUNGE_ANGLE_RAD``
        of the tool axis (a plunge or a retract)?"""
        d = self.cl.tip[k] - self.cl.tip[k - 1]
        L = float(np.linalg.norm(d))
        return L > 0 and abs(float(d @ self.cl.axis[k])) >= L * math.cos(K.PLUNGE_ANGLE_RAD)

    def _stations(self, start: float, end: float, ends: bool = False) -> np.ndarray:
        """Path lengths of the pre-check's stations on [start, end] [mm]: the middles of
        equal parts no longer than the pre-check step (with ``ends``, the ends too)."""
        length = end - start
        h = K.PRECHECK_STEP_PER_DIAMETER * self.tool.diameter_mm
        n = max(1, math.ceil(length / h - 1e-9))
        mids = start + (np.arange(n) + 0.5) / n * length
        return np.concatenate([[start], mids, [end]]) if ends else mids

    def _material_at(self, L: float, block_start: float, rapid: bool = False) -> int:
        """How many of the tool's samples at path length ``L`` meet material the moves
        before left (0: none)?

        The pre-check of a block (coarse: every micro-edge sample of flute 0 at
        every ``PRECHECK_ROTATION_STRIDE``-th rotation step). For a feed move, the
        moves up to one feed per tooth behind the tool count as before; for a rapid,
        those before the block's start (rapids remove nothing). The tool is shrunk by
        ``PRECHECK_INSET_MM`` (``RAPID_TOUCH_MM`` for a rapid: positioning onto the
        stock's surface is no crash).
        """
        tool = self.tool
        tip, u, seg, s = self._at(L)
        frame = tool_frame(u, seg, tool.rotation_sign)
        interval = self._bottom_interval(tip, frame)
        z_top = self._stock_top(tip, frame, interval)
        if z_top < -tool.radius_mm:
            return 0
        if rapid:
            behind = max(L - block_start, 0.0)
        else:
            feed, spindle = float(self.cl.feed_mm_min[s]), float(self.cl.spindle_rpm[s])
            behind = feed / (spindle * tool.flutes) if spindle > 0 and feed > 0 else 0.0
        t1, _, _ = self._near_sweeps(tip, u, L, behind, z_top)
        if not rapid and not self._shank_hit:
            # the shank is tested at every station too, not only at the block's points
            self._shank_hit = self._above_flutes(tip, frame, interval, t1, z_top)
        # the micro edges not above the stock's top, the tool shrunk a little
        local = self.engager.precheck_samples(self.edges.z <= z_top + self.res.pixel_mm,
                                              K.RAPID_TOUCH_MM if rapid else K.PRECHECK_INSET_MM)
        inside = self.bottom.in_stock_local(self.stock, interval, tip, frame, local)
        if not inside.any():
            return 0
        removed = self._inside_sweeps(tip + local[inside] @ frame, t1)
        return int((~removed).sum())

    # --- one point ---------------------------------------------------------
    def point(self, block: int, L: float, cut_length: float) -> PointGeometry:
        tool, bt = self.tool, self.bottom
        tip, u, seg, s = self._at(L, block)
        feed = float(self.cl.feed_mm_min[s])
        spindle = float(self.cl.spindle_rpm[s])
        frame = tool_frame(u, seg, tool.rotation_sign)
        feed_dir = seg / max(np.linalg.norm(seg), 1e-300)
        base = dict(block=block, path_mm=float(L), tip=tip, axis=u, frame=frame,
                    feed_mm_min=feed, spindle_rpm=spindle)
        if not spindle > 0:
            return PointGeometry(status="spindle-stopped", feed_per_tooth_world=np.zeros(3),
                                 **base)
        fz = feed / (spindle * tool.flutes)
        f_tooth = fz * feed_dir
        base["feed_per_tooth_world"] = f_tooth
        # the stock's material in the bottom view
        interval = self._bottom_interval(tip, frame)
        z_top = self._stock_top(tip, frame, interval)
        if z_top < -tool.radius_mm:
            return PointGeometry(status="no-cut", **base)
        t1, t2, t1_ids = self._near_sweeps(tip, u, L, fz, z_top)
        base["above_flutes"] = self._above_flutes(tip, frame, interval, t1, z_top)
        # engagement of flute 0 over one revolution
        removed = _RemovedMemo(self.tool, t1, self._sweep_map(), L - fz, t1_ids)
        eng = self.engager.engagement(tip, frame, interval, removed, f_tooth, z_top)
        if eng is None:
            return PointGeometry(status="no-cut", **base)
        cutting0, weight0, shift0, cl_rev = eng
        base.update(cut_length_mm=float(cut_length), cutting0=cutting0,
                    weight0=weight0, shift0=shift0,
                    cl_per_rev=cl_rev)
        fin = bt.finished_surface(self.stock, interval, tip, frame, t1, t2, removed.test)
        notes = []
        gen, used = None, "bottom"
        if fin.xyz.shape[0]:
            gen = _generation(tool, fin.xyz, fin.phi, fin.kappa, frame, tip)
            if fin.refined_pixels:
                used = "bottom-zoom"
        wall = None
        if gen is None or gen.kappa_rad > K.VIEW_CORRECTION_KAPPA_RAD:
            sgen = self._side_view(tip, frame, fin, cutting0, t1, t2)
            if sgen is not None:
                gen, used = sgen, "side"
                notes.append("side view (steep contact)")
        elif tool.corner_radius_mm < tool.radius_mm \
                and cutting0[:, self.edges.segment == 2].any():
            # a floor, and the flank cuts: the wall it may finish at the same time
            sgen = self._side_view(tip, frame, fin, cutting0, t1, t2)
            if sgen is not None and sgen.kappa_rad > K.VIEW_CORRECTION_KAPPA_RAD:
                wall = sgen
                notes.append("a wall finished by the flank too (side view)")
        if gen is None:
            return PointGeometry(status="no-finished-surface", cutting_pixels=fin.cutting_pixels,
                                 notes=tuple(notes), **base)
        rho_m = float(np.hypot(gen.point_tool[0], gen.point_tool[1]))
        status = "predicted"
        if rho_m < tool.radius_mm * math.sin(K.MIN_AXIS_NORMAL_ANGLE_RAD):
            status = "axis-normal"
        sens = None
        if status == "predicted" and self.sensitivity:
            # the same cut with the stock a little thicker along the normal:
            # how the error grows when the correction moves the tool deeper
            delta = K.SENSITIVITY_STEP_MM
            deeper = self.engager.engagement(tip, frame, interval, removed, f_tooth,
                                             z_top + delta,
                                             stock_shift=delta * (frame @ gen.normal_world))
            if deeper is not None:
                sens = (delta, deeper[0], deeper[1], deeper[2])
        base["sensitivity"] = sens
        return PointGeometry(status=status, gen=gen, view=used,
                             cutting_pixels=fin.cutting_pixels, finished_pixels=gen.pixels,
                             notes=tuple(notes), wall=wall, **base)

    def _above_flutes(self, tip, frame, interval, t1, z_top: float) -> bool:
        """Does material the moves before left lie inside the shank, just above the
        flutes' end (:attr:`PointGeometry.above_flutes`)?

        A ring of ``ABOVE_FLUTES_SAMPLES`` points of the shank's radius (the tool's
        where smaller) less ``ABOVE_FLUTES_INSET_MM``, a pixel above the sweeps' tool
        solid at that radius (the flutes and the corner radius's cap on them): any of
        them in the stock and outside T1 (the flutes of the moves before: an earlier
        pass higher up removes what lies above this one's flutes). Only where the
        stock's top under the tool is that high.
        """
        tool = self.tool
        r = min(tool.shank_diameter_mm, tool.diameter_mm) / 2 - K.ABOVE_FLUTES_INSET_MM
        # the sweeps' tool solid ends in a cap of the corner radius above the flutes
        # (errpred/_kernels.py): the ring goes a pixel above the cap at its radius
        rc, c = tool.corner_radius_mm, tool.core_radius_mm
        h = (tool.flute_length_mm + math.sqrt(max(rc * rc - max(r - c, 0.0) ** 2, 0.0))
             + self.res.pixel_mm)
        if not z_top > h:
            return False
        ang = np.arange(K.ABOVE_FLUTES_SAMPLES) * (2 * math.pi / K.ABOVE_FLUTES_SAMPLES)
        local = np.column_stack([r * np.cos(ang), r * np.sin(ang), np.full(ang.size, h)])
        inside = self.bottom.in_stock_local(self.stock, interval, tip, frame, local)
        if not inside.any():
            return False
        removed = self._inside_sweeps(tip + local[inside] @ frame, t1)
        return bool((~removed).any())

    def _inside_sweeps(self, world: np.ndarray, sweeps) -> np.ndarray:
        """Which world points (k, 3) lie inside any of ``sweeps`` (T1 or a part of it),
        every one tested exactly (no height map, no memo)."""
        tool = self.tool
        return inside_any_sweep_clustered(world, np.ones(world.shape[0], dtype=np.bool_),
                                          *sweeps, tool.core_radius_mm, tool.corner_radius_mm,
                                          tool.flute_length_mm, K.MEMBERSHIP_EPS_MM,
                                          K.CLUSTER_CELL_MM)

    def _stock_top(self, tip, frame, interval) -> float:
        """Height above the tip of the highest stock under the tool [mm]."""
        if interval is None:
            lo, hi = self.stock.bounds
            corners = np.array([[x, y, zz] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                for zz in (lo[2], hi[2])])
            return float(((corners - tip) @ frame[2]).max())
        fin = interval.top[np.isfinite(interval.top)]
        if (np.isposinf(interval.top) & (interval.bottom < math.inf)).any():
            return math.inf  # material without a top in view: everything counts
        return (float(fin.max()) - self.bottom.depth_offset_mm) if fin.size else -math.inf

    def _sweep_map(self) -> SweepMap | None:
        """This process's height map of the sweeps (made on first use), or None where
        it does not apply or is switched off."""
        if self.use_sweep_map is False or (self.use_sweep_map is None and not self._zmap_on):
            return None
        if self._zmap is None:
            self._zmap = sweep_map(self.sweeps, self.tool) or False
        return self._zmap or None

    def plan_sweep_map(self, blocks: list[int]) -> None:
        """Whether a run over ``blocks`` (in order) uses the height map, when
        :attr:`use_sweep_map` is None: the map is filled in program order, so a run
        that starts far into the program first fills each tile it touches with every
        sweep before it that reaches it (``ZMAP_CATCHUP_PER_BLOCK``: seconds for a
        slice of the mold-ball program, against 1-5 ms a block saved); it is used
        where the sweeps before the run and after the map's time are at most
        ``ZMAP_CATCHUP_PER_BLOCK`` a block of the run (the tiles a jump left behind
        are caught up as touched, whichever way)."""
        if not blocks:
            return
        first = self.block_points(int(min(blocks)))
        if first is None:
            return
        start = float(self.path[first[0]])
        k0 = int(np.searchsorted(self.sweeps.path_end, start, side="right"))
        done = self._zmap.time if isinstance(self._zmap, SweepMap) else 0
        self._zmap_on = k0 - min(done, k0) <= K.ZMAP_CATCHUP_PER_BLOCK * len(blocks)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_zmap"] = None  # per process, rebuilt where it is used
        state["_last_interval"] = state["_last_near"] = None
        state["_block_span"] = state["_block_near"] = state["_kept_near"] = None
        state["_shank_hit"] = False
        return state

    def _bottom_interval(self, tip, frame) -> StockView | None:
        """The stock's interval in the bottom view at a tool position (None for a box).

        The last answer is kept: the pre-check's test at a stretch's middle and the
        prediction point there see the same position (same inputs, same answer).
        """
        if getattr(self.stock, "is_box", False):
            return None
        key = (id(self.stock), tip.tobytes(), frame.tobytes())
        last = self._last_interval
        if last is not None and last[0] == key:
            return last[1]
        bt, tool = self.bottom, self.tool
        view = View.along_axis(tip, frame, bt.window_mm, bt.pixel_mm, bt.depth_offset_mm)
        interval = stock_view(self.stock, view,
                              (0.0, bt.depth_offset_mm + tool.flute_length_mm + tool.radius_mm))
        for a in (interval.bottom, interval.top, interval.smooth_bottom, interval.smooth_top):
            a.flags.writeable = False
        self._last_interval = (key, interval)
        return interval

    def _near_sweeps(self, tip, u, L, fz, z_top=math.inf):
        """T1 and T2 near the tool's part below the stock top, nearest first, and the
        sweep each part of T1 comes from (arrays read-only: the last answer is kept, for
        the prediction point at the pre-check's last position)."""
        key = (np.asarray(tip, float).tobytes(), np.asarray(u, float).tobytes(), float(L),
               float(fz), float(z_top))
        last = self._last_near
        if last is not None and last[0] == key:
            out, box = last[1]
        else:
            out, box = self._near_sweeps_new(tip, u, L, fz, z_top)
            read_only(*out[0], *out[1], out[2])
            self._last_near = (key, (out, box))
        # the block's look-ups so far, in one box (PointGeometry.lookup_box)
        have = self._lookup_box
        self._lookup_box = box.copy() if have is None else np.stack(
            [np.minimum(have[0], box[0]), np.maximum(have[1], box[1])])
        return out

    def _near_sweeps_new(self, tip, u, L, fz, z_top):
        tool = self.tool
        R = tool.radius_mm
        height = min(tool.flute_length_mm + tool.corner_radius_mm,
                     max(z_top, 0.0) + 2 * self.res.pixel_mm + tool.corner_radius_mm)
        top = tip + height * u
        ext = R * np.sqrt(np.clip(1 - u * u, 0, None)) + 2 * self.res.pixel_mm
        lo, hi = np.minimum(tip, top) - ext, np.maximum(tip, top) + ext
        box = np.stack([lo, hi])
        # the sweeps whose bounds overlap the box, without the test of whether they may
        # reach the ball around everything this point tests: it kept 92-96 % of them on
        # the bench slices and cost more than it saved (each kernel call prunes what
        # cannot reach its own points: wall-radius 12 % less CPU, raster 3 %, contour 0)
        return self.sweeps.near(lo, hi, tip, math.inf, tip + R * u, L - fz, L + fz,
                                within=self._shared_lookup(lo, hi)), box

    def _shared_lookup(self, lo, hi) -> np.ndarray | None:
        """The block's shared sweep look-up (:class:`~errpred.sweeps.BlockLookup`,
        made on first use, or the one before it where that holds the block's box) for
        the box ``[lo, hi]``, or None."""
        span = self._block_span
        if span is None:
            return None
        if self._block_near is None:
            i0, i1 = span
            k = max(i0 - 1, 0)
            tool = self.tool
            own = BlockLookup(
                self.sweeps, self.cl.tip[k:i1 + 1], self.cl.axis[k:i1 + 1], tool.radius_mm,
                tool.flute_length_mm + tool.corner_radius_mm, 2 * self.res.pixel_mm,
                K.SHARED_LOOKUP_SPAN_PER_DIAMETER * tool.diameter_mm,
                K.SHARED_LOOKUP_GROW_PER_DIAMETER * tool.diameter_mm)
            kept = self._kept_near
            if kept is not None and kept.holds(own):
                own = kept
            self._block_near = self._kept_near = own
        return self._block_near.ids_for(lo, hi)

    def _side_view(self, tip, frame, fin, cutting0, t1, t2) -> GenerationPoint | None:
        """Finished surface seen from the side where the cutting region lies."""
        tool, res = self.tool, self.res
        phi_c = fin.cutting_phi
        if phi_c.size == 0:
            # nothing cuts in the bottom view (the flank): aim at the cutting edges
            i, j = np.nonzero(cutting0)
            n = cutting0.shape[0]
            phi_c = i * (2 * math.pi / n) - self.edges.psi[j]
        if phi_c.size == 0:
            return None
        mean = math.atan2(float(np.sin(phi_c).mean()), float(np.cos(phi_c).mean()))
        rel = np.angle(np.exp(1j * (phi_c - mean)))
        cut_edges = cutting0.any(axis=0)
        zmax = float(self.edges.z[cut_edges].max()) if cut_edges.any() else 0.0
        zcut = float(fin.cutting_z.max()) if fin.cutting_z.size else 0.0
        height = min(tool.flute_length_mm, max(zmax, zcut) + res.pixel_mm)
        # toward the middle of the cutting region; failing that (a slot: the
        # finished walls are at its two ends), toward either end
        for az in (mean, mean + float(rel.max()), mean + float(rel.min())):
            side = View.side(tip, frame, az, tool.diameter_mm + 2 * res.pixel_mm,
                             max(height, 2 * res.pixel_mm), res.pixel_mm / K.VIEW_ZOOM)
            probe = StockProbe(self.stock, side, (0.0, tool.diameter_mm + 2 * res.pixel_mm))
            # regions(envelope_hits(...)) kept to the pixels whose hit is in the stock;
            # its finished pixels only (the cutting region is not needed here)
            reg = side_regions(tool, side, frame, tip, probe, t1, t2, cutting=False)
            gen = generation_point(tool, reg, frame, tip)
            if gen is not None:
                return gen
        return None


def _generation(tool: Tool, xyz, phi, kappa, frame, tip) -> GenerationPoint:
    """Generation point from finished sub-pixels (means of their attributes)."""
    phi_m = math.atan2(float(np.sin(phi).mean()), float(np.cos(phi).mean()))
    kappa_m = float(kappa.mean())
    if kappa_m < math.pi / 2 - 1e-9:
        rho, z = (float(v) for v in tool.profile_point(kappa_m))
    else:
        rho, z = tool.radius_mm, float(xyz[:, 2].mean())
    pt = np.array([rho * math.sin(phi_m), rho * math.cos(phi_m), z])
    sk, ck = math.sin(kappa_m), math.cos(kappa_m)
    n_tool = np.array([-sk * math.sin(phi_m), -sk * math.cos(phi_m), ck])
    theta = (phi_m + float(tool.helix_lag(z))) % (2 * math.pi)
    strip = strip_samples(tool, phi, kappa, xyz[:, 2], frame)
    return GenerationPoint(theta_rad=theta, phi_rad=phi_m, kappa_rad=kappa_m, point_tool=pt,
                           point_world=tip + pt @ frame, normal_world=n_tool @ frame,
                           pixels=int(xyz.shape[0]), **strip)


def _without_samples(gen: GenerationPoint | None) -> GenerationPoint | None:
    """A generation point without its strip's samples (kept in results)."""
    if gen is None or gen.samples_theta is None:
        return gen
    return dataclasses.replace(gen, samples_theta=None, samples_kappa=None, samples_z=None,
                               samples_normal=None)


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index ranges of the runs of True in a 1-d bool array."""
    f = np.concatenate([[False], np.asarray(flags, bool), [False]])
    d = np.diff(f.astype(np.int8))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(),
                    strict=True))

