"""Numba kernels of the zero-order (ZOA) stability analysis.

The compliance is ``G(w) = sum_g d_g d_g^T g_g(w)`` over *direction groups*
(modes sharing one direction add their receptances). The non-zero
eigenvalues of ``P G`` are those of the small matrix ``Q diag(g(w))`` with
``Q = D^T P D`` (``D`` the group directions as columns, ``ng`` groups), so
the kernels work with ``Q`` (closed-form eigenvalues for ``ng <= 3``).

With ``lambda`` an eigenvalue of ``P G(i w)`` the boundary scaling is
``s = 1 / (2 Re lambda)`` (only ``Re lambda > 0`` gives ``s > 0``; this is the
contract's ``(L_R / 2)(1 + (L_I / L_R)^2)`` with ``Lambda = 1 / lambda``), and
the phase condition at tooth period ``tau`` is
``F(w) = w tau - pi - 2 arg(lambda) = 2 pi k`` (``k = 0, 1, ...``).
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from numba import njit, prange

from .._root_kernels import illinois

__all__ = ["critical_one", "eig_small", "margin_batch", "margin_batch_serial", "margin_one",
           "margin_speeds", "receptance"]

_TWO_PI = 2.0 * math.pi
#: Candidates (crossings) kept per posture for refinement.
N_CANDIDATES = 4
#: Candidates within this relative distance of the best interpolated one are refined [-].
REFINE_WINDOW = 0.15
#: Root-finding iterations of the phase condition, and its relative tolerance [-].
REFINE_ITERATIONS = 40
REFINE_RTOL = 1e-10
#: Golden-section iterations of the critical (speed-independent) maximum.
GOLDEN_ITERATIONS = 40
#: Newton iterations, step tolerance and minimum root separation (relative to
#: the roots' scale) of the cubic's roots continued along the grid [-].
NEWTON_ITERATIONS = 6
NEWTON_TOL = 1e-5
ROOT_SEPARATION = 1e-6


@njit(cache=True, inline="always")
def _wrap(a):
    """Angle difference ``a`` in (-2 pi, 2 pi) (two angles of (-pi, pi]) wrapped into
    (-pi, pi], by one shift instead of a floating modulo."""
    if a > math.pi:
        return a - _TWO_PI
    if a <= -math.pi:
        return a + _TWO_PI
    return a


@njit(cache=True, inline="always")
def _l1(z):
    """``|Re z| + |Im z|``: a norm within sqrt(2) of ``abs(z)``, without the hypot."""
    return abs(z.real) + abs(z.imag)


@njit(cache=True, inline="always")
def _cdiv(a, b):
    """``a / b`` without the overflow guards of the generic complex division."""
    d = b.real * b.real + b.imag * b.imag
    return complex((a.real * b.real + a.imag * b.imag) / d,
                   (a.imag * b.real - a.real * b.imag) / d)


@njit(cache=True)
def receptance(w, mk, mm, mc, mr, group, ng, out):
    """Group receptances at ``w`` [rad/s] into ``out`` (ng,) complex [m/N]:
    ``(1 + i w r) / (k - m w^2 + i c w)`` summed per group (``mr`` = r [s])."""
    for i in range(ng):
        out[i] = 0.0
    for i in range(mk.shape[0]):
        re = mk[i] - mm[i] * w * w
        im = mc[i] * w
        d = re * re + im * im
        wr = w * mr[i]
        out[group[i]] += complex((re + wr * im) / d, (wr * re - im) / d)


@njit(cache=True, inline="always")
def _fast_atan2(y, x):
    """atan2 to about 1e-5 rad (odd minimax polynomial of atan on [0, 1]); used only to
    locate crossings on the grid, which are then refined with the exact angle."""
    ax, ay = abs(x), abs(y)
    if ax == 0.0 and ay == 0.0:
        return 0.0
    swap = ay > ax
    t = ax / ay if swap else ay / ax
    t2 = t * t
    r = t * (0.99997726 + t2 * (-0.33262347 + t2 * (0.19354346 + t2 * (-0.11643287
                                                                     + t2 * (0.05265332
                                                                             - t2 * 0.01172120)))))
    if swap:
        r = 0.5 * math.pi - r
    if x < 0.0:
        r = math.pi - r
    return -r if y < 0.0 else r


@njit(cache=True, inline="always")
def _angle(z):
    return math.atan2(z.imag, z.real)


@njit(cache=True)
def _cbrt(z):
    """Principal complex cube root."""
    if z == 0:
        return 0j
    a = _angle(z) / 3.0
    return abs(z) ** (1.0 / 3.0) * complex(math.cos(a), math.sin(a))


@njit(cache=True)
def eig_small(q, g, out):
    """Eigenvalues of ``q @ diag(g)`` (``q`` (ng, ng) real, ``g`` (ng,) complex) into ``out``.

    Closed form for ng = 1, 2, 3 (Cardano, one Newton polish per root);
    LAPACK for larger ng.
    """
    ng = g.shape[0]
    if ng == 1:
        out[0] = q[0, 0] * g[0]
    elif ng == 2:
        tr = q[0, 0] * g[0] + q[1, 1] * g[1]
        det = (q[0, 0] * q[1, 1] - q[0, 1] * q[1, 0]) * g[0] * g[1]
        r = cmath.sqrt(tr * tr - 4.0 * det)
        out[0] = 0.5 * (tr + r)
        out[1] = 0.5 * (tr - r)
    elif ng == 3:
        a2, a1, a0 = _cubic_coeffs(q, g[0], g[1], g[2])
        p = a1 - a2 * a2 / 3.0
        qq = 2.0 * a2 * a2 * a2 / 27.0 - a2 * a1 / 3.0 + a0
        d = cmath.sqrt(0.25 * qq * qq + p * p * p / 27.0)
        c1 = -0.5 * qq + d
        c2 = -0.5 * qq - d
        c = c1 if abs(c1) >= abs(c2) else c2
        u = _cbrt(c)
        w1 = complex(-0.5, 0.8660254037844386)
        w2 = complex(-0.5, -0.8660254037844386)
        shift = -a2 / 3.0
        for k in range(3):
            uk = u if k == 0 else (u * w1 if k == 1 else u * w2)
            t = uk - p / (3.0 * uk) if uk != 0 else 0j
            lam = t + shift
            f = ((lam + a2) * lam + a1) * lam + a0
            df = (3.0 * lam + 2.0 * a2) * lam + a1
            if df != 0:
                lam = lam - f / df
            out[k] = lam
    else:
        m = np.empty((ng, ng), dtype=np.complex128)
        for i in range(ng):
            for j in range(ng):
                m[i, j] = q[i, j] * g[j]
        ev = np.linalg.eigvals(m)
        for i in range(ng):
            out[i] = ev[i]


@njit(cache=True)
def _match(prev, cur, tmp):
    """Reorder ``cur`` in place so that ``cur[i]`` continues ``prev[i]``."""
    n = cur.shape[0]
    if n == 1:
        return
    if n == 2:
        if abs(prev[0] - cur[1]) + abs(prev[1] - cur[0]) < \
                abs(prev[0] - cur[0]) + abs(prev[1] - cur[1]):
            c = cur[0]
            cur[0] = cur[1]
            cur[1] = c
        return
    if n == 3:
        best, bp = 1e300, 0
        for perm in range(6):
            a = perm // 2
            b = (a + 1 + perm % 2) % 3
            c = 3 - a - b
            dd = abs(prev[0] - cur[a]) + abs(prev[1] - cur[b]) + abs(prev[2] - cur[c])
            if dd < best:
                best, bp = dd, perm
        a = bp // 2
        b = (a + 1 + bp % 2) % 3
        c = 3 - a - b
        tmp[0], tmp[1], tmp[2] = cur[a], cur[b], cur[c]
        cur[0], cur[1], cur[2] = tmp[0], tmp[1], tmp[2]
        return
    # greedy nearest assignment
    used = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        best, bj = 1e300, 0
        for j in range(n):
            if not used[j]:
                dd = abs(prev[i] - cur[j])
                if dd < best:
                    best, bj = dd, j
        used[bj] = True
        tmp[i] = cur[bj]
    for i in range(n):
        cur[i] = tmp[i]


@njit(cache=True, inline="always")
def _cubic_coeffs(q, g0, g1, g2):
    """``(a2, a1, a0)``: ``det(lambda I - q diag(g)) = lambda^3 + a2 lambda^2 + a1 lambda + a0``."""
    m00, m01, m02 = q[0, 0] * g0, q[0, 1] * g1, q[0, 2] * g2
    m10, m11, m12 = q[1, 0] * g0, q[1, 1] * g1, q[1, 2] * g2
    m20, m21, m22 = q[2, 0] * g0, q[2, 1] * g1, q[2, 2] * g2
    a2 = -(m00 + m11 + m22)
    a1 = (m00 * m11 - m01 * m10) + (m00 * m22 - m02 * m20) + (m11 * m22 - m12 * m21)
    a0 = -(m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)
           + m02 * (m10 * m21 - m11 * m20))
    return a2, a1, a0


@njit(cache=True, inline="always")
def _newton3(a2, a1, a0, z, scale):
    """Newton iterations on a root of the monic cubic from ``z``; returns (ok, z)."""
    for _ in range(NEWTON_ITERATIONS):
        f = ((z + a2) * z + a1) * z + a0
        df = (3.0 * z + 2.0 * a2) * z + a1
        if df == 0:
            return False, z
        step = _cdiv(f, df)
        z = z - step
        if _l1(step) <= NEWTON_TOL * scale:
            return True, z
    return False, z


@njit(cache=True)
def _needed(q, gw, rmin, need):
    """Grid points where an eigenvalue can have ``Re >= rmin`` (and their neighbours).

    ``Re lambda <= |lambda| <= ||Q diag(g)||_F``; where that bound is below
    ``rmin`` at both ends of a grid segment, no crossing in it can have a
    margin below ``0.5 / rmin``. ``rmin <= 0``: every point.
    """
    nw, ng = gw.shape[0], gw.shape[1]
    if rmin <= 0.0:
        for j in range(nw):
            need[j] = True
        return
    col = np.zeros(ng)
    for a in range(ng):
        for b in range(ng):
            col[b] += q[a, b] * q[a, b]
    r2 = rmin * rmin
    for j in range(nw):
        f2 = 0.0
        for b in range(ng):
            g = gw[j, b]
            f2 += col[b] * (g.real * g.real + g.imag * g.imag)
        need[j] = f2 >= r2
    prev = False
    for j in range(nw):                       # dilate by one point each way
        cur = need[j]
        if not cur and (prev or (j + 1 < nw and need[j + 1])):
            need[j] = True
            prev = False                      # a dilated point does not dilate further
        else:
            prev = cur


@njit(cache=True)
def _eigs_grid(q, omega, gw, lam, need):
    """Eigenvalue branches over the grid: ``lam`` (nw, ng) complex, continuity-matched.

    ng = 2 closed form with pairwise matching; ng = 3 continues the roots from
    the previous grid point by Aberth iterations (which keeps the branches),
    with Cardano plus matching as the fallback; other ng use LAPACK plus
    greedy matching. Points where ``need`` is False get 0 (not computed; a run
    of needed points starts afresh).
    """
    nw, ng = gw.shape[0], gw.shape[1]
    if ng == 1:
        for j in range(nw):
            lam[j, 0] = q[0, 0] * gw[j, 0] if need[j] else 0j
        return
    if ng == 2:
        q00, q11 = q[0, 0], q[1, 1]
        dq = q[0, 0] * q[1, 1] - q[0, 1] * q[1, 0]
        for j in range(nw):
            if not need[j]:
                lam[j, 0] = 0j
                lam[j, 1] = 0j
                continue
            g0, g1 = gw[j, 0], gw[j, 1]
            tr = q00 * g0 + q11 * g1
            r = cmath.sqrt(tr * tr - 4.0 * dq * g0 * g1)
            e0 = 0.5 * (tr + r)
            e1 = 0.5 * (tr - r)
            if j > 0 and need[j - 1]:
                p0, p1 = lam[j - 1, 0], lam[j - 1, 1]
                if abs(p0 - e1) + abs(p1 - e0) < abs(p0 - e0) + abs(p1 - e1):
                    e0, e1 = e1, e0
            lam[j, 0] = e0
            lam[j, 1] = e1
        return
    tmp = np.empty(ng, dtype=np.complex128)
    for j in range(nw):
        if not need[j]:
            for i in range(ng):
                lam[j, i] = 0j
            continue
        if ng == 3 and j > 1 and need[j - 1] and need[j - 2]:
            a2, a1, a0 = _cubic_coeffs(q, gw[j, 0], gw[j, 1], gw[j, 2])
            h = min((omega[j] - omega[j - 1]) / (omega[j - 1] - omega[j - 2]), 1.0)
            scale = _l1(lam[j - 1, 0]) + _l1(lam[j - 1, 1]) + _l1(lam[j - 1, 2]) + 1e-300
            ok0, z0 = _newton3(a2, a1, a0, lam[j - 1, 0] + h * (lam[j - 1, 0] - lam[j - 2, 0]),
                               scale)
            ok1, z1 = _newton3(a2, a1, a0, lam[j - 1, 1] + h * (lam[j - 1, 1] - lam[j - 2, 1]),
                               scale)
            z2 = -a2 - z0 - z1                         # Vieta: the sum of the roots
            f2 = ((z2 + a2) * z2 + a1) * z2 + a0
            ok2 = _l1(f2) <= NEWTON_TOL * scale * (_l1(z2 - z0) * _l1(z2 - z1) + 1e-300)
            if ok0 and ok1 and ok2 and min(_l1(z0 - z1), _l1(z0 - z2), _l1(z1 - z2)) \
                    > ROOT_SEPARATION * scale:
                lam[j, 0] = z0
                lam[j, 1] = z1
                lam[j, 2] = z2
                continue
        eig_small(q, gw[j], lam[j])
        if j > 0 and need[j - 1]:
            _match(lam[j - 1], lam[j], tmp)


@njit(cache=True)
def _nearest_eig(q, w, ref, mk, mm, mc, mr, group, g, ev):
    """Eigenvalue of ``Q diag(g(w))`` nearest to ``ref`` (Newton from ``ref`` for ng = 3)."""
    ng = g.shape[0]
    receptance(w, mk, mm, mc, mr, group, ng, g)
    if ng == 3:
        a2, a1, a0 = _cubic_coeffs(q, g[0], g[1], g[2])
        ok, z = _newton3(a2, a1, a0, ref, abs(ref) + abs(a2) + 1e-300)
        if ok:
            return z
    eig_small(q, g, ev)
    best, bi = 1e300, 0
    for i in range(ng):
        d = abs(ev[i] - ref)
        if d < best:
            best, bi = d, i
    return ev[bi]


@njit(cache=True)
def _eig_between(x, q, wa, wb, la, lb, mk, mm, mc, mr, group, g, ev):
    """The eigenvalue at ``x`` continued from ``la`` at ``wa`` to ``lb`` at ``wb``."""
    t = (x - wa) / (wb - wa)
    return _nearest_eig(q, x, la + t * (lb - la), mk, mm, mc, mr, group, g, ev)


@njit(cache=True)
def _phase_gap(x, q, tau, wa, wb, la, lb, arg_a, level, mk, mm, mc, mr, group, g, ev):
    """``F(x) - level``, the phase condition at ``x`` [rad/s] (see :func:`_refine_crossing`)."""
    lam = _eig_between(x, q, wa, wb, la, lb, mk, mm, mc, mr, group, g, ev)
    return x * tau - math.pi - 2.0 * (arg_a + _wrap(_angle(lam) - arg_a)) - level


@njit(cache=True)
def _refine_crossing(q, tau, wa, wb, la, lb, level, mk, mm, mc, mr, group, g, ev):
    """Root of ``F(w) = level`` on [wa, wb] (:func:`orient._root_kernels.illinois`);
    returns (s, w) or (inf, w)."""
    arg_a = _angle(la)
    fa = wa * tau - math.pi - 2.0 * arg_a - level
    fb = wa * tau - math.pi - 2.0 * arg_a + tau * (wb - wa) \
        - 2.0 * _wrap(_angle(lb) - arg_a) - level
    x = illinois(_phase_gap, (q, tau, wa, wb, la, lb, arg_a, level, mk, mm, mc, mr, group, g,
                              ev), wa, fa, wb, fb, 0.0, REFINE_RTOL, REFINE_ITERATIONS)
    lam = _eig_between(x, q, wa, wb, la, lb, mk, mm, mc, mr, group, g, ev)
    if lam.real <= 0.0:
        return np.inf, x
    return 0.5 / lam.real, x


@njit(cache=True)
def margin_one(q, omega, gw, tau, mk, mm, mc, mr, group, lam, rmin=0.0):
    """ZOA margin at tooth period ``tau`` [s]; returns (s_min, chatter w [rad/s]).

    ``lam`` is a (nw, ng) complex work array. With ``rmin > 0`` the result is
    exact where it is below ``0.5 / rmin`` and otherwise some value at or
    above it (eigenvalues are computed only where they can matter, see
    :func:`_needed`).
    """
    nw, ng = gw.shape[0], gw.shape[1]
    need = np.empty(nw, dtype=np.bool_)
    _needed(q, gw, rmin, need)
    _eigs_grid(q, omega, gw, lam, need)
    arg = np.empty((nw, ng))
    for j in range(nw):
        for i in range(ng):
            z = lam[j, i]
            arg[j, i] = _fast_atan2(z.imag, z.real) if z.real > 0.0 or \
                (j > 0 and lam[j - 1, i].real > 0.0) or \
                (j + 1 < nw and lam[j + 1, i].real > 0.0) else 0.0
    cs = np.full(N_CANDIDATES, np.inf)
    cj = np.zeros(N_CANDIDATES, dtype=np.int64)
    ci = np.zeros(N_CANDIDATES, dtype=np.int64)
    cl = np.zeros(N_CANDIDATES)
    for i in range(ng):
        for j in range(nw - 1):
            la, lb = lam[j, i], lam[j + 1, i]
            ra, rb = la.real, lb.real
            if ra <= 0.0 and rb <= 0.0:
                continue
            arg_a = arg[j, i]
            fa = omega[j] * tau - math.pi - 2.0 * arg_a
            fb = fa + tau * (omega[j + 1] - omega[j]) - 2.0 * _wrap(arg[j + 1, i] - arg_a)
            if fb == fa:
                continue
            lo, hi = (fa, fb) if fb > fa else (fb, fa)
            kmin = math.ceil(lo / _TWO_PI)
            kmax = math.floor(hi / _TWO_PI)
            if kmin > kmax:
                continue
            want_late = rb >= ra            # the crossing nearest the larger Re(lambda)
            k = kmax if (want_late == (fb > fa)) else kmin
            level = k * _TWO_PI
            t = (level - fa) / (fb - fa)
            r = ra + t * (rb - ra)
            if r <= 0.0:
                continue
            s = 0.5 / r
            if s < cs[N_CANDIDATES - 1]:
                pos = N_CANDIDATES - 1
                while pos > 0 and cs[pos - 1] > s:
                    cs[pos], cj[pos], ci[pos], cl[pos] = cs[pos - 1], cj[pos - 1], \
                        ci[pos - 1], cl[pos - 1]
                    pos -= 1
                cs[pos], cj[pos], ci[pos], cl[pos] = s, j, i, level
    best, wbest = np.inf, np.nan
    if not np.isfinite(cs[0]):
        return best, wbest
    g = np.empty(ng, dtype=np.complex128)
    ev = np.empty(ng, dtype=np.complex128)
    for c in range(N_CANDIDATES):
        if cs[c] > cs[0] * (1.0 + REFINE_WINDOW):
            break
        j, i = cj[c], ci[c]
        s, w = _refine_crossing(q, tau, omega[j], omega[j + 1], lam[j, i], lam[j + 1, i],
                                cl[c], mk, mm, mc, mr, group, g, ev)
        if s < best:
            best, wbest = s, w
    return best, wbest


@njit(cache=True)
def _max_re(q, w, mk, mm, mc, mr, group, g, ev):
    receptance(w, mk, mm, mc, mr, group, g.shape[0], g)
    eig_small(q, g, ev)
    m = -np.inf
    for i in range(ev.shape[0]):
        m = max(m, ev[i].real)
    return m


@njit(cache=True)
def critical_one(q, omega, gw, mk, mm, mc, mr, group, curve):
    """Speed-independent ZOA margin ``1 / (2 max Re lambda)``; fills ``curve`` (nw,) with
    the per-frequency ``s`` (inf where no eigenvalue has Re > 0); returns (s, w)."""
    nw, ng = gw.shape[0], gw.shape[1]
    ev = np.empty(ng, dtype=np.complex128)
    g = np.empty(ng, dtype=np.complex128)
    jbest, rbest = -1, 0.0
    for j in range(nw):
        eig_small(q, gw[j], ev)
        m = -np.inf
        for i in range(ng):
            m = max(m, ev[i].real)
        curve[j] = 0.5 / m if m > 0.0 else np.inf
        if m > rbest:
            rbest, jbest = m, j
    if jbest < 0:
        return np.inf, np.nan
    a = omega[max(jbest - 1, 0)]
    b = omega[min(jbest + 1, nw - 1)]
    inv = (math.sqrt(5.0) - 1.0) / 2.0
    x1 = b - inv * (b - a)
    x2 = a + inv * (b - a)
    f1 = _max_re(q, x1, mk, mm, mc, mr, group, g, ev)
    f2 = _max_re(q, x2, mk, mm, mc, mr, group, g, ev)
    for _ in range(GOLDEN_ITERATIONS):
        if f1 > f2:
            b, x2, f2 = x2, x1, f1
            x1 = b - inv * (b - a)
            f1 = _max_re(q, x1, mk, mm, mc, mr, group, g, ev)
        else:
            a, x1, f1 = x1, x2, f2
            x2 = a + inv * (b - a)
            f2 = _max_re(q, x2, mk, mm, mc, mr, group, g, ev)
    x = 0.5 * (a + b)
    r = max(_max_re(q, x, mk, mm, mc, mr, group, g, ev), rbest)
    return 0.5 / r, x


@njit(cache=True)
def _q_matrix(p, d, q):
    """``q = d p d^T`` for ``p`` (3, 3) and group directions ``d`` (ng, 3)."""
    ng = d.shape[0]
    for a in range(ng):
        for b in range(ng):
            acc = 0.0
            for i in range(3):
                for j in range(3):
                    acc += d[a, i] * p[i, j] * d[b, j]
            q[a, b] = acc


@njit(cache=True)
def margin_speeds(p, d, omega, gw, taus, mk, mm, mc, mr, group):
    """ZOA margins of one posture at many tooth periods ``taus`` (n,) [s]."""
    ng = d.shape[0]
    q = np.empty((ng, ng))
    _q_matrix(p, d, q)
    lam = np.empty((omega.shape[0], ng), dtype=np.complex128)
    out = np.empty(taus.shape[0])
    for i in range(taus.shape[0]):
        # rmin given (0.0): omitted, it compiled a version of margin_one of its own
        out[i] = margin_one(q, omega, gw, taus[i], mk, mm, mc, mr, group, lam, 0.0)[0]
    return out


@njit(cache=True)
def _posture_margin(p, d, omega, gw, tau, mk, mm, mc, mr, group, q, lam, rmin, cap):
    """One posture's margin for :func:`margin_batch` and :func:`margin_batch_serial`
    (``q`` and ``lam`` are work arrays the caller owns)."""
    _q_matrix(p, d, q)
    s = margin_one(q, omega, gw, tau, mk, mm, mc, mr, group, lam, rmin)[0]
    return min(s, cap)


@njit(cache=True, parallel=True)
def margin_batch(p, d, omega, gw, taus, mk, mm, mc, mr, group, cap=np.inf):
    """ZOA margins of many postures: ``p`` (n, 3, 3), ``d`` (n or 1, ng, 3),
    ``taus`` (n or 1,) [s]. Returns (n,); with a finite ``cap``, margins at or
    above it are returned as ``cap`` (exact below it, and much faster)."""
    n = p.shape[0]
    ng = d.shape[1]
    dstep = 1 if d.shape[0] > 1 else 0
    tstep = 1 if taus.shape[0] > 1 else 0
    rmin = 0.5 / cap if cap < np.inf else 0.0
    out = np.empty(n)
    for i in prange(n):
        q = np.empty((ng, ng))
        lam = np.empty((omega.shape[0], ng), dtype=np.complex128)
        out[i] = _posture_margin(p[i], d[i * dstep], omega, gw, taus[i * tstep], mk, mm, mc,
                                 mr, group, q, lam, rmin, cap)
    return out


@njit(cache=True)
def margin_batch_serial(p, d, omega, gw, taus, mk, mm, mc, mr, group, cap=np.inf):
    """:func:`margin_batch` in the calling thread (the same loop body, no thread
    launch): for a few hundred postures the launch of numba's threads costs more
    than the margins (about 6 ms of CPU a call on a shared 2-core machine against
    tens of microseconds a posture)."""
    n = p.shape[0]
    ng = d.shape[1]
    dstep = 1 if d.shape[0] > 1 else 0
    tstep = 1 if taus.shape[0] > 1 else 0
    rmin = 0.5 / cap if cap < np.inf else 0.0
    out = np.empty(n)
    q = np.empty((ng, ng))
    lam = np.empty((omega.shape[0], ng), dtype=np.complex128)
    for i in range(n):
        out[i] = _posture_margin(p[i], d[i * dstep], omega, gw, taus[i * tstep], mk, mm, mc,
                                 mr, group, q, lam, rmin, cap)
    return out
