"""Tool libraries (LinuxCNC .tbl, Fusion 360 JSON) and CutPro .frf files in scenarios."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from errpred.dynamics import Compliance, FRFDataError, Mode
from errpred.pipeline import predict
from errpred.scenario import ScenarioError, bundled_scenario, load_scenario
from errpred.tool import Holder, Tool
from errpred.toollib import ToolLibraryError, library_tool

INCH = 25.4

# A scenario around the [tool] table under test; everything else minimal and valid.
SCENARIO = """name = "lib"
[stock]
box_min_mm = [0.0, 0.0, -10.0]
box_max_mm = [60.0, 40.0, 0.0]
[tool]
{tool}
[program]
gcode = "prog.nc"
[cutting]
Ktc_N_mm2 = 3680.0
Krc_N_mm2 = 1470.0
Kac_N_mm2 = 550.0
Kte0_N_mm = 37.7
Kre0_N_mm = 45.2
Kae0_N_mm = 11.3
[dynamics]
{dynamics}
"""
MODES = """[[dynamics.modes]]
direction = "x"
frequency_hz = 2000.0
damping_ratio = 0.03
stiffness_N_m = 6.0e6
[[dynamics.modes]]
direction = "y"
frequency_hz = 2100.0
damping_ratio = 0.03
stiffness_N_m = 6.5e6"""


def fusion(*tools, version=36):
    return json.dumps({"data": list(tools), "version": version})


def ftool(number, kind="flat end mill", unit="millimeters", holder=None, **geometry):
    t = {"type": kind, "unit": unit, "description": f"tool {number}",
         "guid": f"g{number}", "geometry": geometry,
         "post-process": {"number": number, "diameter-offset": number,
                          "length-offset": number, "comment": ""}}
    if holder is not None:
        t["holder"] = holder
    return t


def segs(unit, *hlu):
    return {"type": "holder", "unit": unit, "description": "holder",
            "segments": [{"height": h, "lower-diameter": lo, "upper-diameter": up}
                         for h, lo, up in hlu]}


def write_scenario(tmp_path: Path, tool: str, files: dict, dynamics: str = MODES) -> Path:
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    (tmp_path / "prog.nc").write_text("G21 G90\nS8000 M3\nG0 X0 Y0 Z5\nG1 Z-1 F300\nM30\n")
    path = tmp_path / "scenario.toml"
    path.write_text(SCENARIO.format(tool=tool, dynamics=dynamics))
    return path


# --------------------------------------------------------------------------- known-good pairs
#: (id, library file name, its text, [tool] keys beside it, the Tool it must give)
GOOD = [
    ("tbl-mm-flat", "tools.tbl",
     "T1 P1 D6.000 Z+0.000 ;6 mm flat\nT2 P2 D10 ;other\n",
     'library = "tools.tbl"\nnumber = 1\nlibrary_units = "mm"\ntype = "flat"\nflutes = 4\n'
     'helix_deg = 35.0\nflute_length_mm = 12.0',
     Tool("flat", 6.0, 0.0, 4, 35.0, flute_length_mm=12.0)),
    ("tbl-inch-ball", "tools.tbl",
     "; mill tools\n\nT7 P3 D0.250 X+0.1 Z+1.500000 ;1/4 ball\n",
     'library = "tools.tbl"\nnumber = 7\nlibrary_units = "inch"\ntype = "ball"\nflutes = 2\n'
     'helix_deg = 30.0\nflute_length_mm = 12.7',
     Tool("ball", 0.25 * INCH, 0.125 * INCH, 2, 30.0, flute_length_mm=12.7)),
    ("tbl-lowercase-bull", "t.tbl",
     "t3  p3   d10.  z-1.0 q0 ;bull\n",
     'library = "t.tbl"\nnumber = 3\nlibrary_units = "mm"\ntype = "radius"\n'
     'corner_radius_mm = 0.5\nflutes = 3\nhelix_deg = 40.0\nflute_length_mm = 25.0\n'
     'overhang_mm = 60.0',
     Tool("radius", 10.0, 0.5, 3, 40.0, flute_length_mm=25.0, overhang_mm=60.0)),
    ("fusion-mm-ball", "tools.json",
     fusion(segs("millimeters", (10, 8, 8)) | {"guid": "h"},
            ftool(5, "drill", DC=5.0, NOF=2),
            ftool(3, "ball end mill", DC=10.0, NOF=2, LCF=20.0, LB=40.0, SFDM=10.0, OAL=75.0,
                  holder=segs("millimeters", (30.0, 24.0, 24.0), (50.0, 24.0, 32.0)))),
     'library = "tools.json"\nnumber = 3\nhelix_deg = 30.0',
     Tool("ball", 10.0, 5.0, 2, 30.0, flute_length_mm=20.0, overhang_mm=40.0,
          shank_diameter_mm=10.0, holder=Holder(32.0, 80.0))),
    ("fusion-inch-bull-mm-holder", "lib.json",
     fusion(ftool(12, "bull nose end mill", "inches", DC=0.5, RE=0.03125, NOF=4, LCF=1.0,
                  LB=2.0, SFDM=0.5, holder=segs("millimeters", (40.0, 30.0, 44.0)))),
     'library = "lib.json"\nnumber = 12\nhelix_deg = 45.0',
     Tool("radius", 0.5 * INCH, 0.03125 * INCH, 4, 45.0, flute_length_mm=1.0 * INCH,
          overhang_mm=2.0 * INCH, shank_diameter_mm=0.5 * INCH, holder=Holder(44.0, 40.0))),
    ("fusion-inch-holder-inch", "lib.json",
     fusion(ftool(1, "flat end mill", "inches", DC=0.375, RE=0.0, NOF=3, LCF=0.75, LB=1.5,
                  holder=segs("inches", (1.0, 1.0, 1.25), (0.5, 1.5, 1.5)))),
     'library = "lib.json"\nnumber = 1\nhelix_deg = 30.0',
     Tool("flat", 0.375 * INCH, 0.0, 3, 30.0, flute_length_mm=0.75 * INCH,
          overhang_mm=1.5 * INCH, holder=Holder(1.5 * INCH, 1.5 * INCH))),
    ("fusion-overridden", "tools.json",
     fusion(ftool(2, "flat end mill", DC=8.0, NOF=2, LCF=16.0, LB=30.0,
                  holder=segs("millimeters", (20.0, 30.0, 30.0)))),
     'library = "tools.json"\nnumber = 2\nhelix_deg = 30.0\nflutes = 3\noverhang_mm = 35.0\n'
     'rotation = "ccw"\n[tool.holder]\ndiameter_mm = 20.0\nlength_mm = 50.0',
     Tool("flat", 8.0, 0.0, 3, 30.0, flute_length_mm=16.0, overhang_mm=35.0, rotation="ccw",
          holder=Holder(20.0, 50.0))),
]


@pytest.mark.parametrize("case", GOOD, ids=[c[0] for c in GOOD])
def test_library_tool_is_the_expected_tool(tmp_path, case):
    _, name, text, keys, want = case
    s = load_scenario(write_scenario(tmp_path, keys, {name: text}))
    got = s.tool
    for f in dataclasses.fields(Tool):
        a, b = getattr(got, f.name), getattr(want, f.name)
        if isinstance(b, float):
            assert a == pytest.approx(b, rel=1e-12, abs=1e-12), f.name
        elif isinstance(b, Holder):
            assert (a.diameter_mm, a.length_mm) == pytest.approx((b.diameter_mm, b.length_mm),
                                                                 rel=1e-12), f.name
        else:
            assert a == b, f.name


def test_library_values_in_millimetres(tmp_path):
    p = tmp_path / "lib.json"
    p.write_text(GOOD[4][2])
    t = library_tool(p, 12)
    assert t.values["diameter_mm"] == pytest.approx(12.7)
    assert t.values["corner_radius_mm"] == pytest.approx(0.79375)
    assert t.values["holder"] == {"diameter_mm": 44.0, "length_mm": 40.0}
    assert t.where == "data[0]" and t.format == "Fusion 360 tool library"
    (tmp_path / "t.tbl").write_text("T4 P1 D0.5 Z2.0 X0.1 A15 ;half inch\n")
    t = library_tool(tmp_path / "t.tbl", 4, units="inch")
    assert t.values == {"diameter_mm": pytest.approx(12.7)} and t.description == "half inch"
    assert t.extra == {"Z": pytest.approx(50.8), "X": pytest.approx(2.54), "A": 15.0}


# --------------------------------------------------------------------------- what a .tbl lacks
TBL = "T3 P3 D10.0 Z+0.0 ;bull\n"
TBL_KEYS = 'library = "t.tbl"\nnumber = 3\nlibrary_units = "mm"\n'


@pytest.mark.parametrize("keys,key,words", [
    ('type = "flat"\nhelix_deg = 30.0\nflute_length_mm = 20.0', "tool.flutes",
     "no flute count: give flutes in [tool] beside library"),
    ('type = "flat"\nflutes = 2\nhelix_deg = 30.0', "tool.flute_length_mm",
     "no flute length: give flute_length_mm in [tool]"),
    ('type = "radius"\nflutes = 2\nhelix_deg = 30.0\nflute_length_mm = 20.0',
     "tool.corner_radius_mm", "no corner radius: give corner_radius_mm in [tool]"),
    ('flutes = 2\nhelix_deg = 30.0\nflute_length_mm = 20.0', "tool.type",
     "no tool type: give type in [tool]"),
    ('type = "flat"\nflutes = 2\nflute_length_mm = 20.0', "tool.helix_deg", "no helix angle"),
])
def test_tbl_gaps_are_named_with_where_to_put_them(tmp_path, keys, key, words):
    path = write_scenario(tmp_path, TBL_KEYS + keys, {"t.tbl": TBL})
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    msg = str(exc.value)
    assert msg.startswith(f"{path}: {key}: missing; t.tbl is a LinuxCNC tool table")
    assert words in msg and "\n" not in msg


def test_tbl_with_gaps_supplied_loads(tmp_path):
    keys = TBL_KEYS + ('type = "radius"\ncorner_radius_mm = 1.0\nflutes = 2\nhelix_deg = 0.0\n'
                       'flute_length_mm = 20.0')
    s = load_scenario(write_scenario(tmp_path, keys, {"t.tbl": TBL}))
    assert (s.tool.kind, s.tool.diameter_mm, s.tool.corner_radius_mm, s.tool.flutes) == \
        ("radius", 10.0, 1.0, 2)


def test_fusion_gap_helix(tmp_path):
    path = write_scenario(tmp_path, 'library = "tools.json"\nnumber = 3',
                          {"tools.json": GOOD[3][2]})
    with pytest.raises(ScenarioError, match=r"tool\.helix_deg: missing; tools\.json is a "
                                            r"Fusion 360 tool library, which has no helix"):
        load_scenario(path)


# --------------------------------------------------------------------------- bad inputs
BAD_TBL = [
    ("P1 D6\n", 1, r"t\.tbl: line 1: missing tool number \(T\)"),
    ("T1 P1 D6\n\nT2 P2 D6,5\n", 1, r"t\.tbl: line 3: 'D6,5': D needs a number"),
    ("T1 P1 Dnan\n", 1, r"t\.tbl: line 1: 'Dnan': D needs a number"),
    ("T1 P1 K3 D6\n", 1, r"t\.tbl: line 1: 'K3' is not a word of a LinuxCNC tool table"),
    ("T1 P1 D6 D7\n", 1, r"t\.tbl: line 1: D given twice"),
    ("T1.5 P1 D6\n", 1, r"t\.tbl: line 1: 'T1.5': T needs a whole number"),
    ("T1 P1 D-6\n", 1, r"t\.tbl: line 1 \(T1\): D \(diameter\): expected a finite number > 0, "
                       r"got -6"),
    ("T1 P1 D0 ;probe\n", 1, r"t\.tbl: line 1 \(T1\): D \(diameter\): expected a finite "
                             r"number > 0, got 0"),
    ("T1 P1 Z1.0\n", 1, r"t\.tbl: line 1 \(T1\): no diameter \(D\)"),
    ("T1 P1 D6\nT2 P2 D8\n", 3, r"t\.tbl: no tool T3 \(tools: T1, T2\)"),
    ("T1 P1 D6\nT1 P2 D8\n", 1, r"t\.tbl: line 2: T1 is also on line 1"),
    ("T1 P1 D0.4 I95 J155 Q1\n", 1, r"t\.tbl: line 1 \(T1\): a lathe tool \(Q, I, J given\)"),
    ("TOOLNO POCKET LENGTH DIAMETER COMMENT\n1 1 +0.5 0.125 x\n", 1,
     r"t\.tbl: line 1: a tool table in the old column format"),
]


@pytest.mark.parametrize("text,number,msg", BAD_TBL, ids=range(len(BAD_TBL)))
def test_bad_tbl_one_clear_error(tmp_path, text, number, msg):
    p = tmp_path / "t.tbl"
    p.write_text(text)
    with pytest.raises(ToolLibraryError, match=msg) as exc:
        library_tool(p, number, units="mm")
    assert "\n" not in str(exc.value) and str(exc.value).startswith(str(p))


NAN = float("nan")
BAD_FUSION = [
    (fusion({"type": "flat end mill", "unit": "millimeters", "geometry": {"DC": 6}}), 1,
     r"data\[0\]: missing post-process\.number"),
    (fusion(ftool(1, "drill", DC=6.0)), 1,
     r"data\[0\] \(tool 1\): type 'drill' is not an end mill"),
    (fusion(ftool(1, DC=NAN, NOF=2)), 1,
     r"data\[0\] \(tool 1\): geometry\.DC: expected a finite number > 0, got nan"),
    (fusion(ftool(1, DC=-6.0, NOF=2)), 1,
     r"data\[0\] \(tool 1\): geometry\.DC: expected a finite number > 0, got -6"),
    (fusion(ftool(1, NOF=2)), 1, r"data\[0\] \(tool 1\): missing geometry\.DC"),
    (fusion(ftool(1, DC=6.0, NOF=2.5)), 1,
     r"geometry\.NOF: expected a whole number >= 1, got 2\.5"),
    (fusion(ftool(1, unit="feet", DC=6.0)), 1, r"\(tool 1\): unit 'feet'; expected one of"),
    (fusion(ftool(1, DC=6.0, RE=0.5)), 1, r"a flat end mill with corner radius 0\.5 mm is a "
                                          r"bull-nose end mill"),
    (fusion(ftool(1, "bull nose end mill", DC=6.0, RE=3.0)), 1,
     r"corner radius 3 mm: a bull-nose end mill needs 0 < r < D/2 = 3 mm"),
    (fusion(ftool(1, "ball end mill", DC=6.0, RE=1.0)), 1,
     r"a ball end mill has corner radius D/2 = 3 mm, the library gives 1 mm"),
    (fusion(ftool(1, DC=6.0, holder=segs("millimeters", (-5.0, 20.0, 20.0)))), 1,
     r"\(tool 1\): holder\.segments\[0\]\.height: expected a finite number > 0, got -5"),
    (fusion(ftool(1, DC=6.0), ftool(2, DC=8.0)), 4, r"no tool number 4 \(tool numbers: 1, 2\)"),
    (fusion(ftool(1, DC=6.0), ftool(1, DC=8.0)), 1, r"data\[1\]: tool number 1 is also "
                                                    r"data\[0\]"),
    ('{"data": [\n  {"type": "flat end mill",}\n]}', 1, r"line 2: not valid JSON"),
    ('[{"type": "flat end mill"}]', 1, r"expected a Fusion 360 tool library: an object with "
                                       r"a \"data\" list"),
]


@pytest.mark.parametrize("text,number,msg", BAD_FUSION, ids=range(len(BAD_FUSION)))
def test_bad_fusion_one_clear_error(tmp_path, text, number, msg):
    p = tmp_path / "tools.json"
    p.write_text(text)
    with pytest.raises(ToolLibraryError, match=msg) as exc:
        library_tool(p, number)
    assert "\n" not in str(exc.value) and str(exc.value).startswith(str(p))


@pytest.mark.parametrize("keys,key,msg", [
    ('number = 3\ntype = "flat"', "tool.library", "missing; number needs library"),
    ('library = "tools.json"\nhelix_deg = 30.0', "tool.number", "missing"),
    ('library = "nope.json"\nnumber = 3', "tool.library", "file not found"),
    ('library = "t.tbl"\nnumber = 3\ntype = "flat"', "tool.library_units",
     "missing; a LinuxCNC tool table carries no units"),
    ('library = "tools.json"\nnumber = 3\nlibrary_units = "mm"\nhelix_deg = 30.0',
     "tool.library_units", "for a LinuxCNC tool table (.tbl) only"),
    ('library = "t.tbl"\nnumber = 3\nlibrary_units = "cm"', "tool.library_units",
     "unknown value 'cm'"),
    ('library = "tools.json"\nnumber = 9\nhelix_deg = 30.0', "tool.library",
     "tools.json: no tool number 9"),
    ('library = "tools.json"\nnumber = 3\nhelix_deg = 30.0\nflute_length_mm = 50.0',
     "tool", "overhang_mm: 40 mm is shorter than the flute length 50 mm (with "),
])
def test_scenario_library_keys_refused(tmp_path, keys, key, msg):
    path = write_scenario(tmp_path, keys, {"tools.json": GOOD[3][2], "t.tbl": TBL})
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    assert str(exc.value).startswith(f"{path}: {key}: ") and msg in str(exc.value)
    assert "\n" not in str(exc.value)


# --------------------------------------------------------------------------- CutPro .frf
def _frf(f, modes):
    return Compliance.from_modes(modes).response(2 * np.pi * f)[:, 0]


F = np.linspace(50.0, 6000.0, 400)
GX = _frf(F, {"x": [Mode.from_frequency(2000.0, 0.03, 6e6)]})
GY = _frf(F, {"y": [Mode.from_frequency(2150.0, 0.04, 7e6)]})


def test_frf_cutpro_round_trip(tmp_path):
    px, py = tmp_path / "FRFX.frf", tmp_path / "FRFY.frf"
    np.savetxt(px, np.column_stack([F, GX.real, GX.imag]), delimiter="\t",
               header="Freq (Hz)\tReal (m/N)\tImag (m/N)", comments="")
    np.savetxt(py, np.column_stack([F, GY.real, GY.imag]), delimiter="\t")
    got = Compliance.from_cutpro({"x": px, "y": py})
    want = Compliance.from_frf(F, {"x": GX, "y": GY})
    w = 2 * np.pi * np.concatenate([F, np.linspace(0.0, 9000.0, 301)])
    assert np.array_equal(got.response(w), want.response(w))
    assert any("y: " in n and "no unit label; m/N assumed" in n for n in got.notes)
    assert not any(n.startswith("x: ") and "assumed" in n for n in got.notes)


def test_frf_cutpro_exporter_layout_and_units(tmp_path):
    """Rows end in a tab; the first row carries the labels ``Freq Hz Real m/N Imag Real``."""
    def write(path, unit, fac):
        rows = [f"{f:14.6e}\t{g.real * fac:14.12e}\t{g.imag * fac:14.12e}\t"
                for f, g in zip(F, GX)]
        rows[0] += f"Freq\tHz\tReal\t{unit}\tImag\tReal\t"
        path.write_text("\n".join(rows) + "\n")
    write(tmp_path / "m.frf", "m/N", 1.0)
    write(tmp_path / "mm.frf", "mm/N", 1e3)
    a = Compliance.from_cutpro({"x": tmp_path / "m.frf", "y": tmp_path / "m.frf"})
    b = Compliance.from_cutpro({"x": tmp_path / "mm.frf", "y": tmp_path / "mm.frf"})
    # the values as the exporter's formats round them: 7 digits of frequency, 13 of G
    fr = np.array([float(f"{f:14.6e}") for f in F])
    gr = np.array([complex(float(f"{g.real:14.12e}"), float(f"{g.imag:14.12e}")) for g in GX])
    w = 2 * np.pi * np.concatenate([fr, np.linspace(0.0, 9000.0, 301)])
    ref = Compliance.from_frf(fr, {"x": gr, "y": gr}).response(w)
    assert np.array_equal(a.response(w), ref)
    assert np.allclose(b.response(w), ref, rtol=1e-11, atol=0)
    assert not np.allclose(a.response(w), Compliance.from_frf(fr, {"x": gr * 1e3, "y": gr})
                           .response(w), rtol=1e-3)     # the label is what scales mm/N
    assert all("assumed" not in n for n in a.notes + b.notes)


@pytest.mark.parametrize("text,msg", [
    ("1\t2e-7\t-1e-7\n2\t2e-7\n", r"line 2, column 3: 2 fields; expected three"),
    ("1\t2e-7\t-1e-7\n2\t2e-7\t-1e-7\t5\n", r"line 2, column 4: 4 fields; expected three"),
    ("1\t2e-7\t-1e-7\t7\n2\t2e-7\t-1e-7\n", r"line 1, column 4: 4 fields"),
    ("1\t2e-7\t-1e-7\nend of data\n", r"line 2, column 1: expected three numbers"),
    ("2\t2e-7\t-1e-7\n1\t2e-7\t-1e-7\n", r"line 2, column 1: frequency 1\.0 Hz: frequencies "
                                         r"must be >= 0 and strictly increasing"),
    ("1\tnan\t-1e-7\n2\t2e-7\t-1e-7\n", r"line 1, column 2: real: 'nan' is not a finite"),
    ("# header\n1\t2e-7\t-1e-7\n", r"need at least 2 rows .* found 1"),
    ("Freq Hz Real mm/N\nImag m/N\n1\t2e-7\t-1e-7\n2\t2e-7\t-1e-7\n",
     r"line 2: unit labels disagree: mm/n, m/n"),
    ("1\t2,5e-7\t-1e-7\n2\t2e-7\t-1e-7\n", r"line 1, column 2: real: '2,5e-7' is not a finite"),
])
def test_frf_cutpro_errors_name_file_line_column(tmp_path, text, msg):
    p = tmp_path / "x.frf"
    p.write_text(text)
    with pytest.raises(FRFDataError, match=msg) as exc:
        Compliance.from_cutpro({"x": p, "y": p})
    assert str(exc.value).startswith(str(p))


def test_scenario_names_frf_cutpro_files(tmp_path):
    for name, g in (("x.frf", GX), ("y.frf", GY)):
        np.savetxt(tmp_path / name, np.column_stack([F, g.real, g.imag]), delimiter="\t")
    dyn = 'frf_cutpro = { x = "x.frf", y = "y.frf" }\nstatic_compliance_m_N = { x = 1.7e-7 }'
    s = load_scenario(write_scenario(tmp_path, 'type = "flat"\ndiameter_mm = 6.0\nflutes = 2\n'
                                               'helix_deg = 30.0', {}, dyn))
    assert s.compliance.kind == "measured" and s.compliance.directions == ("x", "y")
    w = 2 * np.pi * F
    assert np.array_equal(s.compliance.response(w),
                          Compliance.from_frf(F, {"x": GX, "y": GY},
                                              {"x": 1.7e-7}).response(w))
    bad = write_scenario(tmp_path, 'type = "flat"\ndiameter_mm = 6.0\nflutes = 2\n'
                                   'helix_deg = 30.0', {}, 'frf_csv = { x = "x.frf", y = "y.frf" }')
    with pytest.raises(ScenarioError, match=r"dynamics\.frf_csv: .*x\.frf, line 1: expected a "
                                            r"header .*a CutPro \.frf file\? .*frf_cutpro"):
        load_scenario(bad)


# --------------------------------------------------------------------------- same prediction
def test_scenario_with_library_predicts_as_its_tool_table(tmp_path):
    """The bundled mold-ball scenario, its [tool] table replaced by a Fusion library tool."""
    src = bundled_scenario("mold-ball")
    text = src.read_text()
    base = src.parent
    head, sep, rest = text.partition("[tool]\n")
    _, sep2, tail = rest.partition("[program]\n")
    assert sep and sep2
    lib = fusion(ftool(7, "ball end mill", DC=10.0, NOF=2, LCF=20.0, LB=40.0, SFDM=10.0,
                       holder=segs("millimeters", (30.0, 20.0, 24.0), (50.0, 24.0, 24.0))))
    (tmp_path / "tools.json").write_text(lib)
    tool = 'library = "tools.json"\nnumber = 7\nhelix_deg = 30.0\nrotation = "cw"\n\n'
    new = head + "[tool]\n" + tool + "[program]\n" + tail
    for name in ("stock.stl", "design.stl", "finish.nc"):
        assert f'"{name}"' in new
        new = new.replace(f'"{name}"', json.dumps(str(base / name)))
    (tmp_path / "s.toml").write_text(new)
    a = load_scenario(src)
    b = load_scenario(tmp_path / "s.toml")
    assert b.tool == a.tool          # the same dataclass values, holder included
    lines = (19118, 19121)
    a, b = dataclasses.replace(a, lines=lines), dataclasses.replace(b, lines=lines)
    stock = a.stock.load()
    pa, pb = predict(a, stock=stock).points, predict(b, stock=stock).points
    done = [(p.line, q.line) for p, q in zip(pa, pb) if p.status == "predicted"]
    assert len(pa) == len(pb) and len(done) >= 2
    for p, q in zip(pa, pb):
        assert (p.line, p.status) == (q.line, q.status)
        if p.status == "predicted":
            assert p.result.E_um == q.result.E_um and math.isfinite(p.result.E_um)
