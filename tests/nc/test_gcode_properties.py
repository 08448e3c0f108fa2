"""Property tests: random programs in random styles read back as written.

A generator writes straight moves with known absolute targets in every style
CAM posts use (G90/G91 per block, mm/inch, words omitted when unchanged,
lower case, no spaces, no leading zero, trailing dot, N numbers, comments).
The reader must recover the targets; rewriting random points must give
exactly those points back; and LinuxCNC's rs274 must agree on the same text.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from nc import parse_program
from nc.linuxcnc import run_rs274
from nc.rewrite import rewrite_coordinates

coord = st.integers(-200_000, 200_000).map(lambda k: k / 1000)  # mm, 3 decimals


@st.composite
def programs(draw, max_blocks=25):
    n = draw(st.integers(1, max_blocks))
    style = draw(st.fixed_dictionaries({
        "lower": st.booleans(), "spaces": st.booleans(), "numbers": st.booleans(),
        "leading_zero": st.booleans(), "comments": st.booleans()}))
    lines = ["G21 G90 G17 G94"]
    expected = []
    pos = np.zeros(3)
    units = 21
    distance = 90
    first_feed = True
    for k in range(n):
        words = []
        new_units = draw(st.sampled_from([20, 21])) if draw(st.booleans()) else units
        new_distance = draw(st.sampled_from([90, 91]))
        if new_units != units:
            words.append(f"G{new_units}")
            units = new_units
        if new_distance != distance:
            words.append(f"G{new_distance}")
            distance = new_distance
        motion = draw(st.sampled_from([0, 1]))
        words.append(f"G{motion}" if draw(st.booleans()) or k == 0 else f"G0{motion}")
        scale = 25.4 if units == 20 else 1.0
        target = pos.copy()
        moved = False
        for a, letter in enumerate("XYZ"):
            if draw(st.booleans()) or (a == 2 and not moved):
                value = draw(coord) / (10 if units == 20 else 1)  # inch: 4 decimals
                decimals = 4 if units == 20 else 3
                text = f"{value:.{decimals}f}"
                if not style["leading_zero"]:
                    text = text.replace("0.", ".", 1) if text.startswith(("0.", "-0.")) else text
                words.append(f"{letter}{text}")
                v = float(text) * scale
                target[a] = pos[a] + v if distance == 91 else v
                moved = True
        if motion == 1 and first_feed:
            words.append("F250.")
            first_feed = False
        sep = " " if style["spaces"] else ""
        line = sep.join(words)
        if style["numbers"]:
            line = f"N{(k + 1) * 10}{sep}{line}"
        if style["comments"] and draw(st.booleans()):
            line += " (cut)" if draw(st.booleans()) else " ; note"
        if style["lower"]:
            line = line.lower()
        lines.append(line)
        expected.append((len(lines), motion, target))
        pos = target
    lines.append("M2")
    return "\n".join(lines) + "\n", expected


@settings(max_examples=150)
@given(programs())
def test_random_programs_read_back(case):
    src, expected = case
    prog = parse_program(src)
    assert [b.line for b in prog] == [e[0] for e in expected]
    assert [b.motion for b in prog] == [e[1] for e in expected]
    np.testing.assert_allclose(prog.end[:, :3], np.array([e[2] for e in expected]),
                               atol=1e-9)


@settings(max_examples=100)
@given(programs(), st.data())
def test_rewrite_random_points(case, data):
    src, _ = case
    prog = parse_program(src)
    chosen = data.draw(st.sets(st.integers(0, len(prog) - 1)))
    shifts = data.draw(st.lists(st.tuples(*[st.integers(-50, 50)] * 3),
                                min_size=len(chosen), max_size=len(chosen)))
    ends = {i: prog.end[i, :3] + np.array(d) * 1e-3 for i, d in zip(sorted(chosen), shifts)}
    out = rewrite_coordinates(prog, ends, min_decimals=4)
    back = parse_program(out)
    target = prog.end[:, :3].copy()
    for i, e in ends.items():
        target[i] = e
    units = back.modal_column("units")
    res = np.where(units == 20, 0.5e-4 * 25.4, 0.5e-4)  # 4 decimals in both units
    assert np.all(np.abs(back.end[:, :3] - target) <= 2 * res[:, None] + 1e-9)
    # untouched lines are byte for byte the same unless a word had to be added
    for a, b in zip(src.splitlines(), out.splitlines()):
        if a != b:
            assert len(b) > len(a) or any(ch.isdigit() for ch in a)


@settings(max_examples=15)
@given(programs(max_blocks=12))
def test_rs274_agrees_on_random_programs(rs274, tmp_path_factory, case):
    src, _ = case
    path = tmp_path_factory.mktemp("prop") / "p.ngc"
    path.write_text(src)
    prog = parse_program(src)
    canon = run_rs274(path)
    assert len(canon.kind) == len(prog)
    assert np.all(np.abs(prog.end[:, :3] - canon.end[:, :3]) <= canon.resolution[:, None] + 1e-9)
