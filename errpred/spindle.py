"""Spindle speed and the periods and frequencies it sets: the one conversion of the project.

A spindle turning at ``S`` rev/min with ``z`` teeth passes a tooth every
``tau = 60 / (S z)`` seconds, at ``S z / 60`` Hz; with ``z = 1`` these are the
revolution's period and frequency. Plain arithmetic: floats and numpy arrays alike.
"""

from __future__ import annotations

from typing import Any

__all__ = ["SECONDS_PER_MINUTE", "rpm_for_tooth_period", "tooth_frequency", "tooth_period"]

#: rev/min to rev/s [s/min].
SECONDS_PER_MINUTE = 60.0


def tooth_period(spindle_rpm: Any, teeth: Any = 1) -> Any:
    """Tooth-passing period ``60 / (spindle_rpm teeth)`` [s].

    Parameters
    ----------
    spindle_rpm : float or ndarray [rev/min]
    teeth : int or ndarray [-]
        Teeth (flutes), or any number of equal steps per revolution; 1: the revolution.
    """
    return SECONDS_PER_MINUTE / (spindle_rpm * teeth)


def rpm_for_tooth_period(period_s: Any, teeth: Any = 1) -> Any:
    """Spindle speed whose tooth period is ``period_s``, ``60 / (period_s teeth)`` [rev/min].

    Parameters
    ----------
    period_s : float or ndarray [s]
    teeth : int or ndarray [-]
    """
    return SECONDS_PER_MINUTE / (period_s * teeth)


def tooth_frequency(spindle_rpm: Any, teeth: Any = 1) -> Any:
    """Tooth-passing frequency ``spindle_rpm / 60 teeth`` [Hz].

    Parameters
    ----------
    spindle_rpm : float or ndarray [rev/min]
    teeth : int or ndarray [-]
    """
    return spindle_rpm / SECONDS_PER_MINUTE * teeth
