"""``nc``: read G-code, hold tool paths, 5-axis kinematics, write NC programs."""
from .errors import NCParseError
from .gcode import parse_program, read_program

__all__ = ["parse_program", "read_program", "NCParseError"]
