"""Numba kernels of the exact engagement: which angles of each micro edge's circle cut.

For one posture (``orient/engagement.py`` describes the material model), a
micro edge of flute 0 at arc length ``s`` along the cutting profile moves on
a circle, ``p(phi) = tip + z u + rho (sin phi x' + cos phi y')``. It cuts where

1. its chip thickness is positive, ``h = fz (A1 sin phi + B1 cos phi + C1) > 0``;
2. it is below the stock top (for a flat surface ``d - n.p > 0``, also of the
   form ``A2 sin phi + B2 cos phi + C2 > 0``; for a curved one a quadric);
3. it is outside the previous pass's swept tool solid.

(1) and a flat (2) are arcs of the circle in closed form; a curved top and
the previous pass are sampled every ``root_step`` inside those arcs and
their sign changes refined to roots (Illinois regula falsi): the cutting set
of each circle is a union of exact angle intervals (:func:`edge_intervals`).
The per-posture geometry vector is built by :func:`posture_geometry`. The
process gain integrates over these intervals in :mod:`orient._kernels`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from errpred.sweeps import sweep_distance

from ._root_kernels import illinois

__all__ = [
    "BUF_ROWS",
    "GEO_SIZE",
    "MAX_INTERVALS_PER_EDGE",
    "edge_intervals",
    "infinite_ball_sweep_distance",
    "posture_geometry",
]

#: Intervals one micro edge may cut in (closed-form arcs split by roots);
#: the interval buffers have 16 more rows of work space.
MAX_INTERVALS_PER_EDGE = 32
BUF_ROWS = MAX_INTERVALS_PER_EDGE + 16
#: Changes of the interval structure located within one scan cell, at most.
MAX_CHANGES_PER_CELL = 4
_TWO_PI = 2.0 * math.pi

# layout of the per-posture geometry vector (see posture_geometry)
_F = 0          # 9: frame rows x', y', u
_LF = 9         # 3: f
_LB = 12        # 3: b
_LN = 15        # 3: n
_TIP = 18       # 3: tip
_FT = 21        # 3: unit feed in the tool frame
_NXY = 24       # 2: n . x', n . y'
_DEPTH = 26
_KF = 27        # curvature of the stock top along f (offset surface)
_KB = 28
_CURVED = 29    # 1 if a curvature is non-zero
_CONCAVE = 30   # 1 if a curvature is negative
_PREV = 31      # 1 if a previous pass exists
_CPREV = 32     # 3: previous pass's core start (tip + r u, shifted)
_UP = 35        # 3: unit component of u normal to f
_LMAX = 38      # length of the core's projection normal to f
_P0 = 39        # 3: start tip of a long sweep standing for the previous pass
_D = 42         # 3: its displacement
_SIDE = 45      # side of the previous pass (+-1)
_PICK = 46      # pick feed [mm]
_CPREV_R = 47   # corner radius (ball centre = tip + r u)
_VN = 48        # 3: angle where v.n falls through 0 (atan2(n.x', n.y')), its sin, cos
GEO_SIZE = 51


@njit(cache=True, nogil=True)
def posture_geometry(u_in, n_in, f_in, depth, pick, side, kf, kb, rot, c0, r, top, geo):
    """Fill ``geo`` (``GEO_SIZE``) for one posture; False if it is not valid.

    Parameters
    ----------
    u_in, n_in, f_in : ndarray, shape (3,)
        Tool axis, surface normal, feed direction (any lengths).
    depth, pick : float [mm]
    side : float
        -1, 0 or +1 (previous pass at ``side pick b``).
    kf, kb : float [1/mm]
        Curvatures of the finished surface along f and b (positive convex).
    rot : float
        +1 clockwise spindle, -1 counter-clockwise (mirrored frame).
    c0, r, top : float [mm]
        Core radius ``R - r``, corner radius, flute length.
    """
    nn = math.sqrt(n_in[0] ** 2 + n_in[1] ** 2 + n_in[2] ** 2)
    uu = math.sqrt(u_in[0] ** 2 + u_in[1] ** 2 + u_in[2] ** 2)
    if nn == 0.0 or uu == 0.0:
        return False
    nx_, ny_, nz_ = n_in[0] / nn, n_in[1] / nn, n_in[2] / nn
    ux, uy, uz = u_in[0] / uu, u_in[1] / uu, u_in[2] / uu
    fn = f_in[0] * nx_ + f_in[1] * ny_ + f_in[2] * nz_
    fx, fy, fz = f_in[0] - fn * nx_, f_in[1] - fn * ny_, f_in[2] - fn * nz_
    fl = math.sqrt(fx * fx + fy * fy + fz * fz)
    if fl == 0.0:
        return False
    fx, fy, fz = fx / fl, fy / fl, fz / fl
    bx, by, bz = ny_ * fz - nz_ * fy, nz_ * fx - nx_ * fz, nx_ * fy - ny_ * fx
    un = ux * nx_ + uy * ny_ + uz * nz_
    # tool frame as errpred.frames.tool_frames: x' = feed normal to u, y' = u x x'
    uf = fx * ux + fy * uy + fz * uz
    xx, xy, xz = fx - uf * ux, fy - uf * uy, fz - uf * uz
    xl = math.sqrt(xx * xx + xy * xy + xz * xz)
    if xl < 1e-9:
        return False
    xx, xy, xz = xx / xl, xy / xl, xz / xl
    yx, yy, yz = uy * xz - uz * xy, uz * xx - ux * xz, ux * xy - uy * xx
    if rot < 0:   # mirrored frame of a counter-clockwise spindle
        xx, xy, xz = -xx, -xy, -xz
    geo[_F], geo[_F + 1], geo[_F + 2] = xx, xy, xz
    geo[_F + 3], geo[_F + 4], geo[_F + 5] = yx, yy, yz
    geo[_F + 6], geo[_F + 7], geo[_F + 8] = ux, uy, uz
    geo[_LF], geo[_LF + 1], geo[_LF + 2] = fx, fy, fz
    geo[_LB], geo[_LB + 1], geo[_LB + 2] = bx, by, bz
    geo[_LN], geo[_LN + 1], geo[_LN + 2] = nx_, ny_, nz_
    # tip: the envelope point with outward normal -n is the contact (origin)
    npx, npy, npz = nx_ - un * ux, ny_ - un * uy, nz_ - un * uz
    npl = math.sqrt(npx * npx + npy * npy + npz * npz)
    s = c0 / npl if npl > 1e-12 else 0.0
    tx = r * (nx_ - ux) + s * npx
    ty = r * (ny_ - uy) + s * npy
    tz = r * (nz_ - uz) + s * npz
    geo[_TIP], geo[_TIP + 1], geo[_TIP + 2] = tx, ty, tz
    geo[_FT] = fx * xx + fy * xy + fz * xz
    geo[_FT + 1] = fx * yx + fy * yy + fz * yz
    geo[_FT + 2] = uf
    geo[_NXY] = nx_ * xx + ny_ * xy + nz_ * xz
    geo[_NXY + 1] = nx_ * yx + ny_ * yy + nz_ * yz
    geo[_DEPTH] = depth
    # the stock top is the finished surface offset by depth: curvature k/(1 + k d)
    geo[_KF] = kf / (1.0 + kf * depth)
    geo[_KB] = kb / (1.0 + kb * depth)
    geo[_CURVED] = 1.0 if (kf != 0.0 or kb != 0.0) else 0.0
    geo[_CONCAVE] = 1.0 if (kf < 0.0 or kb < 0.0) else 0.0
    geo[_PREV] = 1.0 if side != 0.0 else 0.0
    off = side * pick
    geo[_CPREV] = tx + off * bx + r * ux
    geo[_CPREV + 1] = ty + off * by + r * uy
    geo[_CPREV + 2] = tz + off * bz + r * uz
    upx, upy, upz = ux - uf * fx, uy - uf * fy, uz - uf * fz
    upl = math.sqrt(upx * upx + upy * upy + upz * upz)
    if upl > 0.0:
        geo[_UP], geo[_UP + 1], geo[_UP + 2] = upx / upl, upy / upl, upz / upl
    else:
        geo[_UP], geo[_UP + 1], geo[_UP + 2] = 0.0, 0.0, 0.0
    geo[_LMAX] = max(top - r, 0.0) * upl
    half = 2.0 * (2.0 * (c0 + r) + top) + abs(pick)
    geo[_P0] = tx + off * bx - half * fx
    geo[_P0 + 1] = ty + off * by - half * fy
    geo[_P0 + 2] = tz + off * bz - half * fz
    geo[_D], geo[_D + 1], geo[_D + 2] = 2.0 * half * fx, 2.0 * half * fy, 2.0 * half * fz
    geo[_SIDE], geo[_PICK], geo[_CPREV_R] = side, pick, r
    root_vn = math.atan2(geo[_NXY], geo[_NXY + 1])
    geo[_VN], geo[_VN + 1], geo[_VN + 2] = root_vn, math.sin(root_vn), math.cos(root_vn)
    return True


@njit(cache=True, inline="always")
def infinite_ball_sweep_distance(qx, qy, qz, geo):
    """Distance from q - (previous pass's ball centre) to the swept core.

    The core of a ball end mill (``errpred/_kernels.py``) is the axis from
    the ball centre up to the flute top; swept along the infinite line of
    the pass it is a half strip, which normal to ``f`` projects to a segment
    from the centre along ``u'`` of length ``_LMAX``.
    """
    fx, fy, fz = geo[_LF], geo[_LF + 1], geo[_LF + 2]
    qf = qx * fx + qy * fy + qz * fz
    px, py, pz = qx - qf * fx, qy - qf * fy, qz - qf * fz
    s = px * geo[_UP] + py * geo[_UP + 1] + pz * geo[_UP + 2]
    if s < 0.0:
        s = 0.0
    elif s > geo[_LMAX]:
        s = geo[_LMAX]
    px -= s * geo[_UP]
    py -= s * geo[_UP + 1]
    pz -= s * geo[_UP + 2]
    return math.sqrt(px * px + py * py + pz * pz)


@njit(cache=True, inline="always")
def _arc(a, b, c, eps):
    """Where ``a sin phi + b cos phi + c > eps``: (start, length), length in [0, 2 pi]."""
    amp = math.sqrt(a * a + b * b)
    t = eps - c
    if amp <= 1e-300:
        return 0.0, (_TWO_PI if t < 0.0 else 0.0)
    x = t / amp
    if x <= -1.0:
        return 0.0, _TWO_PI
    if x >= 1.0:
        return 0.0, 0.0
    half = math.acos(x)
    centre = math.atan2(a, b)
    start = (centre - half) % _TWO_PI
    return start, 2.0 * half


@njit(cache=True)
def _material_sc(sp, cp, ox, oy, oz, rho, geo, c0, r, top, mem_eps):
    """Margin of the non-circular material conditions at angle phi (sine, cosine).

    ``(g, kind)``: g > 0 where the point is below a curved stock top and
    outside the previous pass (+1 if neither applies); kind 3 when the
    previous pass decides, 4 the curved top.

    Called, not inlined: numba inlined (``inline="always"``) its four copies, each
    with a sweep's distance, took 3.5 s of the gain kernel's 17.5 s to compile on an
    empty cache; called, a posture's gain costs about 3 % more
    (``benchmarks/bench_gain.py --points 300``, four runs each, alternating: 27.2-28.8
    against 28.1-29.5 us).
    """
    px = ox + rho * (sp * geo[_F] + cp * geo[_F + 3])
    py = oy + rho * (sp * geo[_F + 1] + cp * geo[_F + 4])
    pz = oz + rho * (sp * geo[_F + 2] + cp * geo[_F + 5])
    g = 1.0
    kind = 4
    if geo[_CURVED] != 0.0:
        pn = px * geo[_LN] + py * geo[_LN + 1] + pz * geo[_LN + 2]
        pf = px * geo[_LF] + py * geo[_LF + 1] + pz * geo[_LF + 2]
        pb = px * geo[_LB] + py * geo[_LB + 1] + pz * geo[_LB + 2]
        g = geo[_DEPTH] - pn - 0.5 * (geo[_KF] * pf * pf + geo[_KB] * pb * pb)
    if geo[_PREV] != 0.0:
        if c0 == 0.0:
            dist = infinite_ball_sweep_distance(px - geo[_CPREV], py - geo[_CPREV + 1],
                                                pz - geo[_CPREV + 2], geo)
        else:
            dist = sweep_distance(px, py, pz, geo[_P0:_P0 + 3], geo[_D:_D + 3],
                                  geo[_F + 6:_F + 9], c0, r, top)
        gp = dist - r - mem_eps
        if gp < g:
            g = gp
            kind = 3
    return g, kind


@njit(cache=True)
def _margin_at(x, ox, oy, oz, rho, geo, c0, r, top, mem_eps):
    """The material margin of :func:`_material_sc` at angle ``x`` [rad]."""
    g, _kind = _material_sc(math.sin(x), math.cos(x), ox, oy, oz, rho, geo, c0, r, top, mem_eps)
    return g


@njit(cache=True)
def _refine(a, ga, b, gb, ox, oy, oz, rho, geo, c0, r, top, mem_eps, tol, maxit):
    """Root of the material margin between a and b; (root, kind there).

    :func:`orient._root_kernels.illinois` (a margin that is flat on one side, as
    the distance to a flat end mill's core, takes its bisection steps).
    """
    x = illinois(_margin_at, (ox, oy, oz, rho, geo, c0, r, top, mem_eps), a, ga, b, gb, tol,
                 0.0, maxit)
    _g, kind = _material_sc(math.sin(x), math.cos(x), ox, oy, oz, rho, geo, c0, r, top,
                            mem_eps)
    return x, kind


@njit(cache=True)
def _top_bound(ox, oy, oz, on, rho, geo):
    """``(A, B, C)`` of the circle's necessary material condition ``A sin + B cos + C > 0``.

    A concave top rises by at most ``kc ((f.x)^2 + (b.x)^2) / 2`` (``kc`` its
    tightest concave curvature), and ``(f.x)^2 + (b.x)^2 = |x|^2 - (n.x)^2 <=
    |x|^2 - m^2`` with ``m`` the least ``|n.x|`` on the circle: ``|x|^2`` is of the
    form A sin + B cos + C on the circle, ``m`` a constant. (Without ``m`` the
    bound let the flank high above the contact pass for material on a tilted
    tool, the band of the profile that can cut grew to the whole flank, and its
    probes missed the true band near the contact: no engagement at all.)
    """
    kc = -min(geo[_KF], geo[_KB], 0.0)
    a = -rho * geo[_NXY]
    b = -rho * geo[_NXY + 1]
    c = geo[_DEPTH] - on
    if kc > 0.0:
        ox_ = ox * geo[_F] + oy * geo[_F + 1] + oz * geo[_F + 2]
        oy_ = ox * geo[_F + 3] + oy * geo[_F + 4] + oz * geo[_F + 5]
        m = max(abs(on) - rho * math.sqrt(geo[_NXY] ** 2 + geo[_NXY + 1] ** 2), 0.0)
        a += kc * rho * ox_
        b += kc * rho * oy_
        c += 0.5 * kc * (ox * ox + oy * oy + oz * oz + rho * rho - m * m)
    return a, b, c


@njit(cache=True)
def _clip(n_in, iv, ik, s, l, kind, tmp, tk):
    """Intersect intervals ``iv[:n_in]`` (kinds ``ik``) with the arc (start s, length l)."""
    if l >= _TWO_PI:
        return n_in
    n = 0
    for q in range(n_in):
        for shift in (-_TWO_PI, 0.0, _TWO_PI):
            lo = max(iv[q, 0], s + shift)
            hi = min(iv[q, 1], s + l + shift)
            if hi > lo and n < tmp.shape[0]:
                tmp[n, 0], tmp[n, 1] = lo, hi
                tk[n, 0] = ik[q, 0] if iv[q, 0] >= s + shift else kind
                tk[n, 1] = ik[q, 1] if iv[q, 1] <= s + l + shift else kind
                n += 1
    for q in range(n):
        iv[q, 0], iv[q, 1] = tmp[q, 0], tmp[q, 1]
        ik[q, 0], ik[q, 1] = tk[q, 0], tk[q, 1]
    return n


@njit(cache=True)
def _necessary_arcs(rho, z, sk, ck, geo, c0, chip_eps, iv, ik, tmp, tk):
    """Intervals of the edge circle where the closed-form necessary conditions hold.

    Chip thickness > 0 (kind 1); below a plane bounding the stock top
    (kind 2, :func:`_top_bound`); for a ball end mill's ball, on the side of
    the mid-plane between the passes away from the previous pass (kind 5: a
    point of the ball outside the previous pass's cylinder has
    ``side (p - c).b < pick / 2``, c the ball centre). Into ``iv`` (K, 2)
    with kinds ``ik`` (``tmp``, ``tk`` alike: work space); returns the count,
    -1 when the circle is above the top.
    """
    ox = geo[_TIP] + z * geo[_F + 6]
    oy = geo[_TIP + 1] + z * geo[_F + 7]
    oz = geo[_TIP + 2] + z * geo[_F + 8]
    on = ox * geo[_LN] + oy * geo[_LN + 1] + oz * geo[_LN + 2]
    a2, b2, c2 = _top_bound(ox, oy, oz, on, rho, geo)
    if c2 + math.sqrt(a2 * a2 + b2 * b2) <= 0.0:
        return -1
    s1, l1 = _arc(sk * geo[_FT], sk * geo[_FT + 1], -ck * geo[_FT + 2], chip_eps)
    if l1 <= 0.0:
        return 0
    iv[0, 0], iv[0, 1] = s1, s1 + l1
    k1 = 0 if l1 >= _TWO_PI else 1
    ik[0, 0], ik[0, 1] = k1, k1
    s2, l2 = _arc(a2, b2, c2, 0.0)
    # typed, not literal, arguments: a literal compiles a version of _clip of its own
    n = _clip(np.int64(1), iv, ik, s2, l2, np.int64(2), tmp, tk)
    if n > 0 and geo[_PREV] != 0.0 and c0 == 0.0 and ck > 1e-9:
        side, half = geo[_SIDE], 0.5 * geo[_PICK]
        cx = geo[_TIP] + geo[_CPREV_R] * geo[_F + 6]
        cy = geo[_TIP + 1] + geo[_CPREV_R] * geo[_F + 7]
        cz = geo[_TIP + 2] + geo[_CPREV_R] * geo[_F + 8]
        ob = (ox - cx) * geo[_LB] + (oy - cy) * geo[_LB + 1] + (oz - cz) * geo[_LB + 2]
        xb = geo[_F] * geo[_LB] + geo[_F + 1] * geo[_LB + 1] + geo[_F + 2] * geo[_LB + 2]
        yb = geo[_F + 3] * geo[_LB] + geo[_F + 4] * geo[_LB + 1] + geo[_F + 5] * geo[_LB + 2]
        s3, l3 = _arc(-side * rho * xb, -side * rho * yb, half - side * ob, 0.0)
        n = _clip(n, iv, ik, s3, l3, np.int64(5), tmp, tk)
    return n


@njit(cache=True)
def _circle_intervals(rho, z, sk, ck, geo, c0, r, top, set_par, tol, out, kinds, wf, wi):
    """Cutting intervals in phi of the edge circle at (rho, z, kappa) into ``out`` (K, 2).

    ``kinds`` (K, 2) gets what bounds each end: 1 chip thickness, 2 the
    (flat) top's arc, 3 the previous pass, 4 a curved top, 5 the mid-plane
    between the passes, 0 none (the circle's wrap). Returns the count; -1
    when the whole circle is above the stock top. ``set_par``: chip eps,
    membership eps, root step, tolerance, iterations, band probes, band
    bisections, least samples per arc; ``tol`` the roots' tolerance [rad], or
    0 for the structure only (roots left at the middle of their sampling
    step). ``wf`` (16, 2) and ``wi`` (16, 2) int are work space.
    """
    chip_eps, mem_eps, root_step, maxit = set_par[0], set_par[1], set_par[2], int(set_par[4])
    min_samples = int(set_par[7])
    ox = geo[_TIP] + z * geo[_F + 6]
    oy = geo[_TIP + 1] + z * geo[_F + 7]
    oz = geo[_TIP + 2] + z * geo[_F + 8]
    arcs, akinds = wf[:8], wi[:8]
    n_arcs = _necessary_arcs(rho, z, sk, ck, geo, c0, chip_eps, arcs, akinds, wf[8:], wi[8:])
    if n_arcs <= 0:
        return n_arcs
    exact = geo[_CURVED] == 0.0 and geo[_PREV] == 0.0
    count = 0
    kmax = out.shape[0]
    for q in range(n_arcs):
        lo, hi = arcs[q, 0], arcs[q, 1]
        k_lo, k_hi = akinds[q, 0], akinds[q, 1]
        if count >= kmax:
            break
        if exact:
            out[count, 0], out[count, 1] = lo, hi
            kinds[count, 0], kinds[count, 1] = k_lo, k_hi
            count += 1
            continue
        # samples at most root_step apart, at least min_samples per arc
        n_s = max(min_samples, math.ceil((hi - lo) / root_step))
        step = (hi - lo) / n_s
        cs, ss = math.cos(step), math.sin(step)
        sp, cp = math.sin(lo), math.cos(lo)
        a = lo
        ga, k_a = _material_sc(sp, cp, ox, oy, oz, rho, geo, c0, r, top, mem_eps)
        inside = ga > 0.0
        start, k_start = lo, k_lo
        for i in range(1, n_s + 1):
            bb = hi if i == n_s else lo + i * step
            sp, cp = sp * cs + cp * ss, cp * cs - sp * ss   # rotation by one step
            gb, _k = _material_sc(sp, cp, ox, oy, oz, rho, geo, c0, r, top, mem_eps)
            if (gb > 0.0) != inside:
                if tol > 0.0:
                    root, k_root = _refine(a, ga, bb, gb, ox, oy, oz, rho, geo, c0, r, top,
                                           mem_eps, tol, maxit)
                else:  # structure only: what bounds the material, seen from outside it
                    root, k_root = 0.5 * (a + bb), (_k if inside else k_a)
                if inside:
                    if root > start and count < kmax:
                        out[count, 0], out[count, 1] = start, root
                        kinds[count, 0], kinds[count, 1] = k_start, k_root
                        count += 1
                else:
                    start, k_start = root, k_root
                inside = not inside
            a, ga, k_a = bb, gb, _k
        if inside and hi > start and count < kmax:
            out[count, 0], out[count, 1] = start, hi
            kinds[count, 0], kinds[count, 1] = k_start, k_hi
            count += 1
    return count


@njit(cache=True)
def edge_intervals(geo, rho, z, kappa, c0, r, top, set_par):
    """Cutting intervals of micro edges of flute 0 for one posture.

    Returns
    -------
    counts : ndarray, shape (m,), int
    intervals : ndarray, shape (m, MAX_INTERVALS_PER_EDGE, 2) [rad]
        ``[phi_in, phi_out]`` (``phi_out > phi_in``, unwrapped) per edge.
    kinds : ndarray, shape (m, MAX_INTERVALS_PER_EDGE, 2), int
        What bounds each end (:func:`_circle_intervals`).
    """
    m = rho.shape[0]
    counts = np.zeros(m, dtype=np.int64)
    out = np.zeros((m, MAX_INTERVALS_PER_EDGE, 2))
    kinds = np.zeros((m, MAX_INTERVALS_PER_EDGE, 2), dtype=np.int64)
    wf, wi = np.empty((16, 2)), np.empty((16, 2), dtype=np.int64)
    for j in range(m):
        counts[j] = max(0, _circle_intervals(rho[j], z[j], math.sin(kappa[j]),
                                             math.cos(kappa[j]), geo, c0, r, top, set_par,
                                             set_par[3], out[j], kinds[j], wf, wi))
    return counts, out, kinds
