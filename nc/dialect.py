"""The dialect's code tables: G and M codes, modal groups, what may be allowed.

G and M numbers are keys ``round(10 * number)``: 10 is G1, 434 is G43.4.
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from .cycles import CYCLE_CODES
from .errors import InputError

__all__ = ["ALLOWABLE_EXAMPLES", "AXIS_LETTERS", "AXIS_INDEX", "BASE_WORDS", "PARAM_WORDS", "CYCLE_WORDS",
           "MOTION_CODES", "G_GROUPS", "M_GROUPS", "NOT_ALLOWABLE", "PASSIVE", "STRICT_REFUSED",
           "normalise_allow", "code_key", "code_name", "why_not"]

ALLOWABLE_EXAMPLES = ("G64", "G61", "G61.1", "G4", "M7", "M8", "M9", "M1")

# G codes as int(10 * number): 10 = G1, 434 = G43.4.
MOTION_CODES = {0: 0, 10: 1, 20: 2, 30: 3, **CYCLE_CODES}
G_GROUPS = {
    0: "motion", 10: "motion", 20: "motion", 30: "motion",
    # canned drilling cycles (nc.cycles), modal like G0...G3; G98/G99 their
    # return level
    **{k: "motion" for k in CYCLE_CODES},
    980: "retract", 990: "retract",
    # Fanuc-family coordinate rotation and tilted plane (nc.rotation; not LinuxCNC's)
    680: "rotation", 682: "rotation", 690: "rotation", 531: "orient",
    # G80 cancels a canned cycle: with G0...G3 in the same block (the safety
    # line "G0 G17 G40 G49 G80 G90") the motion code wins, as on Fanuc and
    # LinuxCNC; alone it leaves no motion mode (LinuxCNC's rule)
    800: "cycle",
    170: "plane", 180: "plane", 190: "plane",
    900: "distance", 910: "distance",
    901: "arc_distance", 911: "arc_distance",
    930: "feed_mode", 940: "feed_mode", 950: "feed_mode",
    200: "units", 210: "units",
    400: "cutter_comp",
    430: "length", 434: "length", 435: "length", 490: "length",
    540: "wcs", 550: "wcs", 560: "wcs", 570: "wcs", 580: "wcs", 590: "wcs",
    # non-modal codes that change the frame or go to a reference point
    # (nc.frames); at most one per block, as LinuxCNC requires
    100: "frame", 280: "frame", 281: "frame", 300: "frame", 301: "frame", 520: "frame",
    530: "frame", 920: "frame", 921: "frame", 922: "frame", 923: "frame",
}
#: Codes modelled since the reader stopped refusing them (the frame codes
#: above, feed per revolution): ``strict`` refuses them as before.
STRICT_REFUSED = frozenset(k for k, g in G_GROUPS.items() if g in ("frame", "retract", "rotation", "orient")) | {
    950, *CYCLE_CODES}
M_GROUPS = {0: "stop", 10: "stop", 20: "stop", 300: "stop", 30: "spindle", 40: "spindle",
            50: "spindle", 60: "toolchange"}

#: Codes that neither move the tool nor change the frame: read and passed
#: over (counted in :attr:`Program.ignored`) unless the reader is strict.
#: Value: the parameter words the code owns in its block (taken from the
#: block, never read as axis or arc words) and what the code is.
PASSIVE: dict[str, dict[int, tuple[str, str]]] = {
    "G": {
        40: ("PX", "dwell (G4 P; Fanuc G04 X in seconds)"),
        90: ("", "exact stop, this block"),
        610: ("", "exact stop mode"), 611: ("", "exact path mode"),
        620: ("", "corner override"), 630: ("", "tapping mode"),
        640: ("PQ", "path blending"),
        # Fanuc high-speed machining and look-ahead; LinuxCNC's G5 and G5.1 are
        # splines (axis words, I J): told apart in nc.gcode by their words
        50: ("P", "high-speed machining on/off (Fanuc G05 P10000 / P0)"),
        51: ("QR", "AI contour control (Fanuc G05.1 Q1 / Q0)"),
        80: ("P", "look-ahead (Fanuc G08 P1 / P0; LinuxCNC lathe radius mode)"),
        150: ("", "polar coordinates off"),
        501: ("", "mirror image off"),
        970: ("", "constant spindle speed (rev/min, the default)"),
        # the reader models them (nc.cycles); strict passes them over if allowed
        980: ("", "canned-cycle return to the initial level"),
        990: ("", "canned-cycle return to the R level"),
        1030: ("P", "block look-ahead limit (Haas)"),
        1870: ("PE", "smoothness setting (Haas)"),
    },
    "M": {
        70: ("", "mist coolant on"), 80: ("", "flood coolant on"), 90: ("", "coolant off"),
        100: ("", "clamp (rotary axis brake on)"), 110: ("", "unclamp (rotary axis brake off)"),
        190: ("PQR", "spindle orientation"),
        290: ("", "rigid tapping mode"),
        480: ("", "feed and speed overrides on"), 490: ("", "feed and speed overrides off"),
        500: ("P", "feed override control"), 510: ("P", "spindle override control"),
        520: ("P", "adaptive feed control"), 530: ("P", "feed stop control"),
        620: ("PQ", "digital output"), 630: ("PQ", "digital output"),
        640: ("PQ", "digital output"), 650: ("PQ", "digital output"),
        660: ("PELQ", "wait on input"), 670: ("EQ", "analog output"),
        680: ("EQ", "analog output"),
    },
}

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
        682: "a tilted working plane", 531: "a tool axis alignment", 70: "diameter mode",
        160: "polar coordinates", 511: "a mirror image", 650: "a macro call",
        541: "an extended work offset", 591: "a work offset", 592: "a work offset",
        593: "a work offset", 440: "a tool length offset", 450: "a tool offset",
        460: "a tool offset", 470: "a tool offset", 480: "a tool offset",
        120: "a circle pocket", 130: "a circle pocket", 121: "polar interpolation",
        131: "polar interpolation", 1500: "a pocket cycle", 700: "inch units or a cycle",
        710: "metric units or a cycle",
        331: "spindle-synchronized motion", 50: "a spline", 51: "a spline", 52: "a spline",
        431: "a dynamic tool length offset", 432: "a tool length offset",
        **{c: "a canned cycle" for c in CYCLE_CODES},
        760: "a fine-boring or threading cycle",
        880: "a boring cycle retracted by hand (the tool's position after it is not known)",
        **{c: "a probing move" for c in (382, 383, 384, 385)},
    },
    "M": {980: "a subroutine call", 990: "a subroutine return", 600: "a pallet change",
          720: "a restore of modal state", 730: "a restore of modal state"},
}
AXIS_LETTERS = "XYZABC"
AXIS_INDEX = {c: i for i, c in enumerate(AXIS_LETTERS)}
BASE_WORDS = frozenset("NGMXYZABCIJKRFSTHP")
PARAM_WORDS = frozenset("PQDELHR")  # words an allowed code may bring
CYCLE_WORDS = frozenset("LQ")  # a canned cycle's words beyond BASE_WORDS


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



def why_not(letter: str, key: int | None, strict: bool = False) -> str:
    """The tail of an "unknown code" message: why it cannot be, or how to allow it."""
    if key is None:
        return ""
    reason = NOT_ALLOWABLE[letter].get(key)
    if strict and letter == "G" and key in STRICT_REFUSED:
        what = reason or PASSIVE[letter].get(key, ("", code_name(letter, key)))[1]
        return f" ({what}; read without strict to model it)"
    if strict and key in PASSIVE[letter]:
        how = "" if reason else f", or allow it: --allow {code_name(letter, key)}"
        return f" ({PASSIVE[letter][key][1]}; read without strict to pass it over{how})"
    if reason:
        return f" ({reason}, which this reader does not model)"
    return f"; if it is harmless here, pass it in allow (e.g. --allow {code_name(letter, key)})"
