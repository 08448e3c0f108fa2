"""Thin-wall modes by finite elements (orient.workpiece_fem), against closed forms.

References used (all independent of the code under test):

* Euler-Bernoulli cantilever: ``f1 = (1.8751^2 / 2 pi) sqrt(E I / (rho A L^4))``,
  tip static compliance ``L^3 / (3 E I)``, share of the first mode in it
  ``3 / (beta1 L)^4 * 4 = 0.9707``, modal mass of the first mode for a unit tip
  displacement ``m_total / 4`` (|phi(L)| = 2 for shapes with int phi^2 = L);
  e.g. Rao, *Vibration of Continuous Systems* (2007), ch. 11.
* Long plate strip: the same with ``E / (1 - nu^2)``; Leissa, *Vibration of
  Plates* (NASA SP-160, 1969), table 4.60: the square cantilever plate's first
  frequency parameter 3.492 lies 0.7 % below the strip's 3.516, so a wall's free
  ends soften it by less than 1 % (less for a long wall).
* Stepped cantilever (two uniform Euler-Bernoulli segments, continuity of
  deflection, slope, moment and shear at the step): solved here by an 8 x 8
  determinant.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from errpred.dynamics import Mode
from orient.workpiece_fem import (
    ALUMINIUM,
    STEEL,
    Material,
    ThinWall,
    wall_mesh,
    wall_modes,
)

BETA1 = 1.8751040687  # first root of cos(b) cosh(b) = -1


def _e_pa(mat: Material, strip: bool) -> float:
    e = mat.young_GPa * 1e9
    return e / (1.0 - mat.poisson ** 2) if strip else e


def eb_cantilever_f1(e_pa: float, rho: float, t_m: float, length_m: float) -> float:
    """First bending frequency [Hz] of a uniform rectangular cantilever (bending
    across thickness t)."""
    return BETA1 ** 2 / (2 * math.pi) * math.sqrt(e_pa * t_m ** 2 / (12 * rho * length_m ** 4))


def stepped_cantilever_f1(e_pa: float, rho: float, t1: float, t2: float, l1: float,
                          l2: float) -> float:
    """First frequency [Hz] of a cantilever strip of thickness t1 over [0, l1] and t2
    over [l1, l1 + l2] (per unit width, Euler-Bernoulli)."""

    def basis(b: float, x: float) -> np.ndarray:  # rows: w, w', w'', w'''
        c, s, ch, sh = math.cos(b * x), math.sin(b * x), math.cosh(b * x), math.sinh(b * x)
        return np.array([[c, s, ch, sh], [-b * s, b * c, b * sh, b * ch],
                         [-b * b * c, -b * b * s, b * b * ch, b * b * sh],
                         [b ** 3 * s, -b ** 3 * c, b ** 3 * sh, b ** 3 * ch]])

    def det(w: float) -> float:
        i1, i2 = t1 ** 3 / 12, t2 ** 3 / 12
        b1 = (rho * t1 * w * w / (e_pa * i1)) ** 0.25
        b2 = (rho * t2 * w * w / (e_pa * i2)) ** 0.25
        a = np.zeros((8, 8))
        a[0:2, 0:4] = basis(b1, 0.0)[0:2]                      # clamped root
        j1, j2 = basis(b1, l1), basis(b2, 0.0)
        a[2:4, 0:4], a[2:4, 4:8] = j1[0:2], -j2[0:2]           # w, w' continuous
        a[4:6, 0:4], a[4:6, 4:8] = e_pa * i1 * j1[2:4], -e_pa * i2 * j2[2:4]  # M, V
        a[6:8, 4:8] = basis(b2, l2)[2:4]                       # free tip
        return float(np.linalg.det(a))

    ws = np.linspace(1.0, 2e5, 4000)
    d = np.array([det(w) for w in ws])
    i = int(np.flatnonzero(np.sign(d[:-1]) != np.sign(d[1:]))[0])
    return brentq(det, ws[i], ws[i + 1], xtol=1e-9) / (2 * math.pi)


# --------------------------------------------------------------------- references
def test_stepped_reference_reduces_to_uniform():
    e, rho = 70e9, 2700.0
    f_u = eb_cantilever_f1(e, rho, 2e-3, 0.03)
    assert stepped_cantilever_f1(e, rho, 2e-3, 2e-3, 0.012, 0.018) == pytest.approx(f_u, rel=1e-6)


def test_beam_like_wall_first_frequency_vs_euler_bernoulli():
    # 2.5 mm along x 2 mm thick x 40 mm: a beam (b^2 / (L t) = 0.08, so the
    # plate's anticlastic restraint is negligible). Tolerance 2 %: shear and
    # rotary inertia (-0.2 % at L/t = 20), the 3-D clamp restraining Poisson
    # contraction at the root (+), mesh (< 0.6 %, FE converges from above).
    wall = ThinWall(2.5, 40.0, 2.0, ALUMINIUM)
    m = wall_modes(wall, n_modes=3, elements=(1, 1, 16))
    e, rho = ALUMINIUM.young_GPa * 1e9, ALUMINIUM.density_kg_m3
    f_n = eb_cantilever_f1(e, rho, 2e-3, 0.04)   # bending across the thickness
    f_a = eb_cantilever_f1(e, rho, 2.5e-3, 0.04)  # bending along the wall
    assert m.frequencies_hz[0] == pytest.approx(f_n, rel=0.02)
    assert m.frequencies_hz[1] == pytest.approx(f_a, rel=0.02)
    top = (1.25, 0.0, 40.0)
    d = m.flexible_direction(top)
    assert abs(d @ np.array(wall.normal)) > 0.9999


def test_long_wall_first_frequency_vs_plate_strip():
    # 200 x 30 x 2 mm, free ends: the cylindrical mode of a plate strip,
    # E/(1-nu^2). Tolerance 1.5 %: free ends < 1 % (Leissa), shear 0.2 %, mesh.
    wall = ThinWall(200.0, 30.0, 2.0, STEEL)
    m = wall_modes(wall, n_modes=1, elements=(20, 1, 12))
    f = eb_cantilever_f1(_e_pa(STEEL, True), STEEL.density_kg_m3, 2e-3, 0.03)
    assert m.frequencies_hz[0] == pytest.approx(f, rel=0.015)
    # ... and clearly above the narrow beam's (E): 1 / sqrt(1 - nu^2) = +4.5 %
    f_beam = eb_cantilever_f1(_e_pa(STEEL, False), STEEL.density_kg_m3, 2e-3, 0.03)
    assert m.frequencies_hz[0] > 1.03 * f_beam


def test_default_mesh_converges():
    # 60 x 40 x 3 mm aluminium wall: default mesh (18 x 1 x 12 Q2 elements) vs
    # the mesh halved over the height, along the wall and through the thickness
    # (one at a time, to keep the test fast; halving all three at once moves
    # f1 by 0.3 %). The refined spaces contain the default one, so by
    # Rayleigh-Ritz their frequencies are lower.
    wall = ThinWall(60.0, 40.0, 3.0, ALUMINIUM)
    base = wall_modes(wall, n_modes=1)
    assert base.mesh.cells.shape[0] == 18 * 12
    for finer in ((18, 1, 24), (36, 1, 12), (18, 2, 12)):
        f = wall_modes(wall, n_modes=1, elements=finer).frequencies_hz[0]
        assert f < base.frequencies_hz[0]
        assert abs(base.frequencies_hz[0] / f - 1.0) < 0.01


def test_modal_static_compliance_approaches_beam_formula():
    wall = ThinWall(2.5, 40.0, 2.0, ALUMINIUM)
    m = wall_modes(wall, n_modes=12, elements=(1, 1, 16))
    e = ALUMINIUM.young_GPa * 1e9
    b, t, h = 2.5e-3, 2e-3, 0.04
    c_beam = h ** 3 / (3 * e * b * t ** 3 / 12)
    top = (1.25, 0.0, 40.0)
    u = m.shapes_at(top)
    n = np.array(wall.normal)
    share = (u @ n) ** 2 / m.omega_rad_s ** 2
    partial = np.cumsum(share)
    # each mode adds compliance; 12 modes include the first 3 bending modes
    # across the thickness (99.85 % of the tip compliance in beam theory).
    assert np.all(np.diff(partial) >= 0)
    assert partial[-1] == pytest.approx(c_beam, rel=0.02)
    assert m.static_compliance_at(top)[1, 1] == pytest.approx(partial[-1], rel=1e-12)
    assert partial[0] / c_beam == pytest.approx(12 / BETA1 ** 4, rel=0.02)
    # first mode: modal mass at the tip = m_total / 4
    (mode1, d1), *_ = m.modes_at(top)
    m_total = ALUMINIUM.density_kg_m3 * b * t * h
    assert mode1.m_kg == pytest.approx(m_total / 4, rel=0.02)
    assert abs(d1 @ n) > 0.9999


# --------------------------------------------------------------------- in-process
@pytest.mark.parametrize("cut_to_z, direction", [(20.0, "up"), (10.0, "down")])
def test_in_process_frequency_follows_stepped_beam(cut_to_z, direction):
    # A long wall (strip) finished top-down from 3 mm to 1.5 mm. Removing the
    # top material first raises the first frequency (mass leaves faster than
    # stiffness) and lowers it once enough is removed: the stepped beam says
    # so and the FE must agree. Tolerance 3 %: the beam ignores shear (0.4 %
    # at t/L = 0.075) and the 3-D flexibility of the clamped root and of the
    # step junction (an effective lengthening of a few tenths of the
    # thickness), all of which lower the FE value; mesh < 0.5 %.
    mat, ts, tf, h = ALUMINIUM, 3.0, 1.5, 40.0
    stock = ThinWall(120.0, h, ts, mat)
    wall = stock.in_process(cut_to_z, tf)
    el = (8, 1, 16)
    m0 = wall_modes(stock, n_modes=6, elements=el)
    m1 = wall_modes(wall, n_modes=6, elements=el)
    e, rho = _e_pa(mat, True), mat.density_kg_m3
    f_ref = stepped_cantilever_f1(e, rho, ts * 1e-3, tf * 1e-3, cut_to_z * 1e-3,
                                  (h - cut_to_z) * 1e-3)
    f_ref0 = eb_cantilever_f1(e, rho, ts * 1e-3, h * 1e-3)
    assert m1.frequencies_hz[0] == pytest.approx(f_ref, rel=0.03)
    ratio, ratio_ref = m1.frequencies_hz[0] / m0.frequencies_hz[0], f_ref / f_ref0
    assert ratio == pytest.approx(ratio_ref, rel=0.03)
    assert (ratio > 1.05) if direction == "up" else (ratio < 0.95)
    top = (60.0, 0.0, h)
    n = np.array(wall.normal)
    # removing material always makes the wall more compliant (energy argument)
    assert n @ m1.static_compliance_at(top) @ n > 1.5 * (n @ m0.static_compliance_at(top) @ n)
    assert abs(m1.flexible_direction(top) @ n) > 0.9999


def test_in_process_geometry_and_exact_step_mesh():
    stock = ThinWall(30.0, 20.0, 4.0, ALUMINIUM, finish_side="front")
    w = stock.in_process(12.0, 1.0)
    assert w.profile == ((12.0, 1.0),)
    assert w.thickness_at(11.9) == 4.0 and w.thickness_at(12.0) == 1.0
    assert w.faces_at(5.0) == (-2.0, 2.0) and w.faces_at(15.0) == (-2.0, -1.0)
    deeper = w.in_process(5.0, 1.0)
    assert deeper.profile == ((5.0, 1.0),)
    assert stock.in_process(25.0, 1.0) is stock
    assert stock.in_process(-1.0, 1.0).thickness_at(0.0) == 1.0
    both = ThinWall(30.0, 20.0, 4.0, ALUMINIUM).in_process(12.0, 1.0)
    assert both.faces_at(15.0) == (-0.5, 0.5)
    assert ThinWall(30.0, 20.0, 4.0, ALUMINIUM, finish_side="back").in_process(
        12.0, 1.0).faces_at(15.0) == (1.0, 2.0)
    for wall in (w, both):
        m = wall_modes(wall, n_modes=1, elements=(3, 1, 4))
        vol = np.prod(m.mesh.upper - m.mesh.lower, axis=1).sum()
        assert vol == pytest.approx(30.0 * (12.0 * 4.0 + 8.0 * 1.0), rel=1e-12)
    # a point on the ledge left by the cut and one on the finished face
    m = wall_modes(w, n_modes=2, elements=(3, 1, 4))
    assert np.all(np.isfinite(m.shapes_at(w.to_workpiece((15.0, 1.0, 12.0)))))
    assert m.shapes_at((15.0, -1.0, 18.0)).shape == (2, 3)
    with pytest.raises(ValueError, match="point_mm"):
        m.shapes_at((15.0, 1.0, 18.0))   # 2 mm in front of the finished face


# --------------------------------------------------------------------- modes_at, FRF, frames
def _small_wall(**kw) -> ThinWall:
    return ThinWall(20.0, 15.0, 1.5, ALUMINIUM, damping_ratio=0.02, **kw)


def test_modes_at_sum_to_frf_and_skip_nodal_modes():
    wall = _small_wall()
    m = wall_modes(wall, n_modes=6, elements=(4, 1, 4))
    om = 2 * np.pi * np.linspace(100.0, 1.5 * m.frequencies_hz[-1], 37)
    for p in ((10.0, 0.0, 15.0), (3.0, 0.75, 11.0)):
        g = m.frf_at(p, om)
        pairs = m.modes_at(p)
        gs = sum(np.einsum("i,j,w->wij", d, d, 1.0 / (mo.k_N_m - mo.m_kg * om ** 2
                                                       + 1j * mo.c_Ns_m * om))
                 for mo, d in pairs)
        assert np.allclose(gs, g, rtol=1e-6, atol=1e-6 * np.abs(g).max())
        for mo, d in pairs:
            assert isinstance(mo, Mode)
            assert mo.damping_ratio == pytest.approx(0.02, rel=1e-12)
            assert np.linalg.norm(d) == pytest.approx(1.0, rel=1e-12)
            assert d @ np.array(wall.normal) > -1e-9  # signed toward +normal
        n = np.array(wall.normal)
        pn = m.modes_at(p, direction=2.0 * n)
        gn = sum(1.0 / (mo.k_N_m - mo.m_kg * om ** 2 + 1j * mo.c_Ns_m * om) for mo, _ in pn)
        assert np.allclose(gn, np.einsum("i,wij,j->w", n, g, n), rtol=1e-6)
        # the static limit of the FRF is the modal static compliance
        assert np.allclose(m.frf_at(p, [0.0])[0].real, m.static_compliance_at(p), rtol=1e-12)
    # at the middle of the top, modes antisymmetric about the mid-length do not move it
    centre = m.modes_at((10.0, 0.0, 15.0))
    assert 0 < len(centre) < 6
    freqs = {round(mo.natural_frequency_hz, 6) for mo, _ in centre}
    assert freqs <= {round(f, 6) for f in m.frequencies_hz}
    # on the clamped base nothing moves
    assert m.modes_at((10.0, 0.0, 0.0)) == []


def _rot(axis, angle) -> np.ndarray:
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def test_rotating_the_placement_rotates_directions():
    base = _small_wall()
    r = _rot((0.3, -0.5, 0.8), 1.1)
    origin = np.array([5.0, -7.0, 12.0])
    moved = _small_wall(origin_mm=tuple(origin), along=tuple(r[:, 0]), normal=tuple(r[:, 1]),
                        up=tuple(r[:, 2]))
    m0 = wall_modes(base, n_modes=5, elements=(4, 1, 4))
    m1 = wall_modes(moved, n_modes=5, elements=(4, 1, 4))
    assert np.allclose(m1.frequencies_hz, m0.frequencies_hz, rtol=1e-9)
    p0 = np.array([4.0, 0.75, 13.0])
    p1 = origin + r @ p0
    assert np.allclose(moved.to_local(p1), p0)
    for (a, da), (b, db) in zip(m0.modes_at(p0), m1.modes_at(p1), strict=True):
        assert b.k_N_m == pytest.approx(a.k_N_m, rel=1e-8)
        assert np.allclose(db, r @ da, atol=1e-8)
    om = np.array([0.0, 0.9 * m0.omega_rad_s[0]])
    assert np.allclose(m1.frf_at(p1, om), r @ m0.frf_at(p0, om) @ r.T,
                       atol=1e-8 * np.abs(m0.frf_at(p0, om)).max())
    assert np.allclose(m1.flexible_direction(p1), r @ m0.flexible_direction(p0), atol=1e-8)
    # p0 is on the front face: there the section's bending rotation adds
    # in-plane motion (n * slope), so the flexible direction leans off the
    # normal by a few degrees (it is the normal on the mid-plane)
    assert m1.flexible_direction(p1) @ np.array(moved.normal) > math.cos(math.radians(8.0))
    p_mid = origin + r @ np.array([4.0, 0.0, 13.0])
    assert m1.flexible_direction(p_mid) @ np.array(moved.normal) > math.cos(math.radians(0.5))


def test_clamped_ends_stiffen_every_mode():
    # Extra constraints shrink the admissible space: by the min-max principle no
    # eigenvalue can drop; the end faces do not move.
    free = wall_modes(_small_wall(), n_modes=4, elements=(4, 1, 4))
    clamped = wall_modes(_small_wall(clamp_ends=True), n_modes=4, elements=(4, 1, 4))
    assert np.all(clamped.frequencies_hz > free.frequencies_hz)
    # a 20 x 15 plate clamped on three sides is far stiffer than the cantilever
    assert clamped.frequencies_hz[0] > 2.0 * free.frequencies_hz[0]
    assert np.allclose(clamped.shapes_at((0.0, 0.0, 10.0)), 0.0, atol=0.0)
    assert not np.allclose(free.shapes_at((0.0, 0.0, 10.0)), 0.0)


def test_default_up_points_up():
    w = ThinWall(10.0, 5.0, 1.0, ALUMINIUM, along=(1, 0, 0), normal=(0, -1, 0))
    assert np.allclose(w.up, (0, 0, 1))
    w = ThinWall(10.0, 5.0, 1.0, ALUMINIUM, along=(0, 3, 0), normal=(2, 0, 0))
    assert np.allclose(w.along, (0, 1, 0)) and np.allclose(w.up, (0, 0, 1))


# --------------------------------------------------------------------- validation
@pytest.mark.parametrize("kw, match", [
    ({"length_mm": float("nan")}, "ThinWall.length_mm"),
    ({"thickness_mm": -1.0}, "ThinWall.thickness_mm"),
    ({"damping_ratio": float("inf")}, "ThinWall.damping_ratio"),
    ({"normal": (0.1, 1.0, 0.0)}, "orthogonal"),
    ({"normal": (0.0, 0.0, 0.0)}, "ThinWall.normal"),
    ({"up": (0.0, 1.0, 1.0)}, "orthogonal"),
    ({"profile": ((5.0, 1.0), (4.0, 1.0))}, "ThinWall.profile"),
    ({"profile": ((5.0, float("nan")),)}, "ThinWall.profile"),
    ({"profile": ((20.0, 1.0),)}, "ThinWall.profile"),
    ({"finish_side": "left"}, "ThinWall.finish_side"),
    ({"origin_mm": (0.0, float("nan"), 0.0)}, "ThinWall.origin_mm"),
])
def test_thin_wall_validation(kw, match):
    args = {"length_mm": 30.0, "height_mm": 20.0, "thickness_mm": 3.0, "material": ALUMINIUM}
    with pytest.raises(ValueError, match=match):
        ThinWall(**(args | kw))


def test_other_validation():
    with pytest.raises(ValueError, match="Material.poisson"):
        Material(70.0, 2700.0, 0.5)
    with pytest.raises(ValueError, match="Material.young_GPa"):
        Material(float("nan"), 2700.0, 0.3)
    with pytest.raises(TypeError, match="ThinWall.material"):
        ThinWall(30.0, 20.0, 3.0, "aluminium")
    w = ThinWall(30.0, 20.0, 3.0, ALUMINIUM)
    with pytest.raises(ValueError, match="finished_thickness_mm"):
        w.in_process(10.0, 3.5)
    with pytest.raises(ValueError, match="cut_to_z_mm"):
        w.in_process(float("nan"), 1.0)
    with pytest.raises(ValueError, match="n_modes"):
        wall_modes(w, n_modes=0)
    with pytest.raises(ValueError, match="elements"):
        wall_modes(w, elements=(2, 0, 2))
    with pytest.raises(ValueError, match="elements"):
        wall_modes(w, elements=float("nan"))
    with pytest.raises(ValueError, match="MAX_DOFS"):
        wall_modes(w, elements=(100, 4, 100))
    assert wall_modes(w, n_modes=1, elements=10.0).mesh.cells.shape[0] == 3 * 1 * 2
    m = wall_modes(w, n_modes=1, elements=(2, 1, 2))
    with pytest.raises(ValueError, match="omega_rad_s"):
        m.frf_at((15.0, 0.0, 20.0), [1.0, float("nan")])
    with pytest.raises(ValueError, match="direction"):
        m.modes_at((15.0, 0.0, 20.0), direction=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="point_mm"):
        m.shapes_at((15.0, 0.0, float("nan")))


# --------------------------------------------------------------------- kernel cross-check
def test_q2_kernel_matches_scikit_fem():
    # The tensor-product element matrices against scikit-fem's quadrature
    # assembly (ElementHex2, same mesh of unequal boxes, clamped at z = 0).
    skfem = pytest.importorskip("skfem")
    from skfem.helpers import dot
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    from orient.fem import q2hex

    x, y = np.array([0.0, 1e-3, 2.5e-3]), np.array([-1e-3, 1e-3])
    z = np.array([0.0, 5.0, 12.0, 20.0]) * 1e-3
    lam, mu = lame_parameters(70e9, 0.33)
    rho = 2700.0
    mine = q2hex.build_mesh((x, y, z), np.ones((2, 1, 3), dtype=bool))
    k, m = q2hex.assemble(mine, lam, mu, rho)
    w2_mine, _ = q2hex.lowest_modes(k, m, np.repeat(mine.nodes[:, 2] > 0, 3), 6)

    mesh = skfem.MeshHex.init_tensor(x, y, z)
    basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementHex2()), intorder=4)
    ks = skfem.asm(linear_elasticity(lam, mu), basis)

    @skfem.BilinearForm
    def mass(u, v, _):
        return rho * dot(u, v)

    ms = skfem.asm(mass, basis)
    free = np.ones(ks.shape[0], dtype=bool)
    free[basis.get_dofs(lambda p: np.isclose(p[2], 0.0)).all()] = False
    w2_sk, _ = q2hex.lowest_modes(ks, ms, free, 6)
    assert k.shape == ks.shape
    assert np.allclose(w2_mine, w2_sk, rtol=1e-9)
    assert m.sum() == pytest.approx(3 * rho * 2.5e-3 * 2e-3 * 20e-3, rel=1e-12)  # total mass x 3


def test_shape_along_names_the_kept_modes_with_their_signs():
    """shape_along keeps the same modes as modes_at, and |amp| gives their equivalent
    masses (m = 1 / amp^2); the sign of an antisymmetric mode flips across the middle."""
    wall = _small_wall()
    m = wall_modes(wall, n_modes=6, elements=(4, 1, 4))
    n = np.array(wall.normal)
    left, right = (5.0, 0.0, 15.0), (15.0, 0.0, 15.0)
    idx_l, amp_l = m.shape_along(left, n)
    pairs = m.modes_at(left, direction=n)
    assert len(idx_l) == len(pairs)
    for k, a, (mo, _) in zip(idx_l, amp_l, pairs, strict=True):
        assert mo.natural_frequency_hz == pytest.approx(m.frequencies_hz[k], rel=1e-12)
        assert mo.m_kg == pytest.approx(1.0 / a ** 2, rel=1e-9)
    idx_r, amp_r = m.shape_along(right, n)
    common = sorted(set(idx_l.tolist()) & set(idx_r.tolist()))
    ratio = [amp_r[list(idx_r).index(k)] / amp_l[list(idx_l).index(k)] for k in common]
    # mirror points: each mode is symmetric (+1) or antisymmetric (-1) about the middle
    assert np.allclose(np.abs(ratio), 1.0, rtol=1e-6)
    assert any(r < 0 for r in ratio) and any(r > 0 for r in ratio)


def test_elements_near_finds_the_element_a_pass_over_all_finds():
    """shapes_at's element from the grid's look-up against a pass over every element (the
    nearest, the first of equals): points inside, on shared faces, edges and corners (one
    element of several), in front of the step left by the cut within the tolerance, and
    beyond it (the same error)."""
    from orient.fem import q2hex

    w = ThinWall(30.0, 20.0, 4.0, ALUMINIUM, finish_side="front").in_process(12.0, 1.0)
    m = wall_modes(w, n_modes=2, elements=(5, 2, 6))
    mesh = m.mesh
    lo, hi = mesh.lower, mesh.upper
    rng = np.random.default_rng(7)
    lines = mesh.lines
    pts = [rng.uniform(lo.min(axis=0) - 0.3, hi.max(axis=0) + 0.3, size=(400, 3)),
           np.stack([rng.choice(x, 200) for x in lines], axis=1)]      # grid nodes: ties
    tol = 0.25
    checked = refused = 0
    for p in np.concatenate(pts):
        dist = np.linalg.norm(np.clip(p, lo, hi) - p, axis=1)
        want = int(np.argmin(dist))
        near = mesh.elements_near(p, tol)
        assert np.all(np.diff(near) > 0)
        if dist[want] <= tol:
            assert want in near
            sub = np.linalg.norm(np.clip(p, lo[near], hi[near]) - p, axis=1)
            assert int(near[np.argmin(sub)]) == want
            u = m.shapes_at(w.to_workpiece(p), tol_mm=tol)
            e = want
            n = q2hex.shape_functions((np.clip(p, lo[e], hi[e]) - lo[e]) / (hi[e] - lo[e]))
            np.testing.assert_array_equal(u, np.einsum("i,kij->kj", n,
                                                       m.shapes[:, m.elements[e], :]))
            checked += 1
        else:
            with pytest.raises(ValueError, match="from the wall's material"):
                m.shapes_at(w.to_workpiece(p), tol_mm=tol)
            refused += 1
    assert checked > 300 and refused > 20


def test_nested_dissection_orders_every_node_once_and_separates_the_halves():
    """The order holds each node once; at the top split, no element has nodes in both
    halves that come before the separator (the separator, last, decouples them)."""
    from orient.fem import q2hex

    wall = ThinWall(40.0, 20.0, 3.0, Material(210.0, 7850.0, 0.29))
    mesh = wall_mesh(wall, None)
    si = q2hex.Q2Mesh(lines=mesh.lines, cells=mesh.cells, elements=mesh.elements,
                      nodes=mesh.nodes)
    order = q2hex.nested_dissection(si, leaf=8)
    n = mesh.nodes.shape[0]
    assert np.array_equal(np.sort(order), np.arange(n))
    # the top split: the elements' centres about their median along the longest spread
    c = mesh.nodes[mesh.elements].mean(axis=1)
    axis = int(np.argmax(np.ptp(c, axis=0)))
    below = c[:, axis] < np.median(c[:, axis])
    in_a = np.zeros(n, bool)
    in_a[mesh.elements[below].ravel()] = True
    in_b = np.zeros(n, bool)
    in_b[mesh.elements[~below].ravel()] = True
    sep = in_a & in_b
    assert sep.any() and np.array_equal(np.sort(order[n - sep.sum():]), np.flatnonzero(sep))
    rank = np.empty(n, int)
    rank[order] = np.arange(n)
    assert rank[in_a & ~sep].max() < rank[in_b & ~sep].min()   # one half, then the other
    with pytest.raises(ValueError, match="leaf"):
        q2hex.nested_dissection(si, leaf=0)
    # one element: its nodes in number order; two side by side, parts of one: the face
    # they share (9 nodes) last
    one = q2hex.build_mesh((np.array([0.0, 1.0]),) * 3, np.ones((1, 1, 1), dtype=bool))
    assert np.array_equal(q2hex.nested_dissection(one), np.arange(27))
    two = q2hex.build_mesh((np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0]),
                            np.array([0.0, 1.0])), np.ones((2, 1, 1), dtype=bool))
    order = q2hex.nested_dissection(two, leaf=1)
    assert np.array_equal(np.sort(order), np.arange(45))
    assert np.all(two.nodes[order[-9:], 0] == 1.0)


def test_modes_in_nested_dissection_order_equal_superlus_own_ordering():
    """The eigenpairs do not depend on the elimination order: the same frequencies and
    mode shapes (to rounding; each up to its sign, which the largest entry sets and a
    symmetric wall's come in mirror pairs of equal size) with the nodes in
    nested-dissection order as with SuperLU's own minimum-degree ordering."""
    from orient.fem import q2hex

    wall = ThinWall(40.0, 20.0, 3.0, Material(210.0, 7850.0, 0.29)).in_process(12.0, 2.5)
    mesh = wall_mesh(wall, None)
    si = q2hex.Q2Mesh(lines=tuple(x * 1e-3 for x in mesh.lines), cells=mesh.cells,
                      elements=mesh.elements, nodes=mesh.nodes * 1e-3)
    lam, mu = wall.material.lame_Pa()
    k, m = q2hex.assemble(si, lam, mu, wall.material.density_kg_m3)
    free = np.repeat(mesh.nodes[:, 2] > 0, 3)
    w2_own, x_own = q2hex.lowest_modes(k, m, free, 6)
    w2_nd, x_nd = q2hex.lowest_modes(k, m, free, 6, q2hex.nested_dissection(si))
    np.testing.assert_allclose(w2_nd, w2_own, rtol=1e-9)
    diff = np.minimum(np.abs(x_nd - x_own).max(axis=0), np.abs(x_nd + x_own).max(axis=0))
    assert np.all(diff <= 1e-6 * np.abs(x_own).max(axis=0))
    assert np.all(x_nd[~free] == 0.0)
    with pytest.raises(ValueError, match="node_order"):
        q2hex.lowest_modes(k, m, free, 6, np.arange(3))
    twice = q2hex.nested_dissection(si).copy()
    twice[0] = twice[1]                     # the right size, a node twice, one missing
    with pytest.raises(ValueError, match="node_order"):
        q2hex.lowest_modes(k, m, free, 6, twice)
