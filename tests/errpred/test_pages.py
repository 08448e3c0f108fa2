"""The pages of ``python -m errpred predict`` and ``compensate``: written beside the other
outputs, self-contained, their tables agree with the JSON reports, and they open in
headless Chromium with every figure decoded (skipped, saying why, without Chromium)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from errpred.cli import main
from errpred.run_page import ErrorSet, is_wall
from errpred.scenario import bundled_scenario
from nc import read_program
from tests.chromium import open_page

WALL = str(bundled_scenario("wall-radius"))
MOLD = str(bundled_scenario("mold-ball"))


def _self_contained(text: str) -> None:
    assert "<script" not in text
    assert not re.search(r"""(src|href)=["'](?!data:)""", text)


def _rows(text: str, first_cell: str) -> list[list[str]]:
    """The rows of the table whose header starts with ``first_cell``."""
    i = text.index(f"<th>{first_cell}")
    table = text[i:text.index("</table>", i)]
    return [re.findall(r"<td>(.*?)</td>", r) for r in re.findall(r"<tr>(.*?)</tr>", table)
            if "<td>" in r]


def _opens(page, tmp_path, images: int) -> str:
    seen = open_page(page, tmp_path)
    assert seen["screenshot_bytes"] > 20_000
    assert "CONSOLE" not in seen["stderr"]
    assert seen["images"] == images and seen["broken"] == 0
    return seen["dom"]


def test_predict_page_of_a_wall_shows_it_unrolled_per_level(tmp_path):
    rep = tmp_path / "wall.json"
    # two waterline levels of the drafted boss (Z 23.5 and 23)
    assert main(["predict", WALL, "--lines", "374", "397", "-o", str(rep), "-q"]) == 0
    page = tmp_path / "wall.html"                  # beside the report
    text = page.read_text()
    _self_contained(text)
    assert "Unrolled wall" in text and "Error per waterline level" in text
    data = json.loads(rep.read_text())
    pts = [p for p in data["points"] if p["status"] == "predicted"]
    # one table row per level, tool tip Z descending, smallest .. largest E as in the JSON
    z = sorted({round(p["point_mm"][2], 3) for p in pts}, reverse=True)
    rows = _rows(text, "level: tool tip Z")
    assert [float(r[0]) for r in rows] == pytest.approx(z, abs=1e-3)
    for r, zk in zip(rows, z, strict=True):
        e = [p["E_um"] for p in pts if abs(p["point_mm"][2] - zk) < 1e-3]
        assert int(r[2]) == len(e)
        assert r[3] == f"{min(e):+.2f} .. {max(e):+.2f}"
    s = data["summary"]
    assert f"{s['max_abs_error_um']:.2f} um at line {s['max_error_at']['line']}" in text
    assert s["tool_change"]["advice"][1:] in text
    dom = _opens(page, tmp_path, images=3)        # error on the part, levels, revolution
    assert "Force and deflection over one revolution" in dom and "Tool change" in dom


def test_predict_page_of_a_free_form_surface_from_above_per_pass(tmp_path):
    rep = tmp_path / "mold.json"
    named = tmp_path / "pages" / "mold page.html"
    named.parent.mkdir()
    assert main(["predict", MOLD, "--lines", "19103", "19170", "-o", str(rep), "-q",
                 "--no-design", "--page", str(named)]) == 0
    assert not (tmp_path / "mold.html").exists()
    text = named.read_text()
    _self_contained(text)
    assert "Seen from above" in text and "Error per pass" in text
    data = json.loads(rep.read_text())
    prog = read_program(data["program"])
    passes = np.cumsum(prog.motion == 0)
    pts = [p for p in data["points"] if p["status"] == "predicted"]
    want = sorted({int(passes[p["block"]]) for p in pts})
    rows = _rows(text, "pass")
    assert len(rows) == len(want) >= 2
    for r, k in zip(rows, want, strict=True):
        e = [p["E_um"] for p in pts if passes[p["block"]] == k]
        assert int(r[2]) == len(e) and r[3] == f"{min(e):+.2f} .. {max(e):+.2f}"
    _opens(named, tmp_path, images=3)


def test_predict_no_page_writes_none_and_a_bad_page_path_is_refused_first(tmp_path):
    rep = tmp_path / "r.json"
    assert main(["predict", WALL, "--lines", "374", "385", "-o", str(rep), "-q",
                 "--no-design", "--no-page"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]
    for page in (str(rep), str(tmp_path / "missing" / "p.html")):
        assert main(["predict", WALL, "--lines", "374", "385", "-o", str(rep), "-q",
                     "--page", page]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.json"]


def test_compensate_page_shows_the_verified_error_before_and_after(tmp_path):
    out, rep = tmp_path / "corrected.nc", tmp_path / "verification.json"
    # the third waterline level's straight block along the wall
    assert main(["compensate", WALL, "--lines", "40", "40", "-o", str(out), "-q",
                 "--report", str(rep)]) == 0
    page = tmp_path / "corrected.html"
    text = page.read_text()
    _self_contained(text)
    v = json.loads(rep.read_text())["verification"]
    # the dense re-prediction's figures, not the fitted points'
    stats = {r[0]: r for r in _rows(text, "program")}
    for name, key in (("original", "before"), ("corrected", "after")):
        assert int(stats[name][1]) == v[key]["points"]
        assert float(stats[name][2]) == pytest.approx(v[key]["max_abs_um"], abs=0.006)
        assert float(stats[name][5]) == pytest.approx(v[key]["rms_um"], abs=0.006)
    level = _rows(text, "level: tool tip Z")
    assert len(level) == 1 and int(level[0][2]) == v["before"]["points"] \
        and int(level[0][5]) == v["after"]["points"]
    assert "before correction" in text and "after correction" in text
    dom = _opens(page, tmp_path, images=3)
    assert "Corrected, verified" in dom


def test_wall_or_free_form_from_the_normals():
    n = 50
    rng = np.random.default_rng(3)

    def errors(normal_z: float) -> ErrorSet:
        nz = np.full(n, normal_z) + rng.normal(0, 0.01, n)
        normal = np.stack([np.sqrt(1 - nz ** 2), np.zeros(n), nz], axis=1)
        z = np.zeros((n, 3))
        return ErrorSet(z, z, normal, np.zeros(n), np.ones(n, int), np.zeros(n, int))

    assert is_wall(errors(0.05))          # a 3 deg draft
    assert not is_wall(errors(0.5))       # a 60 deg flank
    assert not is_wall(ErrorSet(*(np.zeros((0, 3)),) * 3, np.zeros(0), np.zeros(0, int),
                                np.zeros(0, int)))
