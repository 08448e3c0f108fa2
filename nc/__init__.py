"""``nc``: read G-code, hold tool paths, 5-axis kinematics, write NC programs."""
from .dialects import detect_dialect, read_any
from .errors import NCParseError
from .gcode import parse_program, read_program
from .heidenhain import parse_heidenhain, read_heidenhain
from .siemens import parse_siemens, read_siemens

__all__ = ["parse_program", "read_program", "parse_heidenhain", "read_heidenhain",
           "parse_siemens", "read_siemens", "read_any", "detect_dialect", "NCParseError"]
