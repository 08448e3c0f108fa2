"""``nc``: read G-code, hold tool paths, 5-axis kinematics, write NC programs."""
from .gcode import parse_program, read_program
from .errors import NCParseError

__all__ = ["parse_program", "read_program", "NCParseError"]
