"""orient.dynamics: modal systems with directions, tool modes carried by the tool axis."""

from __future__ import annotations

import math

import numpy as np
import pytest

from errpred.dynamics import Compliance, Mode
from orient.dynamics import ModalSystem, fit_modes, minimal_rotation

MX = Mode.from_frequency(600.0, 0.035, 5.6e6)
MY = Mode.from_frequency(660.0, 0.03, 7.5e6)
MX2 = Mode.from_frequency(1500.0, 0.02, 2.0e7)


def _compliance() -> Compliance:
    return Compliance.from_modes({"x": [MX, MX2], "y": MY})


def test_tool_frf_matches_errpred_compliance_for_vertical_tool():
    comp = _compliance()
    sys = ModalSystem.tool(comp)
    w = 2 * math.pi * np.linspace(10.0, 3000.0, 301)
    g = sys.frf(w)
    ref = comp.response(w)                       # independent: errpred's direct FRFs
    assert np.allclose(g[:, 0, 0], ref[:, 0], rtol=1e-12)
    assert np.allclose(g[:, 1, 1], ref[:, 1], rtol=1e-12)
    assert np.all(g[:, 2, :] == 0) and np.all(g[:, 0, 1] == 0)
    assert np.all(sys.source == "tool") and sys.n_modes == 3


@pytest.mark.parametrize("axis", [(0.0, 0.0, 1.0), (0.3, -0.4, 0.8), (1.0, 0.0, 0.0),
                                  (-0.6, 0.7, -0.2)])
def test_minimal_rotation_properties(axis):
    u = np.array(axis) / np.linalg.norm(axis)
    r = minimal_rotation(u)
    assert np.allclose(r @ [0, 0, 1], u, atol=1e-12)
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)
    # minimal: the rotation axis is Z x u, which it leaves fixed
    k = np.cross([0, 0, 1], u)
    if np.linalg.norm(k) > 0:
        assert np.allclose(r @ k, k, atol=1e-12)
    with pytest.raises(ValueError, match="axis"):
        minimal_rotation([0.0, 0.0, -1.0])


def test_tool_modes_bend_perpendicular_to_axis_and_recarry():
    comp = Compliance.from_modes({"x": MX, "y": MY})
    u = np.array([0.3, -0.4, 0.8]) / np.linalg.norm([0.3, -0.4, 0.8])
    sys = ModalSystem.tool(comp, u)
    assert np.allclose(sys.direction @ u, 0.0, atol=1e-12)
    assert np.allclose(sys.tool_axis, u)
    # carrying back to vertical recovers X and Y
    back = sys.with_tool_axis([0, 0, 1])
    assert np.allclose(back.direction, [[1, 0, 0], [0, 1, 0]], atol=1e-12)
    # directions_for_axes == with_tool_axis, workpiece modes untouched
    wp = ModalSystem.from_modes([(Mode.from_frequency(900, 0.02, 3e6), (0, 0.6, 0.8))])
    both = ModalSystem.combine(sys, wp)
    axes = np.array([[0, 0, 1.0], [0.5, 0.5, np.sqrt(0.5)]])
    d = both.directions_for_axes(axes)
    for i, a in enumerate(axes):
        assert np.allclose(d[i], both.with_tool_axis(a).direction, atol=1e-12)
        assert np.allclose(d[i, 2], [0, 0.6, 0.8])


def test_frf_is_sum_of_directional_modes_and_rotation_covariant():
    rng = np.random.default_rng(1)
    dirs = rng.normal(size=(3, 3))
    sys = ModalSystem.from_modes(list(zip([MX, MY, MX2], dirs, strict=True)))
    w = np.array([100.0, 3700.0, 4200.0, 9000.0])
    d = dirs / np.linalg.norm(dirs, axis=1)[:, None]
    ref = sum(np.einsum("i,j->ij", d[k], d[k])[None] /
              (m.k_N_m - m.m_kg * w[:, None, None] ** 2 + 1j * m.c_Ns_m * w[:, None, None])
              for k, m in enumerate([MX, MY, MX2]))
    assert np.allclose(sys.frf(w), ref, rtol=1e-12)
    g = sys.frf(w)
    assert np.allclose(g, np.swapaxes(g, 1, 2))
    r = minimal_rotation([0.2, 0.3, 0.9])
    assert np.allclose(sys.rotated(r).frf(w), r @ g @ r.T, rtol=1e-12, atol=1e-20)


def test_state_matrix_poles_are_the_modal_poles():
    sys = ModalSystem.from_modes([(MX, (1, 0, 0)), (MY, (0, 1, 0))])
    ev = np.sort_complex(np.linalg.eigvals(sys.state_matrix()))
    ref = []
    for m in (MX, MY):
        wn, z = 2 * math.pi * m.natural_frequency_hz, m.damping_ratio
        ref += [complex(-z * wn, s * wn * math.sqrt(1 - z * z)) for s in (1, -1)]
    assert np.allclose(ev, np.sort_complex(np.array(ref)), rtol=1e-10)


def test_measured_and_static_compliance():
    f = np.linspace(50.0, 3000.0, 1200)
    g = Compliance.from_modes({"x": [MX, MX2]}).response(2 * math.pi * f)[:, 0]
    meas = Compliance.from_frf(f, {"x": g})
    with pytest.raises(ValueError, match="measured FRF"):
        ModalSystem.tool(meas)
    with pytest.raises(ValueError, match="static"):
        ModalSystem.tool(Compliance.from_modes({"x": MX}, static_only=True))
    fitted = fit_modes(f, g)
    assert len(fitted) == 2
    for got, ref in zip(fitted, (MX, MX2), strict=True):
        assert got.natural_frequency_hz == pytest.approx(ref.natural_frequency_hz, rel=1e-4)
        assert got.damping_ratio == pytest.approx(ref.damping_ratio, rel=1e-3)
        assert got.k_N_m == pytest.approx(ref.k_N_m, rel=1e-3)
    sys = ModalSystem.tool(meas, fit=True)
    assert np.allclose(sys.frf(2 * math.pi * f)[:, 0, 0], g, rtol=1e-3, atol=1e-3 * abs(g).max())


def test_combine_and_validation():
    tool_a = ModalSystem.tool(Compliance.from_modes({"x": MX}), (0.0, 0.6, 0.8))
    tool_b = ModalSystem.tool(Compliance.from_modes({"y": MY}), (0.0, 0.0, 1.0))
    with pytest.raises(ValueError, match="tool axes"):
        ModalSystem.combine(tool_a, tool_b)
    wp = ModalSystem.from_modes([(MY, (1, 1, 0))])
    both = ModalSystem.combine(tool_a, wp)
    assert both.source.tolist() == ["tool", "workpiece"]
    assert np.allclose(np.linalg.norm(both.direction, axis=1), 1.0)
    with pytest.raises(ValueError, match="k_N_m"):
        ModalSystem(np.array([np.nan]), np.array([1.0]), np.array([1.0]),
                    np.array([[1.0, 0, 0]]), np.array(["tool"]))
    with pytest.raises(ValueError, match="unit"):
        ModalSystem(np.array([1.0]), np.array([1.0]), np.array([1.0]),
                    np.array([[2.0, 0, 0]]), np.array(["tool"]))
    with pytest.raises(ValueError, match="source"):
        ModalSystem(np.array([1.0]), np.array([1.0]), np.array([1.0]),
                    np.array([[1.0, 0, 0]]), np.array(["spindle"]))
    with pytest.raises(ValueError, match="omega"):
        both.frf([np.nan])
    with pytest.raises(ValueError, match="direction"):
        ModalSystem.from_modes([(MX, (np.nan, 0, 0))])
    assert both.direction.flags.writeable is False


def test_residue_modes_and_their_velocity_share():
    """A residue with a real part (non-proportional damping) is a mode whose
    displacement is eta + r eta'; a purely imaginary residue is a real mode."""
    import math

    from orient.dynamics import ModalSystem

    f, z = 500.0, 0.02
    wn = 2 * math.pi * f
    wd = wn * math.sqrt(1 - z * z)
    real_mode = ModalSystem.from_residues([f], [z], [-1j / (2 * 0.5 * wd)], [(1, 0, 0)])
    assert real_mode.velocity_s[0] == 0.0
    assert real_mode.m_kg[0] == pytest.approx(0.5)
    assert real_mode.natural_frequency_rad_s[0] == pytest.approx(wn)
    cplx = ModalSystem.from_residues([f], [z], [2e-5 - 1e-4j], [(0, 2, 0)])
    w = np.array([0.3, 1.0, 1.7]) * wn
    p = complex(-z * wn, wd)
    r = 2e-5 - 1e-4j
    expect = r / (1j * w - p) + np.conj(r) / (1j * w - np.conj(p))
    np.testing.assert_allclose(cplx.frf(w)[:, 1, 1], expect, rtol=1e-12)
    both = ModalSystem.combine(real_mode, cplx)
    np.testing.assert_array_equal(both.velocity_s, [0.0, cplx.velocity_s[0]])
    assert both.with_tool_axis((0, 0.6, 0.8)).velocity_s[1] == cplx.velocity_s[0]
    with pytest.raises(ValueError, match="alpha"):
        ModalSystem.from_residues([f], [z], [1e-4j], [(1, 0, 0)])


def test_a_system_unpickled_keeps_its_arrays_read_only():
    """A system sent to a Dask worker and back is the same, read-only as built (the numba
    kernels type read-only and writable arrays apart: one compiled version for both)."""
    import pickle

    system = ModalSystem.from_modes([(Mode.from_frequency(800.0, 0.03, 2e7), (1, 0, 0)),
                                     (Mode.from_frequency(2500.0, 0.01, 5e7), (0, 1, 0))])
    back = pickle.loads(pickle.dumps(system))
    for name in ("k_N_m", "m_kg", "c_Ns_m", "direction", "velocity_s"):
        np.testing.assert_array_equal(getattr(back, name), getattr(system, name))
        assert not getattr(back, name).flags.writeable
