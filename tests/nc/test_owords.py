"""LinuxCNC O-word control flow (nc.owords): hand-checked moves, rs274, bad input, fuzz."""

from __future__ import annotations

import random

import numpy as np
import pytest

from nc import NCParseError, constants, parse_program
from nc.linuxcnc import compare_with_rs274, rs274_path
from nc.owords import has_owords

# source -> (X Y Z of every move [mm], source line of every move), worked out by hand
TABLE = {
    "call-args": ("G21\no<sq> sub\nG1 X#1 Y#2 F100\no<sq> endsub\no<sq> call [1] [2]\n"
                  "o<sq> call [3]\nM2\n",  # #2 not passed: 0
                  [[1, 2, 0], [3, 0, 0]], [3, 3]),
    "elseif": ("G21\n#1=2\no1 if [#1 EQ 1]\nG0 X1\no1 elseif [#1 EQ 2]\nG0 X2\no1 else\n"
               "G0 X3\no1 endif\nM2\n", [[2, 0, 0]], [6]),
    "else": ("G21\n#1=7\no1 if [#1 EQ 1]\nG0 X1\no1 elseif [#1 EQ 2]\nG0 X2\no1 else\n"
             "G0 X3\no1 endif\nM2\n", [[3, 0, 0]], [8]),
    "while-break-continue": (
        "G21\n#1=0\no2 while [#1 LT 5]\n#1=[#1+1]\no3 if [#1 EQ 2]\no2 continue\no3 endif\n"
        "o4 if [#1 EQ 4]\no2 break\no4 endif\nG0 X#1\no2 endwhile\nM2\n",
        [[1, 0, 0], [3, 0, 0]], [11, 11]),
    "do-while": ("G21\n#1=0\no5 do\nG0 Y#1\n#1=[#1+2]\no5 while [#1 LT 5]\nM2\n",
                 [[0, 0, 0], [0, 2, 0], [0, 4, 0]], [4, 4, 4]),
    "do-runs-once": ("G21\no5 do\nG0 Y7\no5 while [0]\nM2\n", [[0, 7, 0]], [3]),
    "repeat": ("G21\n#<x>=0\no6 repeat [3]\n#<x>=[#<x>+1.5]\nG1 X#<x> F200\no6 endrepeat\nM2\n",
               [[1.5, 0, 0], [3, 0, 0], [4.5, 0, 0]], [5, 5, 5]),
    "repeat-half-to-even": ("G21\no6 repeat [2.5]\nG91 G0 X1\no6 endrepeat\nM2\n",
                            [[1, 0, 0], [2, 0, 0]], [3, 3]),
    "repeat-zero": ("G21\no6 repeat [0]\nG0 X1\no6 endrepeat\nG0 Y1\nM2\n", [[0, 1, 0]], [5]),
    "return-value": ("G21\no<half> sub\n#<h>=[#1/2]\no<half> return [#<h>]\nG0 Z9\n"
                     "o<half> endsub\no<half> call [7]\nG0 X#<_value> Y#<_value_returned>\nM2\n",
                     [[3.5, 1, 0]], [8]),
    "endsub-no-value": ("G21\no<s> sub\no<s> endsub\no<s> call\nG0 X#<_value> "
                        "Y[#<_value_returned>+1]\nM2\n", [[0, 1, 0]], [5]),
    "recursion": ("G21\no<down> sub\no10 if [#1 GT 0]\nG0 Z-#1\no<down> call [#1-1]\n"
                  "o10 endif\no<down> endsub\no<down> call [3]\nM2\n",
                  [[0, 0, -3], [0, 0, -2], [0, 0, -1]], [4, 4, 4]),
    "locals-restored": ("G21\n#1=5\n#<_g>=0\n#<a>=1\no<s> sub\n#1=9\n#<a>=3\n#<_g>=[#<_g>+#2]\n"
                        "o<s> endsub\no<s> call [0] [4]\nG0 X#1 Y#<_g> Z#<a>\nM2\n",
                        [[5, 4, 1]], [11]),
    "sub-after-call": ("G21\no<f> call [2]\nM2\no<f> sub\nG0 X#1\no<f> endsub\n",
                       [[2, 0, 0]], [5]),
    "inch-nested-loops": ("G20\n#1=0\no1 while [#1 LT 2]\n#2=0\no2 while [#2 LT 2]\n"
                          "G1 X#1 Y#2 F10\n#2=[#2+1]\no2 endwhile\n#1=[#1+1]\no1 endwhile\nM2\n",
                          [[0, 0, 0], [0, 25.4, 0], [25.4, 0, 0], [25.4, 25.4, 0]],
                          [6, 6, 6, 6]),
    "numbered-label-in-two-subs": (
        "G21\no100 sub\no1 if [1]\nG0 X1\no1 endif\no100 endsub\no200 sub\no1 if [1]\nG0 Y1\n"
        "o1 endif\no200 endsub\no100 call\no200 call\nM2\n", [[1, 0, 0], [1, 1, 0]], [4, 9]),
    # LinuxCNC's own loop state (nc.owords): a break out of a while loop also ends the
    # next do loop after its first pass ...
    "quirk-break-then-do": ("G21\no1 while [1]\no1 break\no1 endwhile\n#2=0\no2 do\n"
                            "#2=[#2+1]\nG0 X#2\no2 while [#2 LT 3]\nM2\n", [[1, 0, 0]], [8]),
    # ... and a continue in a do loop makes the next repeat that runs out start again
    "quirk-continue-then-repeat": (
        "G21\n#1=0\no1 do\n#1=[#1+1]\no2 if [#1 EQ 1]\no1 continue\no2 endif\n"
        "o1 while [#1 LT 2]\no3 repeat [2]\nG91 G0 X1\no3 endrepeat\nM2\n",
        [[1, 0, 0], [2, 0, 0], [3, 0, 0], [4, 0, 0]], [10, 10, 10, 10]),
    "label-in-exclusive-branches": (  # qt_auto_probe_tool.ngc: one label, two branches
        "G21\no1 if [1]\no2 if [0]\no2 endif\nG0 X1\no1 else\no2 if [0]\no2 endif\no1 endif\n"
        "M2\n", [[1, 0, 0]], [5]),
}


@pytest.mark.parametrize("name", sorted(TABLE))
def test_owords_known_moves_and_lines(name):
    src, moves, lines = TABLE[name]
    assert has_owords(src)
    prog = parse_program(src)
    np.testing.assert_allclose(prog.end[:, :3], moves, atol=1e-12)
    assert list(prog.line) == lines


@pytest.mark.parametrize("name", sorted(TABLE))
def test_owords_known_moves_agree_with_rs274(name, tmp_path):
    if rs274_path() is None:
        pytest.skip("rs274 (Debian's linuxcnc-uspace) is not installed")
    src = TABLE[name][0]
    path = tmp_path / "p.ngc"
    path.write_text(src)
    prog = parse_program(src, file=str(path))
    result = compare_with_rs274(path, prog)
    assert result.ok and result.moves == len(prog), result.message


# source, line, words the one-line message must hold
BAD = [
    ("G21\no1 while [1]\nG0 X1\nM2\n", 2, "o1 while is not closed"),
    ("G21\no1 if [1]\nG0 X1\no2 endif\nM2\n", 4, "o2 endif without o2 if"),
    ("G21\no1 if [1]\no2 while [1]\no1 endif\nM2\n", 3, "o2 while is not closed"),
    ("G21\no<a> endsub\nM2\n", 2, "o<a> endsub without o<a> sub"),
    ("G21\no<a> sub\nG0 X1\n", 2, "o<a> sub is not closed"),
    ("G21\no<a> sub\no<b> sub\no<b> endsub\no<a> endsub\n", 3, "inside o<a> sub"),
    ("G21\no1 if [1]\no<a> sub\no<a> endsub\no1 endif\n", 3, "outside if/while"),
    ("G21\no<a> sub\no<a> endsub\no<a> sub\no<a> endsub\n", 4, "defined twice"),
    ("G21\no<nope> call [1]\nM2\n", 2, "no o<nope> sub in this file"),
    ("G21\no1 return\nM2\n", 2, "outside a subroutine"),
    ("G21\no1 break\nM2\n", 2, "outside a loop"),
    ("G21\no1 repeat [2]\no1 break\no1 endrepeat\nM2\n", 3, "expected a while or do loop"),
    ("G21\no1 if [1]\no1 else\no1 elseif [1]\no1 endif\nM2\n", 4, "after o1 else"),
    ("G21\no1 endwhile\nM2\n", 2, "o1 endwhile without o1 while"),
    ("G21\no1 if 1\no1 endif\nM2\n", 2, "expected '['"),
    ("G21\no1 if [1] G0 X1\no1 endif\nM2\n", 2, "expected only comments"),
    ("G21\no1 frob\nM2\n", 2, "unknown O-word command 'FROB'"),
    ("G21\no1 if [1 +]\no1 endif\nM2\n", 2, "unexpected ']' in an expression"),
    ("G21\no1 if [#7 GT 0]\no1 endif\nM2\n", 2, "#7 is used before it is set"),
    ("G21\no1 if [1/0]\no1 endif\nM2\n", 2, "division by zero"),
    ("G21\n/o1 if [1]\no1 endif\nM2\n", 2, "block delete"),
    ("G21\no<s> sub\n#<a>=1\no<s> endsub\no<s> call\nG0 X#<a>\nM2\n", 6, "local to the subroutine"),
    ("G21\no<s> sub\no<s> endsub\n#<_value>=3\no<s> call\nM2\n", 4, "read-only"),
    ("G21\no<s> call " + "[1] " * 31 + "\nM2\n", 2, "more than 30 arguments"),
    ("G21\no<r> sub\no<r> call\no<r> endsub\no<r> call\nM2\n", 3, "nested deeper than 9"),
    ("G21\no1 while [0]\no1 endwhile\no1 while [0]\no1 endwhile\nM2\n", 4, "used again"),
    ("G21\no1 repeat [0]\no1 endrepeat\no1 do\no1 while [0]\nM2\n", 4, "used again"),
    ("G21\no<f> call\no<f> sub\no<f> endsub\nM2\n", 3, "found in illegal location"),
]


@pytest.mark.parametrize("src,line,words", BAD, ids=[b[2] for b in BAD])
def test_bad_owords_end_in_one_line_naming_the_line(src, line, words):
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="p.ngc")
    err = info.value
    assert err.line == line and words in err.message, str(err)
    assert str(err).startswith(f"p.ngc:{line}:") and "\n" not in str(err)


@pytest.mark.parametrize("src,line", [
    ("G21\no1 while [1]\nG0 X1\no1 endwhile\nM2\n", 2),   # moves for ever
    ("G21\no1 while [1]\no1 endwhile\nM2\n", 2),           # an empty loop
    ("G21\no1 do\no1 while [1]\nM2\n", 3),                 # a do loop
    ("G21\no1 repeat [1000000000]\nG0 X1\no1 endrepeat\nM2\n", 2),
])
def test_runaway_loops_stop_at_the_line_budget(src, line, monkeypatch):
    monkeypatch.setattr(constants, "LINUXCNC_MAX_EXECUTED_LINES", 5000)
    with pytest.raises(NCParseError, match="more than 5,000 lines executed") as info:
        parse_program(src, file="p.ngc")
    assert info.value.line in (line, line + 1, line + 2)


@pytest.mark.parametrize("src", [
    "G21\no<s> sub\nG0 X#[" + "9" * 400 + "]\no<s> endsub\no<s> call\nM2\n",
    "G21\no1 if [#" + "9" * 400 + " GT 0]\no1 endif\nM2\n",
    "G21\n#<\x1d>=[1/2]\nG0 X#<\x1d>\nM2\no1 if [1]\no1 endif\n",
    "G21\no<> call\nM2\n",
    "G21\no6 repeat [-" + "9" * 400 + "]\no6 endrepeat\nM2\n",
    "G21\no1\x0b if [1]\no1 endif\nM2\n",
])
def test_inputs_the_fuzz_found_are_read_or_refused_in_one_line(src):
    try:
        parse_program(src, file="f.ngc")
    except NCParseError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("f.ngc:"), str(exc)
        assert exc.line in (2, 3), str(exc)  # the line with the bad parameter or O-word


def test_error_in_a_called_sub_names_the_sub_line():
    src = "G21\no<s> sub\nG0 X[#1/0]\no<s> endsub\no<s> call [1]\nM2\n"
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="p.ngc")
    assert info.value.line == 3 and info.value.column == 8, str(info.value)


def test_reader_errors_in_expanded_lines_name_the_source_line():
    src = "G21\no1 repeat [2]\nG0 X1\no1 endrepeat\nG5 X1\nM2\n"
    with pytest.raises(NCParseError) as info:
        parse_program(src, file="p.ngc")
    assert info.value.line == 5 and info.value.column == 1, str(info.value)


def test_nothing_after_m2_runs_even_inside_a_sub():
    prog = parse_program("G21\no<s> sub\nG0 X1\nM2\no<s> endsub\no<s> call\nG0 Y1\nM2\n")
    np.testing.assert_allclose(prog.end[:, :3], [[1, 0, 0]])


def test_owords_programs_are_not_rewritten_in_place():
    from nc.rewrite import RewriteError, rewrite_coordinates
    prog = parse_program("G21\no1 repeat [2]\nG1 X1 F100\no1 endrepeat\nM2\n")
    with pytest.raises(RewriteError, match="O-word"):
        rewrite_coordinates(prog, {0: np.array([1.001, 0, 0, 0, 0, 0])})


_FRAGMENTS = [
    "o{l} if [{e}]", "o{l} elseif [{e}]", "o{l} else", "o{l} endif", "o{l} while [{e}]",
    "o{l} endwhile", "o{l} do", "o{l} repeat [{e}]", "o{l} endrepeat", "o{l} break",
    "o{l} continue", "o<s{l}> sub", "o<s{l}> endsub", "o<s{l}> call [{e}] [{e}]",
    "o<s{l}> return [{e}]", "G0 X[{e}]", "#{p}=[{e}]", "#<n{l}>=[{e}]", "G1 Y#{p} F100",
    "M2", "o{l} if {e}", "o{l} endwhile [{e}]", "o<{l}", "(o{l} if)", "G0 Z#<_value>",
]
_EXPRS = ["1", "0", "#1", "#2 GT 1", "#3+1", "[#1 LT 3]", "1/0", "SQRT[-1]", "#<n1>", "2.5",
          "#1 EQ #2", "-1", "[", "#99999"]


def _block(rng: random.Random, depth: int, label: list) -> list[str]:
    """A well-nested random block (loops bounded by the line budget)."""
    if depth > 2 or rng.random() < 0.35:
        return [rng.choice(["G0 X[{e}]", "#{p}=[#{p}+1]", "G1 Y#{p} F100", "#<n1>=[{e}]"])
                .format(e=rng.choice(_EXPRS[:7]), p=rng.randint(1, 3))]
    label[0] += 1
    n = label[0]
    kind = rng.choice(["if", "while", "do", "repeat"])
    body = [ln for _ in range(rng.randint(1, 3)) for ln in _block(rng, depth + 1, label)]
    e = rng.choice(["#1 LT 3", "#2 GT 1", "0", "#3 EQ 0"])
    if kind == "if":
        return [f"o{n} if [{e}]"] + body + [f"o{n} else"] + body + [f"o{n} endif"]
    if kind == "while":
        return [f"o{n} while [{e}]", "#1=[#1+1]"] + body + [f"o{n} endwhile"]
    if kind == "do":
        return [f"o{n} do", "#2=[#2-1]"] + body + [f"o{n} while [{e}]"]
    return [f"o{n} repeat [{rng.randint(0, 3)}]"] + body + [f"o{n} endrepeat"]


def test_random_oword_programs_never_crash(monkeypatch):
    """Seeded fuzz: random O-word programs give a Program or one NCParseError line."""
    monkeypatch.setattr(constants, "LINUXCNC_MAX_EXECUTED_LINES", 2000)
    rng = random.Random(18)
    outcomes = {"read": 0, "refused": 0}
    for k in range(1500):
        lines = ["G21", "#1=1 #2=2 #3=0"]
        if k % 2:  # well nested, then maybe one line broken
            lines += _block(rng, 0, [0])
            if rng.random() < 0.3:
                lines.insert(rng.randint(2, len(lines)), rng.choice(_FRAGMENTS).format(
                    l=1, e=rng.choice(_EXPRS), p=1))
        else:
            for _ in range(rng.randint(1, 14)):
                frag = rng.choice(_FRAGMENTS)
                lines.append(frag.format(l=rng.randint(1, 3), e=rng.choice(_EXPRS),
                                         p=rng.randint(1, 4)))
        lines.append("M2")
        try:
            parse_program("\n".join(lines) + "\n", file="f.ngc")
            outcomes["read"] += 1
        except NCParseError as exc:
            assert "\n" not in str(exc) and str(exc).startswith("f.ngc:"), str(exc)
            assert 1 <= exc.line <= len(lines), str(exc)
            outcomes["refused"] += 1
    assert outcomes["read"] > 300 and outcomes["refused"] > 300, outcomes


def _terminating(rng: random.Random, depth: int, label: list) -> list[str]:
    """A random block whose loops end: each loop counts its own named parameter."""
    if depth > 2 or rng.random() < 0.4:
        return [rng.choice(["G1 X[#1] Y[#2] F100", "#1=[#1+1]", "#2=[#2*3 MOD 7]",
                            "o<s> call [#1] [#2]", "G0 Z[#<_value>]",
                            "G1 X[#1*0.5] Z[-#2] F200"])]
    label[0] += 1
    n = label[0]
    c = f"#<c{n}>"
    body = [ln for _ in range(rng.randint(1, 3)) for ln in _terminating(rng, depth + 1, label)]
    kind = rng.choice(["if", "while", "do", "repeat", "break", "continue"])
    if kind == "if":
        return ([f"o{n} if [#1 GT {rng.randint(0, 4)}]"] + body +
                [f"o{n} elseif [#2 LT 3]", "G0 X-1", f"o{n} else"] + body + [f"o{n} endif"])
    if kind == "while":
        return [f"{c}=0", f"o{n} while [{c} LT {rng.randint(0, 3)}]", f"{c}=[{c}+1]"] + body + [
            f"o{n} endwhile"]
    if kind == "do":
        return [f"{c}=0", f"o{n} do", f"{c}=[{c}+1]"] + body + [f"o{n} while [{c} LT 2]"]
    if kind == "break":
        return [f"{c}=0", f"o{n} while [1]", f"{c}=[{c}+1]", f"o{n}9 if [{c} GT 2]",
                f"o{n} break", f"o{n}9 endif"] + body + [f"o{n} endwhile"]
    if kind == "continue":
        return [f"{c}=0", f"o{n} while [{c} LT 3]", f"{c}=[{c}+1]", f"o{n}9 if [{c} EQ 2]",
                f"o{n} continue", f"o{n}9 endif"] + body + [f"o{n} endwhile"]
    return [f"o{n} repeat [{rng.randint(0, 3)}]"] + body + [f"o{n} endrepeat"]


def test_random_terminating_programs_agree_with_rs274(tmp_path):
    """Seeded differential test: 25 random well-nested programs, move by move vs rs274."""
    if rs274_path() is None:
        pytest.skip("rs274 (Debian's linuxcnc-uspace) is not installed")
    rng = random.Random(2026)
    sub = ["o<s> sub", "o1 if [#1 GT #2]", "o<s> return [#1-#2]", "o1 endif",
           "G0 Y[#2]", "o<s> endsub [#2*0.5]"]
    checked = 0
    for k in range(25):
        lines = ["G21 G90"] + sub + ["#1=1 #2=2"]
        label = [0]
        lines += [ln for _ in range(3) for ln in _terminating(rng, 0, label)]
        lines += ["G0 X0 Y0 Z0", "M2"]
        src = "\n".join(lines) + "\n"
        path = tmp_path / f"r{k}.ngc"
        path.write_text(src)
        prog = parse_program(src, file=str(path))
        result = compare_with_rs274(path, prog)
        assert result.ok and result.moves == len(prog), result.message + "\n" + src
        checked += len(prog)
    assert checked > 100


@pytest.mark.parametrize("src,expected", [
    ("o100 sub\nG0 X1\no100 endsub\no100 call\nM2\n", True),   # no bracket at all
    ("G21\n  N10 o1 if [1]\no1 endif\n", True),
    ("%\nO1000\nG0 X1\nM30\n%\n", False),       # a program number, then a block
    ("O1000 (PART)\nG0 X1\n", False),
    ("O12 G0 X1\n", False),                   # a program number and a block: refused
    ("G21\no12 frob\n", True),               # by the reader, a misspelt command here
    ("G0 X1 (do the sub call)\n", False),
])
def test_has_owords_looks_only_at_o_word_lines(src, expected):
    assert has_owords(src) is expected


def test_program_numbers_still_read_as_before():
    prog = parse_program("%\nO1000\nG21 G0 X1\nM30\n%\n")
    np.testing.assert_allclose(prog.end[:, :3], [[1, 0, 0]])
