"""The motion blocks of Klartext: ``L LN LP CC C CR CT CP``, one function each.

Each takes the :class:`~nc.heidenhain_state.TNCState` (whose ``b`` is the
block) and returns True when the block ends the program (M2/M30). Every
word a block does not use is refused by name.
"""

from __future__ import annotations

import math

import numpy as np

from .arcs import ArcWordError, arc_from_words
from .heidenhain_geom import GeomError, check_radii, sweep_to, tangent_centre
from .program import PLANE_AXES

__all__ = ["MOVES"]

_AX = {"X": 0, "Y": 1, "Z": 2}
_ROT = {"A": 0, "B": 1, "C": 2}
_PLANE_OF_PAIR = {frozenset((0, 1)): 17, frozenset((0, 2)): 18, frozenset((1, 2)): 19}
_WORKING = {2: 17, 1: 18, 0: 19}


def _linear(st, d, used, allowed=(0, 1, 2)):
    """Target in the program frame and the linear axes programmed."""
    target = st.ppos.copy()
    axes = []
    for name in ("X", "Y", "Z", "IX", "IY", "IZ"):
        if name in d:
            val, col = d[name]
            a = _AX[name[-1]]
            if a not in allowed:
                raise st.err(f"{name} in this block; expected only "
                             f"{' '.join('XYZ'[k] for k in allowed)}", col)
            v = st.value(name, val, col) * st.scale
            if a in axes:
                raise st.err(f"{name}: axis {name[-1]} programmed twice", col)
            target[a] = target[a] + v if name[0] == "I" else v
            axes.append(a)
            used.add(name)
    return target, axes


def _rotary(st, d, used) -> bool:
    changed = False
    for name in ("A", "B", "C", "IA", "IB", "IC"):
        if name in d:
            val, col = d[name]
            if st.tcpm and st.vector is not None:
                raise st.err(f"rotary word {name} after an LN tool vector under TCPM: the "
                             "reader does not know the machine angles of that vector", col)
            k = _ROT[name[-1]]
            v = math.radians(st.value(name, val, col))
            if name[0] == "I":
                st.rot[k] += v
            elif st.m126:
                diff = (v - st.rot[k] + math.pi) % (2 * math.pi) - math.pi
                st.rot[k] += diff
            else:
                st.rot[k] = v
            used.add(name)
            changed = True
            st.rot_unknown = False
    for name in ("U", "V", "W", "IU", "IV", "IW"):
        if name in d:
            raise st.err(f"axis {name[-1]} is not supported; expected X Y Z A B C", d[name][1])
    return changed


def _feed(st, d, used, arc=False) -> bool:
    """Applies F / FAUTO; True for FMAX (rapid, this block only)."""
    rapid = False
    for name in ("FU", "FZ"):
        if name in d:
            raise st.err(f"{name}: feed per {'revolution' if name == 'FU' else 'tooth'} is "
                         "not supported; expected F in mm/min", d[name][1])
    if "FMAX" in d:
        if arc:
            raise st.err("FMAX on an arc is not supported; expected F", d["FMAX"][1])
        rapid = True
        used.add("FMAX")
    if "FAUTO" in d:
        if not st.auto_feed > 0:
            raise st.err("FAUTO without a feed in TOOL CALL; expected TOOL CALL ... F",
                         d["FAUTO"][1])
        st.feed = st.auto_feed
        used.add("FAUTO")
    if "F" in d:
        val, col = d["F"]
        if val == "MAX":
            rapid = True
        else:
            v = st.value("F", val, col)
            if v < 0:
                raise st.err("negative feed; expected F >= 0", col)
            st.feed = v * st.feed_scale
        used.add("F")
    return rapid


def _comp(st, d, used, radius_word=False) -> None:
    for name in ("RL", "RR"):
        if name in d:
            raise st.err(f"radius compensation {name} moves the tool off the programmed path "
                         "by its radius; expected R0 (a tool-centre path from CAM)", d[name][1])
    if "R" in d and not radius_word:
        val, col = d["R"]
        if val is None or val.replace(" ", "") != "0":
            raise st.err(f"R{val or ''}: radius compensation other than R0 (paraxial R+/R-) "
                         "is not supported; expected R0", col)
        used.add("R")


def _finish(st, d, used) -> None:
    for name, (val, col) in d.items():
        if name not in used:
            raise st.err(f"word {name} is not used by this block", col)


def _direction(st, d, used) -> float:
    if "DR" not in d:
        raise st.err("arc without a direction; expected DR+ (counter-clockwise) or DR-")
    val, col = d["DR"]
    if val not in ("+", "-"):
        raise st.err("expected DR+ or DR-", col)
    used.add("DR")
    return 1.0 if val == "+" else -1.0


def _tangent_after_arc(axes, c, end, sweep):
    a1, a2, _ = axes
    th = math.atan2(end[a2] - c[1], end[a1] - c[0])
    t = np.zeros(3)
    s = 1.0 if sweep > 0 else -1.0
    t[a1], t[a2] = -s * math.sin(th), s * math.cos(th)
    return t


def _arc(st, plane, end, centre, sweep, used, d, ms):
    axes = PLANE_AXES[plane]
    a1, a2, _ = axes
    s = st.ppos
    try:
        radii = check_radii(centre[0], centre[1], s[a1], s[a2], end[a1], end[a2])
    except GeomError as exc:
        raise st.err(str(exc)) from None
    _finish(st, d, used)
    st.emit(3 if sweep > 0 else 2, end, plane, arc=(centre, radii, sweep, axes))
    st.tangent = _tangent_after_arc(axes, centre, end, sweep)
    return st.m_functions(ms, at_end=True)


def _begin(st, verb_len):
    d, ms = st.parse_words(verb_len)
    st.m_functions(ms, at_end=False)
    return d, ms, set()


_L_LINEAR = {"X": (0, False), "Y": (1, False), "Z": (2, False),
             "IX": (0, True), "IY": (1, True), "IZ": (2, True)}
_L_ROTARY = frozenset(("A", "B", "C", "IA", "IB", "IC"))
_L_OTHER = frozenset(("F", "FMAX", "FAUTO", "R", "RL", "RR", "FU", "FZ"))


def L(st) -> bool:
    """Straight line: one pass over the words (most blocks of a CAM program)."""
    d, ms = st.parse_words(1)
    if ms:
        if any(m == 140 for m, _ in ms):
            return _m140(st, d, ms)
        st.m_functions(ms, at_end=False)
    start = st.ppos
    target = None
    seen = 0
    rot = False
    other = False
    for name, (val, col) in d.items():
        lin = _L_LINEAR.get(name)
        if lin is not None:
            a, inc = lin
            bit = 1 << a
            if seen & bit:
                raise st.err(f"{name}: axis {name[-1]} programmed twice", col)
            seen |= bit
            if target is None:
                target = start.copy()
            v = st.value(name, val, col) * st.scale
            target[a] = target[a] + v if inc else v
        elif name in _L_ROTARY:
            rot = True
        elif name in _L_OTHER:
            other = True
        else:
            if name in ("U", "V", "W", "IU", "IV", "IW"):
                raise st.err(f"axis {name[-1]} is not supported; expected X Y Z A B C", col)
            raise st.err(f"word {name} is not used by this block", col)
    rapid = False
    if other:
        used: set = set()
        rapid = _feed(st, d, used)
        _comp(st, d, used)
    turned = _rotary(st, d, set()) if rot else False
    if target is not None or turned:
        st.emit(0 if rapid else 1, start if target is None else target,
                _WORKING[st.tool_axis])
        if target is not None:
            st.tangent = target - start
    return st.m_functions(ms, at_end=True) if ms else False


def _m140(st, d, ms) -> bool:
    if "MB" not in d:
        raise st.err("M140 without MB; expected M140 MB MAX or M140 MB+distance")
    others = [k for k in d if k not in ("MB", "F", "FMAX", "R")]
    if others:
        raise st.err(f"word {others[0]} with M140; expected M140 MB alone", d[others[0]][1])
    st.m_functions([(m, c) for m, c in ms if m != 140], at_end=False)
    if st.tcpm and st.vector is None and any(st.rot):
        raise st.err("M140 with the tool tilted by rotary axes: the tool axis needs the "
                     "machine's kinematics, which the reader does not have")
    axis = np.zeros(3)
    axis[st.tool_axis] = 1.0
    if st.tcpm and st.vector is not None:
        axis = st.R.T @ np.array(st.vector)
    val, col = d["MB"]
    target = st.ppos.copy()
    if val == "MAX":
        if st.retract_limit is None:
            raise st.err("M140 MB MAX retracts to the machine's travel limit, unknown to the "
                         "reader; pass retract_limit_mm (CLI: --retract-limit), the Z it "
                         "reaches, to read it", col)
        if st.tool_axis != 2 or (st.tcpm and st.vector is not None) or st.tilted:
            raise st.err("M140 MB MAX is read only with the tool along Z of an untilted "
                         "frame", col)
        target[2] = max(target[2], st.retract_limit)
    else:
        target = target + st.value("MB", val, col) * st.scale * axis
    st.emit(0, target, _WORKING[st.tool_axis])
    return st.m_functions([(m, c) for m, c in ms if m != 140], at_end=True)


def LN(st) -> bool:
    d, ms, used = _begin(st, 2)
    rapid = _feed(st, d, used)
    _comp(st, d, used)
    target, axes = _linear(st, d, used)
    n = [d.get(k) for k in ("NX", "NY", "NZ")]
    t = [d.get(k) for k in ("TX", "TY", "TZ")]
    if any(v is None for v in n):
        raise st.err("LN needs the surface normal NX NY NZ (all three components)")
    nv = np.array([st.value(k, v[0], v[1]) for k, v in zip(("NX", "NY", "NZ"), n)])
    if not np.linalg.norm(nv) > 1e-9:
        raise st.err("LN surface normal of zero length; expected a direction")
    used.update(("NX", "NY", "NZ"))
    if any(v is not None for v in t):
        if any(v is None for v in t):
            raise st.err("LN tool vector incomplete; expected TX TY TZ together")
        if not st.tcpm:
            raise st.err("LN tool vector TX TY TZ without M128 / FUNCTION TCPM; expected "
                         "tool centre point control on")
        tv = np.array([st.value(k, v[0], v[1]) for k, v in zip(("TX", "TY", "TZ"), t)])
        norm = float(np.linalg.norm(tv))
        if not norm > 1e-9:
            raise st.err("LN tool vector of zero length; expected a direction")
        tv = tv / norm
        st.vector = (float(tv[0]), float(tv[1]), float(tv[2]))
        used.update(("TX", "TY", "TZ"))
    _finish(st, d, used)
    start = st.ppos
    st.emit(0 if rapid else 1, target, _WORKING[st.tool_axis])
    st.tangent = target - start
    return st.m_functions(ms, at_end=True)


def CC(st) -> bool:
    d, ms, used = _begin(st, 2)
    if ms:
        raise st.err("M functions in a CC block; expected coordinates only", ms[0][1])
    target, axes = _linear(st, d, used)
    _finish(st, d, used)
    if not axes:
        plane = _WORKING[st.tool_axis]
    elif len(axes) == 2:
        plane = _PLANE_OF_PAIR[frozenset(axes)]
    else:
        raise st.err("CC needs two coordinates of one plane (or none: the current position)")
    a1, a2, _ = PLANE_AXES[plane]
    st.cc = (plane, float(target[a1]), float(target[a2]))
    return False


def _need_cc(st):
    if st.cc is None:
        raise st.err("no circle centre: expected a CC block before this one (a new tool "
                     "axis, datum shift or tilted plane clears it)")
    return st.cc


def C(st) -> bool:
    d, ms, used = _begin(st, 1)
    plane, c1, c2 = _need_cc(st)
    axes = PLANE_AXES[plane]
    _feed(st, d, used, arc=True)
    _comp(st, d, used)
    sign = _direction(st, d, used)
    end, _ = _linear(st, d, used)
    s = st.ppos
    sweep = sweep_to(c1, c2, s[axes[0]], s[axes[1]], end[axes[0]], end[axes[1]], sign)
    return _arc(st, plane, end, (c1, c2), sweep, used, d, ms)


def _plane_of(st, axes_prog):
    work = _WORKING[st.tool_axis]
    inplane = set(PLANE_AXES[work][:2])
    if set(axes_prog) <= inplane or len(axes_prog) != 2:
        return work
    return _PLANE_OF_PAIR[frozenset(axes_prog)]


def CR(st) -> bool:
    d, ms, used = _begin(st, 2)
    _feed(st, d, used, arc=True)
    _comp(st, d, used, radius_word=True)
    sign = _direction(st, d, used)
    if "R" not in d:
        raise st.err("CR without a radius; expected R+r (up to 180 deg) or R-r (more)")
    r = st.value("R", *d["R"]) * st.scale
    used.add("R")
    end, axes_prog = _linear(st, d, used)
    plane = _plane_of(st, axes_prog)
    s6 = [*st.ppos, 0.0, 0.0, 0.0]
    e6 = [*end, 0.0, 0.0, 0.0]
    try:
        centre, _radii, sweep = arc_from_words({"R": r}, 3 if sign > 0 else 2, plane, 1.0,
                                               911, s6, e6)
    except ArcWordError as exc:
        raise st.err(str(exc), d["R"][1]) from None
    a1, a2, _ = PLANE_AXES[plane]
    return _arc(st, plane, end, (centre[a1], centre[a2]), sweep, used, d, ms)


def CT(st) -> bool:
    d, ms, used = _begin(st, 2)
    _feed(st, d, used, arc=True)
    _comp(st, d, used)
    end, axes_prog = _linear(st, d, used)
    plane = _plane_of(st, axes_prog)
    a1, a2, _ = PLANE_AXES[plane]
    if st.tangent is None:
        raise st.err("CT needs a contour element before it (a line or arc) to be tangent to")
    s = st.ppos
    try:
        c1, c2, sign = tangent_centre(s[a1], s[a2], end[a1], end[a2], st.tangent[a1],
                                      st.tangent[a2])
    except GeomError as exc:
        raise st.err(str(exc)) from None
    sweep = sweep_to(c1, c2, s[a1], s[a2], end[a1], end[a2], sign)
    return _arc(st, plane, end, (c1, c2), sweep, used, d, ms)


def _polar_start(st, plane, c1, c2):
    a1, a2, _ = PLANE_AXES[plane]
    s = st.ppos
    return math.hypot(s[a1] - c1, s[a2] - c2), math.atan2(s[a2] - c2, s[a1] - c1)


def _axial(st, d, used, plane):
    """The axial coordinate (helix) of a polar block; other linear words refused."""
    a1, a2, ax = PLANE_AXES[plane]
    target, _ = _linear(st, d, used, allowed=(ax,))
    return target[ax]


def CP(st) -> bool:
    d, ms, used = _begin(st, 2)
    plane, c1, c2 = _need_cc(st)
    axes = PLANE_AXES[plane]
    _feed(st, d, used, arc=True)
    _comp(st, d, used)
    sign = _direction(st, d, used)
    if "PR" in d or "IPR" in d:
        raise st.err("CP takes no radius (PR); the radius is the distance to the pole CC")
    r, a0 = _polar_start(st, plane, c1, c2)
    if "IPA" in d:
        ipa = st.value("IPA", *d["IPA"])
        if ipa == 0 or (ipa > 0) != (sign > 0):
            raise st.err("CP IPA and DR disagree; expected IPA+ with DR+ and IPA- with DR-",
                         d["IPA"][1])
        sweep = math.radians(ipa)
        used.add("IPA")
    elif "PA" in d:
        pa = math.radians(st.value("PA", *d["PA"]))
        used.add("PA")
        sweep = sweep_to(0.0, 0.0, math.cos(a0), math.sin(a0), math.cos(pa), math.sin(pa),
                         sign)
    else:
        raise st.err("CP without an angle; expected PA or IPA")
    end = st.ppos.copy()
    end[axes[0]] = c1 + r * math.cos(a0 + sweep)
    end[axes[1]] = c2 + r * math.sin(a0 + sweep)
    end[axes[2]] = _axial(st, d, used, plane)
    return _arc(st, plane, end, (c1, c2), sweep, used, d, ms)


def LP(st) -> bool:
    d, ms, used = _begin(st, 2)
    plane, c1, c2 = _need_cc(st)
    axes = PLANE_AXES[plane]
    rapid = _feed(st, d, used)
    _comp(st, d, used)
    r, a = _polar_start(st, plane, c1, c2)
    if "PR" in d:
        r = st.value("PR", *d["PR"]) * st.scale
        used.add("PR")
    elif "IPR" in d:
        r += st.value("IPR", *d["IPR"]) * st.scale
        used.add("IPR")
    if r < 0:
        raise st.err("polar radius PR < 0; expected PR >= 0")
    if "PA" in d:
        a = math.radians(st.value("PA", *d["PA"]))
        used.add("PA")
    elif "IPA" in d:
        a += math.radians(st.value("IPA", *d["IPA"]))
        used.add("IPA")
    end = st.ppos.copy()
    end[axes[2]] = _axial(st, d, used, plane)
    end[axes[0]] = c1 + r * math.cos(a)
    end[axes[1]] = c2 + r * math.sin(a)
    _finish(st, d, used)
    start = st.ppos
    st.emit(0 if rapid else 1, end, plane)
    st.tangent = end - start
    return st.m_functions(ms, at_end=True)


MOVES = {"L": L, "LN": LN, "LP": LP, "CC": CC, "C": C, "CR": CR, "CT": CT, "CP": CP}
