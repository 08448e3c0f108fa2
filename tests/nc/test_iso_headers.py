"""Program numbers and tape headers of the ISO controls: Fanuc/Haas ``O``, Fanuc's
ISO ``:``, Okuma's ``$NAME.MIN%``, ``%`` tape start and end."""

from __future__ import annotations

import pytest

from nc import NCParseError, parse_program


@pytest.mark.parametrize("text,number", [
    ("%\nO1234 (PART)\nG0 X1\nM30\n%\n", "1234"),  # Fanuc/Haas, comment after the O word
    ("%\n:0123\nG0 X1\nM30\n%\n", "0123"),          # Fanuc ISO code: ':' for 'O'
    ("%\n:12 (NAME)\nG0 X1\n", "12"),
    ("O0001\nG0 X1\n", "0001"),                     # no tape start
    ("$OKUMA1.MIN%\nG0 X1\nM02\n", None),           # Okuma: the file's name, no number
    ("G0 X1\n", None),
])
def test_program_number_and_header(text, number):
    prog = parse_program(text)
    assert prog.number == number
    assert len(prog) == 1 and prog.end[0, 0] == 1.0


def test_text_after_closing_percent_is_not_read():
    prog = parse_program("%\nO1234\nG0 X1\nM30\n%\nG0 X5\n")
    assert len(prog) == 1 and prog.end[-1, 0] == 1.0


@pytest.mark.parametrize("text,where,words", [
    ("%\n:12X\nG0 X1\n", "2:1", "program number ':1234' alone"),
    ("O12 G0 X1\n", "1:1", "O program number alone"),
    ("%\nG0 X1\n%X\n", "3:1", "'%' alone"),
])
def test_bad_headers_one_line(text, where, words):
    with pytest.raises(NCParseError) as exc:
        parse_program(text, file="h.nc")
    assert str(exc.value).startswith(f"h.nc:{where}: ") and words in str(exc.value)
