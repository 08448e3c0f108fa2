"""LinuxCNC '#' parameters in straight-line programs (nc.macro), hand-checked and against rs274."""

from __future__ import annotations

import numpy as np
import pytest

from nc import NCParseError, parse_program
from nc.linuxcnc import compare_with_rs274, rs274_path

# source -> X Y Z of every move [mm], worked out by hand
TABLE = [
    ("G21 G90\n#1=2\nG0 X#1 Y[#1*3] Z-#1\n", [[2, 6, -2]]),
    # the line's reads happen before its assignments (LinuxCNC)
    ("G21\n#1=1\n#1=5 G0 X#1 #2=#1\nG0 Y#2\n", [[1, 0, 0], [1, 1, 0]]),
    ("G21\n#<len>=10 #<_g>=4\nG0 X[#<len>/#<_g>] Y[ATAN[1]/[1]]\n", [[2.5, 45, 0]]),
    ("G20\n#1=1\nG0 X[#1+1]\n", [[50.8, 0, 0]]),
    ("G21\n#1=3 (#2=7 in a comment)\nG0 X#1 ; #9\n", [[3, 0, 0]]),
    ("G21\n#1=1\nG0 X#1\nM2\nG0 X#<never>\n", [[1, 0, 0]]),  # nothing after M2 is read
    ("G21\n#1=2\nG1 X[2**#1] F[#1*50]\n", [[4, 0, 0]]),
]


@pytest.mark.parametrize("src,moves", TABLE)
def test_parameters_known_moves(src, moves):
    prog = parse_program(src)
    np.testing.assert_allclose(prog.end[:, :3], moves, atol=1e-12)


@pytest.mark.parametrize("src,col,words", [
    ("G21\nG0 X#1\n", 5, "#1 is used before it is set"),
    ("G21\nG0 X#<a>\n", 5, "#<a> is used before it is set"),
    ("G21\nG0 X#5420\n", 5, "system parameter #5420"),
    ("G21\n#5221=3\n", 1, "assignment to #5221"),
    ("G21\n#1=[1/0]\n", 6, "division by zero"),
    ("G21\n#1 5\n", 4, "expected '='"),
    ("G21\nG0 X[1+\n", 8, "ends early"),
])
def test_refusals_name_line_column_and_reason(src, col, words):
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="p.ngc")
    err = info.value
    assert err.line == 2 and err.column == col and words in err.message, str(err)
    assert "\n" not in str(err)


def test_parameter_program_agrees_with_rs274(tmp_path):
    if rs274_path() is None:
        pytest.skip("rs274 (Debian's linuxcnc-uspace) is not installed")
    src = ("G21 G90\n#1=2\n#<r>=[#1*1.5]\nG0 X#1 Y#<r> Z[-#1] #1=7\nG1 X#1 F[100*2]\n"
           "#2=#1 #1=1\nG1 Y[#2+#1] Z[FIX[-1.5]]\nG1 X[-7 MOD 3] Y[SQRT[2]]\nM2\n")
    path = tmp_path / "p.ngc"
    path.write_text(src)
    prog = parse_program(src, file=str(path))
    result = compare_with_rs274(path, prog)
    assert result.ok and result.moves == len(prog) == 4, result.message


def test_parameter_programs_are_not_rewritten_in_place():
    from nc.rewrite import RewriteError, rewrite_coordinates
    prog = parse_program("G21\n#1=2\nG1 X#1 F100\n")
    with pytest.raises(RewriteError, match="'#' parameters"):
        rewrite_coordinates(prog, {0: np.array([2.001, 0, 0, 0, 0, 0])})


def test_deeply_nested_brackets_are_refused_in_one_line():
    src = "G21\nG0 X" + "[" * 5000 + "1" + "]" * 5000 + "\n"
    with pytest.raises(NCParseError, match="nested too deeply"):
        parse_program(src)
