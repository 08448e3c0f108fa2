"""The simulated machine (``docs/method.md`` §8): time-domain cutting with regeneration,
accelerometers, an NC that runs 5-axis programs behind a Modbus TCP server, and the
controller side that watches for chatter and re-orients the tool over Modbus."""

from .controller import Controller, NCClient, ProgramGeometry
from .cutter import Cut, Cutter
from .cutting import (
    CuttingModel,
    MillingRun,
    growth_rate,
    prepare_cut,
    simulate,
    stability_boundary,
    with_system,
)
from .machine import NCState, SimulatedNC, SurfaceRecord
from .registers import REGISTERS, Register
from .sensors import (
    Accelerometers,
    AccelerometerStream,
    SensorSignals,
    sample_accelerometers,
)
from .server import NCServer, RegisterStore

__all__ = [
    "REGISTERS",
    "AccelerometerStream",
    "Accelerometers",
    "Controller",
    "Cut",
    "Cutter",
    "CuttingModel",
    "MillingRun",
    "NCClient",
    "NCServer",
    "NCState",
    "ProgramGeometry",
    "Register",
    "RegisterStore",
    "SensorSignals",
    "SimulatedNC",
    "SurfaceRecord",
    "growth_rate",
    "prepare_cut",
    "sample_accelerometers",
    "simulate",
    "stability_boundary",
    "with_system",
]
