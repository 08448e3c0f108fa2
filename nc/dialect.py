"""The dialect's code tables: G and M codes, modal groups, what may be allowed.

G and M numbers are keys ``round(10 * number)``: 10 is G1, 434 is G43.4.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from .errors import InputError

__all__ = ["ALLOWABLE_EXAMPLES", "AXIS_LETTERS", "AXIS_INDEX", "BASE_WORDS", "PARAM_WORDS",
           "MOTION_CODES", "G_GROUPS", "M_GROUPS", "NOT_ALLOWABLE", "normalise_allow",
           "code_key", "code_name", "why_not"]

ALLOWABLE_EXAMPLES = ("G64", "G61", "G61.1", "G4", "M7", "M8", "M9", "M1")

# G codes as int(10 * number): 10 = G1, 434 = G43.4.
MOTION_CODES = {0: 0, 10: 1, 20: 2, 30: 3}
G_GROUPS = {
    0: "motion", 10: "motion", 20: "motion", 30: "motion", 800: "motion",
    170: "plane", 180: "plane", 190: "plane",
    900: "distance", 910: "distance",
    901: "arc_distance", 911: "arc_distance",
    930: "feed_mode", 940: "feed_mode",
    200: "units", 210: "units",
    400: "cutter_comp",
    430: "length", 434: "length", 435: "length", 490: "length",
    540: "wcs", 550: "wcs", 560: "wcs", 570: "wcs", 580: "wcs", 590: "wcs",
}
M_GROUPS = {0: "stop", 10: "stop", 20: "stop", 300: "stop", 30: "spindle", 40: "spindle",
            50: "spindle", 60: "toolchange"}

#: Codes that cannot be allowed: they move the tool or the frame.
NOT_ALLOWABLE = {
    "G": {
        40 * 10 + 1: "cutter compensation", 410: "cutter compensation",
        420: "cutter compensation", 411: "cutter compensation", 421: "cutter compensation",
        280: "a return to home", 300: "a return to home", 281: "a return to home",
        301: "a return to home", 100: "a change of offsets", 520: "a local offset",
        530: "a move in machine coordinates", 920: "a change of offsets",
        921: "a change of offsets", 922: "a change of offsets", 923: "a change of offsets",
        680: "a coordinate rotation", 690: "a coordinate rotation", 510: "scaling",
        501: "scaling", 950: "feed per revolution", 330: "spindle-synchronized motion",
        331: "spindle-synchronized motion", 50: "a spline", 51: "a spline", 52: "a spline",
        431: "a dynamic tool length offset", 432: "a tool length offset",
        **{c: "a canned cycle" for c in (730, 740, 760, 810, 820, 830, 840, 850, 860,
                                         870, 880, 890)},
        **{c: "a probing move" for c in (382, 383, 384, 385)},
    },
    "M": {980: "a subroutine call", 990: "a subroutine return"},
}
AXIS_LETTERS = "XYZABC"
AXIS_INDEX = {c: i for i, c in enumerate(AXIS_LETTERS)}
BASE_WORDS = frozenset("NGMXYZABCIJKRFSTHP")
PARAM_WORDS = frozenset("PQDELHR")  # words an allowed code may bring


def code_key(letter: str, text: str) -> int | None:
    """``("G", "43.4")`` -> 434; None when not a multiple of 0.1 or not below 10^6."""
    v = float(text)
    if not abs(v) < 1e6:  # no such code; G9999...9 of 308+ digits is inf
        return None
    k = round(v * 10)
    return k if abs(v * 10 - k) < 1e-6 and k >= 0 else None


def code_name(letter: str, key: int) -> str:
    return f"{letter}{key // 10}" + (f".{key % 10}" if key % 10 else "")


def normalise_allow(allow: Iterable[str]) -> dict[str, set[int]]:
    out: dict[str, set[int]] = {"G": set(), "M": set()}
    for item in allow:
        s = str(item).strip().upper()
        m = re.fullmatch(r"([GM])\s*(\d+(?:\.\d)?)", s)
        if not m:
            raise InputError(f"allow: {item!r} is not a G or M code such as 'G64' or 'M8'")
        letter, key = m.group(1), code_key(m.group(1), m.group(2))
        if key is None:
            raise InputError(f"allow: {item!r} is not a G or M code such as 'G64' or 'M8'")
        reason = NOT_ALLOWABLE[letter].get(key)
        if reason:
            raise InputError(f"allow: {s} is {reason}; ignoring it would misplace the tool")
        out[letter].add(key)
    return out



def why_not(letter: str, key: int | None) -> str:
    """The tail of an "unknown code" message: why it cannot be, or how to allow it."""
    if key is None:
        return ""
    reason = NOT_ALLOWABLE[letter].get(key)
    if reason:
        return f" ({reason}, which this reader does not model)"
    return f"; if it is harmless here, pass it in allow (e.g. --allow {code_name(letter, key)})"
