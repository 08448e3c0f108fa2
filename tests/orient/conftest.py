"""Fixtures shared by the orient tests."""

from __future__ import annotations

import pytest

from orient.plan import plan
from orient.scenario import bundled_scenario, load_plan_scenario


@pytest.fixture(scope="session")
def planned():
    """The bundled thin wall's scenario and its plan in one process (about 35 s; tests
    read it and do not change it)."""
    scn = load_plan_scenario(bundled_scenario("thin-wall"))
    return scn, plan(scn)
