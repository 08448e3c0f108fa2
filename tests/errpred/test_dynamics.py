"""Tests of errpred.dynamics: compliance models, FRF files, periodic deflection."""

from __future__ import annotations

import math
import os

import control
import numpy as np
import pytest
import pyuff
from scipy import signal

from errpred.dynamics import Compliance, FRFDataError, Mode

TWO_PI = 2.0 * math.pi


def angles(n):
    return TWO_PI * np.arange(n) / n


def two_dir_modal():
    return Compliance.from_modes({
        "x": [Mode.from_frequency(700.0, 0.03, 2.0e7), Mode.from_frequency(1900.0, 0.05, 6.0e7)],
        "y": [Mode.from_frequency(850.0, 0.04, 2.5e7)],
    })


def pulse_force(n, teeth=2, f0=(150.0, -60.0)):
    """Intermittent cut: half-sine force pulses, one per tooth, shape (n, 2)."""
    s = np.maximum(np.sin(teeth * angles(n)), 0.0)
    return np.stack([f0[0] * s, f0[1] * s], axis=1)


def write_csv(path, f, g, sep=",", unit="m", comment=True):
    fac = {"m": 1.0, "mm": 1e3, "um": 1e6}[unit]
    with open(path, "w") as fh:
        if comment:
            fh.write("# synthetic FRF\n")
        fh.write(sep.join(["frequency_hz", f"real_{unit}_N", f"imag_{unit}_N"]) + "\n")
        fh.writelines(sep.join([repr(float(fi)), repr(float(gi.real * fac)),
                                repr(float(gi.imag * fac))]) + "\n" for fi, gi in zip(f, g))


def uff_record(f, g, rsp_dir, ref_dir=None, func_type=4, num="m", den="N", spec=8):
    return pyuff.prepare_58(
        binary=0, func_type=func_type, rsp_node=1, rsp_dir=rsp_dir, ref_node=1,
        ref_dir=rsp_dir if ref_dir is None else ref_dir, abscissa_spec_data_type=18,
        abscissa_axis_units_lab="Hz", ordinate_spec_data_type=spec,
        ordinate_axis_units_lab=num, orddenom_spec_data_type=13, orddenom_axis_units_lab=den,
        data=np.asarray(g, dtype=complex), x=np.asarray(f, dtype=float))


def write_uff(path, sets):
    if os.path.exists(path):
        os.remove(path)
    pyuff.UFF(os.fspath(path)).write_sets(sets, mode="add")


# ---------------------------------------------------------------- Mode
def test_mode_from_frequency_and_properties():
    m = Mode.from_frequency(1234.0, 0.037, 3.0e7)
    assert m.natural_frequency_hz == pytest.approx(1234.0, rel=1e-12)
    assert m.damping_ratio == pytest.approx(0.037, rel=1e-12)
    assert m.m_kg == pytest.approx(3.0e7 / (TWO_PI * 1234.0) ** 2, rel=1e-12)


@pytest.mark.parametrize("field,args", [("k_N_m", (0.0, 1.0, 1.0)), ("m_kg", (1.0, -1.0, 1.0)),
                                        ("c_Ns_m", (1.0, 1.0, -0.1)),
                                        ("k_N_m", (math.nan, 1.0, 1.0)),
                                        ("m_kg", (1.0, math.inf, 1.0))])
def test_mode_validation_names_field(field, args):
    with pytest.raises(ValueError, match=field):
        Mode(*args)


def test_mode_rejects_non_number():
    with pytest.raises(TypeError, match="c_Ns_m"):
        Mode(1.0, 1.0, "0.1")


# ---------------------------------------------------------------- 1. quasi-static
def test_stiff_mode_gives_static_deflection():
    spindle, teeth = 6000.0, 2
    f_tooth = spindle / 60.0 * teeth
    k = 5.0e7
    comp = Compliance.from_modes({"x": [Mode.from_frequency(50 * f_tooth, 0.03, k)],
                                  "y": [Mode.from_frequency(50 * f_tooth, 0.03, 2 * k)]})
    n = 128
    th = angles(n)
    fx = 100.0 + 80.0 * np.cos(teeth * th) + 30.0 * np.sin(2 * teeth * th + 0.3) \
        + 10.0 * np.cos(3 * teeth * th)
    fy = -40.0 + 60.0 * np.sin(teeth * th - 0.5)
    force = np.stack([fx, fy], axis=1)
    d = comp.deflection(force, spindle)
    static = force / np.array([k, 2 * k]) * 1000.0
    for j in range(2):
        err = np.max(np.abs(d[:, j] - static[:, j]))
        assert err <= 0.01 * np.max(np.abs(static[:, j])), (j, err)
    # and the static compliance property is sum 1/k
    assert comp.static_compliance_m_N == pytest.approx({"x": 1 / k, "y": 0.5 / k}, rel=1e-12)


# ---------------------------------------------------------------- 2. resonance
def test_resonance_amplitude_and_90_degree_lag():
    spindle = 6000.0                              # 100 Hz: f_n = 1000 Hz is harmonic 10
    zeta, k, f0, harm, n = 0.05, 2.0e7, 50.0, 10, 64
    comp = Compliance.from_modes({"x": [Mode.from_frequency(1000.0, zeta, k)],
                                  "y": [Mode.from_frequency(1730.0, 0.02, k)]})
    th = angles(n)
    force = np.zeros((n, 2))
    force[:, 0] = f0 * np.cos(harm * th + 0.7)
    d = comp.deflection(force, spindle)[:, 0]
    dh, fh = np.fft.rfft(d)[harm], np.fft.rfft(force[:, 0])[harm]
    amp_mm = 2.0 * abs(dh) / n
    expected_mm = f0 / (2.0 * zeta * k) * 1000.0
    assert amp_mm == pytest.approx(expected_mm, rel=0.005)
    lag_deg = math.degrees((np.angle(fh) - np.angle(dh)) % TWO_PI)
    assert abs(lag_deg - 90.0) <= 1.0
    # the time signal itself: a sine lagging the cosine force
    assert np.allclose(d, expected_mm * np.sin(harm * th + 0.7), atol=1e-3 * expected_mm)
    assert np.allclose(comp.deflection(force, spindle)[:, 1], 0.0)


def test_periodic_deflection_matches_time_integration():
    # independent reference: integrate m x'' + c x' + k x = F(t) to steady state
    spindle, n, revs = 3000.0, 512, 20
    mode = Mode.from_frequency(230.0, 0.05, 1.0e7)
    comp = Compliance.from_modes({"x": [mode]})
    period = 60.0 / spindle
    fine = 4 * n
    t = np.arange(revs * fine + 1) * period / fine
    force_t = 150.0 * np.maximum(np.sin(2 * TWO_PI * t / period), 0.0)
    sys = signal.lti([1.0], [mode.m_kg, mode.c_Ns_m, mode.k_N_m])
    _, x, _ = signal.lsim(sys, force_t, t)
    ref_mm = x[-fine - 1:-1:4] * 1000.0                      # last revolution, n samples
    d = comp.deflection(pulse_force(n)[:, :1], spindle)[:, 0]
    assert np.max(np.abs(d - ref_mm)) <= 0.01 * np.max(np.abs(ref_mm))
    # the dynamic result differs from the static one here (the test can tell them apart)
    static = pulse_force(n)[:, 0] / mode.k_N_m * 1000.0
    assert np.max(np.abs(d - static)) > 0.1 * np.max(np.abs(static))


# ---------------------------------------------------------------- 3. multi-mode sum
def test_multimode_sum_and_python_control():
    xs = [Mode(2.0e7, 0.8, 250.0), Mode(6.0e7, 0.4, 300.0), Mode(1.5e8, 0.3, 900.0)]
    ys = [Mode(3.0e7, 1.1, 400.0), Mode(9.0e7, 0.2, 150.0)]
    comp = Compliance.from_modes({"y": ys, "x": xs})
    assert comp.directions == ("x", "y")
    w = np.array([0.0, 100.0, 3000.0, 5000.0, 8000.0, 15000.0, 21000.0, 60000.0])
    g = comp.response(w)
    assert g.shape == (w.size, 2)
    for j, ms in enumerate((xs, ys)):
        hand = sum(1.0 / (m.k_N_m - m.m_kg * w ** 2 + 1j * m.c_Ns_m * w) for m in ms)
        np.testing.assert_allclose(g[:, j], hand, rtol=1e-12)
    tfs = comp.transfer_functions()
    for j, d in enumerate(("x", "y")):
        fr = control.frequency_response(tfs[d], w[1:])     # >= 3 values: not read as limits
        np.testing.assert_allclose(g[1:, j], fr.complex, rtol=1e-9)
        np.testing.assert_allclose(g[:, j], tfs[d](1j * w), rtol=1e-9)
    np.testing.assert_allclose(comp.response(-w), np.conj(g), rtol=1e-15)


# ---------------------------------------------------------------- 4. FRF from files
def dense_grid():
    return np.arange(10.0, 5000.0 + 1e-9, 2.0)


def test_uff_round_trip_at_measured_frequencies(tmp_path):
    comp = two_dir_modal()
    f = dense_grid()
    path = tmp_path / "tip.uff"
    comp.to_uff(path, f)
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]
    meas = Compliance.from_uff(path)
    assert meas.kind == "measured" and meas.directions == ("x", "y")
    np.testing.assert_allclose(meas.response(TWO_PI * f), comp.response(TWO_PI * f),
                               rtol=1e-9, atol=0)
    # writing again replaces the file (no appended duplicate records)
    meas.to_uff(path)
    assert list(pyuff.UFF(os.fspath(path)).get_set_types()) == [58, 58]


@pytest.mark.parametrize("sep,unit", [(",", "m"), ("\t", "m"), (",", "mm"), ("\t", "um")])
def test_csv_round_trip(tmp_path, sep, unit):
    comp = two_dir_modal()
    f = dense_grid()
    g = comp.response(TWO_PI * f)
    paths = {}
    for j, d in enumerate(comp.directions):
        paths[d] = tmp_path / f"{d}.txt"
        write_csv(paths[d], f, g[:, j], sep=sep, unit=unit)
    meas = Compliance.from_csv(paths)
    np.testing.assert_allclose(meas.response(TWO_PI * f), g, rtol=1e-12)


def g2_abs(modes, f):
    """|d^2 G / d f^2| [m/N/Hz^2] of a modal sum (analytic)."""
    w = TWO_PI * f
    total = 0.0
    for m in modes:
        dd = m.k_N_m - m.m_kg * w ** 2 + 1j * m.c_Ns_m * w
        d1 = -2.0 * m.m_kg * w + 1j * m.c_Ns_m
        total = total + (2.0 * d1 ** 2 + 2.0 * m.m_kg * dd) / dd ** 3
    return np.abs(total) * TWO_PI ** 2


def test_interpolation_within_linear_error_bound():
    # |error| <= h^2/8 max|G''| over the bracketing interval, for Re and Im alike
    comp = two_dir_modal()
    h = 10.0
    f = np.arange(20.0, 4000.0 + 1e-9, h)
    meas = Compliance.from_frf(f, {d: comp.response(TWO_PI * f)[:, j]
                                   for j, d in enumerate(comp.directions)})
    rng = np.random.default_rng(3)
    fq = np.concatenate([f[:-1] + h / 2, rng.uniform(f[0], f[-1], 300)])
    err = meas.response(TWO_PI * fq) - comp.response(TWO_PI * fq)
    for j, d in enumerate(comp.directions):
        lo = f[np.clip(np.searchsorted(f, fq, side="right") - 1, 0, f.size - 2)]
        sub = lo[:, None] + h * np.linspace(0.0, 1.0, 41)[None, :]
        bound = h ** 2 / 8.0 * g2_abs(comp.modes[d], sub).max(axis=1) * 1.05
        assert np.all(np.abs(err[:, j].real) <= bound)
        assert np.all(np.abs(err[:, j].imag) <= bound)
        assert np.max(np.abs(err[:, j])) > 0                   # interpolation was exercised


def test_extrapolation_below_and_above_band():
    f = np.array([20.0, 30.0, 100.0])
    g = np.array([1e-7 + 2e-9j, 1.1e-7 + 5e-9j, -3e-8 - 1e-8j])
    held = Compliance.from_frf(f, {"x": g})
    assert held.notes and "held" in held.notes[0]
    blended = Compliance.from_frf(f, {"x": g}, static_m_N={"x": 0.9e-7})
    assert not blended.notes
    w = TWO_PI * np.array([0.0, 10.0, 20.0, 200.0, 400.0])
    gh, gb = held.response(w)[:, 0], blended.response(w)[:, 0]
    np.testing.assert_allclose(gh[:3], g[0])
    np.testing.assert_allclose(gb[:3], [0.9e-7, 0.9e-7 + (g[0] - 0.9e-7) / 2, g[0]])
    # above the band: the last value decaying as 1/omega^2 (continuous at 100 Hz)
    np.testing.assert_allclose(gh[3:], g[-1] * np.array([0.25, 0.0625]))
    assert blended.static_compliance_m_N["x"] == pytest.approx(0.9e-7)
    np.testing.assert_allclose(blended.response(-w), np.conj(blended.response(w)))


def test_deflection_from_dense_measured_frf_matches_modal(tmp_path):
    comp = two_dir_modal()
    path = tmp_path / "tip.uff"
    comp.to_uff(path, dense_grid())
    meas = Compliance.from_uff(path, static_m_N=comp.static_compliance_m_N)
    for spindle in (5130.0, 11870.0):      # harmonics between and (partly) beyond the grid
        force = pulse_force(128)
        d_ref = comp.deflection(force, spindle)
        d = meas.deflection(force, spindle)
        for j in range(2):
            assert np.max(np.abs(d[:, j] - d_ref[:, j])) <= 0.02 * np.max(np.abs(d_ref[:, j]))


def test_uff_direction_by_dof_fields_units_and_sign(tmp_path):
    f = np.arange(10.0, 200.0, 10.0)
    gx = (1.0 + 0.5j) * 1e-7 / (1 + f / 100)
    gy = (2.0 - 0.3j) * 1e-7 / (1 + f / 50)
    coh = np.ones(f.size, dtype=complex)
    path = tmp_path / "mixed.unv"
    write_uff(path, [uff_record(f, gy * 1e6, 2, num="µm"),        # y first, in um/N
                     uff_record(f, coh, 1, func_type=6),          # coherence: skipped
                     uff_record(f, -gx * 1e3, -1, 1, num="mm/N", den="NONE"),  # -X/+X, mm/N
                     uff_record(f, gx, 1, 2)])                    # cross FRF: skipped
    c = Compliance.from_uff(path)
    assert c.directions == ("x", "y")
    np.testing.assert_allclose(c.response(TWO_PI * f), np.stack([gx, gy], 1), rtol=1e-10)
    assert any("record 1" in n and "function type 6" in n for n in c.notes)
    assert any("record 3" in n and "cross" in n for n in c.notes)
    # explicit mapping by record index overrides the DOF fields
    c2 = Compliance.from_uff(path, directions={"x": 0, "y": 3})
    np.testing.assert_allclose(c2.response(TWO_PI * f), np.stack([gy, gx], 1), rtol=1e-10)
    with pytest.raises(FRFDataError, match=r"mixed\.unv, record 1: function type 6"):
        Compliance.from_uff(path, directions={"x": 1})
    with pytest.raises(FRFDataError, match=r"mixed\.unv: direction 'y': record 4 is not"):
        Compliance.from_uff(path, directions={"x": 0, "y": 4})


# pyuff's binary writer leaves a file handle open (its bug, not ours)
@pytest.mark.filterwarnings("ignore::ResourceWarning",
                            "ignore::pytest.PytestUnraisableExceptionWarning")
def test_uff_binary_record(tmp_path):
    f = np.arange(10.0, 100.0, 10.0)
    g = (1.0 + 2.0j) * 1e-7 / (1.0 + f / 30.0)
    rec = uff_record(f, g, 2)
    rec["binary"] = 1
    write_uff(tmp_path / "bin.uff", [rec])
    c = Compliance.from_uff(tmp_path / "bin.uff")
    assert c.directions == ("y",)
    np.testing.assert_array_equal(c.response(TWO_PI * f)[:, 0], g)


def test_uff_two_records_same_direction_is_ambiguous(tmp_path):
    f = np.arange(10.0, 100.0, 10.0)
    g = np.full(f.size, 1e-7 + 0j)
    path = tmp_path / "dup.uff"
    write_uff(path, [uff_record(f, g, 1), uff_record(f, 2 * g, 1)])
    with pytest.raises(FRFDataError, match=r"record 1: a second direct FRF"):
        Compliance.from_uff(path)


# ---------------------------------------------------------------- 5. bad input
def test_csv_errors_name_file_line_column(tmp_path):
    good = "frequency_hz,real_m_N,imag_m_N\n10,1e-7,0\n20,1.1e-7,-1e-9\n"
    cases = {
        "word.csv": (good + "30,abc,0\n",
                     r"word\.csv, line 4, column 2: real_m_N: 'abc' is not a number"),
        "nan.csv": (good + "30,1e-7,nan\n",
                    r"nan\.csv, line 4, column 3: imag_m_N: 'nan' is not finite"),
        "short.csv": (good + "30,1e-7\n",
                      r"short\.csv, line 4, column 3: missing value for 'imag_m_N'"),
        "nohead.csv": ("# c\n10,1e-7,0\n", r"nohead\.csv, line 2: expected a header"),
        "nocol.csv": ("frequency_hz,real_m_N\n10,1e-7\n", r"nocol\.csv, line 1: expected a header"),
        "order.csv": (good + "15,1e-7,0\n", r"order\.csv, line 4, column 1: frequency 15\.0 Hz"),
        "empty.csv": ("frequency_hz,real_m_N,imag_m_N\n10,1,0\n", r"empty\.csv: need a header"),
    }
    for name, (text, msg) in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(FRFDataError, match=msg):
            Compliance.from_csv({"x": tmp_path / name})
    with pytest.raises(ValueError, match=r"missing\.csv: no such file"):
        Compliance.from_csv({"x": tmp_path / "missing.csv"})


def test_uff_errors(tmp_path):
    with pytest.raises(ValueError, match=r"nothere\.uff: no such file"):
        Compliance.from_uff(tmp_path / "nothere.uff")
    nodes = tmp_path / "nodes.uff"
    write_uff(nodes, [pyuff.prepare_15(node_nums=[1], def_cs=[0], disp_cs=[0], color=[1],
                                       x=[0.0], y=[0.0], z=[0.0])])
    with pytest.raises(ValueError, match=r"nodes\.uff: no type-58 .* found: \[15\]"):
        Compliance.from_uff(nodes)
    f = np.arange(10.0, 60.0, 10.0)
    timeresp = tmp_path / "time.uff"
    write_uff(timeresp, [uff_record(f, np.ones(f.size, complex), 1, func_type=1)])
    with pytest.raises(ValueError, match=r"time\.uff: no direct .*record 0: skipped .*type 1"):
        Compliance.from_uff(timeresp)
    with pytest.raises(ValueError, match=r"time\.uff, record 0: function type 1"):
        Compliance.from_uff(timeresp, directions={"x": 0})
    # NaN in the data (pyuff will not write one: patch the text)
    good = tmp_path / "g.uff"
    write_uff(good, [uff_record(f, np.full(f.size, 1e-7 + 1e-8j), 1)])
    lines = good.read_text().splitlines()
    lines[14] = lines[14][:13] + f"{'NaN':>20s}" + lines[14][33:]   # data point 1
    bad = tmp_path / "nan.uff"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"nan\.uff, record 0: non-finite value at point 1"):
        Compliance.from_uff(bad)
    accel = tmp_path / "accel.uff"
    write_uff(accel, [uff_record(f, np.ones(f.size, complex), 1, spec=12, num="m/s^2")])
    with pytest.raises(ValueError, match=r"accel\.uff, record 0: ordinate is acceleration"):
        Compliance.from_uff(accel)
    inch = tmp_path / "inch.uff"
    write_uff(inch, [uff_record(f, np.ones(f.size, complex), 1, num="in")])
    with pytest.raises(ValueError, match=r"inch\.uff, record 0: ordinate units 'in'"):
        Compliance.from_uff(inch)


@pytest.mark.parametrize("rpm", [0.0, -100.0, math.nan, math.inf])
def test_bad_spindle(rpm):
    with pytest.raises(ValueError, match="spindle_rpm"):
        two_dir_modal().deflection(np.ones((8, 2)), rpm)


@pytest.mark.parametrize("shape,msg", [((7, 2), "even number >= 4"), ((2, 2), "even number >= 4"),
                                       ((8, 3), r"shape \(\.\.\., n, 2\)"), ((8,), "shape")])
def test_bad_force_shape(shape, msg):
    with pytest.raises(ValueError, match=msg):
        two_dir_modal().deflection(np.ones(shape), 6000.0)


def test_bad_force_values_and_constructors():
    comp = two_dir_modal()
    f = np.ones((8, 2))
    f[3, 1] = math.nan
    with pytest.raises(ValueError, match="non-finite"):
        comp.deflection(f, 6000.0)
    with pytest.raises(ValueError, match="directions"):
        Compliance.from_modes({"u": [Mode(1.0, 1.0, 0.0)]})
    with pytest.raises(ValueError, match="'y'"):
        Compliance.from_modes({"x": [Mode(1.0, 1.0, 0.0)], "y": []})
    with pytest.raises(ValueError, match="strictly increasing"):
        Compliance.from_frf([10.0, 10.0, 20.0], {"x": [1e-7, 1e-7, 1e-7]})
    with pytest.raises(ValueError, match="non-finite value at point 1"):
        Compliance.from_frf([10.0, 20.0], {"x": [1e-7, math.nan]})
    meas = Compliance.from_frf([10.0, 20.0], {"x": [1e-7, 1e-7]})
    with pytest.raises(ValueError, match="measured FRF has no transfer function"):
        meas.transfer_functions()
    with pytest.raises(ValueError, match="freq_hz is required"):
        comp.to_uff("unused.uff")


# ---------------------------------------------------------------- 6. static model
def test_static_only_is_exactly_compliance_times_force():
    xs = [Mode.from_frequency(300.0, 0.05, 2.0e7), Mode.from_frequency(900.0, 0.02, 5.0e7)]
    ys = [Mode.from_frequency(500.0, 0.03, 4.0e7)]
    zs = [Mode.from_frequency(3000.0, 0.03, 4.0e8)]
    comp = Compliance.from_modes({"x": xs, "y": ys, "z": zs}, static_only=True)
    cstat = np.array([1 / 2.0e7 + 1 / 5.0e7, 1 / 4.0e7, 1 / 4.0e8])
    force = np.random.default_rng(7).normal(0.0, 100.0, (4, 96, 3))   # batch of 4
    np.testing.assert_allclose(comp.deflection(force, 12000.0), force * cstat * 1000.0,
                               rtol=1e-12, atol=1e-18)
    np.testing.assert_array_equal(comp.response([0.0, 1e4, 1e6]).imag, 0.0)
    tf = comp.transfer_functions()["x"]
    assert complex(tf(1j * 5000.0)) == pytest.approx(cstat[0], rel=1e-12)
    # the dynamic model of the same modes does differ
    dyn = Compliance.from_modes({"x": xs, "y": ys, "z": zs})
    assert not np.allclose(dyn.deflection(force, 12000.0), comp.deflection(force, 12000.0),
                           rtol=0.01)
