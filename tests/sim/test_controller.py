"""The controller's set-up: what it prepares before the first chatter, and what it
leaves out when it only watches (open loop)."""

from __future__ import annotations

import pytest

from orient.scenario import load_plan_scenario
from sim.controller import Controller, ProgramGeometry
from sim.sensors import Accelerometers

from .job_scenario import light_scenario


class _Registers:
    """The two calls the controller's set-up makes to its NC (no server)."""

    def state(self) -> dict:
        s = Accelerometers()
        return {"accel_rate_hz": s.sample_rate_hz, "accel_lsb_um_s2": s.lsb_m_s2 * 1e6}

    def holding(self, name: str) -> float:
        assert name == "orient_seq"
        return 0.0


@pytest.fixture(scope="module")
def scn(tmp_path_factory):
    return load_plan_scenario(light_scenario(tmp_path_factory.mktemp("ctl") / "scn"))


@pytest.mark.parametrize("act", [True, False])
def test_the_margins_are_prepared_only_by_a_controller_that_acts(scn, act):
    """Acting (closed loop, eigen rule), the controller builds the wall's model and the
    first posture's margins before the cut; watching only (open loop) it never needs
    them: in ``python -m sim run`` the open loop's controller built the wall's finite
    elements for nothing (10-15 s)."""
    geo = ProgramGeometry(scn)
    Controller(_Registers(), geo, strategy="eigen", act=act)
    assert bool(geo._margin) is act
    assert (geo._workpiece is not None) is act
    assert geo._P                   # the process gain's kernels are loaded either way
