"""``python -m errpred``: called with argument lists, as a user types them."""

from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pytest

from nc import read_program
from errpred.cli import main
from errpred.scenario import bundled_scenario

WALL = str(bundled_scenario("wall-radius"))
PNG = b"\x89PNG\r\n\x1a\n"


def test_predict_writes_report_and_plots(tmp_path, capsys):
    rep, plots = tmp_path / "report.json", tmp_path / "plots"
    assert main(["predict", WALL, "--lines", "374", "385", "-o", str(rep),
                 "--plots", str(plots), "--revolution-line", "378"]) == 0
    out = capsys.readouterr().out
    assert "largest |error|" in out and "blocks/s" in out
    data = json.loads(rep.read_text())
    s = data["summary"]
    assert s["status_counts"]["predicted"] >= 8
    pts = [p for p in data["points"] if p["status"] == "predicted"]
    for key in ("line", "point_mm", "theta_m_deg", "kappa_m_deg", "normal", "peak_force_N",
                "mean_force_N", "deflection_um", "E_d_um", "E_p_um", "E_um",
                "cutting_distance_mm"):
        assert key in pts[0], key
    assert all(abs(p["E_um"] - p["E_d_um"] - p["E_p_um"]) < 1e-3 for p in pts)
    assert s["max_abs_error_um"] == pytest.approx(max(abs(p["E_um"]) for p in pts), abs=1e-3)
    nocut = [p for p in data["points"] if not p["cuts"]]
    assert nocut and all(p["reason"] for p in nocut)
    assert "E_design_um" in pts[0] and "against_design" in s
    names = sorted(os.listdir(plots))
    assert names == sorted(["error_along_program.png", "error_map.png",
                            "wear_per_micro_edge.png", "revolution_line378.png"])
    for n in names:
        assert (plots / n).read_bytes()[:8] == PNG


def test_compensate_writes_a_program_that_reads_back(tmp_path, capsys):
    out = tmp_path / "corrected.nc"
    # the third waterline level: lead-in, approach, the wall's straight block and its arc
    assert main(["compensate", WALL, "--lines", "38", "41", "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "verified on" in said and "no point worse than the original" in said
    orig = read_program(os.path.join(os.path.dirname(WALL), "finish.nc"))
    new = read_program(out)
    # every line of the original is there; split blocks add lines after their own
    assert len(new.lines) >= len(orig.lines) and new.lines[0] == orig.lines[0]
    # each original block end has a corrected one near it (micrometres away)
    d = np.linalg.norm(orig.end[:, None, :3] - new.end[None, :, :3], axis=2)
    moved = d.min(axis=1)
    assert moved.max() > 1e-3  # micrometres moved where it cut ...
    assert moved.max() < 0.2   # ... and nothing wild


def test_bad_scenarios_end_in_one_message_and_no_output(tmp_path, capsys):
    rep = tmp_path / "report.json"
    assert main(["predict", str(tmp_path / "missing.toml"), "-o", str(rep)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "missing.toml" in err and "Traceback" not in err
    # a copy of the bundled scenario with a NaN in it
    src = os.path.dirname(WALL)
    dst = tmp_path / "wall"
    shutil.copytree(src, dst)
    text = (dst / "scenario.toml").read_text().replace("diameter_mm = 20.0",
                                                       "diameter_mm = nan")
    (dst / "scenario.toml").write_text(text)
    assert main(["predict", str(dst / "scenario.toml"), "-o", str(rep)]) == 2
    err = capsys.readouterr().err
    assert "tool.diameter_mm" in err and "scenario.toml" in err
    assert not rep.exists()
    assert main(["predict", WALL, "--lines", "10", "5"]) == 2
    assert "--lines" in capsys.readouterr().err
    # a range beyond the program selects nothing: refused before any prediction
    assert main(["predict", WALL, "--lines", "100000", "100010", "-o", str(rep)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--lines" in err[0] and "no motion block" in err[0], err
    assert not rep.exists()
    out = tmp_path / "never.nc"
    assert main(["compensate", WALL, "-o", str(out), "--tolerance-um", "nan", "-q"]) == 2
    assert "--tolerance-um" in capsys.readouterr().err and not out.exists()
