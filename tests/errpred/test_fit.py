"""python -m errpred fit: a force law's coefficients from mean forces (errpred.fit,
errpred.fit_files, errpred.cli).

Synthetic tests are made by the forward model (errpred.fit.mean_force) with seeded
Gaussian noise of 1 N on each component (12 tests, forces 10-700 N); the fit must
recover every coefficient within 4 of its standard errors, and those must show that
the tests determine it: below 2 % of a tangential or radial chip/specific-force
coefficient, 4 % of an axial one (the axial forces are the smallest, 10-130 N, against
the same noise), 0.015 for an exponent and 0.5 N/mm for an edge coefficient. Without
noise, to 1e-6.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from errpred.cli import main
from errpred.coefficients import CuttingCoefficients
from errpred.fit import MeanForceTest, fit_law, mean_force, slot_force_linear
from errpred.fit_files import FitFileError, read_tests
from errpred.laws.kienzle import KienzleCoefficients
from errpred.scenario import ScenarioError, cutting_coefficients

LIN = CuttingCoefficients(Ktc_N_mm2=2000.0, Krc_N_mm2=700.0, Kac_N_mm2=300.0,
                          Kte0_N_mm=20.0, Kre0_N_mm=25.0, Kae0_N_mm=5.0)
KZ = KienzleCoefficients(kc11_t_N_mm2=2200.0, kc11_r_N_mm2=900.0, kc11_a_N_mm2=350.0,
                         mc_t=0.24, mc_r=0.3, mc_a=0.2)
FEEDS = (0.03, 0.05, 0.08, 0.12)
CUTS = (("slot", 10.0), ("down", 3.0), ("up", 3.0))


def _tests(c, noise_N, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for fz in FEEDS:
        for mode, ae in CUTS:
            t = MeanForceTest(fz, 2.0, ae, mode, 10.0, 3, (0.0, 0.0, 0.0))
            f = mean_force(c, t) + rng.normal(0.0, noise_N, 3)
            out.append(MeanForceTest(fz, 2.0, ae, mode, 10.0, 3, tuple(f)))
    return out


def _check(res, true, names):
    got = res.coefficients.as_dict()
    ref = true.as_dict()
    for n in names:
        se = res.std_error[n]
        assert abs(got[n] - ref[n]) < 4 * se, n
        if n.startswith("mc_"):
            assert se < 0.015, n
        elif n.startswith(("Kte0", "Kre0", "Kae0")):
            assert se < 0.5, n
        elif n.startswith(("Kac", "kc11_a")):
            assert se < 0.04 * abs(ref[n]), n
        else:
            assert se < 0.02 * abs(ref[n]), n


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_linear_fit_recovers_the_coefficients_from_noisy_tests(seed):
    res = fit_law("linear", _tests(LIN, 1.0, seed))
    _check(res, LIN, res.names)
    assert 0.5 < res.rms_N < 1.5 and res.residual_N.shape == (12, 3)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kienzle_fit_recovers_the_coefficients_from_noisy_tests(seed):
    res = fit_law("kienzle", _tests(KZ, 1.0, seed))
    _check(res, KZ, res.names)
    assert 0.5 < res.rms_N < 1.5


@pytest.mark.parametrize("law, true", [("linear", LIN), ("kienzle", KZ)])
def test_fits_without_noise_are_exact(law, true):
    res = fit_law(law, _tests(true, 0.0))
    got, ref = res.coefficients.as_dict(), true.as_dict()
    for n in res.names:
        assert got[n] == pytest.approx(ref[n], rel=1e-6, abs=1e-6), n
    assert res.rms_N < 1e-6


def test_linear_fit_of_closed_form_slot_forces():
    """Slots at four feeds from Altintas' closed form (not the forward model)."""
    tests = [MeanForceTest(fz, 2.0, 10.0, "slot", 10.0, 3,
                           tuple(slot_force_linear(LIN, fz, 2.0, 3))) for fz in FEEDS]
    res = fit_law("linear", tests)
    got, ref = res.coefficients.as_dict(), LIN.as_dict()
    for n in res.names:
        assert got[n] == pytest.approx(ref[n], rel=1e-8), n


def test_a_kienzle_cut_fitted_linearly_leaves_structured_residuals():
    """The wrong law fits worse than the noise: the residuals tell."""
    tests = _tests(KZ, 1.0)
    assert fit_law("linear", tests).rms_N > 3 * fit_law("kienzle", tests).rms_N


def test_fit_refuses_what_it_cannot_identify():
    one_feed = [t for t in _tests(LIN, 1.0) if t.fz_mm == 0.05]
    with pytest.raises(ValueError, match="two feeds"):
        fit_law("linear", one_feed)
    with pytest.raises(ValueError, match="kappa"):
        fit_law("lee-altintas", _tests(LIN, 1.0))
    with pytest.raises(ValueError, match="unknown"):
        fit_law("taylor", _tests(LIN, 1.0))
    with pytest.raises(ValueError, match="ae_mm"):
        MeanForceTest(0.1, 2.0, 12.0, "down", 10.0, 3, (0, 0, 0))
    with pytest.raises(ValueError, match="force"):
        MeanForceTest(0.1, 2.0, 5.0, "down", 10.0, 3, (0, math.nan, 0))


# --- the files and the command ----------------------------------------------------

def _csv(tests, mode_column=True):
    head = "fz_mm,ap_mm,ae_mm,mode,diameter_mm,teeth,rpm,Fx_N,Fy_N,Fz_N"
    rows = ["# synthetic", head if mode_column else head.replace("mode,", "")]
    for t in tests:
        ae = "slot" if t.mode == "slot" else f"{t.ae_mm!r}"
        mode = f"{t.mode}," if mode_column else ""
        rows.append(f"{t.fz_mm!r},{t.ap_mm!r},{ae},{mode}{t.diameter_mm!r},{t.teeth},3000,"
                    + ",".join(repr(x) for x in t.force_N))
    return "\n".join(rows) + "\n"


def test_command_fits_and_writes_a_table_the_scenario_loader_reads(tmp_path, capsys):
    tests = _tests(KZ, 1.0)
    src = tmp_path / "tests.csv"
    src.write_text(_csv(tests))
    assert read_tests(src)[4].force_N == tests[4].force_N
    out = tmp_path / "cutting.toml"
    assert main(["fit", str(src), "--law", "kienzle", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "kc11_t_N_mm2" in printed and "measured - model" in printed
    table = tomllib.loads(out.read_text())["cutting"]
    assert table["law"] == "kienzle"
    c = cutting_coefficients(table, out)
    assert isinstance(c, KienzleCoefficients)
    assert c == fit_law("kienzle", tests).coefficients
    assert "12 mean-force tests" in c.source


def test_command_prints_the_table_without_output(tmp_path, capsys):
    src = tmp_path / "tests.csv"
    src.write_text(_csv([t for t in _tests(LIN, 1.0) if t.mode != "up"], mode_column=False))
    assert main(["fit", str(src), "-q"]) == 0
    table = tomllib.loads(capsys.readouterr().out)["cutting"]
    assert table["law"] == "linear" and abs(table["Ktc_N_mm2"] / 2000.0 - 1) < 0.02


@pytest.mark.parametrize("edit, message", [
    (lambda s: s.replace("fz_mm,", "fz,"), "unknown column 'fz'"),
    (lambda s: s.replace(",teeth,", ",").replace(",3,3000,", ",3000,"), "missing column"),
    (lambda s: s.replace("0.03,2.0,slot", "0.03,2.0,wide", 1), ":3: ae_mm: expected a number"),
    (lambda s: s.replace("0.05,2.0,slot", "-0.05,2.0,slot", 1), ":6: fz_mm"),
    (lambda s: s.replace(",3,3000,", ",2.5,3000,", 1), ":3: teeth"),
    (lambda s: s.replace(",3000,", ",3000,nan,", 1), ":3: 11 cells"),
    (lambda s: s.splitlines()[1] + "\n", "no test below the header"),
])
def test_bad_tests_files_are_refused_naming_file_line_and_column(tmp_path, capsys, edit,
                                                                   message):
    src = tmp_path / "tests.csv"
    src.write_text(edit(_csv(_tests(LIN, 1.0))))
    with pytest.raises(FitFileError, match="tests.csv"):
        read_tests(src)
    out = tmp_path / "cutting.toml"
    assert main(["fit", str(src), "-o", str(out)]) != 0
    err = capsys.readouterr().err
    assert message in err and "tests.csv" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_a_fit_a_scenario_would_refuse_is_not_written(tmp_path, capsys):
    """Ktc must be > 0 in a scenario: forces that fit a negative Ktc are refused."""
    flipped = [MeanForceTest(t.fz_mm, t.ap_mm, t.ae_mm, t.mode, t.diameter_mm, t.teeth,
                             (t.force_N[0], -t.force_N[1], t.force_N[2]))
               for t in _tests(LIN, 0.0)]
    src = tmp_path / "tests.csv"
    src.write_text(_csv(flipped))
    out = tmp_path / "cutting.toml"
    assert main(["fit", str(src), "-o", str(out)]) != 0
    assert "Ktc_N_mm2" in capsys.readouterr().err and not out.exists()
    with pytest.raises(ScenarioError):
        cutting_coefficients({"law": "linear", "Ktc_N_mm2": -1.0, "Krc_N_mm2": 1.0,
                              "Kac_N_mm2": 1.0, "Kte0_N_mm": 1.0, "Kre0_N_mm": 1.0,
                              "Kae0_N_mm": 1.0}, "x.toml")
