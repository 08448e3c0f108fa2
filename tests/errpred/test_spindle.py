"""errpred.spindle: the one conversion between spindle speed and tooth period/frequency."""

from __future__ import annotations

import numpy as np

from errpred.spindle import rpm_for_tooth_period, tooth_frequency, tooth_period


def test_values_round_trip_and_arrays() -> None:
    assert tooth_period(6000.0, 4) == 0.0025          # 100 rev/s, 4 teeth
    assert tooth_period(6000.0) == 0.01               # the revolution
    assert tooth_frequency(6000.0, 4) == 400.0
    assert rpm_for_tooth_period(0.0025, 4) == 6000.0
    rpm = np.array([1000.0, 7321.0, 15000.0])
    tau = tooth_period(rpm, 3)
    np.testing.assert_allclose(rpm_for_tooth_period(tau, 3), rpm, rtol=1e-15)
    np.testing.assert_allclose(tau * tooth_frequency(rpm, 3), 1.0, rtol=1e-15)
    assert tau.shape == (3,)
