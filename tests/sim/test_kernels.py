"""sim's numba kernels (sim/_kernels.py) against their numpy twins."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from sim import _kernels as K
from sim.constants import SUBNORMAL_FLUSH
from sim.sensors import AccelerometerStream, Accelerometers


def _flushed(x: float) -> float:
    return 0.0 if -SUBNORMAL_FLUSH < x < SUBNORMAL_FLUSH else x


def _integrate_twin(start, n_steps, spr, ptr, pos, edge, h0, nrm, f0, f1,
                    ptr_b, pos_b, edge_b, h0_b, nrm_b, f0_b, f1_b, blend,
                    phi_d, gam_d, dirs, scale, mk, mc, mm, mr, tool_mode, linear, rub, half_dt,
                    surface, state, force, disp, acc_tool, chip_mean, contact_loss):
    """numpy twin of :func:`sim._kernels.integrate`: the same steps, written out plainly
    (tables as dicts of their entries at a sample), the same order of operations."""
    nm = dirs.shape[0]
    tables = [(ptr, pos, edge, h0, nrm, f0, f1), (ptr_b, pos_b, edge_b, h0_b, nrm_b, f0_b, f1_b)]
    for n in range(n_steps):
        i = (start + n) % spr
        q = np.zeros(3)
        for k in range(nm):
            for a in range(3):
                q[a] += dirs[k, a] * (state[k, 0] + (half_dt + mr[k]) * state[k, 1])
        entries, chips = [], []
        for t in tables:
            e = np.arange(t[0][i], t[0][i + 1])
            entries.append(e)
            chips.append([t[3][x] + (t[4][x, 0] * (q[0] - surface[t[1][x], t[2][x], 0])
                                     + t[4][x, 1] * (q[1] - surface[t[1][x], t[2][x], 1])
                                     + t[4][x, 2] * (q[2] - surface[t[1][x], t[2][x], 2]))
                          for x in e])
        w = [1.0 - blend[n], blend[n]]
        s = scale[n]
        F = np.zeros(3)
        hsum, wsum, lost = 0.0, 0.0, 0
        for b in (0, 1):
            if w[b] <= 0.0:
                continue
            t = tables[b]
            hs, ws, ls = 0.0, 0.0, 0
            for x, h in zip(entries[b], chips[b]):
                if h > 0.0 or linear:
                    for a in range(3):
                        F[a] += s * w[b] * (t[5][x, a] + h * t[6][x, a])
                    hs += w[b] * h
                    ws += w[b]
                else:
                    ls += 1
                    if h > -rub:
                        for a in range(3):
                            F[a] += s * w[b] * t[5][x, a]
            hsum += hs
            wsum += ws
            lost += ls

        def leave(b, skip):
            t, o = tables[b], tables[1 - b]
            others = {(o[1][x], o[2][x]) for x in entries[1 - b]}
            for x, h in zip(entries[b], chips[b]):
                p, j = t[1][x], t[2][x]
                if skip and (p, j) in others:
                    continue
                if h > 0.0 or linear:
                    surface[p, j] = q
                else:
                    n2 = t[4][x, 0] ** 2 + t[4][x, 1] ** 2 + t[4][x, 2] ** 2
                    for a in range(3):
                        surface[p, j, a] -= t[3][x] * t[4][x, a] / n2

        if w[1] <= 0.0:
            leave(0, False)
        elif w[0] <= 0.0:
            leave(1, False)
        elif w[0] >= w[1]:
            leave(1, True)
            leave(0, False)
        else:
            leave(0, True)
            leave(1, False)
        force[n] = F
        disp[n] = q
        chip_mean[n] = hsum / wsum if wsum > 0.0 else 0.0
        contact_loss[n] = lost
        acc_tool[n] = 0.0
        for k in range(nm):
            u = dirs[k, 0] * F[0] + dirs[k, 1] * F[1] + dirs[k, 2] * F[2]
            if tool_mode[k]:
                acc = (u - mc[k] * state[k, 1] - mk[k] * state[k, 0]) / mm[k]
                for a in range(3):
                    acc_tool[n, a] += dirs[k, a] * acc
            x0 = phi_d[k, 0, 0] * state[k, 0] + phi_d[k, 0, 1] * state[k, 1] + gam_d[k, 0] * u
            x1 = phi_d[k, 1, 0] * state[k, 0] + phi_d[k, 1, 1] * state[k, 1] + gam_d[k, 1] * u
            state[k, 0] = _flushed(x0)
            state[k, 1] = _flushed(x1)


def _table(rng, spr, m, fill):
    """A random engagement table: entries at a share ``fill`` of (sample, flute, edge)."""
    i, f, j = np.nonzero(rng.random((spr, 2, m)) < fill)
    pos = ((i + f * (spr // 2)) % spr).astype(np.int64)
    order = np.lexsort((j, pos, i))      # the kernel's order: sample, position, edge
    i, j, pos = i[order], j[order], pos[order]
    ptr = np.searchsorted(i, np.arange(spr + 1)).astype(np.int64)
    k = i.size
    return (ptr, pos, j.astype(np.int64), rng.uniform(-0.002, 0.02, k),
            rng.normal(0.0, 1e3, (k, 3)), rng.normal(0.0, 20.0, (k, 3)),
            rng.normal(0.0, 2e3, (k, 3)))


def _case(seed, blended, linear, state_scale=1e-6, fill=0.4):
    rng = np.random.default_rng(seed)
    spr, m, nm, n = 16, 5, 4, 200
    a = _table(rng, spr, m, fill)
    b = _table(rng, spr, m, fill) if blended else \
        (np.zeros(spr + 1, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64),
         np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)))
    blend = np.linspace(0.0, 1.0, n) if blended else np.zeros(n)
    r, th = 0.995, rng.uniform(0.1, 0.5, nm)
    phi = np.stack([np.stack([r * np.cos(th), r * np.sin(th)], -1),
                    np.stack([-r * np.sin(th), r * np.cos(th)], -1)], 1)
    gam = rng.normal(0.0, 1e-9, (nm, 2))
    dirs = rng.normal(size=(nm, 3))
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    scale = rng.uniform(0.8, 1.2, n)
    mk, mc, mm = rng.uniform(1e7, 1e8, nm), rng.uniform(10, 100, nm), rng.uniform(0.1, 1, nm)
    mr = np.array([0.0, 1e-6, 0.0, -2e-6])
    tool = np.array([True, True, False, False])
    surface = rng.normal(0.0, 1e-6, (spr, m, 3))
    state = rng.normal(0.0, state_scale, (nm, 2))
    args = (3, n, spr, *a, *b, blend, phi, np.ascontiguousarray(gam), dirs, scale, mk, mc, mm,
            mr, tool, linear, 0.005, 5e-7)
    return args, surface, state, n


def _both(args, surface, state, n, fill):
    """The kernel's and the twin's outputs (surface, state, force, displacement,
    acceleration, chip, contact loss) from the same inputs, outputs first set to ``fill``."""
    out = []
    for f in (K.integrate, _integrate_twin):
        s, st = surface.copy(), state.copy()
        res = (np.full((n, 3), fill), np.full((n, 3), fill), np.full((n, 3), fill),
               np.full(n, fill), np.full(n, int(fill), np.int64))
        f(*args, s, st, *res)
        out.append((s, st, *res))
    return out


@pytest.mark.parametrize("blended", [False, True])
@pytest.mark.parametrize("linear", [False, True])
def test_integrate_equals_its_numpy_twin(blended, linear):
    for seed in range(3):
        args, surface, state, n = _case(seed, blended, linear)
        out = _both(args, surface, state, n, 0.0)
        assert out[0][3].any() and out[0][5].any()          # forces and accelerations ran
        for got, ref in zip(*out):
            np.testing.assert_array_equal(got, ref)


@pytest.mark.parametrize("blended", [False, True])
def test_integrate_with_sparse_tables_equals_its_numpy_twin(blended):
    """A ball's short arc in the cut: most rotation samples engage nothing (the kernel
    skips the tables' helpers there), some only the first table, some only the second."""
    for seed in range(6):
        args, surface, state, n = _case(seed, blended, False, fill=0.06)
        ptr, ptr_b = args[3], args[10]
        a_at, b_at = np.diff(ptr) > 0, np.diff(ptr_b) > 0
        assert (~a_at & ~b_at).sum() >= 2 and a_at.any()
        if blended:
            assert (a_at & ~b_at).any() and (b_at & ~a_at).any()
        out = _both(args, surface, state, n, 1.0)
        assert out[0][2].any() and not out[0][2].all()      # steps with and without force
        for got, ref in zip(*out):
            np.testing.assert_array_equal(got, ref)
            assert np.array_equal(np.signbit(got), np.signbit(ref))


def test_integrate_with_nothing_engaged_equals_its_numpy_twin():
    """An air move (both tables empty: the kernel's ring-down loop) against the twin:
    displacement, tool acceleration, the zero force and chips, the state."""
    for seed in range(3):
        args, surface, state, n = _case(seed, False, False)
        args = list(args)
        args[3] = np.zeros_like(args[3])
        for k in (4, 5, 6, 7, 8, 9):
            args[k] = args[k][:0]
        out = _both(args, surface, state, n, 1.0)
        assert out[0][3].any() and out[0][4].any() and not out[0][2].any()
        for got, ref in zip(*out):
            np.testing.assert_array_equal(got, ref)
            assert np.array_equal(np.signbit(got), np.signbit(ref))


def test_integrate_flushes_a_mode_ringing_down_into_subnormal_numbers():
    args, surface, _, n = _case(0, False, False)
    args = list(args)
    for k in (3, 4, 5, 6, 7, 8, 9):                          # no cut: the modes ring down
        args[k] = args[k][:0] if k != 3 else np.zeros_like(args[3])
    args[1] = 100_000
    args[21] = np.ones(100_000)
    args[17] = np.zeros(100_000)
    state = np.full((4, 2), 1e-300)
    res = (np.zeros((100_000, 3)), np.zeros((100_000, 3)), np.zeros((100_000, 3)),
           np.zeros(100_000), np.zeros(100_000, np.int64))
    K.integrate(*args, surface, state, *res)
    assert np.all(state == 0.0)
    # the twin on the first steps, where the state is still normal, agrees bit for bit
    short = list(args)
    short[1] = 50
    st0, st1 = np.full((4, 2), 1e-300), np.full((4, 2), 1e-300)
    r0 = tuple(np.zeros_like(x[:50]) for x in res)
    r1 = tuple(np.zeros_like(x[:50]) for x in res)
    K.integrate(*short, surface.copy(), st0, *r0)
    _integrate_twin(*short, surface.copy(), st1, *r1)
    np.testing.assert_array_equal(st0, st1)
    assert np.all(np.abs(st0) > SUBNORMAL_FLUSH)


def _piece_steps_twin(counts, w0, w1, start, dt, blend):
    """numpy twin of :func:`sim._kernels.piece_steps` (advance_pieces' former arithmetic)."""
    first = np.cumsum(counts) - counts
    local = np.arange(int(counts.sum())) - np.repeat(first, counts)
    t = np.repeat(start, counts) + local * dt
    if not blend:
        return t, np.zeros(0)
    w = np.repeat(w0, counts) + np.repeat(w1 - w0, counts) * (local + 0.5) \
        / np.repeat(np.maximum(counts, 1), counts)
    return t, 1.0 - w


@pytest.mark.parametrize("blend", [False, True])
def test_piece_steps_equals_its_numpy_twin(blend):
    rng = np.random.default_rng(4)
    counts = np.array([3, 0, 1, 517, 0, 2048, 7], dtype=np.int64)
    w0, w1 = rng.random(counts.size), rng.random(counts.size)
    start = np.cumsum(rng.random(counts.size)) + 12.345
    dt = 1.8351317624605448e-06
    got = K.piece_steps(counts, w0, w1, start, dt, blend)
    ref = _piece_steps_twin(counts, w0, w1, start, dt, blend)
    assert got[0].size == counts.sum() and got[1].size == (counts.sum() if blend else 0)
    for a, b in zip(got, ref):
        np.testing.assert_array_equal(a, b)


def _accel_twin(acc, rotation, factor, sos, zi):
    """numpy twin of :func:`sim._kernels.accel_filter`: the stream's former arithmetic
    (a matrix product, then ``scipy.signal.sosfilt``), without the flush."""
    x = factor * (acc @ rotation.T)[:, :2]
    return signal.sosfilt(sos, x, axis=0, zi=zi)


def _stream():
    return AccelerometerStream(Accelerometers(), 1.8351317624605448e-06)


@pytest.mark.parametrize("rotated", [False, True])
def test_accel_filter_equals_scipy_sosfilt(rotated):
    s = _stream()
    rng = np.random.default_rng(7)
    rot = np.eye(3)
    if rotated:
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        rot = np.ascontiguousarray(q)
    zi0 = rng.normal(0.0, 1.0, s._zi.shape)
    for chunk in (1, 17, 5000):
        acc = rng.normal(0.0, 50.0, (chunk, 3))
        zi = zi0.copy()
        out = np.empty((chunk, 2))
        K.accel_filter(acc, rot, 0.3, s._sos, zi, out)
        ref, zf = _accel_twin(acc, rot, 0.3, s._sos, zi0.copy())
        if rotated:     # the matrix product's rounding (BLAS) may differ in the last bit
            np.testing.assert_allclose(out, ref, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(zi, zf, rtol=1e-12, atol=1e-12)
        else:
            np.testing.assert_array_equal(out, ref)
            np.testing.assert_array_equal(zi, zf)


def test_accel_filter_flushes_where_scipy_keeps_subnormal_numbers():
    s = _stream()
    acc = np.zeros((400_000, 3))
    acc[:100] = np.random.default_rng(3).normal(0.0, 50.0, (100, 3))
    zi = np.zeros_like(s._zi)
    out = np.empty((acc.shape[0], 2))
    K.accel_filter(acc, np.eye(3), 0.3, s._sos, zi, out)
    ref, zf = _accel_twin(acc, np.eye(3), 0.3, s._sos, np.zeros_like(s._zi))
    normal = np.abs(ref) > 1e-290
    np.testing.assert_array_equal(out[normal], ref[normal])
    assert np.max(np.abs(out - ref)) < 1e-290
    assert np.all(zi == 0.0) and np.all(out[-1000:] == 0.0)


def test_stream_samples_are_unchanged_by_the_flush():
    """The converter's samples of a burst and a long ring-down: the stream (kernel) and
    the former arithmetic (matrix product, sosfilt, interpolation, the same noise) give
    the same counts."""
    dt = 1.8351317624605448e-06
    n = 300_000
    t = np.arange(n) * dt
    acc = np.zeros((n, 3))
    acc[:2000] = 40.0 * np.sin(2 * np.pi * 3000.0 * t[:2000])[:, None]
    s = AccelerometerStream(Accelerometers(), dt, seed=5)
    got, _ = s.push_many([t[k:k + 2724] for k in range(0, n, 2724)],
                         [acc[k:k + 2724] for k in range(0, n, 2724)])
    ref_x, _ = _accel_twin(acc, np.eye(3), 0.3, s._sos, np.zeros_like(s._zi))
    fs = Accelerometers().sample_rate_hz
    assert got.time_s.size > 100
    y = np.stack([np.interp(got.time_s, t, ref_x[:, c]) for c in range(2)], axis=1)
    y = y + np.random.default_rng(5).normal(0.0, 0.5, size=y.shape)
    lsb = Accelerometers().lsb_m_s2
    np.testing.assert_array_equal(got.counts, np.clip(np.rint(y / lsb), -32768, 32767))
    assert got.time_s[1] - got.time_s[0] == pytest.approx(1.0 / fs)


def _periodic_forced_twin(ptr, h0, f0, f1, scale, direction, phi, gam):
    """periodic_forced's numpy twin: the static force per sample by bincount, the state
    after one revolution from rest by the step map, the periodic start solved with
    numpy's matrix power, then the steps."""
    spr, nm = ptr.size - 1, phi.shape[0]
    sample = np.repeat(np.arange(spr), np.diff(ptr))
    fe = scale * (f0 + h0[:, None] * f1)
    force = np.stack([np.bincount(sample, fe[:, a], minlength=spr) for a in range(3)], axis=1)
    u = force @ direction.T                                  # (spr, nm)
    s = np.zeros((nm, 2))
    for p in range(spr):
        s = np.einsum("mij,mj->mi", phi, s) + gam * u[p][:, None]
    x = np.empty((spr, nm, 2))
    for m in range(nm):
        x[0, m] = np.linalg.solve(np.eye(2) - np.linalg.matrix_power(phi[m], spr), s[m])
    for p in range(spr - 1):
        x[p + 1] = np.einsum("mij,mj->mi", phi, x[p]) + gam * u[p][:, None]
    return x


@pytest.mark.parametrize("real_poles", [False, True])
def test_periodic_forced_equals_its_twin(real_poles):
    """periodic_forced against its numpy twin on a random table (samples without entries
    among them) and random stable step maps, complex or real eigenvalues, to rounding;
    its rows are periodic (one step on from the last gives the first)."""
    rng = np.random.default_rng(11)
    spr, nm = 701, 5
    counts = rng.integers(0, 4, spr)
    counts[5:9] = 0
    ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    e = int(ptr[-1])
    h0 = rng.uniform(0.0, 0.05, e)
    f0 = rng.normal(0.0, 3.0, (e, 3))
    f1 = rng.normal(0.0, 80.0, (e, 3))
    direction = rng.normal(size=(nm, 3))
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    phi = np.empty((nm, 2, 2))
    for m in range(nm):
        if real_poles:
            lam = np.diag(rng.uniform(-0.99, 0.99, 2))
        else:
            r, t = 0.999, rng.uniform(0.01, 3.0)
            lam = r * np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
        v = rng.normal(size=(2, 2)) + 2.0 * np.eye(2)
        phi[m] = v @ lam @ np.linalg.inv(v)
    gam = rng.normal(0.0, 1e-7, (nm, 2))
    got = np.empty((spr, nm, 2))
    K.periodic_forced(ptr, h0, f0, f1, 1.5, direction, phi, gam, got)
    want = _periodic_forced_twin(ptr, h0, f0, f1, 1.5, direction, phi, gam)
    assert np.abs(want).max() > 0
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9 * np.abs(want).max())
    last = np.arange(ptr[-2], ptr[-1])
    u_last = 1.5 * (f0[last] + h0[last, None] * f1[last]).sum(axis=0) @ direction.T
    nxt = np.einsum("mij,mj->mi", phi, got[-1]) + gam * u_last[:, None]
    np.testing.assert_allclose(nxt, got[0], rtol=0, atol=1e-9 * np.abs(want).max())
