"""Numba kernels of the time-domain regenerative milling model (sim/cutting.py) and of
the accelerometers' analog chain (sim/sensors.py).

They flush subnormal state to zero (``sim.constants.SUBNORMAL_FLUSH``): a mode or a
filter that rings down to subnormal numbers stays there in a limit cycle of rounding,
at about 20 times the cost of every operation, and no answer can see below 2.2e-308.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .constants import SUBNORMAL_FLUSH

__all__ = ["accel_filter", "integrate", "piece_steps", "periodic_forced", "tooth_sums"]

_TINY = SUBNORMAL_FLUSH


@njit(cache=True, nogil=True)
def _flushed(x):
    """``x``, or 0 where it is subnormal (NaN kept)."""
    if -_TINY < x < _TINY:
        return 0.0
    return x


@njit(cache=True, nogil=True)
def _chips(i, ptr, pos, edge, h0, nrm, q0, q1, q2, surface, out):
    """Chips [mm] of a table's entries at rotation sample ``i`` into ``out`` (``q0, q1,
    q2`` the mid-step displacement); their count."""
    k = 0
    for e in range(ptr[i], ptr[i + 1]):
        p = pos[e]
        j = edge[e]
        out[k] = h0[e] + (nrm[e, 0] * (q0 - surface[p, j, 0])
                          + nrm[e, 1] * (q1 - surface[p, j, 1])
                          + nrm[e, 2] * (q2 - surface[p, j, 2]))
        k += 1
    return k


@njit(cache=True, nogil=True)
def _forces(i, ptr, f0, f1, h, s, w, linear, rub, F0, F1, F2):
    """A table's force at sample ``i`` times ``s w`` added to ``F0, F1, F2``; returns the
    sums, the chip sum weighted by ``w``, the weight of the edges in contact and the
    entries whose chip fell to 0. An edge whose chip fell to 0 but not below ``-rub``
    still rubs (edge force only)."""
    hsum = 0.0
    wsum = 0.0
    lost = 0
    for k in range(ptr[i + 1] - ptr[i]):
        e = ptr[i] + k
        if h[k] > 0.0 or linear:
            F0 += s * w * (f0[e, 0] + h[k] * f1[e, 0])
            F1 += s * w * (f0[e, 1] + h[k] * f1[e, 1])
            F2 += s * w * (f0[e, 2] + h[k] * f1[e, 2])
            hsum += w * h[k]
            wsum += w
        else:
            lost += 1
            if h[k] > -rub:
                F0 += s * w * f0[e, 0]
                F1 += s * w * f0[e, 1]
                F2 += s * w * f0[e, 2]
    return F0, F1, F2, hsum, wsum, lost


@njit(cache=True, nogil=True)
def _leave(i, ptr, pos, edge, h0, nrm, h, q0, q1, q2, linear, surface, o_ptr, o_pos, o_edge,
           skip):
    """Writes what a table's edges leave on the surface at sample ``i``; with ``skip``,
    not where the other table (``o_*``) engages at this sample (it writes those). Both
    tables' entries at a sample are in ascending ``(pos, edge)`` order
    (:func:`integrate`), so the other's are walked once alongside."""
    e2 = o_ptr[i]
    end2 = o_ptr[i + 1]
    for k in range(ptr[i + 1] - ptr[i]):
        e = ptr[i] + k
        p = pos[e]
        j = edge[e]
        if skip:
            while e2 < end2 and (o_pos[e2] < p or o_pos[e2] == p and o_edge[e2] < j):
                e2 += 1
            if e2 < end2 and o_pos[e2] == p and o_edge[e2] == j:
                continue
        if h[k] > 0.0 or linear:
            surface[p, j, 0] = q0
            surface[p, j, 1] = q1
            surface[p, j, 2] = q2
        else:                             # not cut: the next flute meets it
            n2 = nrm[e, 0] ** 2 + nrm[e, 1] ** 2 + nrm[e, 2] ** 2
            for a in range(3):
                surface[p, j, a] -= h0[e] * nrm[e, a] / n2


@njit(cache=True, nogil=True)
def _tool_acceleration(u, mk, mc, mm, eta, deta):
    """A tool mode's acceleration under its modal force ``u`` [m/s^2] (stiffness,
    damping, mass ``mk, mc, mm``; state ``eta, deta``)."""
    return (u - mc * deta - mk * eta) / mm


@njit(cache=True, nogil=True)
def _mode_map(p00, p01, p10, p11, g0, g1, eta, deta, u):
    """A mode's state after one step under its modal force ``u``: the discrete map
    ``phi``, ``gam``, subnormal values flushed (the idle loop and the cutting loop
    alike). Scalars in and out: a helper given the arrays had each array's reference
    count raised and dropped at every call, 90% of a ring-down step's time."""
    x0 = p00 * eta + p01 * deta + g0 * u
    x1 = p10 * eta + p11 * deta + g1 * u
    return _flushed(x0), _flushed(x1)


@njit(cache=True, nogil=True)
def _ring_down(n_steps, phi_d, gam_d, dirs, mk, mc, mm, mr, tool_mode, half_dt, state, force,
               disp, acc_tool, chip_mean, contact_loss):
    """:func:`integrate`'s steps when neither table engages anything (an air move): the
    same arithmetic with the force zero (``u = d . 0`` kept as written, so that even the
    signs of zeros are the same), without the tables' empty loops."""
    nm = dirs.shape[0]
    for n in range(n_steps):
        for a in range(3):
            disp[n, a] = 0.0
            force[n, a] = 0.0
            acc_tool[n, a] = 0.0
        for k in range(nm):
            for a in range(3):
                disp[n, a] += dirs[k, a] * (state[k, 0] + (half_dt + mr[k]) * state[k, 1])
        chip_mean[n] = 0.0
        contact_loss[n] = 0
        for k in range(nm):
            u = dirs[k, 0] * 0.0 + dirs[k, 1] * 0.0 + dirs[k, 2] * 0.0
            if tool_mode[k]:
                acc = _tool_acceleration(u, mk[k], mc[k], mm[k], state[k, 0], state[k, 1])
                for a in range(3):
                    acc_tool[n, a] += dirs[k, a] * acc
            state[k, 0], state[k, 1] = _mode_map(phi_d[k, 0, 0], phi_d[k, 0, 1], phi_d[k, 1, 0],
                                                 phi_d[k, 1, 1], gam_d[k, 0], gam_d[k, 1],
                                                 state[k, 0], state[k, 1], u)


@njit(cache=True, nogil=True)
def integrate(start, n_steps, spr, ptr, pos, edge, h0, nrm, f0, f1,
              ptr_b, pos_b, edge_b, h0_b, nrm_b, f0_b, f1_b, blend,
              phi_d, gam_d, dirs, scale,
              mk, mc, mm, mr, tool_mode, linear, rub, half_dt, surface, state, force, disp,
              acc_tool, chip_mean, contact_loss):
    """March the cut ``n_steps`` rotation steps.

    Step ``n`` sits at rotation sample ``i = (start + n) mod spr``; its cutting entries
    are ``ptr[i]:ptr[i+1]``, in ascending ``(pos, edge)`` order
    (:func:`sim.cutting.prepare_cut` sorts them so): surface position ``pos`` (index
    into ``surface``'s rows; the flutes share positions), micro edge ``edge``, static chip ``h0``
    [mm], chip direction ``nrm`` (3) [mm per m of relative displacement],
    force at zero chip ``f0`` (3) [N] and per mm of chip ``f1`` (3) [N/mm],
    world frame. ``disp`` is the mid-step displacement. ``surface`` (spr, m, 3) [m]: the
    relative displacement with which the previous flute left the surface at that place
    (a vector, so that a change of posture -- another chip direction for the same
    place -- reads it along the new direction: the chip is
    ``h0 + nrm . (q - surface)``); where an edge did not cut, it is moved back by
    ``h0`` along the chip direction (the next flute meets the thicker chip).

    A second table (``*_b``, same layout; empty: ``ptr_b`` all zero) is blended
    in: step ``n``'s force is ``(1 - blend[n])`` times the first table's plus
    ``blend[n]`` times the second's (a posture changing along a segment). Both
    read the surface before either writes it; where both engage a place at a
    step, the table with the larger weight writes it.

    The modes (``phi_d``, ``gam_d``: the exact step map of
    ``m eta'' + c eta' + k eta = u`` for ``u`` held over the step) are driven
    by ``u = d . F`` (``dirs`` (nm, 3)). ``scale`` (n_steps,) multiplies the
    chip widths. Fills ``force`` (n, 3) [N], ``disp`` (n, 3) [m] (relative
    displacement at the step's start), ``chip_mean`` (n,) [mm] (mean chip of the
    edges in contact, weighted), ``contact_loss`` (n,) (entries whose chip fell to 0).
    A mode's displacement is ``eta + r eta'`` (``mr`` = r [s], 0 for real modes).
    The chips use the displacement predicted at the middle of the step
    (``eta + (half_dt + r) eta'``), so the force held over the step is centred on it
    (second order in the step, where a force from the step's start would act
    as an extra half-step delay). ``acc_tool`` (n, 3) [m/s^2]: acceleration of the tool (modes with
    ``tool_mode``; ``mk, mc, mm`` their stiffness, damping, mass) at the step's
    start. ``linear``: every engaged edge cuts, whatever its chip (the
    linearized model, no leaving the cut). ``state`` (nm, 2) carries (eta, eta')
    in and out; a value that falls below ``SUBNORMAL_FLUSH`` in magnitude is set to 0
    (module docstring).
    """
    nm = dirs.shape[0]
    if ptr[spr] == 0 and ptr_b[spr] == 0:         # nothing engaged: the modes ring down
        _ring_down(n_steps, phi_d, gam_d, dirs, mk, mc, mm, mr, tool_mode, half_dt, state,
                   force, disp, acc_tool, chip_mean, contact_loss)
        return
    most = 1
    for i in range(spr):
        most = max(most, ptr[i + 1] - ptr[i], ptr_b[i + 1] - ptr_b[i])
    h_a = np.empty(most)
    h_b = np.empty(most)
    # the displacement, the force, the acceleration and the modes' state in local
    # variables and arrays of the kernel's own (the same arithmetic in the same order: the
    # same numbers; an output array may alias an input as far as the compiler knows, so
    # sums kept in them were stored and loaded again at every term)
    eta = np.empty(nm)
    deta = np.empty(nm)
    for k in range(nm):
        eta[k] = state[k, 0]
        deta[k] = state[k, 1]
    for n in range(n_steps):
        i = (start + n) % spr
        q0 = 0.0
        q1 = 0.0
        q2 = 0.0
        for k in range(nm):
            d = eta[k] + (half_dt + mr[k]) * deta[k]
            q0 += dirs[k, 0] * d
            q1 += dirs[k, 1] * d
            q2 += dirs[k, 2] * d
        s = scale[n]
        w_b = blend[n]
        w_a = 1.0 - w_b
        F0, F1, F2 = 0.0, 0.0, 0.0
        hsum, wsum, lost = 0.0, 0.0, 0
        # most samples engage nothing (a ball's short arc in the cut): no table's helpers
        # there (their calls, with every array passed, were 60 % of the kernel's time)
        if ptr[i + 1] > ptr[i] or ptr_b[i + 1] > ptr_b[i]:
            _chips(i, ptr, pos, edge, h0, nrm, q0, q1, q2, surface, h_a)
            _chips(i, ptr_b, pos_b, edge_b, h0_b, nrm_b, q0, q1, q2, surface, h_b)
            if w_a > 0.0:
                F0, F1, F2, hs, ws, ls = _forces(i, ptr, f0, f1, h_a, s, w_a, linear, rub,
                                                 F0, F1, F2)
                hsum += hs
                wsum += ws
                lost += ls
            if w_b > 0.0:
                F0, F1, F2, hs, ws, ls = _forces(i, ptr_b, f0_b, f1_b, h_b, s, w_b, linear,
                                                 rub, F0, F1, F2)
                hsum += hs
                wsum += ws
                lost += ls
            # where both tables engage, the one with the larger weight writes a place
            # both engage (the other skips it); ``both`` and ``not both`` rather than
            # True and False: numba compiles a callee once per literal it is given
            both = not (w_b <= 0.0 or w_a <= 0.0)     # the branches' own tests
            if w_b <= 0.0:
                _leave(i, ptr, pos, edge, h0, nrm, h_a, q0, q1, q2, linear, surface,
                       ptr_b, pos_b, edge_b, both)
            elif w_a <= 0.0:
                _leave(i, ptr_b, pos_b, edge_b, h0_b, nrm_b, h_b, q0, q1, q2, linear,
                       surface, ptr, pos, edge, both)
            elif w_a >= w_b:
                _leave(i, ptr_b, pos_b, edge_b, h0_b, nrm_b, h_b, q0, q1, q2, linear,
                       surface, ptr, pos, edge, both)
                _leave(i, ptr, pos, edge, h0, nrm, h_a, q0, q1, q2, linear, surface,
                       ptr_b, pos_b, edge_b, not both)
            else:
                _leave(i, ptr, pos, edge, h0, nrm, h_a, q0, q1, q2, linear, surface,
                       ptr_b, pos_b, edge_b, both)
                _leave(i, ptr_b, pos_b, edge_b, h0_b, nrm_b, h_b, q0, q1, q2, linear,
                       surface, ptr, pos, edge, not both)
        force[n, 0] = F0
        force[n, 1] = F1
        force[n, 2] = F2
        disp[n, 0] = q0
        disp[n, 1] = q1
        disp[n, 2] = q2
        chip_mean[n] = hsum / wsum if wsum > 0.0 else 0.0
        contact_loss[n] = lost
        a0, a1, a2 = 0.0, 0.0, 0.0
        for k in range(nm):
            u = dirs[k, 0] * F0 + dirs[k, 1] * F1 + dirs[k, 2] * F2
            if tool_mode[k]:
                acc = _tool_acceleration(u, mk[k], mc[k], mm[k], eta[k], deta[k])
                a0 += dirs[k, 0] * acc
                a1 += dirs[k, 1] * acc
                a2 += dirs[k, 2] * acc
            eta[k], deta[k] = _mode_map(phi_d[k, 0, 0], phi_d[k, 0, 1], phi_d[k, 1, 0],
                                        phi_d[k, 1, 1], gam_d[k, 0], gam_d[k, 1], eta[k],
                                        deta[k], u)
        acc_tool[n, 0] = a0
        acc_tool[n, 1] = a1
        acc_tool[n, 2] = a2
    for k in range(nm):
        state[k, 0] = eta[k]
        state[k, 1] = deta[k]


@njit(cache=True, nogil=True)
def accel_filter(acc, rotation, factor, sos, zi, out):
    """The accelerometers' analog chain over new simulation samples: ``out[k, c] =``
    the cascade ``sos`` applied to ``factor * (rotation[c] . acc[k])``, ``c`` = 0, 1
    (machine X and Y).

    ``acc`` (n, 3) [m/s^2] tool acceleration in the workpiece frame; ``rotation`` (3, 3)
    workpiece frame to machine frame (rows); ``factor`` [-] the location factor;
    ``sos`` (ns, 6) second-order sections ``b0 b1 b2 1 a1 a2``; ``zi`` (ns, 2, 2) their
    two delays per channel (``zi[s, d, c]``, sosfilt's layout for ``axis=0``), carried in
    and out; ``out`` (n, 2) [m/s^2]. The arithmetic of
    ``scipy.signal.sosfilt`` (transposed direct form II, section by section, in its
    order) on ``factor * (acc @ rotation.T)[:, :2]``, one pass instead of three array
    operations; a delay that falls below ``SUBNORMAL_FLUSH`` is set to 0 (module
    docstring), where scipy would carry it on as a subnormal number.
    """
    n = acc.shape[0]
    ns = sos.shape[0]
    # the two channels side by side: two independent recurrences in one loop (each with
    # its own arithmetic, as channel by channel), so the processor overlaps them
    for k in range(n):
        x = factor * (acc[k, 0] * rotation[0, 0] + acc[k, 1] * rotation[0, 1]
                      + acc[k, 2] * rotation[0, 2])
        v = factor * (acc[k, 0] * rotation[1, 0] + acc[k, 1] * rotation[1, 1]
                      + acc[k, 2] * rotation[1, 2])
        for s in range(ns):
            y = sos[s, 0] * x + zi[s, 0, 0]
            w = sos[s, 0] * v + zi[s, 0, 1]
            z0 = sos[s, 1] * x - sos[s, 4] * y + zi[s, 1, 0]
            z1 = sos[s, 2] * x - sos[s, 5] * y
            u0 = sos[s, 1] * v - sos[s, 4] * w + zi[s, 1, 1]
            u1 = sos[s, 2] * v - sos[s, 5] * w
            zi[s, 0, 0] = _flushed(z0)
            zi[s, 1, 0] = _flushed(z1)
            zi[s, 0, 1] = _flushed(u0)
            zi[s, 1, 1] = _flushed(u1)
            x = y
            v = w
        out[k, 0] = x
        out[k, 1] = v


@njit(cache=True, nogil=True)
def periodic_forced(ptr, h0, f0, f1, scale, direction, phi, gam, x):
    """The periodic state of the modes under a table's static chips, one revolution:
    ``x`` (spr, nm, 2) [m, m/s] with ``x[p + 1] = phi x[p] + gam u[p]`` and
    ``x[spr] = x[0]``, where ``u[p] = direction . F[p]`` and ``F[p]`` the sum of
    ``scale (f0 + h0 f1)`` over the table's entries at rotation sample ``p``
    (``ptr`` (spr + 1,), ``h0`` (e,), ``f0``/``f1`` (e, 3) [N, N/mm]).

    Per mode, a pass from rest gives ``s = sum_p phi^(spr-1-p) gam u[p]`` and
    ``phi^spr``; ``x[0] = (I - phi^spr)^-1 s`` (2 x 2), and a second pass gives the
    rest: real arithmetic, no eigen-decomposition (``phi`` (nm, 2, 2), ``gam`` (nm, 2),
    ``direction`` (nm, 3))."""
    spr = ptr.size - 1
    nm = phi.shape[0]
    u = np.zeros((spr, nm))
    for p in range(spr):
        fx = 0.0
        fy = 0.0
        fz = 0.0
        for e in range(ptr[p], ptr[p + 1]):
            h = h0[e]
            fx += scale * (f0[e, 0] + h * f1[e, 0])
            fy += scale * (f0[e, 1] + h * f1[e, 1])
            fz += scale * (f0[e, 2] + h * f1[e, 2])
        for m in range(nm):
            u[p, m] = fx * direction[m, 0] + fy * direction[m, 1] + fz * direction[m, 2]
    for m in range(nm):
        a, b = phi[m, 0, 0], phi[m, 0, 1]
        c, d = phi[m, 1, 0], phi[m, 1, 1]
        g0, g1 = gam[m, 0], gam[m, 1]
        s0 = 0.0
        s1 = 0.0
        pa, pb, pc, pd = 1.0, 0.0, 0.0, 1.0         # phi^p
        for p in range(spr):
            s0, s1 = _mode_map(a, b, c, d, g0, g1, s0, s1, u[p, m])
            # phi^(p+1), column by column (a heavily damped mode's powers ring down)
            pa, pc = _mode_map(a, b, c, d, 0.0, 0.0, pa, pc, 0.0)
            pb, pd = _mode_map(a, b, c, d, 0.0, 0.0, pb, pd, 0.0)
        # (I - phi^spr) x0 = s
        ma, mb, mc, md = 1.0 - pa, -pb, -pc, 1.0 - pd
        det = ma * md - mb * mc
        if det == 0.0:              # no periodic response (an undamped mode in tune)
            for p in range(spr):
                x[p, m, 0] = np.nan
                x[p, m, 1] = np.nan
            continue
        x0 = (md * s0 - mb * s1) / det
        x1 = (ma * s1 - mc * s0) / det
        for p in range(spr):
            x[p, m, 0] = x0
            x[p, m, 1] = x1
            x0, x1 = _mode_map(a, b, c, d, g0, g1, x0, x1, u[p, m])


@njit(cache=True, nogil=True)
def tooth_sums(dn, first, counts, spt, gen, per_piece):
    """Per tooth of consecutive pieces of a run, the generating weights' sums ``den`` and
    their sums times the displacement along the normal ``num`` (:func:`sim.generation.
    tooth_surfaces`): row ``t`` of piece ``p`` is step ``first[p] + t`` with weight
    ``gen[p if per_piece else 0, step % spt]``; a piece's teeth are counted from its first
    step's, the pieces' one after the other. ``dn`` (n,) [m]; returns ``num``, ``den`` (the
    pieces' teeth) and how many teeth each piece spans. The sums run in the rows' order,
    as ``np.bincount`` adds its weights (the same numbers)."""
    n_p = counts.shape[0]
    span = np.zeros(n_p, dtype=np.int64)
    total = 0
    for p in range(n_p):
        if counts[p] > 0:
            span[p] = (first[p] + counts[p] - 1) // spt - first[p] // spt + 1
        total += span[p]
    num = np.zeros(total)
    den = np.zeros(total)
    row = 0
    base = 0
    for p in range(n_p):
        g = p if per_piece else 0
        f = first[p]
        t0 = base - f // spt
        for t in range(counts[p]):
            step = f + t
            w = gen[g, step % spt]
            k = step // spt + t0
            num[k] += w * dn[row]
            den[k] += w
            row += 1
        base += span[p]
    return num, den, span


@njit(cache=True, nogil=True)
def piece_steps(counts, w0, w1, start, dt, blend):
    """Per step of consecutive pieces (``counts`` (p,) steps each): its time
    ``start[p] + j dt`` [s] and, with ``blend``, the previous table's weight ``1 - w``,
    ``w = w0[p] + (w1[p] - w0[p]) (j + 1/2) / max(counts[p], 1)`` (``j`` the step within
    its piece; :meth:`sim.cutter.Cutter.advance_pieces`: numpy's arithmetic in the same
    order, the same numbers). Returns ``(t, 1 - w)`` (the latter empty without ``blend``).
    """
    n = 0
    for p in range(counts.shape[0]):
        n += counts[p]
    t = np.empty(n)
    other = np.empty(n if blend else 0)
    k = 0
    for p in range(counts.shape[0]):
        c = counts[p]
        dw = w1[p] - w0[p]
        m = max(c, 1)
        for j in range(c):
            t[k] = start[p] + j * dt
            if blend:
                other[k] = 1.0 - (w0[p] + dw * (j + 0.5) / m)
            k += 1
    return t, other
