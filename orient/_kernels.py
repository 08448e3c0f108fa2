"""Numba kernels of the process gain: the exact cutting intervals integrated in closed form.

The intervals come from :mod:`orient._engagement_kernels`. The directional
matrix ``(Ktc t + Krc r + Kac a) n^T`` (``errpred/force.py``'s unit vectors,
see :func:`_add_moments`; ``Kxc`` the force law's slope ``dF/dh`` of the micro
edge, :func:`_slopes`) has entries of degree 2 in ``sin phi``, ``cos phi``: its
integral over each interval is in closed form, so the time average ``P`` is
exact in time. Along the profile the integrand is smooth between kinks
(where an interval appears or its end switches bound); :func:`gain_adaptive`
finds those and integrates each smooth piece by Gauss-Legendre, or
:func:`gain_fixed` sums given micro edges. ``H(t)`` is the average of the
same integrand over each of ``k`` equal steps of the tooth period, so the
mean of the steps equals ``P`` to round-off.

Angles: flute 0's rotation ``theta``; its micro edge at height ``z`` sits at
``phi = theta - psi``, ``psi = z tan(helix) / R``; flute ``p`` at ``theta + 2 pi
p / N`` (as ``errpred.engagement.expand_flutes``), so the tooth-period
function is the flute-0 function folded modulo ``2 pi / N``.

This closed form needs a slope that is constant along the rotation: the
linear law (a constant) and the Lee-Altintas law (a polynomial in kappa per
micro edge). Laws whose slope depends on the chip (Kienzle) take
``orient.gain``'s sampled path instead.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ._engagement_kernels import (
    _CONCAVE,
    _F,
    _FT,
    _LN,
    _NXY,
    _TIP,
    _TWO_PI,
    _VN,
    BUF_ROWS,
    GEO_SIZE,
    MAX_CHANGES_PER_CELL,
    MAX_INTERVALS_PER_EDGE,
    _circle_intervals,
    _necessary_arcs,
    _top_bound,
    edge_intervals,
    infinite_ball_sweep_distance,
    posture_geometry,
)
from ._root_kernels import illinois

__all__ = [
    "BUF_ROWS",
    "GEO_SIZE",
    "MAX_INTERVALS_PER_EDGE",
    "edge_intervals",
    "gain_adaptive",
    "gain_batch",
    "gain_batch_parallel",
    "gain_fixed",
    "infinite_ball_sweep_distance",
    "posture_geometry",
    "profile_band",
    "profile_point",
]


@njit(cache=True)
def _signature(cnt, kinds):
    """A code of the intervals' structure: how many, and what bounds their ends."""
    if cnt <= 0:
        return 0
    code = cnt
    for q in range(cnt):   # a sum of hashes: independent of the intervals' order
        code += (kinds[q, 0] * 5 + kinds[q, 1] + 1) * 2685821657736338717
    return code


@njit(cache=True)
def _slopes(kc, sk, ck):
    """The force law's ``dF/dh`` (t, r, a) [N/mm^2] of a micro edge at ``kappa``.

    ``kc`` (3, d): per direction a polynomial in kappa [rad], constant term
    first (``errpred.laws``' ``slope_in_kappa``; d = 1 for the linear law,
    whose slope is the constant itself).
    """
    d = kc.shape[1]
    if d == 1:
        return kc[0, 0], kc[1, 0], kc[2, 0]
    kappa = math.atan2(sk, ck)
    v0, v1, v2 = kc[0, d - 1], kc[1, d - 1], kc[2, d - 1]
    for i in range(d - 2, -1, -1):
        v0 = v0 * kappa + kc[0, i]
        v1 = v1 * kappa + kc[1, i]
        v2 = v2 * kappa + kc[2, i]
    return v0, v1, v2


@njit(cache=True)
def _add_moments(Hs, i0, i_s, i_c, i_ss, i_cc, i_sc, db, sk, ck, ktc, krc, kac):
    """Add db * integral of (Ktc t + Krc r + Kac a) n^T (tool frame) from its moments.

    Unit vectors of errpred.force.to_tool_frame: t = (-cos, sin, 0),
    r = -n = (-sk sin, -sk cos, ck), a = (-ck sin, -ck cos, -sk), and the
    chip-thickness direction n = (sk sin, sk cos, -ck); ``i_*`` are the
    integrals of 1, sin, cos, sin^2, cos^2, sin cos over the interval.
    """
    aa = krc * sk + kac * ck
    zz = krc * ck - kac * sk
    Hs[0, 0] += -db * sk * (ktc * i_sc + aa * i_ss)
    Hs[0, 1] += -db * sk * (ktc * i_cc + aa * i_sc)
    Hs[0, 2] += db * ck * (ktc * i_c + aa * i_s)
    Hs[1, 0] += db * sk * (ktc * i_ss - aa * i_sc)
    Hs[1, 1] += db * sk * (ktc * i_sc - aa * i_cc)
    Hs[1, 2] += -db * ck * (ktc * i_s - aa * i_c)
    Hs[2, 0] += db * zz * sk * i_s
    Hs[2, 1] += db * zz * sk * i_c
    Hs[2, 2] += -db * zz * ck * i0


@njit(cache=True)
def _add_interval(Hs, a, b, db, sk, ck, ktc, krc, kac):
    """:func:`_add_moments` over [a, b]."""
    sa, ca = math.sin(a), math.cos(a)
    sb, cb = math.sin(b), math.cos(b)
    i0 = b - a
    d2 = 0.5 * (sb * cb - sa * ca)
    _add_moments(Hs, i0, ca - cb, sb - sa, 0.5 * i0 - d2, 0.5 * i0 + d2,
                 0.5 * (sb * sb - sa * sa), db, sk, ck, ktc, krc, kac)


@njit(cache=True)
def _to_world(Ht, frame, out):
    """out = frame^T Ht frame (tool frame rows -> workpiece frame)."""
    for p in range(3):
        for q in range(3):
            s = 0.0
            for a in range(3):
                fa = frame[a, p]
                for b in range(3):
                    s += fa * Ht[a, b] * frame[b, q]
            out[p, q] = s


@njit(cache=True)
def profile_point(s, c0, r, R):
    """``(rho, z, sin kappa, cos kappa)`` at arc length s along the cutting profile.

    As ``errpred.tool.Tool.profile_at``: bottom face, corner arc, flank.
    """
    corner = r * (0.5 * math.pi)
    if s <= c0:
        return max(s, 0.0), 0.0, 0.0, 1.0
    if r > 0.0 and s <= c0 + corner:
        k = (s - c0) / r
        sk, ck = math.sin(k), math.cos(k)
        return c0 + r * sk, r * (1.0 - ck), sk, ck
    return R, r + (s - c0 - corner), 1.0, 0.0


@njit(cache=True)
def _lowest(s, geo, c0, r, R):
    """Minus the largest margin of the edge circle at arc length s (< 0: may cut) [mm]."""
    rho, z, _sk, _ck = profile_point(s, c0, r, R)
    ox = geo[_TIP] + z * geo[_F + 6]
    oy = geo[_TIP + 1] + z * geo[_F + 7]
    oz = geo[_TIP + 2] + z * geo[_F + 8]
    on = ox * geo[_LN] + oy * geo[_LN + 1] + oz * geo[_LN + 2]
    a, b, c = _top_bound(ox, oy, oz, on, rho, geo)
    return -(c + math.sqrt(a * a + b * b))


@njit(cache=True)
def _accumulate(H, stats, union, n_union, buf, cnt, sk, ck, psi, w, geo, flutes, kc, n_steps):
    """Add one edge's cutting intervals (chip width w) to H, stats and the union.

    Returns the new union count. See :func:`gain_adaptive` for H and stats.
    """
    pitch = _TWO_PI / flutes
    cell = pitch / n_steps
    ktc, krc, kac = _slopes(kc, sk, ck)
    al, be = geo[_NXY], geo[_NXY + 1]          # v.n = al cos phi - be sin phi
    # v.n = 0 at root_vn + k pi, falling through 0 there: it is positive on
    # (root_vn + (k - 1) pi, root_vn + k pi) for even k, negative for odd k
    root_vn, s_root, c_root = geo[_VN], geo[_VN + 1], geo[_VN + 2]
    ha, hb, hc = sk * geo[_FT], sk * geo[_FT + 1], -ck * geo[_FT + 2]
    for q in range(cnt):
        a, b = buf[q, 0], buf[q, 1]
        if n_steps > 1:
            ta, tb = a + psi, b + psi
            for c in range(math.floor(ta / cell), math.floor(tb / cell) + 1):
                lo = max(ta, c * cell)
                hi = min(tb, (c + 1) * cell)
                if hi > lo:
                    _add_interval(H[c % n_steps], lo - psi, hi - psi, w, sk, ck, ktc, krc, kac)
        # pieces between the roots of v.n; their moments from the end points
        k0 = math.floor((a - root_vn) / math.pi) + 1
        lo, s_lo, c_lo = a, math.sin(a), math.cos(a)
        s_b, c_b = math.sin(b), math.cos(b)
        while True:
            cut_at = root_vn + k0 * math.pi
            sgn = 1.0 if k0 % 2 == 0 else -1.0
            if cut_at >= b:
                hi, s_hi, c_hi = b, s_b, c_b
            else:
                hi, s_hi, c_hi = cut_at, sgn * s_root, sgn * c_root
            if hi > lo:
                i0 = hi - lo
                i_s = c_lo - c_hi
                i_c = s_hi - s_lo
                d2 = 0.5 * (s_hi * c_hi - s_lo * c_lo)
                i_ss = 0.5 * i0 - d2
                i_cc = 0.5 * i0 + d2
                i_sc = 0.5 * (s_hi * s_hi - s_lo * s_lo)
                if n_steps == 1:
                    _add_moments(H[0], i0, i_s, i_c, i_ss, i_cc, i_sc, w, sk, ck, ktc, krc, kac)
                vn = (ha * al * i_sc - ha * be * i_ss + hb * al * i_cc - hb * be * i_sc
                      + hc * al * i_c - hc * be * i_s)
                stats[0] += w * vn
                stats[1] += w * sgn * vn
                stats[2] += w * (ha * i_s + hb * i_c + hc * i0)
            if cut_at >= b:
                break
            lo, s_lo, c_lo = hi, s_hi, c_hi
            k0 += 1
        stats[3] += w * (b - a)
        # engaged time: flute 0's rotation interval folded into one tooth period
        length = b - a
        if length >= pitch:
            stats[4] = 1.0
        elif n_union + 2 <= union.shape[0]:
            t0 = (a + psi) % pitch
            if t0 + length <= pitch:
                union[n_union, 0], union[n_union, 1] = t0, t0 + length
                n_union += 1
            else:
                union[n_union, 0], union[n_union, 1] = t0, pitch
                union[n_union + 1, 0], union[n_union + 1, 1] = 0.0, t0 + length - pitch
                n_union += 2
    return n_union


@njit(cache=True)
def _order(union, n):
    """Indices of ``union[:n]`` by start: Shell sort (a few dozen rows, at most a few
    hundred; ``np.argsort`` compiled a quicksort of its own, 0.8 s)."""
    order = np.arange(n)
    gap = 1
    while gap < n // 3:
        gap = 3 * gap + 1
    while gap > 0:
        for t in range(gap, n):
            idx = order[t]
            key = union[idx, 0]
            u = t
            while u >= gap and union[order[u - gap], 0] > key:
                order[u] = order[u - gap]
                u -= gap
            order[u] = idx
        gap //= 3
    return order


@njit(cache=True)
def _finish(H, stats, union, n_union, flutes, n_steps):
    """Scale H to step averages per radian of rotation; the engaged fraction."""
    pitch = _TWO_PI / flutes
    scale = n_steps * flutes / _TWO_PI
    for c in range(H.shape[0]):
        for a in range(3):
            for b in range(3):
                H[c, a, b] *= scale
    if stats[4] < 1.0 and n_union > 0:
        order = _order(union, n_union)
        total = 0.0
        cur_lo, cur_hi = union[order[0], 0], union[order[0], 1]
        for t in range(1, n_union):
            lo, hi = union[order[t], 0], union[order[t], 1]
            if lo > cur_hi:
                total += cur_hi - cur_lo
                cur_lo, cur_hi = lo, hi
            elif hi > cur_hi:
                cur_hi = hi
        total += cur_hi - cur_lo
        stats[4] = min(total / pitch, 1.0)


@njit(cache=True)
def gain_fixed(geo, tab, flank_start, tp, set_par, kc, n_steps, H, stats, buf, kinds, union):
    """H (n_steps, 3, 3) [N/mm] tool frame and stats of given micro edges.

    ``tab`` (5, m): rho, z, kappa, psi, db. Edges from ``flank_start`` on are
    the flank by height: once one is above a stock top that does not rise,
    so are the rest. H and stats as :func:`gain_adaptive`.
    """
    H[:] = 0.0
    stats[:] = 0.0
    c0, r, top, flutes = tp[1], tp[2], tp[3], int(tp[6])
    n_union = np.int64(0)           # typed, not literal (see gain_adaptive)
    for j in range(tab.shape[1]):
        sk, ck = math.sin(tab[2, j]), math.cos(tab[2, j])
        cnt = _circle_intervals(tab[0, j], tab[1, j], sk, ck, geo, c0, r, top, set_par,
                                set_par[3], buf[:MAX_INTERVALS_PER_EDGE],
                                kinds[:MAX_INTERVALS_PER_EDGE], buf[MAX_INTERVALS_PER_EDGE:],
                                kinds[MAX_INTERVALS_PER_EDGE:])
        if cnt < 0 and j >= flank_start and geo[_CONCAVE] == 0.0:
            break
        if cnt > 0:
            n_union = _accumulate(H, stats, union, n_union, buf, cnt, sk, ck, tab[3, j],
                                  tab[4, j], geo, flutes, kc, n_steps)
    _finish(H, stats, union, n_union, flutes, n_steps)


@njit(cache=True)
def _node(s, w, geo, tp, set_par, kc, n_steps, H, stats, buf, kinds, union, n_union, add):
    """Intervals of the edge circle at arc length s; added with chip width w if ``add``.

    Returns (signature, union count).
    """
    c0, r, R, top, tan_helix, flutes = tp[1], tp[2], tp[4], tp[3], tp[5], int(tp[6])
    rho, z, sk, ck = profile_point(s, c0, r, R)
    # only the structure is wanted when not adding: roots not refined
    tol = set_par[3] if add else 0.0
    cnt = _circle_intervals(rho, z, sk, ck, geo, c0, r, top, set_par, tol,
                            buf[:MAX_INTERVALS_PER_EDGE], kinds[:MAX_INTERVALS_PER_EDGE],
                            buf[MAX_INTERVALS_PER_EDGE:], kinds[MAX_INTERVALS_PER_EDGE:])
    if add and cnt > 0:
        n_union = _accumulate(H, stats, union, n_union, buf, cnt, sk, ck, z * tan_helix / R, w,
                              geo, flutes, kc, n_steps)
    return _signature(cnt, kinds), n_union


@njit(cache=True)
def gain_adaptive(geo, tp, set_par, kc, n_steps, n_scan, n_bisect, px, pw, H, stats, buf,
                  kinds, union):
    """H and stats of one posture, micro edges placed along the profile adaptively.

    The band of the profile that can reach the stock (:func:`profile_band`) is
    scanned at ``n_scan`` points; where the structure of the cutting
    intervals changes between neighbours (an interval appears, or its end
    switches from one bound to another: a kink of the integrand along the
    profile) the change is located by ``n_bisect`` bisections. Each piece
    between changes that cuts is integrated with the rule ``px, pw`` (nodes
    and weights on [0, 1], Gauss-Legendre): micro edges at the nodes, chip
    widths the weights times the piece's length.

    ``H`` (n_steps, 3, 3) [N/mm], tool frame: the average over each step of
    the tooth period. ``stats``: integrals per radian of rotation of
    ``db h/fz v.n``, ``db h/fz |v.n|``, ``db h/fz``, ``db``, and the engaged
    fraction of the tooth period.
    """
    H[:] = 0.0
    stats[:] = 0.0
    flutes = int(tp[6])
    # typed, not literal, arguments for the callees: a literal 0, False or True in a
    # call compiles a version of the callee of its own (``_node``: six, ``_finish``,
    # ``_accumulate``: four, each compiled from scratch on a fresh cache)
    n_union = np.int64(0)
    no, yes = np.bool_(False), np.bool_(True)
    s_lo, s_hi = profile_band(geo, tp, set_par, buf[MAX_INTERVALS_PER_EDGE:],
                              kinds[MAX_INTERVALS_PER_EDGE:])
    if s_hi > s_lo:
        width = (s_hi - s_lo) / n_scan
        p0, psig = s_lo, 0                      # piece start, its signature
        x_prev, sig_prev = s_lo, 0              # the circle at s_lo only touches the top
        for i in range(n_scan + 1):
            x = s_lo + (i + 0.5) * width if i < n_scan else s_hi
            sig = 0
            if i < n_scan:
                sig, n_union = _node(x, 0.0, geo, tp, set_par, kc, n_steps, H, stats, buf,
                                     kinds, union, n_union, no)
            left, sig_left = x_prev, sig_prev
            for _t in range(MAX_CHANGES_PER_CELL):
                if sig_left == sig:
                    break
                # locate the first change after ``left``; what follows it
                a, b, sig_b = left, x, sig
                for _ in range(n_bisect):
                    mid = 0.5 * (a + b)
                    sm, n_union = _node(mid, 0.0, geo, tp, set_par, kc, n_steps, H, stats, buf,
                                        kinds, union, n_union, no)
                    if sm == sig_left:
                        a = mid
                    else:
                        b, sig_b = mid, sm
                bp = 0.5 * (a + b)
                if psig != 0:
                    for q in range(px.shape[0]):
                        _s, n_union = _node(p0 + px[q] * (bp - p0), pw[q] * (bp - p0), geo, tp,
                                            set_par, kc, n_steps, H, stats, buf, kinds, union,
                                            n_union, yes)
                p0, psig = bp, sig_b
                left, sig_left = b, sig_b
            x_prev, sig_prev = x, sig
    _finish(H, stats, union, n_union, flutes, n_steps)


@njit(cache=True)
def _feasible(s, geo, tp, chip_eps, wf, wi):
    """Whether the edge circle at arc length s meets the necessary conditions."""
    c0, r, R = tp[1], tp[2], tp[4]
    rho, z, sk, ck = profile_point(s, c0, r, R)
    return _necessary_arcs(rho, z, sk, ck, geo, c0, chip_eps,
                           wf[:8], wi[:8], wf[8:], wi[8:]) > 0


@njit(cache=True)
def profile_band(geo, tp, set_par, wf, wi):
    """Arc lengths ``(s_lo, s_hi)`` of the profile that can cut; ``s_hi <= s_lo`` if none.

    The lowest point of an edge circle, along the profile, falls to its
    minimum at the contact angle ``kappa = acos(u.n)`` and rises after
    (bottom face, corner arc, flank): where it is below the stock top's
    bound is one band (its ends by Illinois). Edges flatter than the feed's
    axial slope have no positive chip thickness and are cut off. The band
    is then probed at ``set_par[5]`` points for the necessary conditions of
    :func:`_necessary_arcs` and shrunk to the feasible probes' span, its ends
    located by ``set_par[6]`` bisections.
    """
    c0, r, top, R = tp[1], tp[2], tp[3], tp[4]
    tol, maxit, chip_eps = 1e-6 * R, int(set_par[4]), set_par[0]
    n_probe, n_bis = int(set_par[5]), int(set_par[6])
    s_total = c0 + r * (0.5 * math.pi) + max(top - r, 0.0)
    un = geo[_F + 6] * geo[_LN] + geo[_F + 7] * geo[_LN + 1] + geo[_F + 8] * geo[_LN + 2]
    incl = math.acos(min(max(un, -1.0), 1.0))
    s_star = min(c0 + r * min(incl, 0.5 * math.pi), s_total)
    g_star = _lowest(s_star, geo, c0, r, R)
    if g_star >= -tol:   # (a zero depth touches the surface along one circle)
        return 0.0, -1.0
    g0 = _lowest(0.0, geo, c0, r, R)
    s_lo = 0.0 if g0 < 0.0 else illinois(_lowest, (geo, c0, r, R), 0.0, g0, s_star, g_star,
                                         tol, 0.0, maxit)
    g1 = _lowest(s_total, geo, c0, r, R)
    s_hi = s_total if g1 < 0.0 else illinois(_lowest, (geo, c0, r, R), s_star, g_star, s_total,
                                             g1, tol, 0.0, maxit)
    fz_axial = geo[_FT + 2]
    if fz_axial > 0.0:   # h > 0 needs tan(kappa) > axial / normal feed
        kh = math.atan2(fz_axial, math.sqrt(geo[_FT] ** 2 + geo[_FT + 1] ** 2))
        s_lo = max(s_lo, c0 + r * kh)
    if s_hi <= s_lo:
        return 0.0, -1.0
    width = (s_hi - s_lo) / n_probe
    first, last = -1, -1
    for i in range(n_probe):
        if _feasible(s_lo + (i + 0.5) * width, geo, tp, chip_eps, wf, wi):
            if first < 0:
                first = i
            last = i
    if first < 0:
        return 0.0, -1.0
    a, b = s_lo + max(first - 0.5, 0.0) * width, s_lo + (first + 0.5) * width
    for _ in range(n_bis):
        mid = 0.5 * (a + b)
        if _feasible(mid, geo, tp, chip_eps, wf, wi):
            b = mid
        else:
            a = mid
    new_lo = a
    a, b = s_lo + (last + 0.5) * width, s_lo + min(last + 1.5, n_probe) * width
    for _ in range(n_bis):
        mid = 0.5 * (a + b)
        if _feasible(mid, geo, tp, chip_eps, wf, wi):
            a = mid
        else:
            b = mid
    return new_lo, b


@njit(cache=True)
def union_rows(m, n_scan, n_piece):
    """Rows of the engaged-time work space: fixed edges (m > 0) or adaptive."""
    if m > 0:
        return 2 * m * MAX_INTERVALS_PER_EDGE
    return 8 * (n_scan + 1) * MAX_CHANGES_PER_CELL * n_piece


@njit(cache=True, nogil=True)
def _batch_range(start, stop, U, Nn, Fd, cuts, tp, set_par, kc, tab, flank_start, n_scan,
                 n_bisect, px, pw, unit, P, stats):
    geo = np.empty(GEO_SIZE)
    H = np.empty((1, 3, 3))
    st = np.empty(5)
    buf = np.empty((BUF_ROWS, 2))
    kinds = np.empty((BUF_ROWS, 2), dtype=np.int64)
    union = np.empty((union_rows(tab.shape[1], n_scan, px.shape[0]), 2))
    frame = np.empty((3, 3))
    one = np.int64(1)       # the steps, typed as process_gain's (one compiled version)
    for i in range(start, stop):
        for a in range(9):      # element loops, not array statements: those compile a
            P[i, a // 3, a % 3] = 0.0   # broadcast and its error message (2.3 s)
        for a in range(stats.shape[1]):
            stats[i, a] = 0.0
        if not posture_geometry(U[i], Nn[i], Fd[i], cuts[i, 0], cuts[i, 1], cuts[i, 2],
                                cuts[i, 4], cuts[i, 5], tp[0], tp[1], tp[2], tp[3], geo):
            continue
        if tab.shape[1] == 0:
            gain_adaptive(geo, tp, set_par, kc, one, n_scan, n_bisect, px, pw, H, st, buf,
                          kinds, union)
        else:
            gain_fixed(geo, tab, flank_start, tp, set_par, kc, one, H, st, buf, kinds, union)
        for a in range(9):
            frame[a // 3, a % 3] = geo[_F + a]
        _to_world(H[0], frame, P[i])
        for a in range(9):
            P[i, a // 3, a % 3] *= unit
        stats[i, 0] = st[0] / st[1] if st[1] > 0.0 else 0.0
        stats[i, 1] = st[4]
        stats[i, 2] = cuts[i, 3] * st[2] / st[3] if st[3] > 0.0 else 0.0


@njit(cache=True, nogil=True)
def gain_batch(U, Nn, Fd, cuts, tp, set_par, kc, tab, flank_start, n_scan, n_bisect, px, pw,
               unit, P, stats):
    """P (n, 3, 3) [N/m] and stats (n, 3) = (cut sense, engaged fraction, mean h [mm]).

    ``cuts`` (n, 6): depth, pick, side, fz, curvature f, curvature b. ``tp``:
    rotation sign, core radius, corner radius, flute length, radius,
    tan(helix), flutes. ``set_par``: chip eps, membership eps, root step,
    root tolerance, iterations. ``kc`` (3, d): the slopes Ktc, Krc, Kac as
    polynomials in kappa (:func:`_slopes`). ``tab`` (5, m): rho,
    z, kappa, psi, db of fixed micro edges (:func:`gain_fixed`); with m = 0
    the adaptive profile rule (:func:`gain_adaptive`). ``unit``: N/mm -> N/m.
    """
    _batch_range(0, U.shape[0], U, Nn, Fd, cuts, tp, set_par, kc, tab, flank_start, n_scan,
                 n_bisect, px, pw, unit, P, stats)


@njit(cache=True, parallel=True)
def gain_batch_parallel(U, Nn, Fd, cuts, tp, set_par, kc, tab, flank_start, n_scan, n_bisect,
                        px, pw, unit, P, stats, n_chunks):
    """As :func:`gain_batch`, chunks of postures spread over numba's threads."""
    n = U.shape[0]
    for c in prange(n_chunks):
        _batch_range((n * c) // n_chunks, (n * (c + 1)) // n_chunks, U, Nn, Fd, cuts, tp,
                     set_par, kc, tab, flank_start, n_scan, n_bisect, px, pw, unit, P, stats)
